#include "physics/units/units.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "physics/core/violations.h"
#include "physics/lb/fluid.h"

namespace cellflow::units {
namespace {

std::string field(std::string_view prefix, std::string_view name) {
  return std::string(prefix) + std::string(name);
}

bool positive_finite(double v) {
  return v > 0.0 && std::isfinite(v);
}

}  // namespace

StatusOr<Units> make_units(const LatticeChoice& c, std::string_view prefix) {
  if (!positive_finite(c.cell_radius_m)) {
    return invalid_argument("cell radius = " + number_text(c.cell_radius_m, 4) + " m must be > 0");
  }
  if (!positive_finite(c.cells_per_radius)) {
    return invalid_argument(field(prefix, "cells_per_radius") + " = " + number_text(c.cells_per_radius, 4) +
                            " must be > 0");
  }
  if (!(c.relaxation_time > 0.5) || !std::isfinite(c.relaxation_time)) {
    return invalid_argument(field(prefix, "relaxation_time") + " = " + number_text(c.relaxation_time, 4) +
                            " must lie in (0.5, 3]");
  }
  if (!positive_finite(c.fluid_density_kg_m3)) {
    return invalid_argument("fluid_density_kg_m3 = " + number_text(c.fluid_density_kg_m3, 4) +
                            " must be > 0");
  }
  if (!positive_finite(c.fluid_viscosity_pa_s)) {
    return invalid_argument("fluid_viscosity_pa_s = " + number_text(c.fluid_viscosity_pa_s, 4) +
                            " must be > 0");
  }
  // dx = R / cells_per_radius
  const double dx = c.cell_radius_m / c.cells_per_radius;
  // nu_lb = (tau - 1/2) / 3,  nu = eta / rho,  dt = nu_lb dx^2 / nu
  const double nu_lb = (c.relaxation_time - 0.5) / 3.0;
  const double nu = c.fluid_viscosity_pa_s / c.fluid_density_kg_m3;
  const double dt = nu_lb * dx * dx / nu;
  // m = rho dx^3
  const double mass = c.fluid_density_kg_m3 * dx * dx * dx;
  return Units(dx, dt, mass, c.relaxation_time);
}

Status validate_lattice(const Units& units, const LatticeChoice& choice, double max_speed_m_per_s,
                        const StabilityLimits& limits, std::string_view prefix) {
  if (!(limits.max_mach > 0.0) || !(limits.max_mach <= 0.3)) {
    return invalid_argument(field(prefix, "max_mach") + " = " + number_text(limits.max_mach, 4) +
                            " must lie in (0, 0.3]");
  }
  const double tau = units.relaxation_time();
  if (!(tau > 0.5) || !(tau <= limits.max_relaxation_time)) {
    return invalid_argument(field(prefix, "relaxation_time") + " = " + number_text(tau, 4) +
                            " must lie in (0.5, " + number_text(limits.max_relaxation_time, 4) + "]");
  }
  // Ma = u_lb / c_s,  c_s = 1/sqrt(3)
  const double mach = std::abs(units.velocity_to_lattice(max_speed_m_per_s)) * std::sqrt(3.0);
  if (!(mach <= limits.max_mach)) {
    // u_lb = u (tau - 1/2) dx / (3 nu): Ma scales as 1 / cells_per_radius and as (tau - 1/2).
    const double cells_needed = choice.cells_per_radius * mach / limits.max_mach;
    const double tau_needed = 0.5 + (tau - 0.5) * limits.max_mach / mach;
    return invalid_argument("Mach number u / c_s = " + number_text(mach, 4) + " (lattice speed " +
                            number_text(units.velocity_to_lattice(max_speed_m_per_s), 4) + ") exceeds " +
                            field(prefix, "max_mach") + " = " + number_text(limits.max_mach, 4) + ": raise " +
                            field(prefix, "cells_per_radius") + " (now " +
                            number_text(choice.cells_per_radius, 4) + ") to at least " +
                            number_text(cells_needed, 4) + " or lower " + field(prefix, "relaxation_time") +
                            " (now " + number_text(tau, 4) + ") to at most " + number_text(tau_needed, 4));
  }
  return Status::ok_status();
}

int nodes_along(const Units& units, double length_m) {
  const double n = std::round(units.length_to_lattice(length_m));
  return n < 1.0 ? 1 : static_cast<int>(n);
}

std::size_t estimate_lattice_bytes(int nx, int ny, int nz, bool single_precision) {
  lb::FluidParams p;
  p.nx = nx;
  p.ny = ny;
  p.nz = nz;
  p.walls_y = true;
  p.force_field = true;
  p.velocity_field = true;
  p.streaming = lb::Streaming::kAA;
  p.precision = single_precision ? lb::Precision::kFloat : lb::Precision::kDouble;
  return lb::memory_bytes(p);
}

Status check_memory(std::size_t bytes, double limit_bytes, std::string_view prefix) {
  // NaN or <= 0: the cap alone
  const double limit = limit_bytes > 0.0 ? std::min(limit_bytes, kMaxLatticeBytes) : kMaxLatticeBytes;
  if (static_cast<double>(bytes) <= limit) return Status::ok_status();
  return Status(StatusCode::kResourceExhausted,
                "fluid lattice needs " + number_text(static_cast<double>(bytes), 4) + " bytes, above " +
                    field(prefix, "memory_limit_bytes") + " = " + number_text(limit_bytes, 4) +
                    (limit == limit_bytes ? std::string() : " (capped at " + number_text(limit, 4) + ")") +
                    ": lower " + field(prefix, "cells_per_radius") +
                    " (memory scales as its cube) or shrink the box");
}

}  // namespace cellflow::units
