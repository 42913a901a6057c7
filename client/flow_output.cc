#include "client/flow_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "client/svg_plot.h"
#include "io/h5md.h"

namespace cellflow::client {

namespace {

// Columns of the flow CSV, those of `cellflow-run` (tools/run_job.cc,
// deformation_csv_header), and the observable each comes from.
struct Column {
  const char* name;
  const char* observable;
  int component;  // of a vector observable; -1: the sample index (from the record number)
  bool integer;
};
constexpr Column kColumns[] = {
    {"sample", "taylor_deformation", -1, true},
    {"time_s", "", 0, false},  // the time of the records
    {"strain", "strain", 0, false},
    {"taylor_deformation", "taylor_deformation", 0, false},
    {"inclination_rad", "inclination_rad", 0, false},
    {"net_strain", "net_strain", 0, false},
    {"a1_m", "semi_axes_m", 0, false},
    {"a2_m", "semi_axes_m", 1, false},
    {"a3_m", "semi_axes_m", 2, false},
    {"tank_treading_frequency_per_s", "tank_treading_frequency_per_s", 0, false},
    {"volume_m3", "volume_m3", 0, false},
};

constexpr const char* kSimulation = "#1f77b4";
constexpr const char* kTheory = "#d62728";
constexpr const char* kTable = "#2ca02c";

}  // namespace

bool is_flow_result(const std::string& h5_path) {
  auto names = io::list_observables(h5_path);
  return names.ok() && std::find(names->begin(), names->end(), "strain") != names->end();
}

StatusOr<Curve> read_deformation_series(const std::string& h5_path) {
  auto available = io::list_observables(h5_path);
  if (!available.ok()) return available.status();
  auto has = [&](const std::string& name) {
    return std::find(available->begin(), available->end(), name) != available->end();
  };
  if (!has("strain") || !has("taylor_deformation")) {
    return Status(
        StatusCode::kNotFound,
        h5_path + " holds no deformation time series (/observables/strain); not a shear-flow result");
  }
  std::map<std::string, io::TimeSeries> series;
  std::size_t samples = std::numeric_limits<std::size_t>::max();
  for (const Column& column : kColumns) {
    const std::string name = column.observable;
    if (name.empty() || series.count(name) != 0 || !has(name)) continue;
    auto s = io::read_observable(h5_path, name);
    if (!s.ok()) return s.status();
    samples = std::min(samples, s->step.size());
    series.emplace(name, std::move(*s));
  }
  Curve curve;
  std::vector<const Column*> present;
  for (const Column& column : kColumns) {
    const std::string observable = column.observable;
    if (observable.empty() || series.count(observable) != 0) {
      present.push_back(&column);
      curve.columns.push_back(column.name);
      curve.integer_columns.push_back(column.integer);
    }
  }
  const io::TimeSeries& d = series.at("taylor_deformation");
  for (std::size_t i = 0; i < samples; ++i) {
    std::vector<double> row;
    for (const Column* column : present) {
      const std::string observable = column->observable;
      if (column->component < 0) {
        row.push_back(static_cast<double>(i));  // samples are written in index order, from 0
      } else if (observable.empty()) {
        row.push_back(d.time[i]);
      } else {
        const io::TimeSeries& s = series.at(observable);
        row.push_back(s.value[i * s.width + column->component]);
      }
    }
    curve.rows.push_back(std::move(row));
  }
  return curve;
}

StatusOr<SteadyPoint> read_steady_point(const std::string& h5_path, const std::string& label) {
  SteadyPoint point;
  point.label = label;
  auto ca = io::read_scalar(h5_path, "/parameters/setup/capillary_number");
  if (!ca.ok())
    return Status(StatusCode::kNotFound, label + ": not a shear-flow result (" + ca.status().message() + ")");
  point.capillary_number = *ca;
  auto d = io::read_scalar(h5_path, "/summary/steady_taylor_deformation");
  if (!d.ok())
    return Status(StatusCode::kNotFound,
                  label + ": no steady D in the result (" + d.status().message() + ")");
  point.steady_taylor_deformation = *d;
  auto stop = io::read_string(h5_path, "/summary/stop");
  point.stop = stop.ok() ? *stop : "unknown";
  return point;
}

std::string deformation_svg(const Curve& series, double capillary_number, double steady_taylor_deformation,
                            const std::string& title) {
  const int ix = series.column("strain");
  const int id = series.column("taylor_deformation");
  std::vector<PlotSeries> plot;
  PlotSeries simulation;
  simulation.color = kSimulation;
  simulation.label = "simulation D";
  double x_max = 0.0;
  if (ix >= 0 && id >= 0) {
    for (const auto& row : series.rows) {
      simulation.points.emplace_back(row[ix], row[id]);
      x_max = std::max(x_max, row[ix]);
    }
  }
  plot.push_back(simulation);
  if (steady_taylor_deformation > 0.0 && x_max > 0.0) {
    PlotSeries steady;
    steady.color = kSimulation;
    steady.dash = "2,4";
    steady.label = "steady D = " + fixed(steady_taylor_deformation, 4);
    steady.points = {{0.0, steady_taylor_deformation}, {x_max, steady_taylor_deformation}};
    plot.push_back(steady);
  }
  if (capillary_number > 0.0 && x_max > 0.0) {
    PlotSeries roscoe;
    roscoe.color = kTheory;
    roscoe.dash = "7,5";
    // D = (5/4) Ca   (Roscoe 1967, small-Ca limit; shared/validation/README.md)
    const double d = 1.25 * capillary_number;
    roscoe.label = "small-Ca limit 5/4 Ca = " + fixed(d, 4);
    roscoe.points = {{0.0, d}, {x_max, d}};
    plot.push_back(roscoe);
  }
  return plot_svg(title, "strain \u03b3\u0307 t", "Taylor deformation D", plot, 0.0, 0.0);
}

std::string steady_deformation_svg(const std::vector<SteadyPoint>& points, const std::string& title) {
  std::vector<SteadyPoint> sorted = points;
  std::sort(sorted.begin(), sorted.end(), [](const SteadyPoint& a, const SteadyPoint& b) {
    return a.capillary_number < b.capillary_number;
  });
  double ca_max = 0.0;
  PlotSeries simulation;
  simulation.color = kSimulation;
  simulation.line = false;  // separate jobs: markers only
  simulation.markers = true;
  simulation.label = "simulation (open: not steady)";
  for (const SteadyPoint& p : sorted) {
    simulation.points.emplace_back(p.capillary_number, p.steady_taylor_deformation);
    simulation.hollow.push_back(p.stop != "steady");
    ca_max = std::max(ca_max, p.capillary_number);
  }
  const double x_hi = nice_ticks(0.0, ca_max > 0 ? ca_max : 1.0).back();
  // Theory over the plotted Ca range (the table ends at Ca = 2).
  PlotSeries table;
  table.color = kTable;
  table.label = "Roscoe, \u03bb = 1";
  for (const RoscoePoint& r : roscoe_lambda1()) {
    if (r.capillary_number <= x_hi * (1.0 + 1e-9))
      table.points.emplace_back(r.capillary_number, r.taylor_deformation);
  }
  double d_max = 0.0;
  for (const SteadyPoint& p : sorted) d_max = std::max(d_max, p.steady_taylor_deformation);
  for (const auto& [ca, d] : table.points) d_max = std::max(d_max, d);
  const double y_hi = nice_ticks(0.0, d_max > 0 ? d_max : 1.0).back();
  PlotSeries small;
  small.color = kTheory;
  small.dash = "7,5";
  small.label = "small-Ca limit D = 5/4 Ca";
  // D = (5/4) Ca   (Roscoe 1967, small-Ca limit), drawn to the edge of the frame
  const double small_end = std::min(x_hi, y_hi / 1.25);
  small.points = {{0.0, 0.0}, {small_end, 1.25 * small_end}};
  return plot_svg(title, "capillary number Ca = \u03b7 \u03b3\u0307 / \u03bc", "steady Taylor deformation D",
                  {simulation, small, table}, x_hi, y_hi);
}

const std::vector<RoscoePoint>& roscoe_lambda1() {
  // Columns ca and D_lambda1 of shared/validation/roscoe_elastic_sphere_shear.csv.
  static const std::vector<RoscoePoint> table = {
      {0.01, 0.0125}, {0.02, 0.0250}, {0.05, 0.0621}, {0.1, 0.1216}, {0.2, 0.2273},
      {0.3, 0.3131},  {0.4, 0.3821},  {0.5, 0.4384},  {0.6, 0.4851}, {0.75, 0.5421},
      {1.0, 0.6135},  {1.25, 0.6662}, {1.5, 0.7068},  {2.0, 0.7656},
  };
  return table;
}

}  // namespace cellflow::client
