// The CLI's output helpers: CSV round-trips doubles, the SVG plot is
// well-formed XML with axes, ticks, labels and legend, nice ticks cover the
// range, and watch lines are stable text.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>

#include "client/curve_output.h"
#include "client/exit_codes.h"
#include "client/fit_output.h"
#include "client/flow_output.h"
#include "client/output_file.h"
#include "client/spec_arg.h"
#include "client/study_output.h"
#include "client/suggest.h"
#include "client/suspension_output.h"
#include "client/svg_plot.h"
#include "client/watch_printer.h"
#include "io/h5md.h"

namespace cellflow::client {
namespace {

namespace fs = std::filesystem;

Curve make_curve() {
  Curve curve;
  curve.columns = {"point", "deformation", "force_n", "hertz_force_n"};
  curve.integer_columns = {true, false, false, false};
  for (int i = 0; i < 5; ++i) {
    const double eps = 0.03 * (i + 1);
    // F = (4/3) E* R^2 eps^1.5 with E* = 1333 Pa, R = 5 um, scaled by 1.1 for the "simulation"
    const double hertz = 4.0 / 3.0 * 1333.0 * 25e-12 * std::pow(eps, 1.5);
    curve.rows.push_back({static_cast<double>(i), eps, 1.1 * hertz, hertz});
  }
  return curve;
}

TEST(CurveOutput, CsvRoundTripsDoubles) {
  const Curve curve = make_curve();
  const std::string csv = curve_csv(curve);
  EXPECT_EQ(csv.substr(0, csv.find('\n')), "point,deformation,force_n,hertz_force_n");
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);
  for (const auto& row : curve.rows) {
    ASSERT_TRUE(std::getline(lines, line));
    std::istringstream fields(line);
    std::string field;
    for (double expected : row) {
      ASSERT_TRUE(std::getline(fields, field, ','));
      EXPECT_EQ(std::strtod(field.c_str(), nullptr), expected);  // exact: 17 significant digits
    }
  }
  EXPECT_EQ(csv.find("\n0,"), csv.find('\n'));  // the point index is written as an integer
}

TEST(CurveOutput, NiceTicksCoverTheRangeInRoundSteps) {
  const auto ticks = nice_ticks(0.0, 0.15);
  ASSERT_GE(ticks.size(), 4u);
  EXPECT_EQ(ticks.front(), 0.0);
  EXPECT_GE(ticks.back(), 0.15 - 1e-12);
  const double step = ticks[1] - ticks[0];
  // Six ticks wanted: raw step 0.15 / 5 = 0.03; the smallest 1-2-5 step >= 0.03 is 0.05.
  EXPECT_NEAR(step, 0.05, 1e-15);
  EXPECT_EQ(ticks.size(), 4u);
}

TEST(CurveOutput, SvgIsWellFormedWithAxesLabelsAndLegend) {
  const std::string svg = curve_svg(make_curve(), "job-1 (compression)");
  for (const char* needle : {"<svg", "</svg>", "deformation", "force (", "simulation", "Hertz", "polyline",
                             "stroke-dasharray", "job-1 (compression)"}) {
    EXPECT_NE(svg.find(needle), std::string::npos) << needle;
  }
  const fs::path path = fs::temp_directory_path() / ("cellflow_plot_" + std::to_string(getpid()) + ".svg");
  std::ofstream(path) << svg;
  const std::string command = "xmllint --noout " + path.string() + " 2>&1";
  EXPECT_EQ(std::system(command.c_str()), 0);
  fs::remove(path);
}

TEST(CurveOutput, ReadsTheCurveOfAResultFile) {
  const fs::path path = fs::temp_directory_path() / ("cellflow_curve_" + std::to_string(getpid()) + ".h5");
  {
    auto writer = io::H5mdWriter::create(path.string());
    ASSERT_TRUE(writer.ok());
    for (int i = 0; i < 3; ++i) {
      ASSERT_TRUE((*writer)->append_observable("deformation", i + 1, 0.1 * i, 0.1 * i).ok());
      ASSERT_TRUE((*writer)->append_observable("force_n", i + 1, 0.1 * i, 1e-9 * i).ok());
      const double axes[3] = {1.0 * i, 2.0 * i, 3.0 * i};
      ASSERT_TRUE((*writer)->append_observable("semi_axes_m", i + 1, 0.1 * i, axes).ok());
    }
  }
  auto curve = read_curve(path.string());
  ASSERT_TRUE(curve.ok()) << curve.status().to_string();
  // cellflow-run's column order; only the columns the file can fill.
  EXPECT_EQ(curve->columns,
            (std::vector<std::string>{"point", "deformation", "force_n", "a1_m", "a2_m", "a3_m"}));
  ASSERT_EQ(curve->rows.size(), 3u);
  EXPECT_EQ(curve->rows[2][0], 2.0);
  EXPECT_EQ(curve->rows[2][2], 2e-9);
  EXPECT_EQ(curve->rows[2][5], 6.0);
  fs::remove(path);
}

// Every data point of an SVG plot (circle centres, polyline vertices) lies
// strictly inside the plotting area (the black frame rectangle), and none
// lies inside the legend box (the grey rectangle).
struct Box {
  double x = 0, y = 0, w = 0, h = 0;
  bool contains(double px, double py) const { return px >= x && px <= x + w && py >= y && py <= y + h; }
  bool strictly_contains(double px, double py) const { return px > x && px < x + w && py > y && py < y + h; }
};

Box rect_with(const std::string& svg, const std::string& stroke) {
  const std::regex rect(
      "<rect x=\"([-0-9.]+)\" y=\"([-0-9.]+)\" width=\"([-0-9.]+)\" height=\"([-0-9.]+)\"[^>]*stroke=\"" +
      stroke + "\"");
  std::smatch m;
  EXPECT_TRUE(std::regex_search(svg, m, rect)) << stroke;
  if (m.empty()) return {};
  return {std::stod(m[1]), std::stod(m[2]), std::stod(m[3]), std::stod(m[4])};
}

std::vector<std::pair<double, double>> data_points(const std::string& svg) {
  std::vector<std::pair<double, double>> points;
  const std::regex circle("<circle cx=\"([-0-9.]+)\" cy=\"([-0-9.]+)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), circle); it != std::sregex_iterator(); ++it)
    points.emplace_back(std::stod((*it)[1]), std::stod((*it)[2]));
  const std::regex polyline("points=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), polyline); it != std::sregex_iterator(); ++it) {
    std::istringstream vertices((*it)[1].str());
    std::string vertex;
    while (vertices >> vertex) {
      const auto comma = vertex.find(',');
      points.emplace_back(std::stod(vertex.substr(0, comma)), std::stod(vertex.substr(comma + 1)));
    }
  }
  return points;
}

void expect_data_inside_and_off_the_legend(const std::string& svg, std::size_t min_points) {
  const Box plot = rect_with(svg, "black");
  const Box legend = rect_with(svg, "#999999");
  const auto points = data_points(svg);
  // The legend's own samples are circles too: drop those inside the legend box,
  // then require that no data point was among them (all data lies in the plot).
  std::size_t data = 0;
  for (const auto& [x, y] : points) {
    if (legend.contains(x, y)) {
      EXPECT_FALSE(plot.contains(x, y)) << "legend box over data at " << x << "," << y;
      continue;
    }
    ++data;
    EXPECT_TRUE(plot.strictly_contains(x, y)) << "point on or outside the frame: " << x << "," << y;
  }
  EXPECT_GE(data, min_points);
  // The legend box and the plotting area do not overlap at all.
  EXPECT_TRUE(legend.x >= plot.x + plot.w || legend.x + legend.w <= plot.x || legend.y >= plot.y + plot.h ||
              legend.y + legend.h <= plot.y);
}

TEST(SvgPlot, NiceTicksIncludeTheDataMaximum) {
  // 0.89 is past 0.8 by less than half a 0.2 step: the last tick used to be 0.8.
  for (double hi : {0.89, 0.96, 0.15, 1.0, 7.3, 123.0, 0.0299}) {
    const auto ticks = nice_ticks(0.0, hi);
    EXPECT_LE(ticks.front(), 0.0);
    EXPECT_GE(ticks.back(), hi * (1 - 1e-12)) << hi;
    EXPECT_LT(ticks.back() - (ticks[1] - ticks[0]), hi) << hi;  // no tick beyond the first one past hi
  }
  const auto negative = nice_ticks(-0.37, 2.2);
  EXPECT_LE(negative.front(), -0.37);
  EXPECT_GE(negative.back(), 2.2);
}

TEST(SvgPlot, CurvePointsLieInsideTheFrameAndOffTheLegend) {
  Curve curve = make_curve();
  // A maximum just past a tick (the clipping case), and a point at the origin.
  curve.rows.push_back({5.0, 0.17, 2.0 * curve.rows.back()[2], curve.rows.back()[3]});
  curve.rows.insert(curve.rows.begin(), {0.0, 0.0, 0.0, 0.0});
  expect_data_inside_and_off_the_legend(curve_svg(curve, "c"), 2 * curve.rows.size());
}

TEST(SvgPlot, FlowPlotsLieInsideTheFrameAndOffTheLegend) {
  std::vector<SteadyPoint> points = {
      {"a", 0.05, 0.061, "steady"}, {"b", 0.3, 0.33, "steady"}, {"c", 0.89, 0.64, "max_strain"}};
  expect_data_inside_and_off_the_legend(steady_deformation_svg(points, "steady"), 3);
  Curve d;
  d.columns = {"strain", "taylor_deformation"};
  d.integer_columns = {false, false};
  for (int i = 0; i <= 20; ++i) d.rows.push_back({0.481 * i, 0.33 * (1 - std::exp(-0.5 * i))});
  expect_data_inside_and_off_the_legend(deformation_svg(d, 0.3, 0.33, "d"), 21);
}

// A suspension result as jobs/suspension writes it (the observables and
// scalars the client reads): 3 cells, 6 samples.
fs::path write_suspension_result(const std::string& stem) {
  const fs::path path = fs::temp_directory_path() / (stem + std::to_string(getpid()) + ".h5");
  auto writer = io::H5mdWriter::create(path.string());
  EXPECT_TRUE(writer.ok());
  io::H5mdWriter& w = **writer;
  EXPECT_TRUE(w.write_scalar("/parameters/setup/capillary_number", 0.2).ok());
  EXPECT_TRUE(w.write_scalar("/parameters/setup/volume_fraction", 0.11).ok());
  EXPECT_TRUE(w.write_integer("/parameters/setup/cell_count", 3).ok());
  for (int i = 0; i < 6; ++i) {
    const double t = 0.01 * i, strain = 0.5 * i;
    const double cells[3] = {0.02 * i, 0.03 * i, 0.01 * i};
    EXPECT_TRUE(w.append_observable("strain", 100 * i, t, strain).ok());
    EXPECT_TRUE(w.append_observable("mean_taylor_deformation", 100 * i, t, 0.02 * i).ok());
    EXPECT_TRUE(w.append_observable("mean_inclination_rad", 100 * i, t, 0.5).ok());
    EXPECT_TRUE(w.append_observable("relative_viscosity", 100 * i, t, 1.3).ok());
    EXPECT_TRUE(w.append_count("contact_pairs", 100 * i, t, i % 2).ok());
    const double average = i >= 2 ? 0.07 : 0.0;
    EXPECT_TRUE(w.append_observable("average_taylor_deformation", 100 * i, t, average).ok());
    EXPECT_TRUE(w.append_observable("average_taylor_deformation_error", 100 * i, t, average / 10).ok());
    EXPECT_TRUE(w.append_observable("average_relative_viscosity", 100 * i, t, i >= 2 ? 1.3 : 0.0).ok());
    EXPECT_TRUE(
        w.append_observable("average_relative_viscosity_error", 100 * i, t, i >= 2 ? 0.01 : 0.0).ok());
    EXPECT_TRUE(w.append_observable("cell_taylor_deformation", 100 * i, t, cells).ok());
  }
  EXPECT_TRUE(w.write_string("/summary/stop", "max_strain").ok());
  EXPECT_TRUE(w.write_scalar("/summary/average_taylor_deformation", 0.07).ok());
  EXPECT_TRUE(w.write_scalar("/summary/average_taylor_deformation_error", 0.007).ok());
  EXPECT_TRUE(w.write_scalar("/summary/average_relative_viscosity", 1.3).ok());
  EXPECT_TRUE(w.write_scalar("/summary/average_relative_viscosity_error", 0.01).ok());
  EXPECT_TRUE(w.close().ok());
  return path;
}

TEST(SuspensionOutput, ReadsTheMeanSeriesTheBandAndTheAverages) {
  const fs::path path = write_suspension_result("cellflow_suspension_");
  EXPECT_TRUE(is_suspension_result(path.string()));
  auto series = read_suspension_series(path.string());
  ASSERT_TRUE(series.ok()) << series.status().to_string();
  EXPECT_EQ(series->table.columns,
            (std::vector<std::string>{"sample", "time_s", "strain", "cell_count", "mean_taylor_deformation",
                                      "mean_inclination_rad", "relative_viscosity", "contact_pairs",
                                      "average_taylor_deformation", "average_taylor_deformation_error",
                                      "average_relative_viscosity", "average_relative_viscosity_error"}));
  ASSERT_EQ(series->table.rows.size(), 6u);
  const std::vector<double>& row = series->table.rows[3];
  EXPECT_EQ(row[0], 3.0);
  EXPECT_EQ(row[1], 0.03);
  EXPECT_EQ(row[2], 1.5);
  EXPECT_EQ(row[3], 3.0);
  EXPECT_EQ(row[4], 0.06);
  EXPECT_EQ(row[7], 1.0);
  EXPECT_EQ(row[8], 0.07);
  ASSERT_EQ(series->min_taylor_deformation.size(), 6u);
  EXPECT_EQ(series->min_taylor_deformation[3], 0.03);
  EXPECT_EQ(series->max_taylor_deformation[3], 0.09);
  EXPECT_EQ(curve_csv(series->table).substr(0, 30), "sample,time_s,strain,cell_coun");
  // Mean, band edges and the average: every polyline vertex inside the frame.
  const std::string svg = suspension_svg(*series, "s");
  expect_data_inside_and_off_the_legend(svg, 3 * 6 + 2);
  EXPECT_NE(svg.find("min and max over the cells"), std::string::npos);
  EXPECT_NE(svg.find("time average 0.0700"), std::string::npos);

  auto point = read_suspension_point(path.string(), "job-1");
  ASSERT_TRUE(point.ok()) << point.status().to_string();
  EXPECT_EQ(point->capillary_number, 0.2);
  EXPECT_EQ(point->volume_fraction, 0.11);
  EXPECT_EQ(point->cell_count, 3);
  EXPECT_EQ(point->average_relative_viscosity_error, 0.01);
  EXPECT_EQ(point->stop, "max_strain");
  fs::remove(path);
  // A shear-flow-like file is not a suspension.
  const fs::path flow =
      fs::temp_directory_path() / ("cellflow_not_suspension_" + std::to_string(getpid()) + ".h5");
  {
    auto writer = io::H5mdWriter::create(flow.string());
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE((*writer)->append_observable("strain", 0, 0.0, 0.0).ok());
  }
  EXPECT_FALSE(is_suspension_result(flow.string()));
  EXPECT_EQ(read_suspension_series(flow.string()).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(read_suspension_point(flow.string(), "x").status().code(), StatusCode::kNotFound);
  fs::remove(flow);
}

TEST(SuspensionOutput, AveragesAgainstCaAndVolumeFractionWithErrorBars) {
  std::vector<SuspensionPoint> points = {{"a", 0.1, 0.11, 4, 0.09, 0.004, 1.35, 0.02, "max_strain"},
                                         {"b", 0.2, 0.22, 8, 0.17, 0.006, 1.8, 0.05, "steady"},
                                         {"c", 0.4, 0.11, 4, 0.3, 0.01, 1.2, 0.03, "cancelled"}};
  for (SuspensionAxis axis : {SuspensionAxis::kCapillaryNumber, SuspensionAxis::kVolumeFraction}) {
    const std::string svg = suspension_points_svg(points, axis, "set");
    // One page holding two whole plots.
    EXPECT_EQ(std::count(svg.begin(), svg.end(), '<') - std::count(svg.begin(), svg.end(), '>'), 0);
    const std::regex nested("<svg ");
    EXPECT_EQ(std::distance(std::sregex_iterator(svg.begin(), svg.end(), nested), std::sregex_iterator()), 3);
    // Three markers in each plot (radius 4), one open (the cancelled job).
    const std::regex marker(R"(<circle [^>]*r="4")");
    EXPECT_EQ(std::distance(std::sregex_iterator(svg.begin(), svg.end(), marker), std::sregex_iterator()), 6);
    const std::regex open(R"(<circle [^>]*r="4" fill="white")");
    EXPECT_EQ(std::distance(std::sregex_iterator(svg.begin(), svg.end(), open), std::sregex_iterator()), 2);
    // An error bar per point and plot.
    const std::regex bar(R"(<line [^>]*stroke-width="1.5"/>)");
    EXPECT_GE(std::distance(std::sregex_iterator(svg.begin(), svg.end(), bar), std::sregex_iterator()), 6);
    EXPECT_EQ(svg.find("rigid spheres") != std::string::npos, axis == SuspensionAxis::kVolumeFraction);
  }
}

TEST(StudyOutput, OverlaysAndSweptSteadyDLieInsideTheFrameAndOffTheLegend) {
  std::vector<LabelledCurve> curves;
  for (double e : {500.0, 1000.0, 2000.0}) {
    Curve c = make_curve();
    for (auto& row : c.rows) row[c.column("force_n")] *= e / 1000.0;
    curves.push_back({"youngsModulusPa=" + std::to_string(static_cast<int>(e)), c});
  }
  const std::string svg = curves_overlay_svg(curves, "sweep");
  EXPECT_EQ(std::regex_search(svg, std::regex("youngsModulusPa=2000")), true);
  expect_data_inside_and_off_the_legend(svg, 3 * curves[0].curve.rows.size());
  const std::vector<SweptSteadyPoint> points = {{4e-6, 0.12, true}, {2e-6, 0.05, true}, {6e-6, 0.2, false}};
  expect_data_inside_and_off_the_legend(swept_steady_svg(points, "shearFlow.cell.radiusM", "d"), 3);
}

TEST(StudyOutput, SetArgumentsBecomeAxesAndSpecEdits) {
  auto axis = parse_set_axis(
      "compression.numerics.volumetricTerm=VOLUMETRIC_TERM_PER_TET,\"VOLUMETRIC_TERM_NODAL_AVERAGE\"");
  ASSERT_TRUE(axis.ok()) << axis.status().to_string();
  EXPECT_EQ(axis->path(), "compression.numerics.volumetricTerm");
  ASSERT_EQ(axis->values_size(), 2);
  EXPECT_EQ(axis->values(0), "\"VOLUMETRIC_TERM_PER_TET\"") << "a bare word is a JSON string";
  EXPECT_EQ(axis->values(1), "\"VOLUMETRIC_TERM_NODAL_AVERAGE\"");
  EXPECT_FALSE(parse_set_axis("noequals").ok());
  EXPECT_FALSE(parse_set_axis("a.b=").ok());
  EXPECT_FALSE(parse_set_axis("a.b=1,,2").ok());
  v1::JobSpec spec;
  spec.mutable_compression()->set_max_deformation(0.2);
  auto edited = apply_set(spec, "compression.loadPoints=12");
  ASSERT_TRUE(edited.ok());
  EXPECT_EQ(edited->compression().load_points(), 12);
  auto refused = apply_set(spec, "compression.loadPoints=1.5");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().message().rfind("--set compression.loadPoints: ", 0), 0u)
      << refused.status().message();
  // A child's value index: GRID with the last axis fastest, ZIP the index itself.
  v1::StudySpec study;
  for (int n : {2, 3}) {
    auto* a = study.add_axes();
    for (int k = 0; k < n; ++k) a->add_values(std::to_string(k));
  }
  EXPECT_EQ(study_value_index(study, 4, 0), 1);
  EXPECT_EQ(study_value_index(study, 4, 1), 1);
  EXPECT_EQ(study_value_index(study, 5, 1), 2);
  study.set_combination(v1::StudySpec::ZIP);
  EXPECT_EQ(study_value_index(study, 1, 0), 1);
}

TEST(SvgPlot, FitPointsLieInsideTheFrameAndOffTheLegend) {
  FitCurveSeries s;
  s.name = "cell-1";
  for (int i = 0; i < 12; ++i) {
    const double eps = 0.0123 * i - 0.01;
    const double f = eps > 0 ? 2e-9 * std::pow(eps, 1.5) : -1e-12 * (i + 1);  // noise below zero
    s.sample.push_back(i);
    s.indentation_m.push_back(eps * 10e-6);
    s.deformation.push_back(eps);
    s.force_n.push_back(f * 1.05);
    s.model_force_n.push_back(f);
    s.hertz_force_n.push_back(f * 0.9);
  }
  expect_data_inside_and_off_the_legend(fit_svg({s}, "fit"), 12);
}

TEST(OutputFile, DashIsStdoutAndTheExtensionMustBeTheFormat) {
  EXPECT_TRUE(is_stdout_name("-"));
  EXPECT_FALSE(is_stdout_name("-.svg"));
  EXPECT_EQ(check_output_name("-", "SVG", {".svg"}), "");
  EXPECT_EQ(check_output_name("", "CSV", {".csv"}), "");
  EXPECT_EQ(check_output_name("out/curve.svg", "SVG", {".svg"}), "");
  EXPECT_EQ(check_output_name("CURVE.SVG", "SVG", {".svg"}), "");
  EXPECT_EQ(check_output_name("r.hdf5", "HDF5", {".h5", ".hdf5"}), "");
  EXPECT_EQ(check_output_name("x.png", "SVG", {".svg"}),
            "-o x.png: the extension .png is not SVG output; use .svg (or - for stdout)");
  EXPECT_EQ(check_output_name("result", "HDF5", {".h5", ".hdf5"}),
            "-o result: no extension; use .h5 or .hdf5 (or - for stdout)");
  const fs::path path =
      fs::temp_directory_path() / ("cellflow_output_" + std::to_string(::getpid()) + ".csv");
  ASSERT_TRUE(write_output(path.string(), "a,b\n"));
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "a,b");
  fs::remove(path);
  EXPECT_FALSE(write_output("/nonexistent-dir/x.csv", "a"));
}

TEST(SpecArg, FileDashAndInlineJson) {
  std::istringstream none;
  const SpecText inline_spec = read_spec_arg("  {\"name\": \"x\"}", none);
  EXPECT_EQ(inline_spec.error, "");
  EXPECT_EQ(inline_spec.text, "  {\"name\": \"x\"}");
  EXPECT_EQ(inline_spec.source, "inline spec");
  std::istringstream in("{\"name\": \"from stdin\"}\n");
  const SpecText piped = read_spec_arg("-", in);
  EXPECT_EQ(piped.error, "");
  EXPECT_EQ(piped.text, "{\"name\": \"from stdin\"}\n");
  EXPECT_EQ(piped.source, "stdin");
  std::istringstream empty;
  EXPECT_NE(read_spec_arg("-", empty).error, "");
  const fs::path path = fs::temp_directory_path() / ("cellflow_spec_" + std::to_string(::getpid()) + ".json");
  std::ofstream(path) << "{}";
  const SpecText file = read_spec_arg(path.string(), none);
  EXPECT_EQ(file.error, "");
  EXPECT_EQ(file.text, "{}");
  EXPECT_EQ(file.source, path.string());
  fs::remove(path);
  EXPECT_EQ(read_spec_arg(path.string(), none).error, "cannot read " + path.string());
}

TEST(Suggest, NearestKnownWordWithinAFewEdits) {
  EXPECT_EQ(edit_distance("list", "list"), 0u);
  EXPECT_EQ(edit_distance("lsit", "list"), 1u);  // a swap is one edit
  EXPECT_EQ(edit_distance("", "abc"), 3u);
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
  const std::vector<std::string> commands = {"submit", "watch",  "get",  "list", "cancel",
                                             "delete", "result", "plot", "fit"};
  EXPECT_EQ(closest_word("lsit", commands), "list");
  EXPECT_EQ(closest_word("resutl", commands), "result");
  EXPECT_EQ(closest_word("sumbit", commands), "submit");
  EXPECT_EQ(closest_word("plto", commands), "plot");
  EXPECT_EQ(closest_word("frobnicate", commands), "");
  EXPECT_EQ(closest_word("list", commands), "");        // not mistyped
  EXPECT_EQ(closest_word("canc", commands), "cancel");  // the prefix of one
  const std::vector<std::string> flags = {"--state", "--page-size", "--json", "--server", "--radius-m"};
  EXPECT_EQ(closest_word("--stat", flags), "--state");
  EXPECT_EQ(closest_word("--jsn", flags), "--json");
  EXPECT_EQ(closest_word("--sever", flags), "--server");
  EXPECT_EQ(closest_word("--radius", flags), "--radius-m");
  EXPECT_EQ(closest_word("--verbose", flags), "");
}

TEST(WatchPrinter, LinesAreStableKeyValueText) {
  v1::JobEvent event;
  event.set_sequence(7);
  event.set_attempt(2);
  event.mutable_force_sample()->set_index(3);
  event.mutable_force_sample()->set_deformation(0.04);
  event.mutable_force_sample()->set_force_n(1.5e-9);
  EXPECT_EQ(event_line(event).rfind("seq=7 attempt=2 sample index=3 deformation=0.04 ", 0), 0u)
      << event_line(event);
  EXPECT_NE(event_line(event).find("force_n=1.500000e-09"), std::string::npos);
  v1::JobEvent state;
  state.set_sequence(8);
  state.mutable_state_change()->set_state(v1::Job::FAILED);
  state.mutable_state_change()->set_reason("load point 3: J <= 0");
  EXPECT_EQ(event_line(state), "seq=8 attempt=0 state FAILED reason=\"load point 3: J <= 0\"");
  EXPECT_EQ(progress_bar(0.5, 75, "load point 2/4", 10), "[#####.....]  50%  ETA 1:15  load point 2/4");
  v1::JobEvent suspension;
  suspension.set_sequence(9);
  auto* s = suspension.mutable_suspension_sample();
  s->set_index(4);
  s->set_strain(0.4);
  s->set_cell_count(8);
  s->set_mean_taylor_deformation(0.125);
  s->set_relative_viscosity(1.5);
  s->set_contact_pairs(2);
  EXPECT_EQ(event_line(suspension).rfind("seq=9 attempt=0 sample index=4 ", 0), 0u) << event_line(suspension);
  EXPECT_NE(event_line(suspension).find(" cells=8 mean_taylor_deformation=0.125 "), std::string::npos);
  EXPECT_NE(event_line(suspension).find(" relative_viscosity=1.5 contact_pairs=2"), std::string::npos);
  EXPECT_EQ(event_line(suspension).find("average_"), std::string::npos);  // none before the averaging starts
  s->set_average_taylor_deformation(0.12);
  s->set_average_taylor_deformation_error(0.003);
  EXPECT_NE(event_line(suspension).find("average_taylor_deformation=0.12+-0.003"), std::string::npos);
}

TEST(ExitCodes, MatchTheDocumentedTable) {
  EXPECT_EQ(exit_code_for(grpc::Status::OK), 0);
  EXPECT_EQ(exit_code_for(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "")), 2);
  EXPECT_EQ(exit_code_for(grpc::Status(grpc::StatusCode::NOT_FOUND, "")), 5);
  EXPECT_EQ(exit_code_for(grpc::Status(grpc::StatusCode::UNAVAILABLE, "")), 6);
  EXPECT_EQ(exit_code_for(v1::Job::SUCCEEDED), 0);
  EXPECT_EQ(exit_code_for(v1::Job::FAILED), 3);
  EXPECT_EQ(exit_code_for(v1::Job::CANCELLED), 4);
}

}  // namespace
}  // namespace cellflow::client
