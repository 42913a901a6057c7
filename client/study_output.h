// Studies (sweeps) in the client: the `--set PATH=VALUES` arguments of
// `cellflow sweep` and `submit`, and the plots of a study's children: their
// force curves overlaid (compression, indentation) or their steady Taylor
// deformation against the swept value (shear flow).
#pragma once

#include <string>
#include <vector>

#include "cellflow/v1/spec.pb.h"
#include "client/curve_output.h"
#include "physics/core/status.h"

namespace cellflow::client {

// "compression.cell.material.youngsModulusPa=100,200,400" -> an axis with
// the values as JSON (a word that is not JSON becomes a string: PER_TET ->
// "PER_TET"). INVALID_ARGUMENT naming --set when there is no '=' or no value.
StatusOr<v1::StudyAxis> parse_set_axis(const std::string& argument);

// `submit --set PATH=VALUE`: the spec with that field set (one value).
StatusOr<v1::JobSpec> apply_set(const v1::JobSpec& spec, const std::string& argument);

// The value index of axis `axis` at point `child_index` of `study` (GRID:
// the last axis varies fastest; ZIP: the index itself).
int study_value_index(const v1::StudySpec& study, int child_index, int axis);

// One child's force curve in an overlay.
struct LabelledCurve {
  std::string label;  // "E = 1000" or the child's point label
  Curve curve;
};
// Force against deformation, one coloured series per child, the legend off the data.
std::string curves_overlay_svg(const std::vector<LabelledCurve>& curves, const std::string& title);

// One flow child: its swept value and what its result says about the end state.
struct SweptSteadyPoint {
  double value = 0.0;
  double steady_taylor_deformation = 0.0;
  bool steady = false;
};
// Steady D against the swept value (markers, hollow where not steady).
std::string swept_steady_svg(const std::vector<SweptSteadyPoint>& points, const std::string& x_label,
                             const std::string& title);

}  // namespace cellflow::client
