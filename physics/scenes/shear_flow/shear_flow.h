// Shear-flow scene (paper section 7.1): one tetrahedral Mooney-Rivlin cell in
// plane Couette flow, coupled to a D3Q19 lattice-Boltzmann fluid by the
// immersed-boundary method.
//
// Setup. Box Lx x H x Lz (numerics.box_*_radii times the cell radius R),
// periodic in x and z, walls at y = 0 and y = H moving at -u_wall and +u_wall
// along x with u_wall = H gammadot / 2 (paper section 7.1), or with
// numerics.boundaries = kLeesEdwards periodic in y with sliding images
// (unbounded shear, no walls). The cell starts as a
// stress-free sphere at the box centre. The fluid starts in the steady linear
// Couette profile u_x(y) = gammadot (y - H/2), the analytic steady state of the
// empty box, so the cell sees the full shear from step 0 (no start-up
// transient of the fluid to wait for).
//
// Every vertex of the tetrahedral mesh (surface and interior) is an immersed-
// boundary point; the fluid is not subtracted inside the cell. By default the
// cell interior has the fluid's viscosity (viscosity ratio lambda = 1, the
// paper's standard case) and no lattice node is marked. With viscosity_ratio
// lambda != 1 the nodes inside the cell's surface (physics/marking) relax
// with tau_in = 1/2 + lambda (tau - 1/2) (eta = rho c_s^2 (tau - 1/2) dt),
// re-marked every numerics.marking_every_steps steps by the fast band test,
// and the spreading weighs the inside's nodes by contrast_spread_weight.
// Stability of the lattice needs tau_in >= lb::kMinStableTau = 0.505: at the
// default tau = 1, lambda >= 0.01 (lambda >= 0.005 / (tau - 1/2) in general).
// One lattice time step:
//   f = elastic forces at the vertices          (paper eq. 9-10)
//   spread f onto the lattice (Peskin kernel), Guo forcing
//   collide and stream                          (u(t) written on the way)
//   U = u(t) interpolated at the vertices
//   x += U dt                                   (explicit Euler, lattice units)
//
// Stokes-regime acceleration. The time step is dt = nu_lb dx^2 / nu, so a
// cell in water at gammadot = 4/s needs ~10^6 steps per unit strain. When the
// particle Reynolds number Re_p = rho gammadot R^2 / eta is below
// numerics.target_reynolds_number, the simulated fluid density is raised so
// that Re_p equals that target, or less where the cell is long: its Reynolds
// number on the predicted long half-axis a3, Re_p (a3 / R)^2, stays within
// kLongAxisReynoldsAllowance targets (shear_flow_resolution.h). Well below 1
// the steady deformation does not depend on the fluid density, and the
// number of steps per unit strain drops to cells_per_radius^2 / (Re_p nu_lb).
// Set it to 0 to simulate the physical density. The result reports both
// Reynolds numbers.
//
// SI at this interface; lattice units only inside run_shear_flow, converted
// through physics/units.
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
#include "physics/elastic/elastic_body.h"
#include "physics/ibm/ibm.h"
#include "physics/mesh/tet_mesh.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

// Default mesh of a flow cell. The resolution study (bench/shear_flow,
// Ca = 0.05, peskin4, nu = 0.48) puts the deviation of D from (5/4) Ca at
// about 0.38 dx/R + 5.7 (h/R)(dx/R), h the mesh spacing: at the default 6
// cells per radius, 1000 vertices (h = 0.21 R) give +26 %, 3000 (h = 0.14 R)
// +20 %, for 30 % more time per step. The bulk stiffness couples the mesh
// term: at nu = 0.3 the mesh dependence is three times weaker.
inline constexpr int kFlowDefaultVertexCount = mesh::kDefaultSphereVertexCount;
inline cell::CellParams flow_cell_defaults() {
  cell::CellParams cell;
  cell.target_vertex_count = kFlowDefaultVertexCount;
  return cell;
}

