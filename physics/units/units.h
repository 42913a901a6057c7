// SI <-> lattice units, in one place. The lattice Boltzmann kernels
// (physics/lb) see lattice units only (dx = dt = 1, fluid density 1); every
// SI quantity crosses here.
//
// The conversion is fixed by three choices:
//   dx = R / cells_per_radius                     (resolution of the cell radius R)
//   dt = nu_lb dx^2 / nu,  nu_lb = (tau - 1/2)/3  (tau: relaxation time, nu = eta / rho)
//   m  = rho dx^3                                 (lattice density 1 = fluid density)
// and every other unit follows from dx, dt and m: velocity dx/dt, force
// m dx/dt^2, force density m/(dx^2 dt^2), stress m/(dx dt^2), shear rate 1/dt.
#pragma once

#include <cstddef>
#include <string_view>

#include "physics/core/status.h"

namespace cellflow::units {

// Water at room temperature, the paper's suspending fluid (section 7.1):
// the default of every flow scene.
inline constexpr double kWaterDensityKgM3 = 1e3;
inline constexpr double kWaterViscosityPaS = 1e-3;

// What fixes the conversion (field names follow ShearFlowNumerics).
struct LatticeChoice {
  double cell_radius_m = 0.0;                        // R > 0
  double cells_per_radius = 6.0;                     // R / dx > 0          (numerics.cells_per_radius)
  double relaxation_time = 1.0;                      // tau in (0.5, 3]      (numerics.relaxation_time)
  double fluid_density_kg_m3 = kWaterDensityKgM3;    // rho > 0
  double fluid_viscosity_pa_s = kWaterViscosityPaS;  // eta > 0 (dynamic)
};

// Stability limits of the lattice (validated against by validate_lattice).
struct StabilityLimits {
  double max_mach = 0.1;             // u / c_s, in (0, 0.3]   (numerics.max_mach)
  double max_relaxation_time = 3.0;  // tau above this: viscosity and wall position errors grow
};

class Units {
 public:
  Units(double dx_m, double dt_s, double mass_kg, double relaxation_time)
      : dx_(dx_m), dt_(dt_s), mass_(mass_kg), tau_(relaxation_time) {}

  double dx_m() const { return dx_; }
  double dt_s() const { return dt_; }
  double mass_kg() const { return mass_; }  // rho dx^3
  double relaxation_time() const { return tau_; }
  // nu_lb = (tau - 1/2) / 3
  double kinematic_viscosity_lattice() const { return (tau_ - 0.5) / 3.0; }

  double length_to_lattice(double m) const { return m / dx_; }
  double length_to_si(double l) const { return l * dx_; }
  double time_to_lattice(double s) const { return s / dt_; }
  double time_to_si(double t) const { return t * dt_; }
  // u_lb = u dt / dx
  double velocity_to_lattice(double m_per_s) const { return m_per_s * dt_ / dx_; }
  double velocity_to_si(double u) const { return u * dx_ / dt_; }
  // F_lb = F dt^2 / (m dx)
  double force_to_lattice(double n) const { return n * dt_ * dt_ / (mass_ * dx_); }
  double force_to_si(double f) const { return f * mass_ * dx_ / (dt_ * dt_); }
  // f_lb = f dx^2 dt^2 / m   (N/m^3)
  double force_density_to_lattice(double n_per_m3) const { return n_per_m3 * dx_ * dx_ * dt_ * dt_ / mass_; }
  double force_density_to_si(double f) const { return f * mass_ / (dx_ * dx_ * dt_ * dt_); }
  // gammadot_lb = gammadot dt
  double shear_rate_to_lattice(double per_s) const { return per_s * dt_; }
  double shear_rate_to_si(double g) const { return g / dt_; }
  // sigma_lb = sigma dx dt^2 / m   (Pa)
  double stress_to_lattice(double pa) const { return pa * dx_ * dt_ * dt_ / mass_; }
  double stress_to_si(double s) const { return s * mass_ / (dx_ * dt_ * dt_); }
  // rho_lb = rho dx^3 / m
  double density_to_lattice(double kg_per_m3) const { return kg_per_m3 * dx_ * dx_ * dx_ / mass_; }
  double density_to_si(double r) const { return r * mass_ / (dx_ * dx_ * dx_); }
  // nu_lb = nu dt / dx^2   (m^2/s)
  double kinematic_viscosity_to_lattice(double m2_per_s) const { return m2_per_s * dt_ / (dx_ * dx_); }

 private:
  double dx_, dt_, mass_, tau_;
};

// Checks the choice (every field positive and finite, tau in (0.5, 3]) and
// builds the conversion. Messages name `prefix` + the option, e.g.
// "numerics.relaxation_time = 0.5 must lie in (0.5, 3]".
StatusOr<Units> make_units(const LatticeChoice& choice, std::string_view prefix = "numerics.");

// Refuses a lattice whose largest speed (e.g. the wall speed) exceeds
// max_mach c_s (c_s = 1/sqrt(3) in lattice units), or whose tau lies outside
// (0.5, max_relaxation_time]. The message names the options to change and the
// values that would pass, e.g. "Mach number 0.21 = u / c_s exceeds
// numerics.max_mach = 0.1: raise numerics.cells_per_radius to at least 12.6 or
// lower numerics.relaxation_time to at most 0.74".
Status validate_lattice(const Units& units, const LatticeChoice& choice, double max_speed_m_per_s,
                        const StabilityLimits& limits = {}, std::string_view prefix = "numerics.");

// Lattice nodes along a length: round(L / dx), at least 1. Walls of a box
// of height H sit at y = 0 and y = ny dx, so a scene should take the exact
// H = ny dx (length_to_si(ny)) for its wall speed.
int nodes_along(const Units& units, double length_m);

// Bytes of a coupled fluid lattice (AA populations, force and velocity fields,
// walls in y) of nx x ny x nz nodes in the given precision (the same count
// physics/lb allocates).
std::size_t estimate_lattice_bytes(int nx, int ny, int nz, bool single_precision);

// The largest lattice any run allocates (1 TiB, beyond the memory of a
// compute node): the cap when numerics.memory_limit_bytes is <= 0, and the
// largest limit a spec may set.
inline constexpr double kMaxLatticeBytes = 1099511627776.0;

// kResourceExhausted if `bytes` exceeds `limit_bytes` (a limit <= 0 means
// kMaxLatticeBytes; a larger limit is capped at it), naming
// numerics.memory_limit_bytes and numerics.cells_per_radius.
Status check_memory(std::size_t bytes, double limit_bytes, std::string_view prefix = "numerics.");

}  // namespace cellflow::units
