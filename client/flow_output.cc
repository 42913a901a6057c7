#include "client/flow_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "physics/io/h5md.h"

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

std::string fixed(double value, int digits) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value);
  return buffer;
}

int decimals_for(double step) {
  return std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
}

std::string escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '&')
      out += "&amp;";
    else if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

// One data set of a plot: a polyline and/or markers, with a legend entry.
struct Series {
  std::vector<std::pair<double, double>> points;
  std::string color;
  std::string dash;          // stroke-dasharray, "" = solid
  bool line = true;          // draw the polyline
  bool markers = false;      // draw a circle per point
  std::vector<bool> hollow;  // per point (markers only): an open circle
  std::string label;
};

// A line plot with both axes from 0, nice ticks, a grid, labels and a legend.
std::string plot_svg(const std::string& title, const std::string& x_label, const std::string& y_label,
                     const std::vector<Series>& series, double x_hint, double y_hint) {
  const double width = 720, height = 480, left = 90, right = 30, top = 50, bottom = 70;
  const double plot_w = width - left - right, plot_h = height - top - bottom;
  double x_max = x_hint, y_max = y_hint;
  for (const Series& s : series) {
    for (const auto& [x, y] : s.points) {
      if (std::isfinite(x)) x_max = std::max(x_max, x);
      if (std::isfinite(y)) y_max = std::max(y_max, y);
    }
  }
  const std::vector<double> xt = nice_ticks(0.0, x_max > 0 ? x_max : 1.0);
  const std::vector<double> yt = nice_ticks(0.0, y_max > 0 ? y_max : 1.0);
  const double x_hi = xt.back(), y_hi = yt.back();
  auto px = [&](double x) { return left + plot_w * std::clamp(x / x_hi, 0.0, 1.0); };
  auto py = [&](double y) { return top + plot_h * (1.0 - std::clamp(y / y_hi, 0.0, 1.0)); };

  std::string svg;
  svg += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  svg += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + fixed(width, 0) + "\" height=\"" +
         fixed(height, 0) + "\" viewBox=\"0 0 " + fixed(width, 0) + " " + fixed(height, 0) +
         "\" font-family=\"Helvetica, Arial, sans-serif\" font-size=\"13\">\n";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg += "<text x=\"" + fixed(width / 2, 1) + "\" y=\"28\" text-anchor=\"middle\" font-size=\"16\">" +
         escape(title) + "</text>\n";
  const int xd = xt.size() > 1 ? decimals_for(xt[1] - xt[0]) : 1;
  const int yd = yt.size() > 1 ? decimals_for(yt[1] - yt[0]) : 1;
  for (double t : xt) {
    const std::string x = fixed(px(t), 1);
    svg += "<line x1=\"" + x + "\" y1=\"" + fixed(top, 1) + "\" x2=\"" + x + "\" y2=\"" +
           fixed(top + plot_h, 1) + "\" stroke=\"#e0e0e0\"/>\n";
    svg += "<line x1=\"" + x + "\" y1=\"" + fixed(top + plot_h, 1) + "\" x2=\"" + x + "\" y2=\"" +
           fixed(top + plot_h + 6, 1) + "\" stroke=\"black\"/>\n";
    svg += "<text x=\"" + x + "\" y=\"" + fixed(top + plot_h + 22, 1) + "\" text-anchor=\"middle\">" +
           fixed(t, xd) + "</text>\n";
  }
  for (double t : yt) {
    const std::string y = fixed(py(t), 1);
    svg += "<line x1=\"" + fixed(left, 1) + "\" y1=\"" + y + "\" x2=\"" + fixed(left + plot_w, 1) +
           "\" y2=\"" + y + "\" stroke=\"#e0e0e0\"/>\n";
    svg += "<line x1=\"" + fixed(left - 6, 1) + "\" y1=\"" + y + "\" x2=\"" + fixed(left, 1) + "\" y2=\"" +
           y + "\" stroke=\"black\"/>\n";
    svg += "<text x=\"" + fixed(left - 10, 1) + "\" y=\"" + fixed(py(t) + 4, 1) + "\" text-anchor=\"end\">" +
           fixed(t, yd) + "</text>\n";
  }
  svg += "<rect x=\"" + fixed(left, 1) + "\" y=\"" + fixed(top, 1) + "\" width=\"" + fixed(plot_w, 1) +
         "\" height=\"" + fixed(plot_h, 1) + "\" fill=\"none\" stroke=\"black\"/>\n";
  svg += "<text x=\"" + fixed(left + plot_w / 2, 1) + "\" y=\"" + fixed(height - 20, 1) +
         "\" text-anchor=\"middle\">" + escape(x_label) + "</text>\n";
  svg += "<text transform=\"translate(24 " + fixed(top + plot_h / 2, 1) +
         ") rotate(-90)\" text-anchor=\"middle\">" + escape(y_label) + "</text>\n";

  auto stroke = [](const Series& s) {
    return "stroke=\"" + s.color + "\" stroke-width=\"2\"" +
           (s.dash.empty() ? std::string() : " stroke-dasharray=\"" + s.dash + "\"");
  };
  for (const Series& s : series) {
    if (s.line && s.points.size() > 1) {
      std::string points;
      for (const auto& [x, y] : s.points) points += fixed(px(x), 2) + "," + fixed(py(y), 2) + " ";
      svg += "<polyline fill=\"none\" " + stroke(s) + " points=\"" + points + "\"/>\n";
    }
    if (s.markers) {
      for (std::size_t i = 0; i < s.points.size(); ++i) {
        const bool hollow = i < s.hollow.size() && s.hollow[i];
        svg += "<circle cx=\"" + fixed(px(s.points[i].first), 2) + "\" cy=\"" +
               fixed(py(s.points[i].second), 2) + "\" r=\"" + (s.line ? "3" : "4") + "\" " +
               (hollow ? "fill=\"white\" stroke=\"" + s.color + "\" stroke-width=\"1.5\""
                       : "fill=\"" + s.color + "\"") +
               "/>\n";
      }
    }
  }
  // Legend, top left inside the frame (the data rise to the right).
  const double lx = left + 16, ly = top + 16;
  svg += "<rect x=\"" + fixed(lx - 8, 1) + "\" y=\"" + fixed(ly - 12, 1) + "\" width=\"290\" height=\"" +
         fixed(22.0 * static_cast<double>(series.size()) + 4, 1) + "\" fill=\"white\" stroke=\"#999999\"/>\n";
  for (std::size_t i = 0; i < series.size(); ++i) {
    const Series& s = series[i];
    const double y = ly + 22.0 * static_cast<double>(i);
    if (s.line) {
      svg += "<line x1=\"" + fixed(lx, 1) + "\" y1=\"" + fixed(y, 1) + "\" x2=\"" + fixed(lx + 30, 1) +
             "\" y2=\"" + fixed(y, 1) + "\" " + stroke(s) + "/>\n";
    }
    if (s.markers) {
      svg += "<circle cx=\"" + fixed(lx + 15, 1) + "\" cy=\"" + fixed(y, 1) + "\" r=\"3\" fill=\"" + s.color +
             "\"/>\n";
    }
    svg += "<text x=\"" + fixed(lx + 40, 1) + "\" y=\"" + fixed(y + 4, 1) + "\">" + escape(s.label) +
           "</text>\n";
  }
  svg += "</svg>\n";
  return svg;
}

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
  std::vector<Series> plot;
  Series simulation;
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
    Series steady;
    steady.color = kSimulation;
    steady.dash = "2,4";
    steady.label = "steady D = " + fixed(steady_taylor_deformation, 4);
    steady.points = {{0.0, steady_taylor_deformation}, {x_max, steady_taylor_deformation}};
    plot.push_back(steady);
  }
  if (capillary_number > 0.0 && x_max > 0.0) {
    Series roscoe;
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
  Series simulation;
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
  Series table;
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
  Series small;
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
