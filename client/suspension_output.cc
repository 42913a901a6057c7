#include "client/suspension_output.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "client/svg_plot.h"
#include "io/h5md.h"

namespace cellflow::client {
namespace {

// Columns of the suspension CSV (tools/run_job.cc, jobs::suspension_csv_header)
// and the observable each comes from; "" is the sample index or the time.
struct Column {
  const char* name;
  const char* observable;
  bool integer;
};
constexpr Column kColumns[] = {
    {"sample", "", true},
    {"time_s", "", false},
    {"strain", "strain", false},
    {"cell_count", "", true},
    {"mean_taylor_deformation", "mean_taylor_deformation", false},
    {"mean_inclination_rad", "mean_inclination_rad", false},
    {"relative_viscosity", "relative_viscosity", false},
    {"contact_pairs", "contact_pairs", true},
    {"average_taylor_deformation", "average_taylor_deformation", false},
    {"average_taylor_deformation_error", "average_taylor_deformation_error", false},
    {"average_relative_viscosity", "average_relative_viscosity", false},
    {"average_relative_viscosity_error", "average_relative_viscosity_error", false},
};

constexpr const char* kSimulation = "#1f77b4";
constexpr const char* kBand = "#9ecae1";
constexpr const char* kTheory = "#d62728";

}  // namespace

bool is_suspension_result(const std::string& h5_path) {
  auto names = io::list_observables(h5_path);
  return names.ok() && std::find(names->begin(), names->end(), "mean_taylor_deformation") != names->end();
}

StatusOr<SuspensionSeries> read_suspension_series(const std::string& h5_path) {
  if (!is_suspension_result(h5_path)) {
    return Status(StatusCode::kNotFound,
                  h5_path +
                      " holds no mean deformation series "
                      "(/observables/mean_taylor_deformation); not a suspension result");
  }
  std::map<std::string, io::TimeSeries> series;
  std::size_t samples = std::numeric_limits<std::size_t>::max();
  for (const Column& column : kColumns) {
    const std::string name = column.observable;
    if (name.empty() || series.count(name) != 0) continue;
    auto s = io::read_observable(h5_path, name);
    if (!s.ok()) return s.status();
    samples = std::min(samples, s->step.size());
    series.emplace(name, std::move(*s));
  }
  auto cells = io::read_scalar(h5_path, "/parameters/setup/cell_count");
  const double cell_count = cells.ok() ? *cells : 0.0;
  SuspensionSeries out;
  for (const Column& column : kColumns) {
    out.table.columns.push_back(column.name);
    out.table.integer_columns.push_back(column.integer);
  }
  const io::TimeSeries& mean = series.at("mean_taylor_deformation");
  for (std::size_t i = 0; i < samples; ++i) {
    std::vector<double> row;
    for (const Column& column : kColumns) {
      const std::string name = column.name;
      if (name == "sample") {
        row.push_back(static_cast<double>(i));
      } else if (name == "time_s") {
        row.push_back(mean.time[i]);
      } else if (name == "cell_count") {
        row.push_back(cell_count);
      } else {
        const io::TimeSeries& s = series.at(column.observable);
        row.push_back(s.value[i * static_cast<std::size_t>(s.width)]);
      }
    }
    out.table.rows.push_back(std::move(row));
  }
  // The band: min and max of the cells' D per sample (absent in a result without per-cell series).
  if (auto per_cell = io::read_observable(h5_path, "cell_taylor_deformation"); per_cell.ok()) {
    const auto width = static_cast<std::size_t>(std::max(per_cell->width, 1));
    for (std::size_t i = 0; i < samples && i < per_cell->step.size(); ++i) {
      const auto begin = per_cell->value.begin() + static_cast<std::ptrdiff_t>(i * width);
      const auto [lo, hi] = std::minmax_element(begin, begin + static_cast<std::ptrdiff_t>(width));
      out.min_taylor_deformation.push_back(*lo);
      out.max_taylor_deformation.push_back(*hi);
    }
  }
  return out;
}

StatusOr<SuspensionPoint> read_suspension_point(const std::string& h5_path, const std::string& label) {
  SuspensionPoint point;
  point.label = label;
  auto read = [&](const char* dataset, double& into) -> Status {
    auto value = io::read_scalar(h5_path, dataset);
    if (!value.ok())
      return Status(StatusCode::kNotFound,
                    label + ": not a suspension result (" + value.status().message() + ")");
    into = *value;
    return {};
  };
  double cells = 0.0;
  for (auto [dataset, into] :
       {std::pair{"/parameters/setup/capillary_number", &point.capillary_number},
        std::pair{"/parameters/setup/volume_fraction", &point.volume_fraction},
        std::pair{"/parameters/setup/cell_count", &cells},
        std::pair{"/summary/average_taylor_deformation", &point.average_taylor_deformation},
        std::pair{"/summary/average_taylor_deformation_error", &point.average_taylor_deformation_error},
        std::pair{"/summary/average_relative_viscosity", &point.average_relative_viscosity},
        std::pair{"/summary/average_relative_viscosity_error", &point.average_relative_viscosity_error}}) {
    if (Status s = read(dataset, *into); !s.ok()) return s;
  }
  point.cell_count = static_cast<int>(cells);
  auto stop = io::read_string(h5_path, "/summary/stop");
  point.stop = stop.ok() ? *stop : "unknown";
  return point;
}

std::string suspension_svg(const SuspensionSeries& series, const std::string& title) {
  const Curve& table = series.table;
  const int ix = table.column("strain");
  const int id = table.column("mean_taylor_deformation");
  const int ia = table.column("average_taylor_deformation");
  const int ie = table.column("average_taylor_deformation_error");
  std::vector<PlotSeries> plot;
  PlotSeries mean;
  mean.color = kSimulation;
  mean.label = "mean D over the cells";
  PlotSeries lo, hi;
  lo.color = hi.color = kBand;
  lo.label = "min and max over the cells";
  double x_max = 0.0;
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const auto& row = table.rows[i];
    mean.points.emplace_back(row[ix], row[id]);
    x_max = std::max(x_max, row[ix]);
    if (i < series.min_taylor_deformation.size()) {
      lo.points.emplace_back(row[ix], series.min_taylor_deformation[i]);
      hi.points.emplace_back(row[ix], series.max_taylor_deformation[i]);
    }
  }
  if (!lo.points.empty()) plot.push_back(lo);
  plot.push_back(mean);
  if (!lo.points.empty()) {
    hi.label = "";  // the band's second edge: one legend entry for both
    plot.push_back(hi);
  }
  if (!table.rows.empty() && table.rows.back()[ia] > 0.0) {
    // The last sample's average is the run's: a dotted line over the averaging range with its SE bar.
    const double d = table.rows.back()[ia], se = table.rows.back()[ie];
    double x_from = x_max;
    for (const auto& row : table.rows) {
      if (row[ia] > 0.0) {
        x_from = row[ix];
        break;
      }
    }
    PlotSeries average;
    average.color = kTheory;
    average.dash = "2,4";
    average.label = "time average " + fixed(d, 4) + " \u00b1 " + fixed(se, 4);
    average.points = {{x_from, d}, {x_max, d}};
    average.errors = {0.0, se};
    plot.push_back(average);
  }
  return plot_svg(title, "strain \u03b3\u0307 t", "Taylor deformation D", plot, 0.0, 0.0);
}