// The y boundaries of the box. kWalls: walls at y = 0 and H moving at
// -u_wall and +u_wall (plane Couette, the paper's setup, section 7.1).
// kLeesEdwards: no walls; the periodic images above and below move at
// +-gammadot H along x (lb/lees_edwards.h), so the cell sees unbounded
// simple shear and a smaller box_y_radii does for the same confinement. The
// kernel stencils of the cell must not reach the Lees-Edwards plane (the
// cell starts at the box centre): a run whose cell comes within half a
// kernel width of y = 0 or H stops with an error naming box_y_radii.
enum class ShearFlowBoundaries { kWalls, kLeesEdwards };
std::string_view boundaries_name(ShearFlowBoundaries boundaries);
// "walls" or "lees_edwards"; kInvalidArgument naming `field` otherwise.
StatusOr<ShearFlowBoundaries> parse_boundaries(std::string_view name, std::string_view field);

// Numerical options of the flow scene: each trades time for accuracy or
// guards a stability limit. Field names follow proto ShearFlowNumerics.
struct ShearFlowNumerics {
  // Lattice nodes per cell radius R / dx, in [2, 64]. 6 with the default
  // hydrodynamic_radius_offset (Ca = 0.05, 3000 vertices, one core): D
  // within 0.3 % of (5/4) Ca in ~19000 steps (~65 s on a quiet core); 4 cells
  // (889 vertices): +10 %. Without the offset D was +20 % (6), +32 % (4),
  // +8 % (12 cells, 2793 s) above (5/4) Ca (docs/accuracy/shear_flow.md).
  double cells_per_radius = 6.0;
  double box_x_radii = 10.0;     // box length along the flow / R (periodic)
  double box_y_radii = 15.0;     // wall distance H / R (Lees-Edwards: the box height)
  double box_z_radii = 5.0;      // box depth along the vorticity / R (periodic)
  double relaxation_time = 1.0;  // LB tau in (0.5, 3]; nu_lb = (tau - 1/2) / 3
  double max_mach = 0.1;         // refuse u_wall / c_s above this, in (0, 0.3]
  // Raise the simulated fluid density until Re_p = rho gammadot R^2 / eta
  // reaches this value, or kLongAxisReynoldsAllowance x this / (a3 / R)^2
  // where that is lower (a3 the predicted long half-axis: Re_p 0.04 at
  // Ca = 2); only when the physical Re_p is lower; 0 = physical density.
  // In [0, 1].
  double target_reynolds_number = 0.1;
  ibm::Kernel ibm_kernel = ibm::Kernel::kPeskin4;
  bool single_precision = true;  // float lattice storage (populations as deviations from rest)
  // The elastic forces in float (elastic::ForcePrecision::kFloat; positions
  // relative to the cell's centre, the sums in float, returned in double):
  // faster per core, D and the inclination as with double to far below the
  // accuracy budget (README, elastic kernel rows: the measured figures).
  bool elastic_single_precision = true;
  // Steady state on the drift of window means: the mean D over the last
  // window (steady_window_strain strain units gammadot t, longer at large Ca:
  // steady_window_strain_for) and the mean over the
  // window before it differ by less than steady_tolerance relative to the
  // last one (shear_flow_is_steady). Sample noise and the tank-treading wobble
  // of D (+-0.7 % at Ca = 0.02) average out within a window; a band over one
  // window closes only where the wobble happens to be flat. The slope of D over the last window must also
  // stay below 3 steady_tolerance (an overshoot of D gives two equal window
  // means while D still falls). 0 disables the steady stop (the run goes to
  // max_strain / max_time_s). Measured stop points: docs/accuracy/shear_flow.md.
  double steady_tolerance = 2e-3;     // in [0, 1)
  double steady_window_strain = 1.5;  // > 0, at least 2 samples; the shortest window
  // Stop at gammadot t = max_strain at the latest, > 0. 60: the steady rule
  // stops the exact Ca = 2 transient at strain 45 (steady_window_strain_for).
  double max_strain = 60.0;
  double max_time_s = 0.0;             // > 0: also stop at this time; 0: no limit
  double sample_every_strain = 0.1;    // deformation samples, > 0
  double snapshot_every_strain = 1.0;  // cell positions (and fluid velocity) snapshots; 0: none
  bool fluid_snapshots = false;        // call on_fluid_velocity at snapshot times
  double memory_limit_bytes = 4.0 * 1024 * 1024 * 1024;  // lattice memory; <= 0: no limit
  // Stability of the explicit elastic update: refuse when the stiffest vertex
  // mode k_max (largest eigenvalue of the elastic tangent, lattice units)
  // exceeds this multiple of the Stokes drag of one lattice spacing,
  // 6 pi eta_lb dx. 0: the calibrated limit of the kernel,
  // default_stiffness_limit(ibm_kernel). In [0, 100].
  double max_stiffness_ratio = 0.0;
  // The volumetric term of eq. (5): per tet as in the paper (default), or
  // averaged over the tets around each vertex (elastic_body.h). At Ca = 0.05,
  // 6 cells per radius, 3000 vertices (bench/shear_flow/shear_flow_run):
  // steady D +20.3 % above (5/4) Ca per tet, +12.1 % with the average;
  // inclination -0.79 and +0.85 degrees from Roscoe's; the same cost per
  // step. Not yet the default: the average's stiffest modes are less damped
  // by the kernel, so its stiffness limit is halved (calibrated for peskin4
  // only, see the run's stability check).
  elastic::VolumetricTerm volumetric = elastic::VolumetricTerm::kPerTet;
  // Hydrodynamic radius correction, in lattice spacings: < 0 (default) the
  // kernel's calibrated value default_radius_offset(ibm_kernel); 0 none; at
  // most 2 and half of cells_per_radius. The fluid within the kernel's reach
  // moves with the immersed points, so the cell acts on the fluid like a
  // larger sphere, and D comes out too large by about 3 delta dx / R (the
  // stresslet of a sphere grows as a^3; measured: +20 % at 6 cells per
  // radius). The coupling therefore places the immersed-boundary markers at
  // c + s (X - c), s = 1 - offset dx / R, c the vertex centroid, spreads
  // F / s there and moves the vertices with U_c + (U_marker - U_c) / s
  // (coupling::ImmersedCell::marker_scale): the stresslet sum F (X - c) and
  // the power F . U are those of the mesh, the mesh itself (and every
  // observable) keeps radius R.
  double hydrodynamic_radius_offset = -1.0;
  // Keep the cell's thickness resolved (shear_flow_resolution.h): the plan
  // raises cells_per_radius to resolving_cells_per_radius(Ca) (at most
  // kMaxResolvingCellsPerRadius; the default 6 from Ca = 0.8 with peskin4 up),
  // and a run whose sample thickness falls below kMinThicknessOverKernel
  // kernel widths restarts on a finer lattice (refined_cells_per_radius, at
  // most kMaxResolutionRestarts times; only where the callbacks allow it:
  // ShearFlowCallbacks::on_restart). false: the lattice of cells_per_radius,
  // and only a warning.
  bool resolve_thickness = true;
  ShearFlowBoundaries boundaries = ShearFlowBoundaries::kWalls;
  int threads = 0;  // OpenMP threads; 0 = OpenMP default
  // Viscosity contrast (viscosity_ratio != 1): the fast marking runs every
  // this many steps; 0 (default): the largest divisor of the sample interval
  // at which the walls (the fastest fluid) move at most half the marking
  // band. In [0, 1e6]. (A checkpoint falls on a marking step, so a resumed
  // run re-marks exactly where the uninterrupted one marked.)
  int marking_every_steps = 0;
};

