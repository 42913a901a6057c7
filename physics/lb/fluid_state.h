// The complete time-stepping state of a Fluid as raw bytes, for checkpoints
// (physics/scenes/shear_flow/shear_flow_checkpoint.h): the population arrays
// (every direction array with its padding, in the storage precision) and, for
// the AA pattern with walls, the wall-layer densities of the last even step,
// plus the phase of the streaming scheme. Restoring these into a Fluid made
// with the same FluidParams continues the run bit for bit. The force and
// velocity fields are not state: the coupling clears and refills the force
// field each step and collide_stream rewrites the velocity field.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "physics/lb/fluid.h"

namespace cellflow::lb {

// Where the streaming scheme stands: the step count, the AA phase (odd steps
// leave the populations in the opposite slots) and the two-array half.
struct FluidPhase {
  std::int64_t time_step = 0;
  bool aa_swapped = false;
  int current = 0;  // 0 or 1
};

FluidPhase fluid_phase(const Fluid& fluid);
// kInvalidArgument for a negative step or current outside {0, 1}. (The AA
// phase is not tied to the step's parity: set_equilibrium resets it.)
Status set_fluid_phase(Fluid& fluid, const FluidPhase& phase);

// The population storage and the wall densities as bytes (sizes fixed by the
// params: equal for two fluids made with the same FluidParams).
std::span<const std::byte> population_bytes(const Fluid& fluid);
std::span<std::byte> mutable_population_bytes(Fluid& fluid);
std::span<const std::byte> wall_density_bytes(const Fluid& fluid);
std::span<std::byte> mutable_wall_density_bytes(Fluid& fluid);

}  // namespace cellflow::lb