std::string suspension_points_svg(const std::vector<SuspensionPoint>& points, SuspensionAxis axis,
                                  const std::string& title) {
  const bool by_phi = axis == SuspensionAxis::kVolumeFraction;
  auto x_of = [&](const SuspensionPoint& p) { return by_phi ? p.volume_fraction : p.capillary_number; };
  std::vector<SuspensionPoint> sorted = points;
  std::sort(sorted.begin(), sorted.end(),
            [&](const SuspensionPoint& a, const SuspensionPoint& b) { return x_of(a) < x_of(b); });
  PlotSeries d, eta;
  d.color = eta.color = kSimulation;
  d.line = eta.line = false;  // separate jobs: markers only
  d.markers = eta.markers = true;
  d.label = eta.label = "simulation \u00b1 SE (open: stopped early)";
  double x_max = 0.0;
  for (const SuspensionPoint& p : sorted) {
    const bool early = p.stop != "max_strain" && p.stop != "steady";  // steady: the target SE reached
    d.points.emplace_back(x_of(p), p.average_taylor_deformation);
    d.errors.push_back(p.average_taylor_deformation_error);
    d.hollow.push_back(early);
    eta.points.emplace_back(x_of(p), p.average_relative_viscosity);
    eta.errors.push_back(p.average_relative_viscosity_error);
    eta.hollow.push_back(early);
    x_max = std::max(x_max, x_of(p));
  }
  const std::string x_label =
      by_phi ? "volume fraction \u03c6" : "capillary number Ca = \u03b7 \u03b3\u0307 / \u03bc";
  std::vector<PlotSeries> viscosity{eta};
  if (by_phi) {
    PlotSeries rigid;
    rigid.color = kTheory;
    rigid.dash = "7,5";
    rigid.label = "rigid spheres 1 + 2.5\u03c6 + 6.2\u03c6\u00b2";
    const double x_hi = nice_ticks(0.0, x_max > 0.0 ? x_max : 0.5).back();
    for (int i = 0; i <= 20; ++i) {
      const double phi = x_hi * i / 20.0;
      // Batchelor (1977) for rigid spheres; the small-Ca reference.
      rigid.points.emplace_back(phi, 1.0 + 2.5 * phi + 6.2 * phi * phi);
    }
    viscosity.push_back(rigid);
  }
  // Two plots stacked in one page: each is a whole plot_svg, nested as an <svg> at its offset.
  auto nested = [](std::string svg, double y) {
    svg.erase(0, svg.find("<svg"));  // drop the XML declaration
    return svg.replace(0, 4, "<svg y=\"" + fixed(y, 0) + "\"");
  };
  const std::string top =
      plot_svg(title, x_label, "time-averaged mean Taylor deformation D", {d}, x_max, 0.0);
  const std::string bottom = plot_svg("", x_label, "time-averaged relative viscosity", viscosity, x_max, 1.0);
  const PlotFrame frame_top = frame_with_legend({d});
  const PlotFrame frame_bottom = frame_with_legend(viscosity);
  const double width = std::max(frame_top.width, frame_bottom.width);
  const double height = frame_top.height + frame_bottom.height;
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" +
         fixed(width, 0) + "\" height=\"" + fixed(height, 0) + "\" viewBox=\"0 0 " + fixed(width, 0) + " " +
         fixed(height, 0) + "\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n" +
         nested(top, 0.0) + nested(bottom, frame_top.height) + "</svg>\n";
}

}  // namespace cellflow::client
