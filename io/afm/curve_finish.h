// Last step shared by every reader: bring the height to the model's sign
// convention (positive towards the sample, see force_curve.h) and derive the
// deflection and the tip position where the file did not store them.
#pragma once

#include "io/afm/force_curve.h"
#include "physics/core/status.h"

namespace cellflow::afm {

// The approach moves the cantilever towards the sample by definition, so a
// height that falls over the approach (or rises over the retract, when there
// is no approach) is counted the other way and is negated in every segment.
// Then deflection_m = force_n / k where only force is known, and
// tip_position_m = height_m - deflection_m. Fails on arrays of unequal length.
Status finish_curve(ForceCurve& curve);

}  // namespace cellflow::afm
