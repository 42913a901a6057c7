// Suspension scene: validation of the params, the plan (the shared flow plan
// of the first kind's cell: units, lattice, Mach, memory) and the placement of
// the cells, before anything is allocated.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "physics/ibm/ibm.h"
#include "physics/lb/fluid.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/scenes/suspension/placement.h"
#include "physics/scenes/suspension/suspension.h"
#include "physics/scenes/suspension/suspension_internal.h"

namespace cellflow::scenes {

namespace suspension_detail {

ShearFlowParams flow_params(const SuspensionParams& params, std::size_t kind) {
  ShearFlowParams p;
  p.cell = params.kinds.at(kind).cell;
  p.fluid_density_kg_m3 = params.fluid_density_kg_m3;
  p.fluid_viscosity_pa_s = params.fluid_viscosity_pa_s;
  p.shear_rate_per_s = params.shear_rate_per_s;
  p.capillary_number = params.capillary_number;
  p.numerics = params.numerics.flow;
  return p;
}

std::string suspension_names(std::string message, std::string_view prefix) {
  const std::string p(prefix);
  auto replace_all = [&](const std::string& from, const std::string& to) {
    for (std::size_t at = message.find(from); at != std::string::npos;
         at = message.find(from, at + to.size())) {
      message.replace(at, from.size(), to);
    }
  };
  replace_all(p + "numerics.", p + "numerics.flow.");
  replace_all(p + "cell.", p + "kinds[0].cell.");
  return message;
}

std::size_t cell_state_bytes(std::size_t vertices) {
  // positions, forces, velocities, positions_m, forces_n, markers, marker forces,
  // SI positions for the observables: 8 vectors of 3 doubles.
  return vertices * 3 * sizeof(double) * 8;
}

}  // namespace suspension_detail

using namespace suspension_detail;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kMaxKinds = 64;
// Cells per kind: far beyond what a lattice a machine holds can carry (the
// memory check bounds the run), small enough that counts stay ints.
constexpr int kMaxCellsPerKind = 100000;
constexpr double kMaxVolumeFraction = 0.5;

bool finite(double v) {
  return std::isfinite(v);
}

// Bytes of a kind's mesh (positions, tets, surface flags) and body (per tet
// B and V0), each kind once.
std::size_t kind_mesh_bytes(int vertices) {
  // About 5 tets per vertex for the sphere meshes; per tet 4 ints, 9 + 1 doubles.
  const std::size_t v = static_cast<std::size_t>(std::max(vertices, 0));
  return v * (3 * sizeof(double) + 1) + 5 * v * (4 * sizeof(int) + 10 * sizeof(double));
}

}  // namespace

SuspensionNumerics suspension_numerics_defaults() {
  SuspensionNumerics n;
  n.flow.box_x_radii = 5.0;
  n.flow.box_y_radii = 8.0;
  n.flow.box_z_radii = 4.0;
  n.flow.steady_tolerance = 0.0;
  n.flow.max_strain = 20.0;
  return n;
}

