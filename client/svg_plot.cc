#include "client/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace cellflow::client {

std::string fixed(double value, int digits) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value);
  return buffer;
}

int decimals_for(double step) {
  return std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
}

std::string escape_xml(const std::string& text) {
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

std::vector<double> nice_ticks(double lo, double hi, int target_count) {
  if (!std::isfinite(lo)) lo = 0.0;
  if (!std::isfinite(hi) || !(hi > lo)) hi = lo + 1.0;
  const double raw = (hi - lo) / std::max(target_count - 1, 1);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw * (1.0 - 1e-12)) break;
  }
  // Whole multiples of the step, from the one at or below lo to the one at or
  // above hi (a relative slack so that 0.15 / 0.05 stays 3, not 3.0000000004).
  const double first = std::floor(lo / step + 1e-9);
  const double last = std::ceil(hi / step - 1e-9);
  std::vector<double> ticks;
  for (double k = first; k <= last + 0.5; k += 1.0) {
    const double t = k * step;
    ticks.push_back(std::fabs(t) < 1e-12 * step ? 0.0 : t);
  }
  return ticks;
}

PlotAxis nice_axis(double data_lo, double data_hi, int target_count) {
  PlotAxis axis;
  axis.ticks = nice_ticks(data_lo, data_hi, target_count);
  const double span = axis.ticks.back() - axis.ticks.front();
  axis.lo = axis.ticks.front() - 0.03 * span;
  axis.hi = axis.ticks.back() + 0.03 * span;
  return axis;
}

std::string svg_open(const PlotFrame& frame, const std::string& title) {
  std::string svg;
  svg += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  svg += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + fixed(frame.width, 0) + "\" height=\"" +
         fixed(frame.height, 0) + "\" viewBox=\"0 0 " + fixed(frame.width, 0) + " " + fixed(frame.height, 0) +
         "\" font-family=\"Helvetica, Arial, sans-serif\" font-size=\"13\">\n";
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  svg += "<text x=\"" + fixed(frame.width / 2, 1) + "\" y=\"28\" text-anchor=\"middle\" font-size=\"16\">" +
         escape_xml(title) + "</text>\n";
  return svg;
}

