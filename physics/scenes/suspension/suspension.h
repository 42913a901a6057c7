// Suspension scene (paper section 7.2): N tetrahedral Mooney-Rivlin cells in
// plane Couette flow between walls at y = 0 and y = H, periodic in x and z,
// coupled to one D3Q19 lattice-Boltzmann fluid by the immersed-boundary
// method (physics/coupling), as the single-cell scene (shear_flow.h) does for
// one cell. On top of it:
//   - placement: cells of several kinds (radius, material, viscosity ratio)
//     at random non-overlapping positions and orientations (seeded), or at
//     given places; a volume fraction gives N from the box;
//   - contact: a short-range repulsion between surface vertices of different
//     cells and between surface vertices and the walls, found through a cell
//     list, so its cost grows linearly with the vertex count;
//   - viscosity contrast: nodes inside a cell with viscosity_ratio != 1 relax
//     with the inner viscosity (marked from the moving meshes);
//   - observables: per-cell and mean Taylor deformation, inclination and net
//     strain; the relative viscosity from the mean wall shear stress over the
//     cell-free value; time averages after a transient with block-averaged
//     standard errors; contact counts.
//
// Implementation: suspension_plan.cc (validation, plan, placement via
// placement.h), suspension.cc (time loop), cell_contact.h (repulsion),
// suspension_statistics.h (block averages), suspension_checkpoint.h
// (checkpoint and restart).
//
// SI at this interface; lattice units only inside, converted through
// physics/units. This header is the contract between the scene (physics)
// and its job (jobs/suspension); fields may be added, none removed.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "physics/cell/cell_params.h"
#include "physics/core/status.h"
#include "physics/core/violations.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/scenes/suspension/placement.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

// CellPlacement (a centre and a rotation vector): placement.h.

// Default mesh of a suspended cell (smaller than the single-cell default:
// N cells share the step).
inline constexpr int kSuspensionDefaultVertexCount = 1000;
inline cell::CellParams suspension_cell_defaults() {
  cell::CellParams cell;
  cell.target_vertex_count = kSuspensionDefaultVertexCount;
  return cell;
}

// One kind of cell; exactly one of count > 0, volume_fraction > 0 or
// placements non-empty.
struct SuspendedCellKind {
  cell::CellParams cell = suspension_cell_defaults();  // target_vertex_count kSuspensionDefaultVertexCount
  double viscosity_ratio = 1.0;                        // lambda = eta_in / eta_out in [0.01, 100]
  int count = 0;
  double volume_fraction = 0.0;  // N = round(phi V_box / (4/3 pi R^3)), in (0, 0.5]
  std::vector<CellPlacement> placements;
};

struct SuspensionNumerics {
  // Lattice, time step, sampling, stopping (shear_flow.h). Suspension
  // defaults: box 5 x 8 x 4 radii of the first kind, steady_tolerance 0,
  // max_strain 20 (suspension_numerics_defaults()).
  ShearFlowNumerics flow;
  std::uint64_t seed = 1;
  double contact_range_dx = 1.0;      // repulsion range, lattice spacings, (0, 4]
  double contact_strength = 1.0;      // at zero gap, x mu dx^2 of the cell, (0, 1e3]
  double average_after_strain = 5.0;  // time averages start here, >= 0
  // > 0: stop (ShearFlowStop::kSteady) at the first sample where the block-averaged SE of the
  // mean D, over at least 32 samples after average_after_strain, is below this fraction of it; 0 off.
  double target_standard_error = 0.0;
  int marking_every_steps = 1;  // [1, 1000]
  double min_gap_dx = 1.0;      // placement gap, lattice spacings, [0, 10]
};
SuspensionNumerics suspension_numerics_defaults();

struct SuspensionParams {
  std::vector<SuspendedCellKind> kinds;  // 1 ... 64 kinds
  double fluid_density_kg_m3 = units::kWaterDensityKgM3;
  double fluid_viscosity_pa_s = units::kWaterViscosityPaS;
  // Exactly one drives the flow; Ca = eta gammadot / mu of the first kind.
  double shear_rate_per_s = 0.0;
  double capillary_number = 0.0;
  SuspensionNumerics numerics = suspension_numerics_defaults();
};

// Every field out of range, named relative to the params
// ("kinds[1].viscosity_ratio", "numerics.contact_range_dx", a non-finite
// "kinds[0].placements[3]") with its allowed range. Does not mesh or place:
// an overlapping or outside place needs the lattice's box and is refused by
// plan_suspension_run ("suspension.kinds[0].placements[3]").
Violations violations(const SuspensionParams& params);
Status validate(const SuspensionParams& params, std::string_view field_prefix = "suspension.");

struct SuspensionSetup {
  ShearFlowSetup flow;  // lattice, time step, Ca, Re of the first kind
  int cell_count = 0;
  double volume_fraction = 0.0;  // sum of cell volumes / box volume
  std::size_t memory_bytes = 0;  // lattice + every cell's mesh, body and coupling state
};

// A run whose parameters plan_suspension_run validated, planned and placed.
class PlannedSuspension {
 public:
  const SuspensionParams& params() const { return params_; }
  const SuspensionSetup& setup() const { return setup_; }
  const units::Units& units() const { return units_; }
  // Per cell, in the suspension's order (kinds in order, cells of a kind in
  // order): its kind and its place.
  const std::vector<int>& cell_kinds() const { return cell_kinds_; }
  const std::vector<CellPlacement>& placements() const { return placements_; }
  void set_threads(int threads);

