#include "client/study_output.h"

#include <algorithm>
#include <cmath>

#include "client/svg_plot.h"
#include "jobs/study/study.h"

namespace cellflow::client {

StatusOr<v1::StudyAxis> parse_set_axis(const std::string& argument) {
  const auto equals = argument.find('=');
  if (equals == std::string::npos || equals == 0) {
    return invalid_argument("--set " + argument +
                            ": give PATH=VALUE[,VALUE...], e.g. shearFlow.capillaryNumber=0.05,0.1");
  }
  v1::StudyAxis axis;
  axis.set_path(argument.substr(0, equals));
  const std::string values = argument.substr(equals + 1);
  if (values.empty()) return invalid_argument("--set " + argument + ": no value after '='");
  for (const std::string& value : jobs::split_value_list(values)) {
    if (value.empty()) return invalid_argument("--set " + argument + ": an empty value between commas");
    axis.add_values(jobs::value_text_as_json(value));
  }
  return axis;
}

StatusOr<v1::JobSpec> apply_set(const v1::JobSpec& spec, const std::string& argument) {
  const auto equals = argument.find('=');
  if (equals == std::string::npos || equals == 0 || equals + 1 == argument.size()) {
    return invalid_argument("--set " + argument + ": give PATH=VALUE, e.g. compression.loadPoints=20");
  }
  const std::string path = argument.substr(0, equals);
  return jobs::set_spec_field(spec, path, jobs::value_text_as_json(argument.substr(equals + 1)),
                              "--set " + path, "--set " + path);
}

int study_value_index(const v1::StudySpec& study, int child_index, int axis) {
  if (study.combination() == v1::StudySpec::ZIP) return child_index;
  int rest = child_index;
  for (int i = study.axes_size() - 1; i > axis; --i) rest /= std::max(1, study.axes(i).values_size());
  return rest % std::max(1, study.axes(axis).values_size());
}

namespace {

// Colours of the overlaid series (the tab10 palette), repeated past ten.
const char* const kPalette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

}  // namespace

std::string curves_overlay_svg(const std::vector<LabelledCurve>& curves, const std::string& title) {
  double f_max = 0.0;
  for (const auto& c : curves) {
    const int iforce = c.curve.column("force_n");
    for (const auto& row : c.curve.rows)
      if (iforce >= 0 && std::isfinite(row[iforce])) f_max = std::max(f_max, row[iforce]);
  }
  const ForceUnit unit = force_unit(f_max);
  std::vector<PlotSeries> series;
  for (std::size_t i = 0; i < curves.size(); ++i) {
    const Curve& curve = curves[i].curve;
    const int ix = curve.column("deformation");
    const int iforce = curve.column("force_n");
    PlotSeries s;
    s.color = kPalette[i % (sizeof kPalette / sizeof kPalette[0])];
    s.markers = true;
    s.label = curves[i].label;
    if (ix >= 0 && iforce >= 0) {
      for (const auto& row : curve.rows) s.points.emplace_back(row[ix], row[iforce] / unit.scale);
    }
    series.push_back(std::move(s));
  }
  return plot_svg(title, "deformation \u03b4 / 2R", "force (" + std::string(unit.name) + ")", series, 0.0,
                  0.0);
}

std::string swept_steady_svg(const std::vector<SweptSteadyPoint>& points, const std::string& x_label,
                             const std::string& title) {
  std::vector<SweptSteadyPoint> sorted = points;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.value < b.value; });
  PlotSeries simulation;
  simulation.color = "#1f77b4";
  simulation.markers = true;
  simulation.label = "steady D (open: not steady)";
  for (const auto& p : sorted) {
    simulation.points.emplace_back(p.value, p.steady_taylor_deformation);
    simulation.hollow.push_back(!p.steady);
  }
  return plot_svg(title, x_label, "steady Taylor deformation D", {simulation}, 0.0, 0.0);
}

}  // namespace cellflow::client