std::string svg_axes(const PlotFrame& frame, const std::vector<double>& x_ticks,
                     const std::vector<double>& y_ticks, const PixelOf& px, const PixelOf& py,
                     const std::string& x_label, const std::string& y_label) {
  const double left = frame.left, top = frame.top, plot_w = frame.plot_w(), plot_h = frame.plot_h();
  std::string svg;
  const int xd = x_ticks.size() > 1 ? decimals_for(x_ticks[1] - x_ticks[0]) : 1;
  const int yd = y_ticks.size() > 1 ? decimals_for(y_ticks[1] - y_ticks[0]) : 1;
  for (double t : x_ticks) {
    const std::string x = fixed(px(t), 1);
    svg += "<line x1=\"" + x + "\" y1=\"" + fixed(top, 1) + "\" x2=\"" + x + "\" y2=\"" +
           fixed(top + plot_h, 1) + "\" stroke=\"#e0e0e0\"/>\n";
    svg += "<line x1=\"" + x + "\" y1=\"" + fixed(top + plot_h, 1) + "\" x2=\"" + x + "\" y2=\"" +
           fixed(top + plot_h + 6, 1) + "\" stroke=\"black\"/>\n";
    svg += "<text x=\"" + x + "\" y=\"" + fixed(top + plot_h + 22, 1) + "\" text-anchor=\"middle\">" +
           fixed(t, xd) + "</text>\n";
  }
  for (double t : y_ticks) {
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
  svg += "<text x=\"" + fixed(left + plot_w / 2, 1) + "\" y=\"" + fixed(frame.height - 20, 1) +
         "\" text-anchor=\"middle\">" + escape_xml(x_label) + "</text>\n";
  svg += "<text transform=\"translate(24 " + fixed(top + plot_h / 2, 1) +
         ") rotate(-90)\" text-anchor=\"middle\">" + escape_xml(y_label) + "</text>\n";
  return svg;
}

std::string svg_stroke(const PlotSeries& series) {
  return "stroke=\"" + series.color + "\" stroke-width=\"2\"" +
         (series.dash.empty() ? std::string() : " stroke-dasharray=\"" + series.dash + "\"");
}

namespace {

// The legend box's width: line sample, gap and label (about 7.5 px a
// character at font size 13; UTF-8 continuation bytes not counted).
double legend_box_width(const std::vector<PlotSeries>& series) {
  std::size_t chars = 0;
  for (const PlotSeries& s : series) {
    std::size_t n = 0;
    for (unsigned char c : s.label) n += (c & 0xC0) != 0x80;
    chars = std::max(chars, n);
  }
  return 8.0 + 40.0 + 7.5 * static_cast<double>(chars) + 8.0;
}

}  // namespace

PlotFrame frame_with_legend(const std::vector<PlotSeries>& series) {
  PlotFrame frame;
  const double extra = legend_box_width(series) + 16.0;
  frame.right += extra;
  frame.width += extra;
  return frame;
}

std::string svg_legend(const PlotFrame& frame, const std::vector<PlotSeries>& series) {
  const double box_x = frame.left + frame.plot_w() + 16.0, box_y = frame.top;
  const double lx = box_x + 8.0, ly = box_y + 16.0;
  return "<rect x=\"" + fixed(box_x, 1) + "\" y=\"" + fixed(box_y, 1) + "\" width=\"" +
         fixed(legend_box_width(series), 1) + "\" height=\"" +
         fixed(
             22.0 * static_cast<double>(std::count_if(series.begin(), series.end(),
                                                      [](const PlotSeries& s) { return !s.label.empty(); })) +
                 8.0,
             1) +
         "\" fill=\"white\" stroke=\"#999999\"/>\n" + svg_legend_entries(lx, ly, series);
}

std::string svg_legend_entries(double lx, double ly, const std::vector<PlotSeries>& series) {
  std::string svg;
  std::size_t row = 0;
  for (const PlotSeries& s : series) {
    if (s.label.empty()) continue;  // drawn, not listed (e.g. the second edge of a band)
    const double y = ly + 22.0 * static_cast<double>(row++);
    if (s.line) {
      svg += "<line x1=\"" + fixed(lx, 1) + "\" y1=\"" + fixed(y, 1) + "\" x2=\"" + fixed(lx + 30, 1) +
             "\" y2=\"" + fixed(y, 1) + "\" " + svg_stroke(s) + "/>\n";
    }
    if (s.markers) {
      svg += "<circle cx=\"" + fixed(lx + 15, 1) + "\" cy=\"" + fixed(y, 1) + "\" r=\"3\" fill=\"" + s.color +
             "\"/>\n";
    }
    svg += "<text x=\"" + fixed(lx + 40, 1) + "\" y=\"" + fixed(y + 4, 1) + "\">" + escape_xml(s.label) +
           "</text>\n";
  }
  return svg;
}

ForceUnit force_unit(double max_force_n) {
  const ForceUnit units[] = {{1e-15, "fN"},     {1e-12, "pN"}, {1e-9, "nN"},
                             {1e-6, "\u00b5N"}, {1e-3, "mN"},  {1.0, "N"}};
  ForceUnit unit = units[2];
  for (const ForceUnit& u : units) {
    if (max_force_n >= u.scale) unit = u;
  }
  return unit;
}

std::string plot_svg(const std::string& title, const std::string& x_label, const std::string& y_label,
                     const std::vector<PlotSeries>& series, double x_hint, double y_hint) {
  const PlotFrame frame = frame_with_legend(series);
  double x_min = 0.0, x_max = x_hint, y_min = 0.0, y_max = y_hint;
  for (const PlotSeries& s : series) {
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      const auto [x, y] = s.points[i];
      const double e = i < s.errors.size() && std::isfinite(s.errors[i]) ? std::abs(s.errors[i]) : 0.0;
      if (std::isfinite(x)) x_min = std::min(x_min, x), x_max = std::max(x_max, x);
      if (std::isfinite(y)) y_min = std::min(y_min, y - e), y_max = std::max(y_max, y + e);
    }
  }
  const PlotAxis xa = nice_axis(x_min, x_max > x_min ? x_max : x_min + 1.0);
  const PlotAxis ya = nice_axis(y_min, y_max > y_min ? y_max : y_min + 1.0);
  auto px = [&](double x) { return frame.x_of(xa, x); };
  auto py = [&](double y) { return frame.y_of(ya, y); };

  std::string svg = svg_open(frame, title);
  svg += svg_axes(frame, xa.ticks, ya.ticks, px, py, x_label, y_label);

  for (const PlotSeries& s : series) {
    if (s.line && s.points.size() > 1) {
      std::string points;
      for (const auto& [x, y] : s.points) points += fixed(px(x), 2) + "," + fixed(py(y), 2) + " ";
      svg += "<polyline fill=\"none\" " + svg_stroke(s) + " points=\"" + points + "\"/>\n";
    }
    for (std::size_t i = 0; i < s.points.size() && i < s.errors.size(); ++i) {
      const double e = std::abs(s.errors[i]);
      if (!(e > 0.0) || !std::isfinite(e)) continue;
      const double x = px(s.points[i].first), y = s.points[i].second;
      svg += "<line x1=\"" + fixed(x, 2) + "\" y1=\"" + fixed(py(y - e), 2) + "\" x2=\"" + fixed(x, 2) +
             "\" y2=\"" + fixed(py(y + e), 2) + "\" stroke=\"" + s.color + "\" stroke-width=\"1.5\"/>\n";
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
  // Legend right of the plotting area, off the data.
  svg += svg_legend(frame, series);
  svg += "</svg>\n";
  return svg;
}

}  // namespace cellflow::client
