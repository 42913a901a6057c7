// Shear-flow scene: validation of the params and the plan (units, lattice,
// Mach and memory checks) derived from them before anything is allocated.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>
#include <utility>

#include "physics/lb/fluid.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/scenes/shear_flow/shear_flow_internal.h"
#include "physics/scenes/shear_flow/shear_flow_resolution.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

namespace shear_flow_detail {

double shear_modulus(const elastic::Material& material) {
  const elastic::Moduli m = elastic::moduli_from(material);
  return m.mu1_pa + m.mu2_pa;
}

namespace {

bool positive_finite(double v) {
  return v > 0.0 && std::isfinite(v);
}

// What the scene can run, each bound declared once here.
// Fluid: from a light gas to beyond the densest liquid metal (mercury
// 13.5e3), from below air's viscosity (1.8e-5) to a thick syrup.
constexpr double kMinFluidDensityKgM3 = 1.0, kMaxFluidDensityKgM3 = 1e5;
constexpr double kMinFluidViscosityPaS = 1e-6, kMaxFluidViscosityPaS = 1e3;
// Shear rate: one strain unit in 11 days to one in 0.1 us; the plan's Mach
// and work checks refuse most of both ends for a given cell.
constexpr double kMinShearRatePerS = 1e-6, kMaxShearRatePerS = 1e7;
// Ca = eta gammadot / mu, set or derived: below 1e-6 the deformation
// (5/4 Ca) is far below the mesh's own D (discretisation floor, ~1e-3), and
// the stiffness check refuses the cell anyway; above 100 the cell is a
// thread that no lattice resolves (the kernel warning starts at Ca ~ 1.6).
constexpr double kMinCapillaryNumber = 1e-6, kMaxCapillaryNumber = 100.0;
// A Ca derived from a shear rate (already in its own range) only guards the
// arithmetic here: a cell too stiff for the flow gets the stiffness check's
// message at the start of the run, which names the options to change.
constexpr double kMinDerivedCapillaryNumber = 1e-15;
// tau: nu_lb = (tau - 1/2) / 3 > 1/600: below, the collision is at its
// stability edge and the steps per strain (~ 1 / nu_lb) explode.
constexpr double kMinRelaxationTime = 0.505;
// Ma below 1e-3 makes every shear rate a lattice of hundreds of thousands of
// steps per strain unit: a limit that small refuses every useful run.
constexpr double kMinMaxMach = 1e-3;
// Strain and time limits: 1e4 strain units (hundreds of tank-treading turns);
// max_time_s up to 1e7 s (four months of flow; max_strain ends a run first).
constexpr double kMaxStrain = 1e4;
constexpr double kMaxTimeS = 1e7;
// Samples and snapshots: every 1e-3 strain unit at most often, at most 1e5
// samples (the result keeps each in memory) and 10^4 snapshots per run (each
// writes the mesh positions, or with fluid_snapshots also the lattice's
// velocity field; a run that reaches its steady state stops long before).
constexpr double kMinSampleEveryStrain = 1e-3;
constexpr double kMaxSamples = 1e5;
constexpr double kMinSnapshotEveryStrain = 1e-3;
constexpr double kMaxSnapshots = 1e4;
// Work: lattice node updates (nodes x time steps up to max_strain or
// max_time_s); 4e12 is about a day on one core (~50 M updates/s) and a
// few hours on a node. The default flow job needs 1.4e10.
constexpr double kMaxLatticeNodeSteps = 4e12;

std::string interval(double lo, double hi) {
  return "[" + number_text(lo) + ", " + number_text(hi) + "]";
}

// Smallest box (in radii) that holds the cell and the support of its
// immersed-boundary kernel: periodic directions need the cell and its image
// apart by one kernel width; the wall direction needs half a kernel width
// plus one spacing on each side.
double min_box_periodic_radii(const ShearFlowNumerics& n) {
  return 2.0 + ibm::kernel_width(n.ibm_kernel) / n.cells_per_radius;
}
double min_box_wall_radii(const ShearFlowNumerics& n) {
  return 2.0 + (ibm::kernel_width(n.ibm_kernel) + 2.0) / n.cells_per_radius;
}

}  // namespace

namespace {

StatusOr<Plan> make_plan_at(const ShearFlowParams& params, std::string_view field_prefix);

// Ca = eta gammadot / mu (paper eq. 17), set or derived; 0 when it cannot be derived.
double capillary_number_of(const ShearFlowParams& params) {
  if (params.capillary_number > 0.0) return params.capillary_number;
  const double mu = shear_modulus(params.cell.material);
  return mu > 0.0 ? params.fluid_viscosity_pa_s * params.shear_rate_per_s / mu : 0.0;
}

}  // namespace

StatusOr<Plan> make_plan(const ShearFlowParams& params, std::string_view field_prefix) {
  if (Status s = validate(params, field_prefix); !s.ok()) return s;
  const ShearFlowNumerics& n = params.numerics;
  const double ca = capillary_number_of(params);
  const double resolving =
      std::min(resolving_cells_per_radius(ca, n.ibm_kernel), kMaxResolvingCellsPerRadius);
  if (n.resolve_thickness && predicted_thickness_over_radius(ca) < kFlattenedThicknessOverRadius &&
      resolving > n.cells_per_radius) {
    // The lattice on which the predicted steady thickness spans
    // kThicknessMargin x kMinThicknessOverKernel kernel widths.
    ShearFlowParams finer = params;
    finer.numerics.cells_per_radius = resolving;
    StatusOr<Plan> plan = make_plan_at(finer, field_prefix);
    if (plan.ok()) return plan;
    StatusOr<Plan> coarse = make_plan_at(params, field_prefix);
    if (coarse.ok()) {
      coarse->setup.resolution_note =
          "the lattice that resolves the predicted thickness at Ca = " + number_text(ca, 6) + " (" +
          std::string(field_prefix) + "numerics.cells_per_radius = " + number_text(resolving, 6) +
          ") was refused (" + plan.status().message() + "); running at " + number_text(n.cells_per_radius, 6);
    }
    return coarse;
  }
  return make_plan_at(params, field_prefix);
}

namespace {

StatusOr<Plan> make_plan_at(const ShearFlowParams& params, std::string_view field_prefix) {
  const std::string prefix(field_prefix);
  const std::string numerics_prefix = prefix + "numerics.";
  const ShearFlowNumerics& n = params.numerics;
  Plan plan;
  ShearFlowSetup& setup = plan.setup;
  const double radius = params.cell.radius_m;
  const double eta = params.fluid_viscosity_pa_s;
  setup.shear_modulus_pa = shear_modulus(params.cell.material);
  if (params.capillary_number > 0.0) {
    setup.capillary_number = params.capillary_number;
    // gammadot = Ca mu / eta   (paper eq. 17 solved for the shear rate)
    setup.shear_rate_per_s = params.capillary_number * setup.shear_modulus_pa / eta;
  } else {
    setup.shear_rate_per_s = params.shear_rate_per_s;
    // Ca = eta gammadot / mu   (paper eq. 17)
    setup.capillary_number = eta * params.shear_rate_per_s / setup.shear_modulus_pa;
  }
  const double gammadot = setup.shear_rate_per_s;
  if (!(setup.capillary_number >= kMinDerivedCapillaryNumber &&
        setup.capillary_number <= kMaxCapillaryNumber)) {
    // only a shear rate gets here: a set Ca was checked by validate()
    return invalid_argument(prefix + "shear_rate_per_s = " + number_text(params.shear_rate_per_s) +
                            " gives Ca = eta gammadot / mu = " + number_text(setup.capillary_number, 6) +
                            " (mu = " + number_text(setup.shear_modulus_pa, 6) + " Pa of " + prefix +
                            "cell.material), which must lie in " +
                            interval(kMinDerivedCapillaryNumber, kMaxCapillaryNumber));
  }
  // Re_p = rho gammadot R^2 / eta
  setup.reynolds_number_physical = params.fluid_density_kg_m3 * gammadot * radius * radius / eta;
  setup.simulated_density_kg_m3 = params.fluid_density_kg_m3;
  // The target also bounds the deformed cell: its Reynolds number on the
  // predicted long half-axis, Re_p (a3 / R)^2, at most kLongAxisReynoldsAllowance
  // targets (binding from Ca of about 0.7 up).
  const double elongation = predicted_long_axis_over_radius_squared(setup.capillary_number);
  const double target_re_p =
      std::min(n.target_reynolds_number, kLongAxisReynoldsAllowance * n.target_reynolds_number / elongation);
  if (n.target_reynolds_number > 0.0 && setup.reynolds_number_physical < target_re_p) {
    // rho_sim = Re_p,target eta / (gammadot R^2)
    setup.simulated_density_kg_m3 = target_re_p * eta / (gammadot * radius * radius);
  }
  setup.reynolds_number_simulated = setup.simulated_density_kg_m3 * gammadot * radius * radius / eta;

  units::LatticeChoice choice;
  choice.cell_radius_m = radius;
  choice.cells_per_radius = n.cells_per_radius;
  choice.relaxation_time = n.relaxation_time;
  choice.fluid_density_kg_m3 = setup.simulated_density_kg_m3;
  choice.fluid_viscosity_pa_s = eta;
  StatusOr<units::Units> made = units::make_units(choice, numerics_prefix);
  if (!made.ok()) return made.status();
  plan.units = *made;
  const units::Units& u = plan.units;
  setup.lattice_spacing_m = u.dx_m();
  setup.time_step_s = u.dt_s();
  setup.nx = units::nodes_along(u, n.box_x_radii * radius);
  setup.ny = units::nodes_along(u, n.box_y_radii * radius);
  setup.nz = units::nodes_along(u, n.box_z_radii * radius);
  setup.box_m[0] = u.length_to_si(setup.nx);
  setup.box_m[1] = u.length_to_si(setup.ny);
  setup.box_m[2] = u.length_to_si(setup.nz);
  // u_wall = H gammadot / 2 with the lattice's exact wall distance H = ny dx   (paper section 7.1)
  setup.wall_speed_m_per_s = 0.5 * setup.box_m[1] * gammadot;
  // Ma = u_wall / c_s, c_s = 1 / sqrt(3) in lattice units
  setup.mach_number = std::abs(u.velocity_to_lattice(setup.wall_speed_m_per_s)) * std::sqrt(3.0);
  setup.shear_rate_lattice = u.shear_rate_to_lattice(gammadot);
  setup.steps_per_strain = 1.0 / setup.shear_rate_lattice;
  setup.cells_per_radius = n.cells_per_radius;
  // 2 a1 / (width dx) with dx = R / cells_per_radius
  setup.predicted_thickness_over_kernel = predicted_thickness_over_radius(setup.capillary_number) *
                                          n.cells_per_radius / ibm::kernel_width(n.ibm_kernel);

  units::StabilityLimits limits;
  limits.max_mach = n.max_mach;
  if (Status s = units::validate_lattice(u, choice, setup.wall_speed_m_per_s, limits, numerics_prefix);
      !s.ok()) {
    std::string message = s.message();
    if (setup.simulated_density_kg_m3 > params.fluid_density_kg_m3) {
      // With the density raised, u_wall,lb = (H / 2R) Re nu_lb / cells_per_radius.
      message += ", or lower " + numerics_prefix + "target_reynolds_number (now " +
                 number_text(n.target_reynolds_number, 6) + ")";
    }
    return Status(s.code(), std::move(message));
  }
  setup.viscosity_ratio = params.viscosity_ratio;
  setup.inner_relaxation_time = lb::tau_for_viscosity_ratio(n.relaxation_time, params.viscosity_ratio);
  setup.lattice_bytes = units::estimate_lattice_bytes(setup.nx, setup.ny, setup.nz, n.single_precision);
  if (params.viscosity_ratio != 1.0) {
    // The phase field (1 byte a node), the marking's owner field (4) and the
    // phases it writes through (1).
    setup.lattice_bytes +=
        6 * static_cast<std::size_t>(setup.nx) * setup.ny * static_cast<std::size_t>(setup.nz);
  }
  if (Status s = units::check_memory(setup.lattice_bytes, n.memory_limit_bytes, numerics_prefix); !s.ok())
    return s;
  // The run's work: nodes x the steps up to max_strain (or max_time_s).
  double steps = n.max_strain * setup.steps_per_strain;
  if (n.max_time_s > 0.0) steps = std::min(steps, u.time_to_lattice(n.max_time_s));
  const double node_steps = static_cast<double>(setup.nx) * setup.ny * setup.nz * steps;
  if (!(node_steps <= kMaxLatticeNodeSteps)) {
    return invalid_argument(
        numerics_prefix + "max_strain = " + number_text(n.max_strain) + " needs " + number_text(steps, 4) +
        " time steps (" + number_text(setup.steps_per_strain, 4) + " per strain unit) on " +
        std::to_string(setup.nx) + " x " + std::to_string(setup.ny) + " x " + std::to_string(setup.nz) +
        " nodes: " + number_text(node_steps, 4) + " node updates, more than " +
        number_text(kMaxLatticeNodeSteps) + " (about a day on one core): lower " + numerics_prefix +
        "max_strain, set " + numerics_prefix + "max_time_s, raise " + numerics_prefix +
        "target_reynolds_number (now " + number_text(n.target_reynolds_number) + ") or lower " +
        numerics_prefix + "cells_per_radius (now " + number_text(n.cells_per_radius) + ")");
  }
  return plan;
}

}  // namespace

}  // namespace shear_flow_detail