// Allowed range of ShearFlowParams::viscosity_ratio (proto ShearFlowSpec
// field 7), with tau_in = 1/2 + lambda (tau - 1/2) >= lb::kMinStableTau.
inline constexpr double kMinViscosityRatio = 0.01, kMaxViscosityRatio = 100.0;

struct ShearFlowParams {
  cell::CellParams cell = flow_cell_defaults();
  double fluid_density_kg_m3 = units::kWaterDensityKgM3;    // rho > 0
  double fluid_viscosity_pa_s = units::kWaterViscosityPaS;  // eta > 0
  // Exactly one of the two drives the flow: the shear rate, or the capillary
  // number Ca = eta gammadot / mu (paper eq. 17), mu the shear modulus of the
  // cell material (mu1 + mu2), which then fixes gammadot.
  double shear_rate_per_s = 0.0;
  double capillary_number = 0.0;
  // lambda = eta_inside / eta_outside (paper section 7), in
  // [kMinViscosityRatio, kMaxViscosityRatio] with tau_in >= lb::kMinStableTau.
  double viscosity_ratio = 1.0;
  ShearFlowNumerics numerics;
};

// Calibrated stability limits of k_max / (6 pi eta_lb dx) per kernel: half
// the smallest ratio at which a run blew up (bench/shear_flow, cells_per_radius
// 4, Ca down to 0.001): peskin4 blew up at 8.2 (stable at 5.5) -> 2.5;
// peskin3 at 1.64 (stable at 0.82) -> 0.4; trilinear at 0.16 -> 0.05.
double default_stiffness_limit(ibm::Kernel kernel);

