#include "io/afm/curve_finish.h"

#include <string>

#include "io/afm/preprocess.h"

namespace cellflow::afm {
namespace {

// +1: the height already rises towards the sample, -1: it must be negated,
// 0: no segment tells (no approach or retract with two distinct heights).
int height_direction(const ForceCurve& curve) {
  for (SegmentKind kind : {SegmentKind::kApproach, SegmentKind::kRetract}) {
    const Segment* s = curve.find(kind);
    if (s == nullptr || s->height_m.size() < 2) continue;
    const double change = s->height_m.back() - s->height_m.front();
    if (change == 0.0) continue;
    const bool rises = change > 0.0;
    return (rises == (kind == SegmentKind::kApproach)) ? 1 : -1;
  }
  return 0;
}

}  // namespace

Status finish_curve(ForceCurve& curve) {
  const std::string& file = curve.metadata.source_file;
  for (std::size_t i = 0; i < curve.segments.size(); ++i) {
    const Segment& s = curve.segments[i];
    const std::size_t n = s.force_n.size();
    const bool ok = s.height_m.size() == n && (s.time_s.empty() || s.time_s.size() == n) &&
                    (s.deflection_m.empty() || s.deflection_m.size() == n);
    if (!ok) {
      return invalid_argument(file + ": segment " + std::to_string(i) + " (" + s.name +
                              "): channels have different lengths");
    }
  }

  if (height_direction(curve) < 0) {
    for (Segment& s : curve.segments) {
      for (double& h : s.height_m) h = -h;
      for (double& x : s.tip_position_m) x = -x;  // set directly by text readers without deflection
    }
    curve.metadata.height_sign_flipped = !curve.metadata.height_sign_flipped;
  }

  const auto& k = curve.metadata.spring_constant_n_per_m;
  for (Segment& s : curve.segments) {
    if (s.deflection_m.empty() && k && *k > 0.0) {
      s.deflection_m.resize(s.force_n.size());
      for (std::size_t j = 0; j < s.force_n.size(); ++j) s.deflection_m[j] = s.force_n[j] / *k;
    }
    if (!s.deflection_m.empty()) s.tip_position_m = tip_position_m(s.height_m, s.deflection_m);
  }
  return Status::ok_status();
}

}  // namespace cellflow::afm