Violations violations(const SuspensionParams& params) {
  Violations v;
  if (params.kinds.empty() || params.kinds.size() > static_cast<std::size_t>(kMaxKinds)) {
    v.add("kinds", "has " + std::to_string(params.kinds.size()) + " entries; it must have 1 to " +
                       std::to_string(kMaxKinds));
    return v;
  }
  // Fluid, shear and flow numerics as the single-cell scene checks them, with
  // the first kind's cell (its fields renamed into the suspension's).
  const Violations flow = scenes::violations(flow_params(params, 0));
  for (const Violation& nested : flow.list()) {
    if (nested.field.empty()) {
      v.add_message(nested.problem);
    } else if (nested.field.rfind("numerics.", 0) == 0) {
      v.add("numerics.flow." + nested.field.substr(9), nested.problem);
    } else if (nested.field.rfind("cell.", 0) == 0) {
      v.add("kinds[0]." + nested.field, nested.problem);
    } else {
      v.add(nested.field, nested.problem);
    }
  }
  // The suspension's time loop has walls only (no Lees-Edwards planes).
  if (params.numerics.flow.boundaries != ShearFlowBoundaries::kWalls)
    v.add("numerics.flow.boundaries", "must be walls in a suspension (lees_edwards: single-cell flow only)");
  for (std::size_t k = 0; k < params.kinds.size(); ++k) {
    const SuspendedCellKind& kind = params.kinds[k];
    const std::string name = "kinds[" + std::to_string(k) + "].";
    if (k > 0) v.add_all(cell::check(kind.cell), name + "cell.");
    if (!(kind.viscosity_ratio >= 0.01 && kind.viscosity_ratio <= 100.0)) {
      v.add(name + "viscosity_ratio",
            "= " + number_text(kind.viscosity_ratio, 6) + " must lie in [0.01, 100] (eta_in / eta_out)");
    } else if (const double tau = params.numerics.flow.relaxation_time;
               tau > 0.5 && tau <= 3.0 &&
               !(lb::tau_for_viscosity_ratio(tau, kind.viscosity_ratio) >= lb::kMinStableTau)) {
      // tau_in - 1/2 = lambda (tau - 1/2)
      v.add(name + "viscosity_ratio",
            "= " + number_text(kind.viscosity_ratio, 6) + " gives the inner relaxation time " +
                number_text(lb::tau_for_viscosity_ratio(tau, kind.viscosity_ratio), 6) +
                " = 1/2 + lambda (tau - 1/2), below " + number_text(lb::kMinStableTau) +
                " (unstable): raise numerics.flow.relaxation_time or lambda");
    }
    const int given = (kind.count != 0) + (kind.volume_fraction != 0.0) + (!kind.placements.empty());
    if (given != 1) {
      v.add_message("set exactly one of {}" + name + "count, {}" + name + "volume_fraction and {}" + name +
                    "placements (" + std::to_string(given) + " set)");
    } else if (kind.count != 0 && !(kind.count >= 1 && kind.count <= kMaxCellsPerKind)) {
      v.add(name + "count",
            "= " + std::to_string(kind.count) + " must lie in [1, " + std::to_string(kMaxCellsPerKind) + "]");
    } else if (kind.volume_fraction != 0.0 &&
               !(kind.volume_fraction > 0.0 && kind.volume_fraction <= kMaxVolumeFraction)) {
      v.add(name + "volume_fraction", "= " + number_text(kind.volume_fraction, 6) + " must lie in (0, " +
                                          number_text(kMaxVolumeFraction) + "]");
    } else if (kind.placements.size() > static_cast<std::size_t>(kMaxCellsPerKind)) {
      v.add(name + "placements", "has " + std::to_string(kind.placements.size()) + " entries, at most " +
                                     std::to_string(kMaxCellsPerKind));
    }
    for (std::size_t i = 0; i < kind.placements.size() && i < static_cast<std::size_t>(kMaxCellsPerKind);
         ++i) {
      const CellPlacement& p = kind.placements[i];
      bool ok = true;
      for (int d = 0; d < 3; ++d) ok = ok && finite(p.centre_m[d]) && finite(p.rotation_rad[d]);
      if (!ok)
        v.add(name + "placements[" + std::to_string(i) + "]", "must have a finite centre and rotation");
    }
  }
  const SuspensionNumerics& n = params.numerics;
  if (!(n.contact_range_dx > 0.0 && n.contact_range_dx <= 4.0)) {
    v.add("numerics.contact_range_dx", "= " + number_text(n.contact_range_dx, 6) + " must lie in (0, 4]");
  }
  if (!(n.contact_strength > 0.0 && n.contact_strength <= 1e3)) {
    v.add("numerics.contact_strength", "= " + number_text(n.contact_strength, 6) + " must lie in (0, 1e3]");
  }
  if (!(n.average_after_strain >= 0.0 && finite(n.average_after_strain))) {
    v.add("numerics.average_after_strain",
          "= " + number_text(n.average_after_strain, 6) + " must be >= 0 and finite");
  } else if (finite(n.flow.max_strain) && !(n.average_after_strain < n.flow.max_strain)) {
    v.add("numerics.average_after_strain",
          "= " + number_text(n.average_after_strain, 6) +
              " must be below numerics.flow.max_strain = " + number_text(n.flow.max_strain, 6));
  }
  if (!(n.target_standard_error >= 0.0 && n.target_standard_error < 1.0)) {
    v.add("numerics.target_standard_error",
          "= " + number_text(n.target_standard_error, 6) + " must lie in [0, 1) (0: off)");
  }
  if (!(n.marking_every_steps >= 1 && n.marking_every_steps <= 1000)) {
    v.add("numerics.marking_every_steps",
          "= " + std::to_string(n.marking_every_steps) + " must lie in [1, 1000]");
  }
  if (!(n.min_gap_dx >= 0.0 && n.min_gap_dx <= 10.0)) {
    v.add("numerics.min_gap_dx", "= " + number_text(n.min_gap_dx, 6) + " must lie in [0, 10]");
  }
  return v;
}

Status validate(const SuspensionParams& params, std::string_view field_prefix) {
  return violations(params).status(field_prefix);
}