// Calibrated hydrodynamic radius offsets (numerics.hydrodynamic_radius_offset
// < 0), lattice spacings. Each removes the excess of D over (5/4) Ca at
// Ca = 0.05, 6 cells per radius, 3000 vertices, which the marker scaling
// moves by 3 offset dx / R as predicted (measured at 4 and 6 cells per
// radius, docs/accuracy/shear_flow.md): peskin4 0.4 (then 0.997 at 6 and
// 0.996 at 8 cells per radius), peskin3 0.3 (predicted from its +15 %, then
// 1.002); trilinear 0 (not calibrated). The rigid-cloud stresslet radius
// (bench/shear_flow/ibm_sphere_drag stresslet=1) is larger, R + 0.75 dx for
// the surface points alone and R + 1 dx with the interior: the offset is an
// effective value that also absorbs the mesh's own error.
double default_radius_offset(ibm::Kernel kernel);
// The offset a run uses: numerics.hydrodynamic_radius_offset, or the
// kernel's default when that is negative.
double radius_offset(const ShearFlowNumerics& numerics);

// Viscosity contrast (viscosity_ratio lambda != 1): the inside's relative
// weight g in the spreading of the surface forces
// (coupling::ImmersedCells::phase_spread_weights), g = lambda^kContrastSpreadExponent.
// The kernel spreads a surface force across the viscosity jump (at the mesh
// surface, the markers 0.4 dx inside it); the part that lands inside is
// carried by stress gradients in fluid of viscosity lambda eta and drives a
// spurious flow there about 1 / lambda times that of lambda = 1 (a 1-D force
// layer across the jump, docs/accuracy/viscosity_contrast.md). With the
// plain kernel D at lambda = 0.05 came out 2.5 % below Roscoe's lambda
// dependence at Ca 0.1 and 0.05 (-0.7 % / -2.3 % against +1.8 % / +0.3 %).
// The 1-D model's weights (exponent 1: exact for markers on the jump) give
// +17.5 % with the jump 0.4 dx outside the markers; the exponent is fitted
// (g = 0.85 at lambda = 0.05) to Roscoe's +1.8 % at Ca 0.1, 4 cells per
// radius, 1000 vertices; Ca 0.05 and 0.2 and the default resolution are the
// checks. g > 1 for lambda > 1 (more of the force in the more viscous inside).
inline constexpr double kContrastSpreadExponent = 0.054;
// g = lambda^kContrastSpreadExponent; 1 at lambda = 1.
double contrast_spread_weight(double viscosity_ratio);

// The stability check of the explicit elastic update that run_shear_flow
// does before it starts, for any flow cell (the suspension scene checks each
// kind with it): k_max / (6 pi eta_lb dx s^2), the stiffest vertex mode of
// `body` at `positions_m` (lattice units; s the marker scale of
// params.numerics.hydrodynamic_radius_offset for params.cell.radius_m).
// The ratio goes to *stiffness_ratio (when not null) also on refusal;
// kInvalidArgument above the limit (numerics.max_stiffness_ratio or the
// kernel's), naming the options under `prefix` to change.
Status check_flow_stiffness(const ShearFlowParams& params, const units::Units& units,
                            const elastic::ElasticBody& body, const std::vector<double>& positions_m,
                            std::string_view prefix, double capillary_number, double* stiffness_ratio);

