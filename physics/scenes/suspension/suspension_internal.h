// Internals of the suspension scene shared by suspension_plan.cc and
// suspension.cc. Not part of the public interface.
#pragma once

#include <string>
#include <string_view>

#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/scenes/suspension/suspension.h"

namespace cellflow::scenes::suspension_detail {

// The single-cell flow params of kind `kind` in the suspension's fluid, shear
// and flow numerics: what the shared flow plan and the stiffness check take.
ShearFlowParams flow_params(const SuspensionParams& params, std::size_t kind);

// A shear-flow message or field name in the suspension's names: "numerics."
// becomes "numerics.flow." and "cell." becomes "kinds[0].cell." after `prefix`.
std::string suspension_names(std::string message, std::string_view prefix);

// Bytes of the vertex state of one immersed cell of `vertices` vertices
// (positions, forces, velocities, SI scratch, markers; ImmersedCell).
std::size_t cell_state_bytes(std::size_t vertices);

}  // namespace cellflow::scenes::suspension_detail
