#include "io/afm/force_curve.h"

namespace cellflow::afm {

const char* segment_kind_name(SegmentKind kind) {
  switch (kind) {
    case SegmentKind::kApproach:
      return "approach";
    case SegmentKind::kPause:
      return "pause";
    case SegmentKind::kRetract:
      return "retract";
    case SegmentKind::kUnknown:
      break;
  }
  return "unknown";
}

const Segment* ForceCurve::find(SegmentKind kind) const {
  for (const Segment& s : segments) {
    if (s.kind == kind) return &s;
  }
  return nullptr;
}

}  // namespace cellflow::afm