// Every field out of range, named relative to the params
// ("numerics.cells_per_radius", "cell.radius_m") with its allowed range.
Violations violations(const ShearFlowParams& params);
// violations(params) as a Status (INVALID_ARGUMENT lists each violation with
// field_prefix + field and its allowed range). Does not build the lattice.
Status validate(const ShearFlowParams& params, std::string_view field_prefix = "shear_flow.");

// The resolved setup: everything derived from the params before time stepping.
struct ShearFlowSetup {
  double shear_rate_per_s = 0.0;
  double capillary_number = 0.0;
  double shear_modulus_pa = 0.0;           // mu = mu1 + mu2 of the cell material
  double reynolds_number_physical = 0.0;   // rho gammadot R^2 / eta
  double reynolds_number_simulated = 0.0;  // with the simulated density
  double simulated_density_kg_m3 = 0.0;
  double lattice_spacing_m = 0.0;      // dx
  double time_step_s = 0.0;            // dt
  int nx = 0, ny = 0, nz = 0;          // lattice nodes
  double box_m[3] = {0, 0, 0};         // nx dx, ny dx (= H), nz dx
  double wall_speed_m_per_s = 0.0;     // u_wall = H gammadot / 2 (Lees-Edwards: the speed at y = 0 and H)
  double mach_number = 0.0;            // u_wall / c_s
  double shear_rate_lattice = 0.0;     // gammadot dt
  double steps_per_strain = 0.0;       // 1 / (gammadot dt)
  double viscosity_ratio = 1.0;        // lambda = eta_in / eta_out
  double inner_relaxation_time = 0.0;  // tau_in = 1/2 + lambda (tau - 1/2); = tau for lambda = 1
  std::size_t lattice_bytes = 0;       // with the phase field and the marking when lambda != 1
  // The lattice resolution used: numerics.cells_per_radius, or the larger
  // resolving_cells_per_radius(Ca) with numerics.resolve_thickness.
  double cells_per_radius = 0.0;
  // predicted_thickness_over_radius(Ca) x cells_per_radius / kernel width:
  // the steady thickness 2 a1 in kernel widths this lattice should give.
  double predicted_thickness_over_kernel = 0.0;
  // Non-empty: the resolving lattice was refused (memory, work, Mach) and
  // the run uses numerics.cells_per_radius; the reason (a result warning).
  std::string resolution_note;
};

// validate + units + Mach + memory checks, no allocation: what a server
// calls to refuse a job up front. Errors: kInvalidArgument (a field, the
// Mach number; the message names the option to change), kResourceExhausted
// (lattice above numerics.memory_limit_bytes).
StatusOr<ShearFlowSetup> plan_shear_flow(const ShearFlowParams& params,
                                         std::string_view field_prefix = "shear_flow.");

// A run whose parameters plan_shear_flow_run validated and planned: what a
// job holds after its one conversion, so that running it validates nothing
// again. Only plan_shear_flow_run makes one.
class PlannedShearFlow {
 public:
  const ShearFlowParams& params() const { return params_; }
  const ShearFlowSetup& setup() const { return setup_; }
  const units::Units& units() const { return units_; }
  // OpenMP threads of the run (0: the OpenMP default), clamped to [0, 1024]
  // as validate() allows: the one field a caller may set after planning.
  void set_threads(int threads);

 private:
  friend StatusOr<PlannedShearFlow> plan_shear_flow_run(const ShearFlowParams& params,
                                                        std::string_view field_prefix);
  PlannedShearFlow(ShearFlowParams params, ShearFlowSetup setup, units::Units units)
      : params_(std::move(params)), setup_(std::move(setup)), units_(units) {}
  ShearFlowParams params_;
  ShearFlowSetup setup_;
  units::Units units_;
};

// plan_shear_flow, keeping the parameters and the unit conversion for the run.
StatusOr<PlannedShearFlow> plan_shear_flow_run(const ShearFlowParams& params,
                                               std::string_view field_prefix = "shear_flow.");

