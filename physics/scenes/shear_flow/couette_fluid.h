// The fluid of the flow scenes (shear_flow, suspension): a D3Q19 lattice with
// walls at y = 0 and y = H moving at -u_wall and +u_wall along x, started in
// the steady plane Couette profile, and its velocity snapshots in SI. One
// place for both scenes, so that they hold the same fluid.
#pragma once

#include <functional>
#include <string_view>
#include <vector>

#include "physics/core/status.h"
#include "physics/lb/fluid.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

// The lattice of `setup` (nodes, wall speed) with the force and velocity
// fields the coupling needs, and a phase field with these relaxation times
// when phase_taus is not empty (lb::FluidParams::phase_taus); errors
// prefixed with field_prefix + "numerics: ".
StatusOr<lb::Fluid> make_couette_fluid(const ShearFlowSetup& setup, const units::Units& units,
                                       const ShearFlowNumerics& numerics, std::string_view field_prefix,
                                       const std::vector<double>& phase_taus = {});

// Sets the populations to the equilibrium of the steady Couette profile
// u_x(y) = u_wall (2 y / H - 1) (nodes at y = j + 1/2) and writes the velocity field.
void start_couette_profile(lb::Fluid& fluid, double wall_speed_lattice);

// The mean shear rate du_x/dy at the two walls (lattice units): the velocity
// gradient (u(y = 1/2) + u_wall) / (1/2) at the lower wall and
// (u_wall - u(y = H - 1/2)) / (1/2) at the upper one, u averaged over the x-z
// plane of the first node layer (half-way bounce-back puts the walls at y = 0
// and H exactly), the two walls averaged. The wall shear stress is eta times
// it: the momentum the walls put into the fluid. The steady Couette profile
// of the empty box gives exactly 2 u_wall / H.
double couette_wall_shear_rate(const lb::Fluid& fluid, double wall_speed_lattice);

// Calls `emit` with the velocity field of the whole lattice in SI.
void emit_fluid_velocity(const lb::Fluid& fluid, const units::Units& units, int index, double time_s,
                         const std::function<void(const FluidVelocitySnapshot&)>& emit);

}  // namespace cellflow::scenes