StatusOr<PlannedSuspension> plan_suspension_run(const SuspensionParams& params,
                                                std::string_view field_prefix) {
  if (Status s = validate(params, field_prefix); !s.ok()) return s;
  const std::string prefix(field_prefix);
  // The lattice, time step and flow of the first kind's cell (shear_flow_plan.cc).
  ShearFlowParams flow = flow_params(params, 0);
  flow.numerics.memory_limit_bytes = 0.0;  // the suspension checks its whole memory below
  StatusOr<PlannedShearFlow> planned_flow = plan_shear_flow_run(flow, field_prefix);
  if (!planned_flow.ok()) {
    return Status(planned_flow.status().code(),
                  suspension_names(planned_flow.status().message(), field_prefix));
  }
  PlannedSuspension planned;
  planned.params_ = params;
  planned.units_ = planned_flow->units();
  SuspensionSetup& setup = planned.setup_;
  setup.flow = planned_flow->setup();
  const units::Units& u = planned.units_;
  const double dx = u.dx_m();
  const ShearFlowNumerics& fn = params.numerics.flow;
  const std::array<double, 3> box = {setup.flow.box_m[0], setup.flow.box_m[1], setup.flow.box_m[2]};
  const double box_volume = box[0] * box[1] * box[2];

  // Cells of each kind and their placement.
  placement::PlacementBox pbox;
  pbox.size_m = box;
  pbox.cell_gap_m = params.numerics.min_gap_dx * dx;
  // Walls: the kernel's half width (a vertex closer loses force into the
  // wall and the run stops), the wall repulsion's range, then the gap.
  pbox.wall_gap_m = (0.5 * ibm::kernel_width(fn.ibm_kernel) + params.numerics.contact_range_dx +
                     params.numerics.min_gap_dx) *
                    dx;
  std::vector<placement::PlacementKind> kinds;
  std::size_t cell_bytes = 0, mesh_bytes = 0;
  double cell_volume = 0.0;
  int total = 0;
  for (std::size_t k = 0; k < params.kinds.size(); ++k) {
    const SuspendedCellKind& kind = params.kinds[k];
    const std::string name = prefix + "kinds[" + std::to_string(k) + "].";
    placement::PlacementKind pk;
    pk.radius_m = kind.cell.radius_m;
    pk.fixed = kind.placements;
    pk.placements_field = name + "placements";
    if (kind.count > 0) {
      pk.random_count = kind.count;
      pk.count_field = name + "count";
    } else if (kind.volume_fraction > 0.0) {
      // N = round(phi V_box / (4/3 pi R^3))
      const double n_real = kind.volume_fraction * box_volume / (4.0 / 3.0 * kPi * std::pow(pk.radius_m, 3));
      if (!(n_real >= 0.5)) {
        return invalid_argument(name + "volume_fraction = " + number_text(kind.volume_fraction) + " gives " +
                                number_text(n_real, 4) + " cells of radius " + number_text(pk.radius_m, 6) +
                                " m in the box (" + number_text(box_volume, 6) +
                                " m^3), which rounds to none: raise it or enlarge the box");
      }
      if (!(n_real <= kMaxCellsPerKind)) {
        return invalid_argument(name + "volume_fraction = " + number_text(kind.volume_fraction) + " gives " +
                                number_text(n_real, 4) + " cells, more than " +
                                std::to_string(kMaxCellsPerKind));
      }
      pk.random_count = static_cast<int>(std::lround(n_real));
      pk.count_field = name + "volume_fraction";
    }
    const int cells = pk.random_count + static_cast<int>(pk.fixed.size());
    total += cells;
    for (int c = 0; c < cells; ++c) planned.cell_kinds_.push_back(static_cast<int>(k));
    cell_volume += cells * 4.0 / 3.0 * kPi * std::pow(pk.radius_m, 3);
    cell_bytes += static_cast<std::size_t>(cells) *
                  cell_state_bytes(static_cast<std::size_t>(std::max(kind.cell.target_vertex_count, 0)));
    mesh_bytes += kind_mesh_bytes(kind.cell.target_vertex_count);
    kinds.push_back(std::move(pk));
  }
  setup.cell_count = total;
  setup.volume_fraction = cell_volume / box_volume;
  // Lattice + cells + the contact search (per surface vertex: bins, order,
  // wrapped positions); with a viscosity contrast the marking (an owner index
  // and a phase byte per node).
  setup.memory_bytes = setup.flow.lattice_bytes + mesh_bytes + cell_bytes + cell_bytes / 8;
  bool contrast = false;
  for (const SuspendedCellKind& kind : params.kinds) contrast = contrast || kind.viscosity_ratio != 1.0;
  if (contrast) {
    setup.memory_bytes += static_cast<std::size_t>(setup.flow.nx) * setup.flow.ny * setup.flow.nz *
                          (sizeof(std::int32_t) + sizeof(std::uint8_t));
  }
  if (Status s = units::check_memory(setup.memory_bytes, fn.memory_limit_bytes, prefix + "numerics.flow.");
      !s.ok()) {
    return s;
  }
  StatusOr<std::vector<CellPlacement>> placed = placement::place_cells(pbox, kinds, params.numerics.seed);
  if (!placed.ok()) return placed.status();
  planned.placements_ = std::move(*placed);
  return planned;
}

void PlannedSuspension::set_threads(int threads) {
  params_.numerics.flow.threads = std::clamp(threads, 0, 1024);
}

}  // namespace cellflow::scenes