struct ShearFlowSample {
  int index = 0;
  std::int64_t time_step = 0;
  double time_s = 0.0;
  double strain_units = 0.0;            // gammadot t
  double taylor_deformation = 0.0;      // D = (a3 - a1) / (a3 + a1)   (paper eq. 13)
  double inclination_deg = 0.0;         // major axis from +x in the x-y plane
  double net_strain = 0.0;              // (d_max - 2R) / 2R   (paper eq. 18)
  std::array<double, 3> semi_axes_m{};  // a1 <= a2 <= a3
  std::array<double, 3> centroid_m{};   // box coordinates, walls at y = 0 and H
  double volume_m3 = 0.0;
  double elastic_energy_j = 0.0;
  // Mean angular velocity of surface material points about the centroid in
  // the x-y plane, clockwise positive (the sense of the shear vorticity), over
  // the last steady window (or since the start when shorter). A rigid sphere:
  // gammadot / 2.
  double tank_treading_frequency_per_s = 0.0;
};

// Velocity field of the whole lattice in SI; node (i, j, k) at
// ((i + 1/2) dx, (j + 1/2) dx, (k + 1/2) dx), element i + nx (j + ny k).
struct FluidVelocitySnapshot {
  int index = 0;
  double time_s = 0.0;
  int nx = 0, ny = 0, nz = 0;
  double spacing_m = 0.0;
  std::span<const double> ux_m_per_s, uy_m_per_s, uz_m_per_s;
};

// A checkpoint written during a run (shear_flow_checkpoint.h has the format).
struct ShearFlowCheckpointWritten {
  Status status;               // not ok: nothing usable was written (the run goes on)
  std::string path;            // the file, complete (written to path + ".tmp" and renamed)
  std::int64_t time_step = 0;  // the run resumes after this step
  int last_sample_index = -1;  // samples 0 .. last_sample_index are inside
  std::uint64_t bytes = 0;
  double seconds = 0.0;  // wall time the write took
};

// Checkpoint and restart. A checkpoint holds the whole state of the time loop
// (lattice populations and the AA phase, vertex positions, the spreading
// support, the samples so far with the steady-state window and the tank-
// treading accumulators, the position snapshots so far); the scene has no
// random numbers. A run resumed from it continues bit for bit as the run that
// wrote it would have (same spec, same thread count, same binary), except the
// fluid velocity frames before the checkpoint, which are not kept (a warning
// says so).
// A checkpointed run keeps the cell positions of its snapshots for the
// checkpoints (so a resumed run's recorder gets every frame), up to this many
// bytes; later frames are not kept, and a run resumed without them says so.
inline constexpr std::size_t kMaxCheckpointSnapshotBytes = std::size_t{64} << 20;

struct ShearFlowCheckpointing {
  // Identifies the job (e.g. a hash of its spec); a checkpoint written under
  // another value is refused.
  std::uint64_t spec_hash = 0;
  // Non-empty: resume from this file. It is hostile input: every size is
  // bounded, the dimensions must match this run, the checksums must hold; a
  // refused file means a run from step 0, with the reason in
  // ShearFlowResult::resume_refused and a warning.
  std::string resume_path;
  // Polled at every sample step (after the sample and the snapshot); true:
  // write a checkpoint to write_path now. Unset or write_path empty: never.
  std::function<bool()> due;
  std::string write_path;
  std::function<void(const ShearFlowCheckpointWritten&)> on_written;
  // Polled when should_stop returns true (checkpoints enabled): true (e.g. a
  // worker shutting down, not a cancel) makes the run go on to the next
  // sample step, write a checkpoint there and then stop (kCancelled), so the
  // next attempt loses nothing. Re-polled every 256 steps meanwhile.
  std::function<bool()> checkpoint_before_stop;
};

// A run that restarts on a finer lattice (numerics.resolve_thickness): the
// sample that fell below kMinThicknessOverKernel and the new lattice.
struct ShearFlowRestart {
  double strain_units = 0.0;           // of the sample that fired the check
  double thickness_over_kernel = 0.0;  // its 2 a1 / (kernel width dx)
  double old_cells_per_radius = 0.0;
  double new_cells_per_radius = 0.0;
  double abandoned_wall_time_s = 0.0;  // the coarse attempt's time, lost
  ShearFlowSetup setup;                // the finer plan
};

