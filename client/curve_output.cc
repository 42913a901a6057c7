#include "client/curve_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "client/svg_plot.h"
#include "io/h5md.h"

namespace cellflow::client {

namespace {

// Columns of the curve CSV, those of `cellflow-run` (tools/run_job.cc), and
// the observable each comes from ("" = computed here).
struct Column {
  const char* name;
  const char* observable;
  int component;  // of a vector observable
  bool integer;
};
constexpr Column kColumns[] = {
    {"point", "force_n", -1, true},  // from the step: step = point + 1
    {"deformation", "deformation", 0, false},
    {"displacement_m", "displacement_m", 0, false},
    {"force_n", "force_n", 0, false},
    {"hertz_force_n", "hertz_force_n", 0, false},
    {"force_over_hertz", "", 0, false},
    {"taylor_deformation", "taylor_deformation", 0, false},
    {"a1_m", "semi_axes_m", 0, false},
    {"a2_m", "semi_axes_m", 1, false},
    {"a3_m", "semi_axes_m", 2, false},
    {"volume_m3", "volume_m3", 0, false},
    {"elastic_energy_j", "elastic_energy_j", 0, false},
    {"max_penetration_m", "max_penetration_m", 0, false},
    {"newton_iterations", "newton_iterations", 0, true},
    {"step_splits", "step_splits", 0, true},
    {"residual", "residual", 0, false},
};

// As cellflow-run writes them: integers plainly, doubles with 17 significant digits.
std::string number(double value, bool integer) {
  char buffer[40];
  if (integer) {
    std::snprintf(buffer, sizeof buffer, "%lld", static_cast<long long>(value));
  } else {
    std::snprintf(buffer, sizeof buffer, "%.17g", value);
  }
  return buffer;
}

}  // namespace

int Curve::column(const std::string& name) const {
  for (std::size_t i = 0; i < columns.size(); ++i) {
    if (columns[i] == name) return static_cast<int>(i);
  }
  return -1;
}

StatusOr<Curve> read_curve(const std::string& h5_path) {
  auto available = io::list_observables(h5_path);
  if (!available.ok()) return available.status();
  auto has = [&](const char* name) {
    return std::find(available->begin(), available->end(), name) != available->end();
  };
  if (!has("force_n") || !has("deformation")) {
    return Status(StatusCode::kNotFound, h5_path + " holds no force curve (/observables/force_n)");
  }
  std::map<std::string, io::TimeSeries> series;
  std::size_t points = std::numeric_limits<std::size_t>::max();
  for (const Column& column : kColumns) {
    const std::string name = column.observable;
    if (name.empty() || series.count(name) != 0 || !has(column.observable)) continue;
    auto s = io::read_observable(h5_path, name);
    if (!s.ok()) return s.status();
    points = std::min(points, s->step.size());
    series.emplace(name, std::move(*s));
  }
  Curve curve;
  std::vector<const Column*> present;
  for (const Column& column : kColumns) {
    const std::string name = column.name;
    const bool computed = std::string(column.observable).empty();
    if (computed ? (series.count("hertz_force_n") != 0) : (series.count(column.observable) != 0)) {
      present.push_back(&column);
      curve.columns.push_back(name);
      curve.integer_columns.push_back(column.integer);
    }
  }
  for (std::size_t i = 0; i < points; ++i) {
    std::vector<double> row;
    for (const Column* column : present) {
      if (column->component < 0) {
        row.push_back(static_cast<double>(series.at(column->observable).step[i] - 1));
      } else if (std::string(column->observable).empty()) {
        // F / F_Hertz, 0 where Hertz is 0 (as cellflow-run writes it).
        const double hertz = series.at("hertz_force_n").value[i];
        row.push_back(hertz > 0.0 ? series.at("force_n").value[i] / hertz : 0.0);
      } else {
        const io::TimeSeries& s = series.at(column->observable);
        row.push_back(s.value[i * s.width + column->component]);
      }
    }
    curve.rows.push_back(std::move(row));
  }
  return curve;
}

std::string curve_csv(const Curve& curve) {
  std::string out;
  for (std::size_t i = 0; i < curve.columns.size(); ++i) {
    if (i > 0) out += ',';
    out += curve.columns[i];
  }
  out += "\n";
  for (const auto& row : curve.rows) {
    for (std::size_t i = 0; i < row.size(); ++i) {
      if (i > 0) out += ',';
      out += number(row[i], i < curve.integer_columns.size() && curve.integer_columns[i]);
    }
    out += "\n";
  }
  return out;
}

std::string curve_svg(const Curve& curve, const std::string& title) {
  const int ix = curve.column("deformation");
  const int iforce = curve.column("force_n");
  const int ihertz = curve.column("hertz_force_n");
  // Axes from 0 (or below, for negative data) to past the data's maximum.
  double x_min = 0.0, x_max = 0.0, f_min = 0.0, f_max = 0.0;
  for (const auto& row : curve.rows) {
    if (ix >= 0 && std::isfinite(row[ix])) {
      x_min = std::min(x_min, row[ix]);
      x_max = std::max(x_max, row[ix]);
    }
    for (int column : {iforce, ihertz}) {
      if (column >= 0 && std::isfinite(row[column])) {
        f_min = std::min(f_min, row[column]);
        f_max = std::max(f_max, row[column]);
      }
    }
  }
  const ForceUnit unit = force_unit(f_max);  // the largest force in [1, 1000) of the unit
  const PlotAxis xa = nice_axis(x_min, x_max > x_min ? x_max : x_min + 1.0);
  const PlotAxis ya =
      nice_axis(f_min / unit.scale, f_max > f_min ? f_max / unit.scale : f_min / unit.scale + 1.0);

  PlotSeries simulation;
  simulation.color = "#1f77b4";
  simulation.markers = true;
  simulation.label = "simulation";
  PlotSeries hertz;
  hertz.color = "#d62728";
  hertz.dash = "7,5";
  hertz.label = "Hertz";
  const PlotFrame frame = frame_with_legend({simulation, hertz});
  auto px = [&](double x) { return frame.x_of(xa, x); };
  auto py = [&](double f) { return frame.y_of(ya, f / unit.scale); };

  std::string svg = svg_open(frame, title);
  // The y ticks are in the prefixed unit, py takes newtons.
  svg += svg_axes(
      frame, xa.ticks, ya.ticks, px, [&](double t) { return py(t * unit.scale); }, "deformation \u03b4 / 2R",
      "force (" + std::string(unit.name) + ")");

  // Every point, even a single one, is drawn: Hertz under the simulation.
  auto polyline = [&](int column, const PlotSeries& style) {
    std::string points;
    for (const auto& row : curve.rows)
      points += fixed(px(row[ix]), 2) + "," + fixed(py(row[column]), 2) + " ";
    return "<polyline fill=\"none\" " + svg_stroke(style) + " points=\"" + points + "\"/>\n";
  };
  if (ix >= 0 && ihertz >= 0) svg += polyline(ihertz, hertz);
  if (ix >= 0 && iforce >= 0) {
    svg += polyline(iforce, simulation);
    for (const auto& row : curve.rows) {
      svg += "<circle cx=\"" + fixed(px(row[ix]), 2) + "\" cy=\"" + fixed(py(row[iforce]), 2) +
             "\" r=\"3\" fill=\"#1f77b4\"/>\n";
    }
  }
  // Legend right of the plotting area, off the data.
  svg += svg_legend(frame, {simulation, hertz});
  svg += "</svg>\n";
  return svg;
}

}  // namespace cellflow::client
