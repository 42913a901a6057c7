// The pieces of the client's SVG plots (curve_output, flow_output): number
// formatting, XML escaping, nice ticks, the frame with grid, ticks and axis
// labels, and the legend entries, so every plot is drawn alike.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace cellflow::client {

// `value` with `digits` digits after the decimal point ("%.*f").
std::string fixed(double value, int digits);

// Digits after the decimal point that show tick step `step` exactly enough.
int decimals_for(double step);

// `text` with &, <, > and " as XML entities.
std::string escape_xml(const std::string& text);

// "Nice" tick positions (1, 2, 5 x 10^k steps) covering [lo, hi]: the first
// tick is <= lo and the last >= hi.
std::vector<double> nice_ticks(double lo, double hi, int target_count = 6);

// One axis of a plot: nice ticks covering the data, and the drawn range
// [lo, hi], the ticks' span padded by 3% on either side so that no data point
// lies on the frame.
struct PlotAxis {
  std::vector<double> ticks;
  double lo = 0.0, hi = 1.0;
};

// The axis for data in [data_lo, data_hi] (an empty or reversed range becomes
// [data_lo, data_lo + 1]).
PlotAxis nice_axis(double data_lo, double data_hi, int target_count = 6);

// The SI prefix of a force axis: the largest force lands in [1, 1000) of it
// (fN ... N; nN when every force is below 1 fN).
struct ForceUnit {
  double scale;      // newtons per unit
  const char* name;  // "nN"
};
ForceUnit force_unit(double max_force_n);

// The plot's page and the margins around the plotting area, in SVG pixels.
struct PlotFrame {
  double width = 720, height = 480, left = 90, right = 30, top = 50, bottom = 70;
  double plot_w() const { return width - left - right; }
  double plot_h() const { return height - top - bottom; }
  // Value `v` on `axis` to its SVG x (left to right) or y (bottom to top).
  double x_of(const PlotAxis& axis, double v) const {
    return left + plot_w() * (v - axis.lo) / (axis.hi - axis.lo);
  }
  double y_of(const PlotAxis& axis, double v) const {
    return top + plot_h() * (1.0 - (v - axis.lo) / (axis.hi - axis.lo));
  }
};

// A tick value (in axis units) to its SVG pixel coordinate.
using PixelOf = std::function<double(double)>;

// The XML declaration, the <svg> element, a white background and the title.
std::string svg_open(const PlotFrame& frame, const std::string& title);

// Grid lines, ticks and tick labels at `x_ticks` and `y_ticks`, the frame
// around the plotting area and both axis labels.
std::string svg_axes(const PlotFrame& frame, const std::vector<double>& x_ticks,
                     const std::vector<double>& y_ticks, const PixelOf& px, const PixelOf& py,
                     const std::string& x_label, const std::string& y_label);

// One data set of a plot: a polyline and/or markers, with a legend entry.
struct PlotSeries {
  std::vector<std::pair<double, double>> points;
  std::string color;
  std::string dash;            // stroke-dasharray, "" = solid
  bool line = true;            // draw the polyline
  bool markers = false;        // draw a circle per point
  std::vector<bool> hollow;    // per point (markers only): an open circle
  std::vector<double> errors;  // per point: a vertical bar y +- error (none where 0 or missing)
  std::string label;           // empty: no legend entry
};

// The stroke attributes of a series' line: color, width 2, dashes if any.
std::string svg_stroke(const PlotSeries& series);

// The default frame widened on the right by room for the legend of
// `series`, so that the legend sits outside the plotting area and covers no
// data; the plotting area keeps its size.
PlotFrame frame_with_legend(const std::vector<PlotSeries>& series);

// The legend of `series` in its box, right of the plotting area of `frame`
// (made by frame_with_legend), top aligned with it.
std::string svg_legend(const PlotFrame& frame, const std::vector<PlotSeries>& series);

// One legend row per series from (lx, ly) down, 22 px apart: its line
// sample, marker and label (the box around them is the caller's).
std::string svg_legend_entries(double lx, double ly, const std::vector<PlotSeries>& series);

// A whole plot of `series`: both axes from 0 (or below, for negative data)
// to past the data and the hints, nice ticks, grid, labels, the series'
// lines and markers (hollow where asked) and the legend off the data.
std::string plot_svg(const std::string& title, const std::string& x_label, const std::string& y_label,
                     const std::vector<PlotSeries>& series, double x_hint, double y_hint);

}  // namespace cellflow::client