struct ShearFlowCallbacks {
  // Set: a run may restart on a finer lattice (numerics.resolve_thickness);
  // called before the restart, after which the run starts again from step 0
  // and the callbacks below see the finer run from its first sample and its
  // mesh on (never with checkpoints). Unset: the run keeps its (predicted)
  // lattice and warns when the cell still thins below the limit.
  std::function<void(const ShearFlowRestart&)> on_restart;
  std::function<void(const ShearFlowSample&)> on_sample;
  std::function<void(double fraction_done)> on_progress;  // 0..1
  std::function<bool()> should_stop;                      // true: stop, status kCancelled
  // The mesh once (reference positions as meshed, centred at the origin) and
  // the current positions (box coordinates, metres) at each snapshot; after a
  // numerical failure once more with the last sampled (good) state.
  std::function<void(const mesh::TetMesh&)> on_mesh;
  std::function<void(int index, double time_s, std::span<const double> positions_m)> on_positions;
  // At snapshot times when numerics.fluid_snapshots is set.
  std::function<void(const FluidVelocitySnapshot&)> on_fluid_velocity;
  // A resumed run replays on_mesh, the stored snapshots (on_positions) and
  // every stored sample (on_sample) before it steps on, so a recorder sees
  // the whole run.
  ShearFlowCheckpointing checkpointing;
};

// The thinnest cell, in kernel widths, whose D the lattice still gets right.
// Measured at Ca = 2 (docs/shear_flow/large_ca.md): 6 cells per radius, the
// cell 0.81-0.99 kernel widths thick, steady D within 1.1 % of the exact
// ellipsoid (validation/shear_flow); 6, 9 and 12 cells per radius (0.66 to
// 1.4 kernel widths) within 0.4 % of each other along the transient.
inline constexpr double kMinThicknessOverKernel = 0.75;

enum class ShearFlowStop {
  kSteady,     // D steady within numerics.steady_tolerance over the window
  kMaxStrain,  // reached numerics.max_strain
  kMaxTime,    // reached numerics.max_time_s
  kCancelled,  // should_stop returned true
  kFailed,     // status says why
};
std::string_view stop_name(ShearFlowStop stop);

struct ShearFlowResult {
  Status status;  // ok for kSteady / kMaxStrain / kMaxTime
  ShearFlowStop stop = ShearFlowStop::kFailed;
  ShearFlowSetup setup;
  std::vector<ShearFlowSample> samples;  // every sample taken, also on failure
  // Means over the last steady window of samples (whatever stopped the run).
  double steady_taylor_deformation = 0.0;
  double steady_inclination_deg = 0.0;
  double steady_net_strain = 0.0;
  double tank_treading_frequency_per_s = 0.0;
  double steady_relative_change = 0.0;        // steady_window_drift at the end (0: under two windows)
  double reference_taylor_deformation = 0.0;  // D of the undeformed mesh (discretisation floor)
  // Stability of the explicit update: k_max / (6 pi eta_lb dx s^2), lattice
  // units (s the marker scale of numerics.hydrodynamic_radius_offset).
  double stiffness_ratio = 0.0;
  double mesh_spacing_over_dx = 0.0;  // mean edge length / dx
  // The cell's thickness 2 a1 (minor axis of the equivalent ellipsoid, last
  // sample) over the kernel width (ibm::kernel_width dx). Below
  // kMinThicknessOverKernel the kernel does not resolve the thickness (Ca >=
  // 1.6 at 6 cells per radius); a warning says so. Measured at Ca = 2: a
  // resolved cell (8.5 cells per radius) follows the same D(t) within 0.5 %,
  // so the thinning itself is not a kernel artefact (docs/shear_flow/large_ca.md).
  double thickness_over_kernel = 0.0;
  // The smallest 2 a1 / (kernel width dx) of the samples after the first.
  double min_thickness_over_kernel = 0.0;
  // Restarts on a finer lattice (numerics.resolve_thickness), in order; the
  // result, setup and samples are those of the last lattice; wall_time_s
  // includes the abandoned attempts.
  std::vector<ShearFlowRestart> restarts;
  std::vector<std::string> warnings;
  std::int64_t time_steps = 0;
  // The step this run resumed after (checkpointing.resume_path), -1: from 0.
  std::int64_t resumed_from_step = -1;
  std::string resume_refused;  // why the checkpoint was not used (the run started from 0)
  int checkpoints_written = 0;
  double wall_time_s = 0.0;
  // Wall time split (seconds): elastic forces, spreading + interpolation,
  // LB collide-stream, observables.
  double elastic_s = 0.0, coupling_s = 0.0, lattice_s = 0.0, observables_s = 0.0;
  // Viscosity contrast: marking updates run (0 with lambda = 1: nothing is
  // marked), exact markings among them (the first, fallbacks and resumes),
  // the nodes inside the cell at the end, and the wall time of marking and
  // phase writes (not in the four above).
  std::int64_t marking_updates = 0;
  std::int64_t marking_full = 0;
  std::int64_t marked_nodes = 0;
  double marking_s = 0.0;
};

