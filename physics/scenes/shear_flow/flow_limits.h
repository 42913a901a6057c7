// Failure limits and the threading threshold of the explicit flow step,
// shared by the single-cell scene (shear_flow.cc) and the suspension
// (suspension.cc), so that both stop a run for the same reasons.
#pragma once

#include <cstddef>

namespace cellflow::scenes {

// Elastic energy above this multiple of mu V0 is a blow-up: the paper's
// largest deformation (strain 1.8 at Ca = 2) stores about 3 mu V0.
inline constexpr double kEnergyBlowUp = 100.0;

// A vertex faster than this (lattice units, Mach 0.35) means the explicit
// coupling has gone unstable; the flow itself never exceeds u_wall.
inline constexpr double kRunawaySpeedLattice = 0.2;

// Vertex count (of all cells together) from which the coupling kernels use
// OpenMP threads (3000 vertices: elastic forces 0.56 ms serial, 0.37 ms on
// two free cores).
inline constexpr std::size_t kParallelVertices = 2000;

}  // namespace cellflow::scenes