using namespace shear_flow_detail;

Violations violations(const ShearFlowParams& params) {
  Violations v;
  v.add_all(cell::check(params.cell), "cell.");
  if (!positive_finite(params.fluid_density_kg_m3)) {
    v.add("fluid_density_kg_m3",
          "= " + number_text(params.fluid_density_kg_m3, 6) + " must be > 0 and finite");
  } else if (!(params.fluid_density_kg_m3 >= kMinFluidDensityKgM3 &&
               params.fluid_density_kg_m3 <= kMaxFluidDensityKgM3)) {
    v.add_value("fluid_density_kg_m3", params.fluid_density_kg_m3,
                "lie in " + interval(kMinFluidDensityKgM3, kMaxFluidDensityKgM3) + " kg/m^3");
  }
  if (!positive_finite(params.fluid_viscosity_pa_s)) {
    v.add("fluid_viscosity_pa_s",
          "= " + number_text(params.fluid_viscosity_pa_s, 6) + " must be > 0 and finite");
  } else if (!(params.fluid_viscosity_pa_s >= kMinFluidViscosityPaS &&
               params.fluid_viscosity_pa_s <= kMaxFluidViscosityPaS)) {
    v.add_value("fluid_viscosity_pa_s", params.fluid_viscosity_pa_s,
                "lie in " + interval(kMinFluidViscosityPaS, kMaxFluidViscosityPaS) + " Pa s");
  }
  const bool has_rate = params.shear_rate_per_s != 0.0;
  const bool has_ca = params.capillary_number != 0.0;
  if (has_rate && has_ca) {
    v.add_message("set only one of {}shear_rate_per_s and {}capillary_number");
  } else if (!has_rate && !has_ca) {
    v.add_message("set one of {}shear_rate_per_s (> 0) or {}capillary_number (> 0)");
  } else if (has_rate && !positive_finite(params.shear_rate_per_s)) {
    v.add("shear_rate_per_s", "= " + number_text(params.shear_rate_per_s, 6) + " must be > 0 and finite");
  } else if (has_ca && !positive_finite(params.capillary_number)) {
    v.add("capillary_number", "= " + number_text(params.capillary_number, 6) + " must be > 0 and finite");
  } else if (has_rate && !(params.shear_rate_per_s >= kMinShearRatePerS &&
                           params.shear_rate_per_s <= kMaxShearRatePerS)) {
    v.add_value("shear_rate_per_s", params.shear_rate_per_s,
                "lie in " + interval(kMinShearRatePerS, kMaxShearRatePerS) + " /s");
  } else if (has_ca && !(params.capillary_number >= kMinCapillaryNumber &&
                         params.capillary_number <= kMaxCapillaryNumber)) {
    v.add_value("capillary_number", params.capillary_number,
                "lie in " + interval(kMinCapillaryNumber, kMaxCapillaryNumber));
  }

  const ShearFlowNumerics& n = params.numerics;
  const bool cpr_ok = n.cells_per_radius >= 2.0 && n.cells_per_radius <= 64.0;
  if (!cpr_ok) {
    v.add("numerics.cells_per_radius", "= " + number_text(n.cells_per_radius, 6) + " must lie in [2, 64]");
  }
  auto check_box = [&](const char* name, double value, double minimum, const char* why) {
    if (!(value >= minimum && value <= 1000.0)) {
      v.add(std::string("numerics.") + name, "= " + number_text(value, 6) + " must lie in [" +
                                                 number_text(minimum, 6) + ", 1000] (" + why + ")");
    }
  };
  const double min_periodic = cpr_ok ? min_box_periodic_radii(n) : 2.0;
  // A Lees-Edwards plane needs no spacing beyond the kernel's reach: the
  // stencil must only not cross it.
  const double min_wall = !cpr_ok                                             ? 2.0
                          : n.boundaries == ShearFlowBoundaries::kLeesEdwards ? min_box_periodic_radii(n)
                                                                              : min_box_wall_radii(n);
  check_box("box_x_radii", n.box_x_radii, min_periodic,
            "the cell diameter 2 plus one kernel width between the cell and its periodic image");
  check_box("box_y_radii", n.box_y_radii, min_wall,
            n.boundaries == ShearFlowBoundaries::kLeesEdwards
                ? "the cell diameter 2 plus half a kernel width on each side of the Lees-Edwards plane"
                : "the cell diameter 2 plus half a kernel width and one spacing at each wall");
  check_box("box_z_radii", n.box_z_radii, min_periodic,
            "the cell diameter 2 plus one kernel width between the cell and its periodic image");
  if (!(n.relaxation_time > 0.5 && n.relaxation_time <= 3.0)) {
    v.add("numerics.relaxation_time", "= " + number_text(n.relaxation_time, 6) + " must lie in (0.5, 3]");
  } else if (!(n.relaxation_time >= kMinRelaxationTime)) {
    v.add_value("numerics.relaxation_time", n.relaxation_time, "lie in " + interval(kMinRelaxationTime, 3.0));
  }
  if (!(n.max_mach > 0.0 && n.max_mach <= 0.3)) {
    v.add("numerics.max_mach", "= " + number_text(n.max_mach, 6) + " must lie in (0, 0.3]");
  } else if (!(n.max_mach >= kMinMaxMach)) {
    v.add_value("numerics.max_mach", n.max_mach, "lie in " + interval(kMinMaxMach, 0.3));
  }
  if (!(n.target_reynolds_number >= 0.0 && n.target_reynolds_number <= 1.0)) {
    v.add("numerics.target_reynolds_number",
          "= " + number_text(n.target_reynolds_number, 6) + " must lie in [0, 1]");
  }
  if (!(n.steady_tolerance >= 0.0 && n.steady_tolerance < 1.0)) {
    v.add("numerics.steady_tolerance", "= " + number_text(n.steady_tolerance, 6) + " must lie in [0, 1)");
  }
  bool sample_ok = n.sample_every_strain > 0.0 && n.sample_every_strain <= 1.0;
  if (!sample_ok) {
    // At most 1 strain unit between samples keeps the tank-treading angle
    // increments (gammadot / 2 per unit strain) unambiguous.
    v.add("numerics.sample_every_strain",
          "= " + number_text(n.sample_every_strain, 6) + " must lie in (0, 1]");
  } else if (!(n.sample_every_strain >= kMinSampleEveryStrain)) {
    v.add_value("numerics.sample_every_strain", n.sample_every_strain,
                "lie in " + interval(kMinSampleEveryStrain, 1.0));
    sample_ok = false;
  }
  if (!(positive_finite(n.steady_window_strain) &&
        (!sample_ok || n.steady_window_strain >= 2.0 * n.sample_every_strain))) {
    v.add("numerics.steady_window_strain", "= " + number_text(n.steady_window_strain, 6) +
                                               " must be finite and at least 2 sample_every_strain = " +
                                               number_text(2.0 * n.sample_every_strain, 6));
  } else if (!(n.steady_window_strain <= kMaxStrain)) {
    v.add_value("numerics.steady_window_strain", n.steady_window_strain,
                "lie in [2 sample_every_strain, " + number_text(kMaxStrain) + "]");
  }
  const bool strain_ok = positive_finite(n.max_strain) && n.max_strain <= kMaxStrain;
  if (!strain_ok) {
    v.add("numerics.max_strain", "= " + number_text(n.max_strain, 6) + " must lie in (0, 1e4]");
  } else if (sample_ok && n.max_strain / n.sample_every_strain > kMaxSamples) {
    v.add_value("numerics.sample_every_strain", n.sample_every_strain,
                "give at most " + number_text(kMaxSamples) + " samples up to max_strain = " +
                    number_text(n.max_strain) + " (max_strain / sample_every_strain = " +
                    number_text(n.max_strain / n.sample_every_strain, 6) + ")");
  }
  if (!(n.max_time_s >= 0.0 && std::isfinite(n.max_time_s))) {
    v.add("numerics.max_time_s",
          "= " + number_text(n.max_time_s, 6) + " must be >= 0 (0: no limit) and finite");
  } else if (!(n.max_time_s <= kMaxTimeS)) {
    v.add_value("numerics.max_time_s", n.max_time_s,
                "lie in [0, " + number_text(kMaxTimeS) + "] s (0: no limit)");
  }
  if (!(n.snapshot_every_strain >= 0.0 && std::isfinite(n.snapshot_every_strain))) {
    v.add("numerics.snapshot_every_strain",
          "= " + number_text(n.snapshot_every_strain, 6) + " must be >= 0 (0: none)");
  } else if (n.snapshot_every_strain > 0.0 &&
             !(n.snapshot_every_strain >= kMinSnapshotEveryStrain && n.snapshot_every_strain <= kMaxStrain)) {
    v.add_value("numerics.snapshot_every_strain", n.snapshot_every_strain,
                "be 0 (none) or lie in " + interval(kMinSnapshotEveryStrain, kMaxStrain));
  } else if (n.snapshot_every_strain > 0.0 && strain_ok &&
             n.max_strain / n.snapshot_every_strain > kMaxSnapshots) {
    v.add_value("numerics.snapshot_every_strain", n.snapshot_every_strain,
                "give at most " + number_text(kMaxSnapshots) + " snapshots up to max_strain = " +
                    number_text(n.max_strain) + " (max_strain / snapshot_every_strain = " +
                    number_text(n.max_strain / n.snapshot_every_strain, 6) + ")");
  }
  if (!std::isfinite(n.memory_limit_bytes)) {
    v.add("numerics.memory_limit_bytes",
          "= " + number_text(n.memory_limit_bytes, 6) + " must be finite (<= 0: no limit)");
  } else if (!(n.memory_limit_bytes <= units::kMaxLatticeBytes)) {
    v.add_value("numerics.memory_limit_bytes", n.memory_limit_bytes,
                "be at most " + number_text(units::kMaxLatticeBytes) +
                    " (1 TiB, the lattice cap; <= 0: the cap alone)");
  }
  if (!(n.hydrodynamic_radius_offset >= -1.0 && n.hydrodynamic_radius_offset <= 2.0)) {
    v.add("numerics.hydrodynamic_radius_offset",
          "= " + number_text(n.hydrodynamic_radius_offset, 6) +
              " must lie in [0, 2] lattice spacings (negative down to -1: the kernel's default)");
  } else if (cpr_ok && !(radius_offset(n) <= 0.5 * n.cells_per_radius)) {
    v.add("numerics.hydrodynamic_radius_offset",
          "= " + number_text(n.hydrodynamic_radius_offset, 6) +
              " must be at most half of cells_per_radius (the markers would shrink below R / 2)");
  }
  if (!(n.max_stiffness_ratio >= 0.0 && n.max_stiffness_ratio <= 100.0)) {
    v.add("numerics.max_stiffness_ratio",
          "= " + number_text(n.max_stiffness_ratio, 6) + " must lie in [0, 100] (0: default)");
  }
  if (n.boundaries != ShearFlowBoundaries::kWalls && n.boundaries != ShearFlowBoundaries::kLeesEdwards)
    v.add("numerics.boundaries", "must be walls or lees_edwards");
  if (n.threads < 0) v.add("numerics.threads", "= " + std::to_string(n.threads) + " must be >= 0");
  if (n.marking_every_steps < 0 || n.marking_every_steps > 1000000) {
    v.add("numerics.marking_every_steps",
          "= " + std::to_string(n.marking_every_steps) + " must lie in [0, 1e6]");
  }
  const double lambda = params.viscosity_ratio;
  if (!positive_finite(lambda)) {
    v.add("viscosity_ratio", "= " + number_text(lambda, 6) + " must be > 0 and finite");
  } else if (!(lambda >= kMinViscosityRatio && lambda <= kMaxViscosityRatio)) {
    v.add_value("viscosity_ratio", lambda, "lie in " + interval(kMinViscosityRatio, kMaxViscosityRatio));
  } else if (n.relaxation_time > 0.5 && std::isfinite(n.relaxation_time) && lambda != 1.0 &&
             !(lb::tau_for_viscosity_ratio(n.relaxation_time, lambda) >= lb::kMinStableTau)) {
    // tau_in = 1/2 + lambda (tau - 1/2) >= 0.505
    v.add("viscosity_ratio",
          "= " + number_text(lambda, 6) + " gives the inner relaxation time " +
              number_text(lb::tau_for_viscosity_ratio(n.relaxation_time, lambda), 6) + " below the stable " +
              number_text(lb::kMinStableTau, 6) + ": at numerics.relaxation_time " +
              number_text(n.relaxation_time, 6) +
              " it must be >= " + number_text((lb::kMinStableTau - 0.5) / (n.relaxation_time - 0.5), 6) +
              " (raise numerics.relaxation_time for a smaller ratio)");
  }
  return v;
}