// Runs the scene until D is steady, max_strain or max_time_s. Refuses up
// front (nothing run) with the errors of plan_shear_flow and, for a cell too
// stiff for the explicit update, kInvalidArgument naming the options to
// change. A numerical failure (NaN, J <= 0, energy blow-up, runaway vertex
// speed, the cell reaching a wall) ends it with kNumericalFailure naming the
// time step and the cause; the samples so far are kept.
ShearFlowResult run_shear_flow(const ShearFlowParams& params, const ShearFlowCallbacks& callbacks = {});
// The same for a planned run: no validation or planning again.
ShearFlowResult run_shear_flow(const PlannedShearFlow& planned, const ShearFlowCallbacks& callbacks = {});

// Small-Ca limit of Roscoe's theory for an elastic sphere, exact for any
// hyperelastic law (shared/validation/README.md): D = (5/4) Ca and, for
// viscosity ratio lambda = 1, inclination pi/4 - (5/4) Ca.
double small_ca_taylor_deformation(double capillary_number);

// The steady window grows with Ca beyond steady_window_strain. The shape of a
// viscoelastic cell relaxes on the time eta / mu, Ca strain units, and at
// large Ca it overshoots: the exact homogeneous Kelvin-Voigt ellipsoid
// (validation/shear_flow/kv_ellipsoid.py, Stokes, lambda = 1) at Ca = 2
// rises to D = 0.851 at strain 9, falls to 0.754 at 24 and settles at
// Roscoe's 0.766 near 30. Windows of 1.5 strain units see two equal means on
// that peak (the rule stopped there, 11 % high); with windows of 4 Ca strain
// units the rule stops within 0.26 % of the final D at every Ca of the
// reference (0.05-2; shear_flow_steady_test).
inline constexpr double kSteadyWindowStrainPerCa = 4.0;
// max(numerics.steady_window_strain, kSteadyWindowStrainPerCa x Ca).
double steady_window_strain_for(const ShearFlowNumerics& n, double capillary_number);
// Samples per steady window: steady_window_strain_for / sample_every_strain, at least 1.
int steady_window_samples(const ShearFlowNumerics& n, double capillary_number);
// |mean D over the last window - mean D over the window before| / mean D over
// the last window, windows of steady_window_samples each; NaN with fewer than
// two full windows after the first (undeformed) sample. A pure function of the
// samples, so a resumed run stops where the uninterrupted one does.
double steady_window_drift(const std::vector<ShearFlowSample>& samples, const ShearFlowNumerics& n,
                           double capillary_number);
// |least-squares slope of D over the last window| x the window's strain /
// mean D there; NaN with fewer than two samples in it.
double steady_window_trend(const std::vector<ShearFlowSample>& samples, const ShearFlowNumerics& n,
                           double capillary_number);
// The trend test allows this multiple of steady_tolerance.
inline constexpr double kSteadyTrendFactor = 3.0;
// steady_tolerance > 0, steady_window_drift < steady_tolerance and
// steady_window_trend < kSteadyTrendFactor steady_tolerance.
bool shear_flow_is_steady(const std::vector<ShearFlowSample>& samples, const ShearFlowNumerics& n,
                          double capillary_number);
double small_ca_inclination_deg_lambda1(double capillary_number);

}  // namespace cellflow::scenes
