#include "client/curve_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "physics/io/h5md.h"

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

std::string fixed(double value, int digits) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value);
  return buffer;
}

// Digits after the decimal point that show tick step `step` exactly enough.
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

std::vector<double> nice_ticks(double lo, double hi, int target_count) {
  if (!(hi > lo)) hi = lo + 1.0;
  const double raw = (hi - lo) / std::max(target_count - 1, 1);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw) break;
  }
  std::vector<double> ticks;
  for (double t = std::floor(lo / step) * step; t <= hi + 0.5 * step; t += step) {
    ticks.push_back(std::fabs(t) < 1e-12 * step ? 0.0 : t);
    if (t >= hi - 1e-9 * step) break;
  }
  return ticks;
}

std::string curve_svg(const Curve& curve, const std::string& title) {
  const int ix = curve.column("deformation");
  const int iforce = curve.column("force_n");
  const int ihertz = curve.column("hertz_force_n");
  // Plot frame in SVG pixels.
  const double width = 720, height = 480, left = 90, right = 30, top = 50, bottom = 70;
  const double plot_w = width - left - right, plot_h = height - top - bottom;

  double x_max = 0.0, f_max = 0.0;
  for (const auto& row : curve.rows) {
    if (ix >= 0) x_max = std::max(x_max, row[ix]);
    if (iforce >= 0) f_max = std::max(f_max, row[iforce]);
    if (ihertz >= 0) f_max = std::max(f_max, row[ihertz]);
  }
  // SI prefix for the force axis: the data's maximum lands in [1, 1000).
  struct Prefix {
    double scale;
    const char* name;
  };
  const Prefix prefixes[] = {{1e-15, "fN"},     {1e-12, "pN"}, {1e-9, "nN"},
                             {1e-6, "\u00b5N"}, {1e-3, "mN"},  {1.0, "N"}};
  Prefix unit = prefixes[2];
  for (const Prefix& p : prefixes) {
    if (f_max >= p.scale) unit = p;
  }
  const std::vector<double> xt = nice_ticks(0.0, x_max > 0 ? x_max : 1.0);
  const std::vector<double> yt = nice_ticks(0.0, f_max > 0 ? f_max / unit.scale : 1.0);
  const double x_hi = xt.back(), y_hi = yt.back();
  auto px = [&](double x) { return left + plot_w * x / x_hi; };
  auto py = [&](double f) { return top + plot_h * (1.0 - f / unit.scale / y_hi); };

  std::string svg;
  svg += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  svg += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + fixed(width, 0) + "\" height=\"" +
         fixed(height, 0) + "\" viewBox=\"0 0 " + fixed(width, 0) + " " + fixed(height, 0) +
         "\" font-family=\"Helvetica, Arial, sans-serif\" font-size=\"13\">\n";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg += "<text x=\"" + fixed(width / 2, 1) + "\" y=\"28\" text-anchor=\"middle\" font-size=\"16\">" +
         escape(title) + "</text>\n";
  // Grid and ticks.
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
    const std::string y = fixed(py(t * unit.scale), 1);
    svg += "<line x1=\"" + fixed(left, 1) + "\" y1=\"" + y + "\" x2=\"" + fixed(left + plot_w, 1) +
           "\" y2=\"" + y + "\" stroke=\"#e0e0e0\"/>\n";
    svg += "<line x1=\"" + fixed(left - 6, 1) + "\" y1=\"" + y + "\" x2=\"" + fixed(left, 1) + "\" y2=\"" +
           y + "\" stroke=\"black\"/>\n";
    svg += "<text x=\"" + fixed(left - 10, 1) + "\" y=\"" + fixed(py(t * unit.scale) + 4, 1) +
           "\" text-anchor=\"end\">" + fixed(t, yd) + "</text>\n";
  }
  // Axes and labels.
  svg += "<rect x=\"" + fixed(left, 1) + "\" y=\"" + fixed(top, 1) + "\" width=\"" + fixed(plot_w, 1) +
         "\" height=\"" + fixed(plot_h, 1) + "\" fill=\"none\" stroke=\"black\"/>\n";
  svg += "<text x=\"" + fixed(left + plot_w / 2, 1) + "\" y=\"" + fixed(height - 20, 1) +
         "\" text-anchor=\"middle\">deformation \u03b4 / 2R</text>\n";
  svg += "<text transform=\"translate(24 " + fixed(top + plot_h / 2, 1) +
         ") rotate(-90)\" text-anchor=\"middle\">force (" + std::string(unit.name) + ")</text>\n";

  auto polyline = [&](int column, const char* style) {
    std::string points;
    for (const auto& row : curve.rows)
      points += fixed(px(row[ix]), 2) + "," + fixed(py(row[column]), 2) + " ";
    return "<polyline fill=\"none\" " + std::string(style) + " points=\"" + points + "\"/>\n";
  };
  if (ix >= 0 && ihertz >= 0)
    svg += polyline(ihertz, "stroke=\"#d62728\" stroke-width=\"2\" stroke-dasharray=\"7,5\"");
  if (ix >= 0 && iforce >= 0) {
    svg += polyline(iforce, "stroke=\"#1f77b4\" stroke-width=\"2\"");
    for (const auto& row : curve.rows) {
      svg += "<circle cx=\"" + fixed(px(row[ix]), 2) + "\" cy=\"" + fixed(py(row[iforce]), 2) +
             "\" r=\"3\" fill=\"#1f77b4\"/>\n";
    }
  }
  // Legend, top left inside the frame (the curves rise to the right).
  const double lx = left + 16, ly = top + 16;
  svg += "<rect x=\"" + fixed(lx - 8, 1) + "\" y=\"" + fixed(ly - 12, 1) +
         "\" width=\"200\" height=\"48\" fill=\"white\" stroke=\"#999999\"/>\n";
  svg += "<line x1=\"" + fixed(lx, 1) + "\" y1=\"" + fixed(ly, 1) + "\" x2=\"" + fixed(lx + 30, 1) +
         "\" y2=\"" + fixed(ly, 1) + "\" stroke=\"#1f77b4\" stroke-width=\"2\"/>\n";
  svg += "<circle cx=\"" + fixed(lx + 15, 1) + "\" cy=\"" + fixed(ly, 1) + "\" r=\"3\" fill=\"#1f77b4\"/>\n";
  svg += "<text x=\"" + fixed(lx + 40, 1) + "\" y=\"" + fixed(ly + 4, 1) + "\">simulation</text>\n";
  svg += "<line x1=\"" + fixed(lx, 1) + "\" y1=\"" + fixed(ly + 22, 1) + "\" x2=\"" + fixed(lx + 30, 1) +
         "\" y2=\"" + fixed(ly + 22, 1) +
         "\" stroke=\"#d62728\" stroke-width=\"2\" stroke-dasharray=\"7,5\"/>\n";
  svg += "<text x=\"" + fixed(lx + 40, 1) + "\" y=\"" + fixed(ly + 26, 1) + "\">Hertz</text>\n";
  svg += "</svg>\n";
  return svg;
}

}  // namespace cellflow::client