 private:
  friend StatusOr<PlannedSuspension> plan_suspension_run(const SuspensionParams& params,
                                                         std::string_view field_prefix);
  PlannedSuspension() = default;
  SuspensionParams params_;
  SuspensionSetup setup_;
  units::Units units_{1.0, 1.0, 1.0, 1.0};  // replaced by the plan
  std::vector<int> cell_kinds_;
  std::vector<CellPlacement> placements_;
};

// validate + units + Mach + memory + placement (random placement is done
// here, reproducibly from numerics.seed; "kinds[0].volume_fraction" names a
// fraction that cannot be placed). No lattice is allocated.
StatusOr<PlannedSuspension> plan_suspension_run(const SuspensionParams& params,
                                                std::string_view field_prefix = "suspension.");

struct SuspendedCellSample {
  double taylor_deformation = 0.0;  // D (paper eq. 13)
  double inclination_deg = 0.0;
  double net_strain = 0.0;  // (d_max - 2R) / 2R (paper eq. 18)
  std::array<double, 3> semi_axes_m{};
  std::array<double, 3> centroid_m{};  // box coordinates (x, z unwrapped)
  double volume_m3 = 0.0;
};

struct SuspensionSample {
  int index = 0;
  std::int64_t time_step = 0;
  double time_s = 0.0;
  double strain_units = 0.0;
  std::vector<SuspendedCellSample> cells;  // every cell, in order
  double mean_taylor_deformation = 0.0;
  double mean_inclination_deg = 0.0;
  double relative_viscosity = 0.0;  // mean wall shear stress / cell-free value
  int contact_pairs = 0;            // cell pairs with a vertex pair in repulsion range
  // Averages since numerics.average_after_strain (0 before), block-averaged SE.
  double average_taylor_deformation = 0.0;
  double average_taylor_deformation_error = 0.0;
  double average_relative_viscosity = 0.0;
  double average_relative_viscosity_error = 0.0;
};

struct SuspensionCallbacks {
  std::function<void(const SuspensionSample&)> on_sample;
  std::function<void(double fraction_done)> on_progress;
  std::function<bool()> should_stop;
  // Once: the mesh of every kind (reference positions centred at the origin).
  std::function<void(std::span<const mesh::TetMesh> kind_meshes)> on_meshes;
  // At each snapshot: every cell's current positions (box coordinates, m).
  std::function<void(int index, double time_s, int cell, std::span<const double> positions_m)> on_positions;
  std::function<void(const FluidVelocitySnapshot&)> on_fluid_velocity;
  // Checkpoint and restart, as the single cell's (ShearFlowCheckpointing,
  // shear_flow.h; format in suspension_checkpoint.h): the state after a
  // sample step (with a viscosity contrast a sample step that is also a
  // marking step: one of every lcm(sample interval, marking_every_steps)
  // steps) is every cell's vertex positions, the lattice populations and
  // phase, the contact list's build positions, the samples so far (the time
  // averages follow from them) and the snapshot positions so far (up to
  // kMaxCheckpointSnapshotBytes). A run resumed from it continues bit for
  // bit as the run that wrote it would have (same spec, thread count and
  // binary), except the fluid velocity frames before it (not kept; a warning
  // says so). A resumed run replays on_meshes, the stored snapshots
  // (on_positions) and every stored sample (on_sample) before it steps on.
  // A refused checkpoint (ShearFlowCheckpointing::resume_path is hostile
  // input) means a run from step 0, the reason in resume_refused.
  ShearFlowCheckpointing checkpointing;
};

struct SuspensionResult {
  Status status;
  ShearFlowStop stop = ShearFlowStop::kFailed;
  SuspensionSetup setup;
  std::vector<SuspensionSample> samples;
  double average_taylor_deformation = 0.0, average_taylor_deformation_error = 0.0;
  double average_relative_viscosity = 0.0, average_relative_viscosity_error = 0.0;
  int max_contact_pairs = 0;
  std::vector<std::string> warnings;
  std::int64_t time_steps = 0;
  // The step this run resumed after (checkpointing.resume_path), -1: from 0.
  std::int64_t resumed_from_step = -1;
  std::string resume_refused;  // why the checkpoint was not used (the run started from 0)
  int checkpoints_written = 0;
  double wall_time_s = 0.0;
  // Wall time split (seconds) of this run (a resumed one: since the resume):
  // LB, elastic forces, spreading + interpolation, contact search and
  // forces, marking, observables.
  double lattice_s = 0.0, elastic_s = 0.0, coupling_s = 0.0, contact_s = 0.0, marking_s = 0.0,
         observables_s = 0.0;
  // Work counters: builds of the contact pair list (cell_contact.h), marking
  // updates and full markings of a cell (the start counts each cell).
  std::int64_t contact_list_builds = 0, marking_updates = 0, marking_full = 0;
};

SuspensionResult run_suspension(const PlannedSuspension& planned, const SuspensionCallbacks& callbacks = {});

}  // namespace cellflow::scenes