Status validate(const ShearFlowParams& params, std::string_view field_prefix) {
  return violations(params).status(field_prefix);
}

StatusOr<ShearFlowSetup> plan_shear_flow(const ShearFlowParams& params, std::string_view field_prefix) {
  StatusOr<Plan> plan = make_plan(params, field_prefix);
  if (!plan.ok()) return plan.status();
  return plan->setup;
}

StatusOr<PlannedShearFlow> plan_shear_flow_run(const ShearFlowParams& params, std::string_view field_prefix) {
  StatusOr<Plan> plan = make_plan(params, field_prefix);
  if (!plan.ok()) return plan.status();
  ShearFlowParams chosen = params;
  chosen.numerics.cells_per_radius = plan->setup.cells_per_radius;  // the resolving lattice, if raised
  return PlannedShearFlow(std::move(chosen), std::move(plan->setup), plan->units);
}

void PlannedShearFlow::set_threads(int threads) {
  params_.numerics.threads = std::clamp(threads, 0, 1024);
}

std::string_view boundaries_name(ShearFlowBoundaries boundaries) {
  switch (boundaries) {
    case ShearFlowBoundaries::kWalls:
      return "walls";
    case ShearFlowBoundaries::kLeesEdwards:
      return "lees_edwards";
  }
  return "unknown";
}

StatusOr<ShearFlowBoundaries> parse_boundaries(std::string_view name, std::string_view field) {
  if (name == "walls") return ShearFlowBoundaries::kWalls;
  if (name == "lees_edwards") return ShearFlowBoundaries::kLeesEdwards;
  // The name is hostile input: quote at most 64 characters of it.
  return invalid_argument(std::string(field) + " = \"" + std::string(name.substr(0, 64)) +
                          "\" must be \"walls\" or \"lees_edwards\"");
}

double default_radius_offset(ibm::Kernel kernel) {
  switch (kernel) {
    case ibm::Kernel::kPeskin4:
      return 0.4;
    case ibm::Kernel::kPeskin3:
      return 0.3;
    case ibm::Kernel::kTrilinear:
      return 0.0;
  }
  return 0.0;
}

double radius_offset(const ShearFlowNumerics& numerics) {
  return numerics.hydrodynamic_radius_offset < 0.0 ? default_radius_offset(numerics.ibm_kernel)
                                                   : numerics.hydrodynamic_radius_offset;
}

double contrast_spread_weight(double viscosity_ratio) {
  return std::pow(viscosity_ratio, kContrastSpreadExponent);
}

}  // namespace cellflow::scenes
