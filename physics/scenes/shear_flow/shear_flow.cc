// Shear-flow scene: the time loop (elastic forces, spreading, collide and
// stream, advection, samples and snapshots) and run_shear_flow, which sets up
// the cell, the fluid and the immersed cells. Plan and validation:
// shear_flow_plan.cc; observables: shear_flow_observables.cc; stability
// check: stiffness_check.cc.
#include "physics/scenes/shear_flow/shear_flow.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "physics/cell/cell_body.h"
#include "physics/coupling/immersed_cell.h"
#include "physics/elastic/elastic_body.h"
#include "physics/elastic/material.h"
#include "physics/lb/fluid.h"
#include "physics/lb/lees_edwards.h"
#include "physics/marking/marking.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"
#include "physics/observables/shape.h"
#include "physics/scenes/shear_flow/couette_fluid.h"
#include "physics/scenes/shear_flow/shear_flow_checkpoint.h"
#include "physics/scenes/shear_flow/shear_flow_internal.h"
#include "physics/scenes/shear_flow/shear_flow_resolution.h"
#include "physics/units/units.h"

namespace cellflow::scenes {

using namespace shear_flow_detail;

namespace {

// Every this many marking updates the cell is re-marked by the exact test
// (a check of the band update; the displacement fallback covers the rest).
constexpr int kFullMarkingEveryUpdates = 200;

// Surface vertices within this fraction of R of the equatorial plane z = 0
// (reference configuration) carry the tank-treading estimate: their angle in
// the x-y plane about the centroid is well defined.
constexpr double kTankTreadBand = 0.7;

void emit_positions(Run& run, double time_s, const std::vector<double>& x_lb) {
  if (run.keep_snapshots &&
      (run.snapshots.size() + 1) * x_lb.size() * sizeof(double) <= kMaxCheckpointSnapshotBytes) {
    run.snapshots.push_back({run.snapshot_index, time_s, x_lb});
  }
  if (!run.callbacks->on_positions) return;
  const double dx = run.plan.units.dx_m();
  std::vector<double> positions(x_lb.size());
  for (std::size_t i = 0; i < x_lb.size(); ++i) positions[i] = x_lb[i] * dx;
  run.callbacks->on_positions(run.snapshot_index, time_s, positions);
}

template <class T>
void emit_fluid(Run& run, const lb::Fluid& fluid, int index, double time_s) {
  if (!run.callbacks->on_fluid_velocity || !run.params->numerics.fluid_snapshots) return;
  emit_fluid_velocity(fluid, run.plan.units, index, time_s, run.callbacks->on_fluid_velocity);
}

std::string where(const Run& run, std::int64_t step) {
  return "time step " + std::to_string(step) +
         " (t = " + number_text(run.plan.units.time_to_si(static_cast<double>(step)), 6) + " s, strain " +
         number_text(static_cast<double>(step) * run.plan.setup.shear_rate_lattice, 6) + ")";
}

}  // namespace

namespace shear_flow_detail {

Schedule schedule_of(const Run& run) {
  const ShearFlowNumerics& n = run.params->numerics;
  const ShearFlowSetup& setup = run.plan.setup;
  Schedule schedule;
  schedule.sample_steps =
      std::max<std::int64_t>(1, std::llround(n.sample_every_strain * setup.steps_per_strain));
  schedule.snapshot_steps =
      n.snapshot_every_strain > 0.0
          ? std::max<std::int64_t>(1, std::llround(n.snapshot_every_strain * setup.steps_per_strain))
          : 0;
  // The step counts in double first: the plan bounds them (kMaxLatticeNodeSteps),
  // and a cast of a double beyond int64 would be undefined.
  constexpr double kMaxSteps = 9e18;
  double max_steps_real = std::ceil(n.max_strain * setup.steps_per_strain);
  schedule.limit_stop = ShearFlowStop::kMaxStrain;
  if (n.max_time_s > 0.0) {
    const double time_steps = std::ceil(run.plan.units.time_to_lattice(n.max_time_s));
    if (time_steps < max_steps_real) {
      max_steps_real = time_steps;
      schedule.limit_stop = ShearFlowStop::kMaxTime;
    }
  }
  schedule.max_steps = static_cast<std::int64_t>(std::min(max_steps_real, kMaxSteps));
  return schedule;
}

std::int64_t marking_interval(const ShearFlowNumerics& n, double wall_speed_lattice,
                              std::int64_t sample_steps) {
  std::int64_t wanted = n.marking_every_steps;
  if (wanted <= 0) {
    // The surface moves no faster than the walls: half the band per interval.
    const double band = marking::MarkingParams{}.band_lattice;
    const double speed = std::max(std::abs(wall_speed_lattice), 1e-12);
    wanted = static_cast<std::int64_t>(std::min(1e6, std::floor(0.5 * band / speed)));
  }
  wanted = std::clamp<std::int64_t>(wanted, 1, std::max<std::int64_t>(1, sample_steps));
  // The largest divisor of the sample interval not above it: checkpoints
  // (at sample steps) then fall on marking steps.
  for (std::int64_t d = wanted; d > 1; --d)
    if (sample_steps % d == 0) return d;
  return 1;
}

Status start_marking(Run& run, lb::Fluid& fluid, std::int64_t updates_so_far, ShearFlowResult& result) {
  marking::MarkingParams mp;
  mp.full_every_updates = kFullMarkingEveryUpdates;
  StatusOr<marking::NodeMarking> made = marking::make_marking(run.cells, fluid, mp);
  if (!made.ok()) return made.status();
  run.marking = std::move(*made);
  run.marking->set_update_count(updates_so_far);
  const std::uint8_t phase_of_cell[1] = {1};
  if (Status s = marking::apply_phases(*run.marking, phase_of_cell, fluid); !s.ok()) return s;
  result.marking_updates = run.marking->stats().updates;
  return Status::ok_status();
}

}  // namespace shear_flow_detail

namespace {

// Writes a checkpoint after `step` and tells the caller.
void write_checkpoint_now(Run& run, ShearFlowResult& result, const lb::Fluid& fluid, std::int64_t step) {
  const ShearFlowCheckpointing& ck = run.callbacks->checkpointing;
  const auto t0 = std::chrono::steady_clock::now();
  ShearFlowCheckpointWritten written;
  written.path = ck.write_path;
  written.time_step = step;
  written.last_sample_index = static_cast<int>(result.samples.size()) - 1;
  StatusOr<std::uint64_t> bytes = write_checkpoint(run, result, fluid, step, ck.spec_hash, ck.write_path);
  if (bytes.ok()) {
    written.bytes = *bytes;
    result.checkpoints_written++;
  } else {
    written.status = bytes.status();
  }
  written.seconds = seconds_since(t0);
  if (ck.on_written) ck.on_written(written);
}

// A resumed run: the recorder gets the mesh's snapshots and samples so far.
void replay(Run& run, const ShearFlowResult& result) {
  const ShearFlowCallbacks& cb = *run.callbacks;
  const double dx = run.plan.units.dx_m();
  if (cb.on_positions) {
    for (const StoredSnapshot& snap : run.snapshots) {
      std::vector<double> positions(snap.x_lb.size());
      for (std::size_t i = 0; i < positions.size(); ++i) positions[i] = snap.x_lb[i] * dx;
      cb.on_positions(snap.index, snap.time_s, positions);
    }
  }
  if (cb.on_sample) {
    for (const ShearFlowSample& s : result.samples) cb.on_sample(s);
  }
}

// resume_step > 0: the state after that step was restored from a checkpoint.
// lees_edwards set: the y boundaries are Lees-Edwards planes, else walls.
template <class T>
void time_loop(Run& run, lb::Fluid& fluid, lb::LeesEdwards* lees_edwards, ShearFlowResult& result,
               std::int64_t resume_step) {
  using Clock = std::chrono::steady_clock;
  const ShearFlowNumerics& n = run.params->numerics;
  const ShearFlowCallbacks& cb = *run.callbacks;
  const ShearFlowSetup& setup = run.plan.setup;
  const ibm::Kernel kernel = n.ibm_kernel;
  const int width = ibm::kernel_width(kernel);
  const int threads = n.threads;
  // Below kParallelVertices the coupling kernels run serial: OpenMP fork/join
  // costs more than the work (bench/shear_flow: 1000 vertices, 0.4 ms serial).
  const int coupling_threads = run.mesh.num_vertices() >= kParallelVertices ? threads : 1;
  const double dx = run.plan.units.dx_m();
  coupling::ImmersedCells& cells = run.cells;
  const coupling::ImmersedCell& cell = cells[0];  // the cell the observables follow

  const Schedule schedule = schedule_of(run);
  const std::int64_t sample_steps = schedule.sample_steps;
  const std::int64_t snapshot_steps = schedule.snapshot_steps;
  const std::int64_t max_steps = schedule.max_steps;
  const ShearFlowStop limit_stop = schedule.limit_stop;
  const ShearFlowCheckpointing& ck = cb.checkpointing;
  const bool checkpoints = ck.due && !ck.write_path.empty();
  // Walls: a vertex closer than half a kernel width loses force into the
  // wall. Lees-Edwards: its stencil would reach across the plane, where the
  // lattice rows are shifted and moving (not handled: the run stops).
  const double wall_margin = 0.5 * width;

  auto fail = [&](std::int64_t step, const std::string& cause) {
    result.status = numerical_failure(where(run, step) + ": " + cause);
    result.stop = ShearFlowStop::kFailed;
    result.time_steps = step;
    run.snapshot_index++;
    emit_positions(run, run.plan.units.time_to_si(static_cast<double>(result.samples.back().time_step)),
                   run.last_good_x_lb);
  };

  std::int64_t step = 0;
  bool stop_pending = false;  // stop at the next sample step, after its checkpoint
  if (resume_step > 0) {
    step = resume_step;
    replay(run, result);
  } else {
    // Sample and snapshot at t = 0.
    const auto t0 = Clock::now();
    to_si(run);
    run.last_energy_j = elastic::elastic_energy(run.body, run.x_si.data(), coupling_threads).energy_j;
    const ShearFlowSample s = take_sample(run, result, 0);
    run.last_good_x_lb = cell.positions_lattice;
    if (cb.on_sample) cb.on_sample(s);
    if (snapshot_steps > 0) {
      emit_positions(run, 0.0, cell.positions_lattice);
      emit_fluid<T>(run, fluid, run.snapshot_index, 0.0);
    }
    result.observables_s += seconds_since(t0);
  }
  while (true) {
    if (step >= max_steps) {
      result.stop = limit_stop;
      break;
    }
    // Elastic forces at the vertices.
    const auto t0 = Clock::now();
    const std::vector<elastic::ElasticEvaluation>& evals =
        coupling::compute_elastic_forces(cells, coupling_threads);
    for (const elastic::ElasticEvaluation& eval : evals) {
      if (eval.first_inverted_tet >= 0) {
        fail(step, "tetrahedron " + std::to_string(eval.first_inverted_tet) +
                       " inverted (J <= 0); the explicit update is unstable or the deformation too large");
        return;
      }
      if (!(eval.energy_j <= run.energy_limit_j)) {
        fail(step, "elastic energy " + number_text(eval.energy_j, 6) + " J exceeds " +
                       number_text(kEnergyBlowUp, 6) + " mu V0 = " + number_text(run.energy_limit_j, 6) +
                       " J (blow-up or NaN)");
        return;
      }
    }
    run.last_energy_j = evals[0].energy_j;
    const auto t1 = Clock::now();
    result.elastic_s += std::chrono::duration<double>(t1 - t0).count();

    // Spread onto the lattice (only the nodes near the cell are cleared).
    coupling::spread_forces(cells, fluid, kernel, coupling_threads);
    const auto t2 = Clock::now();
    result.coupling_s += std::chrono::duration<double>(t2 - t1).count();

    // Collide and stream; the velocity field u(t) of this step is written.
    if (lees_edwards != nullptr)
      lees_edwards->collide_stream(fluid);
    else
      lb::collide_stream(fluid);
    const auto t3 = Clock::now();
    result.lattice_s += std::chrono::duration<double>(t3 - t2).count();

    // Interpolate u(t) at the vertices and move them: X += U dt.
    const std::vector<coupling::AdvectReport>& reports =
        coupling::advect_cells(cells, fluid, kernel, coupling_threads);
    ++step;
    result.coupling_s += seconds_since(t3);
    for (const coupling::AdvectReport& moved : reports) {
      if (!std::isfinite(moved.max_speed_lattice)) {
        fail(step, "vertex velocity is NaN");
        return;
      }
      if (moved.max_speed_lattice > kRunawaySpeedLattice) {
        fail(step, "vertex speed " + number_text(moved.max_speed_lattice, 6) + " (lattice units) exceeds " +
                       number_text(kRunawaySpeedLattice, 6) + " (wall speed " +
                       number_text(setup.mach_number / std::sqrt(3.0), 6) +
                       "): the explicit coupling is unstable; lower shear_flow.numerics.max_stiffness_ratio, "
                       "raise shear_flow.numerics.cells_per_radius or lower "
                       "shear_flow.numerics.target_reynolds_number");
        return;
      }
      if (moved.lo[1] < wall_margin || moved.hi[1] > fluid.ny() - wall_margin) {
        const std::string extent = "(extent in y " + number_text(moved.lo[1] * dx, 6) + " .. " +
                                   number_text(moved.hi[1] * dx, 6) + " m, ";
        if (lees_edwards != nullptr) {
          fail(step, "the cell's kernel stencil reached the Lees-Edwards plane " + extent +
                         "plane at 0 and " + number_text(setup.box_m[1], 6) +
                         " m; stencils across it are not supported); enlarge "
                         "shear_flow.numerics.box_y_radii or lower the capillary number");
        } else {
          fail(step, "the cell reached the wall region " + extent + "walls at 0 and " +
                         number_text(setup.box_m[1], 6) +
                         " m); enlarge shear_flow.numerics.box_y_radii or lower the capillary number");
        }
        return;
      }
      if (moved.hi[0] - moved.lo[0] > fluid.nx() - width || moved.hi[2] - moved.lo[2] > fluid.nz() - width) {
        fail(step, "the cell is longer than the periodic box (extent " +
                       number_text((moved.hi[0] - moved.lo[0]) * dx, 6) + " m in x, " +
                       number_text((moved.hi[2] - moved.lo[2]) * dx, 6) +
                       " m in z); enlarge shear_flow.numerics.box_x_radii / box_z_radii");
        return;
      }
    }
    // Viscosity contrast: the nodes inside the moved cell relax with tau_in.
    if (run.marking && step % run.marking_every == 0) {
      marking::update_marking(*run.marking, cells);
      const std::uint8_t phase_of_cell[1] = {1};
      if (Status s = marking::apply_phases(*run.marking, phase_of_cell, fluid); !s.ok()) {
        fail(step, "marking: " + s.message());
        return;
      }
    }

    if (step % sample_steps == 0) {
      const auto ts = Clock::now();
      const ShearFlowSample s = take_sample(run, result, step);
      result.observables_s += seconds_since(ts);
      if (!std::isfinite(s.taylor_deformation) || !(s.volume_m3 > 0.0)) {
        fail(step, "non-finite shape or non-positive volume");
        return;
      }
      run.last_good_x_lb = cell.positions_lattice;
      if (cb.on_sample) cb.on_sample(s);
      if (cb.on_progress)
        cb.on_progress(std::min(1.0, static_cast<double>(step) / static_cast<double>(max_steps)));
      // The thickness check: a cell thinner than the kernel is not resolved
      // (shear_flow_resolution.h); restart on a finer lattice when allowed.
      const double thickness_over_kernel = 2.0 * s.semi_axes_m[0] / (width * dx);
      if (thickness_over_kernel < kMinThicknessOverKernel &&
          2.0 * s.semi_axes_m[0] < kFlattenedThicknessOverRadius * run.params->cell.radius_m && run.refine &&
          run.refine(s, thickness_over_kernel)) {
        run.refine_requested = true;
        result.stop = limit_stop;  // not reported: the run restarts
        break;
      }
      if (is_steady(run, result)) {
        result.stop = ShearFlowStop::kSteady;
        break;
      }
    }
    if (snapshot_steps > 0 && step % snapshot_steps == 0) {
      run.snapshot_index++;
      const double time_s = run.plan.units.time_to_si(static_cast<double>(step));
      emit_positions(run, time_s, cell.positions_lattice);
      emit_fluid<T>(run, fluid, run.snapshot_index, time_s);
    }
    const bool sample_step = step % sample_steps == 0;
    bool checkpointed = false;
    if (checkpoints && sample_step && (stop_pending || ck.due())) {
      write_checkpoint_now(run, result, fluid, step);
      checkpointed = true;
    }
    if (cb.should_stop && (sample_step || step % 256 == 0) && (stop_pending || cb.should_stop())) {
      // A stop that keeps the work (a worker shutting down, not a cancel):
      // on to the next sample step, where a checkpoint can be taken.
      const bool keep = checkpoints && ck.checkpoint_before_stop && ck.checkpoint_before_stop();
      if (keep && !sample_step) {
        stop_pending = true;
        continue;
      }
      if (keep && !checkpointed) write_checkpoint_now(run, result, fluid, step);
      result.stop = ShearFlowStop::kCancelled;
      result.status = Status(StatusCode::kCancelled, "stopped on request at " + where(run, step));
      break;
    }
  }
  result.time_steps = step;
  // A final sample at the stopping step when it fell between samples.
  if (result.samples.back().time_step != step) {
    const ShearFlowSample s = take_sample(run, result, step);
    if (cb.on_sample) cb.on_sample(s);
  }
}

}  // namespace

std::string_view stop_name(ShearFlowStop stop) {
  switch (stop) {
    case ShearFlowStop::kSteady:
      return "steady";
    case ShearFlowStop::kMaxStrain:
      return "max_strain";
    case ShearFlowStop::kMaxTime:
      return "max_time";
    case ShearFlowStop::kCancelled:
      return "cancelled";
    case ShearFlowStop::kFailed:
      return "failed";
  }
  return "unknown";
}

ShearFlowResult run_shear_flow(const ShearFlowParams& params, const ShearFlowCallbacks& callbacks) {
  StatusOr<PlannedShearFlow> planned = plan_shear_flow_run(params, "shear_flow.");
  if (!planned.ok()) {
    ShearFlowResult result;
    result.stop = ShearFlowStop::kFailed;
    result.status = planned.status();
    return result;
  }
  return run_shear_flow(*planned, callbacks);
}

namespace {

using RefineCheck = std::function<bool(const ShearFlowSample&, double)>;

// One run on the planned lattice; `refine` is the thickness check (may be empty).
ShearFlowResult run_attempt(const PlannedShearFlow& planned, const ShearFlowCallbacks& callbacks,
                            const RefineCheck& refine, bool& refine_requested) {
  const auto wall_start = std::chrono::steady_clock::now();
  const std::string prefix = "shear_flow.";
  const ShearFlowParams& params = planned.params();
  ShearFlowResult result;
  result.stop = ShearFlowStop::kFailed;
  Run run;
  run.params = &params;
  run.callbacks = &callbacks;
  run.refine = refine;
  run.plan = Plan{planned.setup(), planned.units()};
  result.setup = run.plan.setup;
  const ShearFlowNumerics& n = params.numerics;
  const units::Units& u = run.plan.units;
  const double radius = params.cell.radius_m;

  // The cell: mesh centred on its volume centroid, and its elastic body.
  StatusOr<cell::CellBody> built =
      cell::build_cell_body(params.cell, n.volumetric, prefix + "cell.", cell::Centring::kVolumeCentroid);
  if (!built.ok()) {
    result.status = built.status();
    return result;
  }
  result.reference_taylor_deformation = built->reference_taylor_deformation;
  run.mesh = std::move(built->mesh);
  run.body = std::move(built->body);
  const std::array<elastic::Material, 2>& materials = built->materials;
  const std::size_t nv = run.mesh.num_vertices();
  const mesh::MeshQuality quality = mesh::mesh_quality(run.mesh);
  result.mesh_spacing_over_dx = quality.mean_edge_length_m / u.dx_m();
  const double mu_max = std::max(shear_modulus(materials[0]), shear_modulus(materials[1]));
  run.energy_limit_j = kEnergyBlowUp * mu_max * quality.volume_m3;

  // Stability of the explicit update (stiffness_check.cc).
  if (Status s = check_stiffness(params, u, run.body, run.mesh.positions_m, prefix, result); !s.ok()) {
    result.status = s;
    return result;
  }
  if (callbacks.on_mesh) callbacks.on_mesh(run.mesh);

  // The fluid: walls at y = 0 and H moving at -u_wall and +u_wall, or
  // periodic in y with Lees-Edwards images sliding at +-2 u_wall.
  const ShearFlowSetup& setup = run.plan.setup;
  const double u_wall_lb = u.velocity_to_lattice(setup.wall_speed_m_per_s);
  // lambda != 1: phase 1 (the cell's inside) relaxes with tau_in.
  const bool contrast = params.viscosity_ratio != 1.0;
  const bool lees_edwards = n.boundaries == ShearFlowBoundaries::kLeesEdwards;
  StatusOr<lb::Fluid> fluid =
      make_couette_fluid(setup, u, n, prefix,
                         contrast ? std::vector<double>{setup.inner_relaxation_time} : std::vector<double>{});
  if (!fluid.ok()) {
    result.status = fluid.status();
    return result;
  }
  std::optional<lb::LeesEdwards> lees_edwards_planes;
  if (lees_edwards) {
    // U = gammadot H = 2 u_wall: the velocity of the image above.
    StatusOr<lb::LeesEdwards> made = lb::LeesEdwards::make(*fluid, 2.0 * u_wall_lb);
    if (!made.ok()) {
      result.status =
          Status(made.status().code(), prefix + "numerics.boundaries: " + made.status().message());
      return result;
    }
    lees_edwards_planes.emplace(std::move(made).value());
  }
  lb::LeesEdwards* planes = lees_edwards_planes ? &*lees_edwards_planes : nullptr;
  // The steady plane Couette profile; with Lees-Edwards planes the steady
  // unbounded shear too.
  auto start_fluid = [&] { start_couette_profile(*fluid, u_wall_lb); };
  start_fluid();

  // Vertices at the box centre (lattice units).
  const double centre[3] = {0.5 * setup.nx, 0.5 * setup.ny, 0.5 * setup.nz};
  coupling::ImmersedCell& immersed = coupling::add_cell(run.cells, run.mesh, run.body, u, centre);
  immersed.elastic_precision =
      n.elastic_single_precision ? elastic::ForcePrecision::kFloat : elastic::ForcePrecision::kDouble;
  // s = 1 - offset dx / R (numerics.hydrodynamic_radius_offset).
  immersed.marker_scale = 1.0 - radius_offset(n) * u.dx_m() / radius;
  // lambda != 1: less of the surface force in the inside (phase 1) for lambda < 1.
  if (contrast) run.cells.phase_spread_weights = {1.0, contrast_spread_weight(params.viscosity_ratio)};
  run.x_si.resize(3 * nv);
  for (std::size_t v = 0; v < nv; ++v) {
    if (run.mesh.on_surface[v] && std::abs(run.mesh.positions_m[3 * v + 2]) < kTankTreadBand * radius) {
      run.tank_vertices.push_back(static_cast<int>(v));
    }
  }
  run.tank_angle.assign(run.tank_vertices.size(), 0.0);
  run.tank_unwrapped.assign(run.tank_vertices.size(), 0.0);

  // Checkpoint and restart (shear_flow_checkpoint.h).
  const ShearFlowCheckpointing& ck = callbacks.checkpointing;
  run.keep_snapshots = ck.due && !ck.write_path.empty();
  std::int64_t resume_step = 0;
  if (!ck.resume_path.empty()) {
    StatusOr<std::int64_t> resumed =
        read_checkpoint(ck.resume_path, ck.spec_hash, schedule_of(run), run, result, *fluid);
    if (resumed.ok()) {
      resume_step = *resumed;
      result.resumed_from_step = resume_step;
      if (n.snapshot_every_strain > 0.0 &&
          run.snapshots.size() < static_cast<std::size_t>(run.snapshot_index) + 1) {
        result.warnings.push_back(
            "resumed from the checkpoint after time step " + std::to_string(resume_step) + ": " +
            std::to_string(run.snapshot_index + 1 - run.snapshots.size()) +
            " position frames before it (beyond the checkpoint's frame budget) are not in "
            "this result");
      }
      if (n.fluid_snapshots && n.snapshot_every_strain > 0.0) {
        result.warnings.push_back("resumed from the checkpoint after time step " +
                                  std::to_string(resume_step) +
                                  ": the fluid velocity frames before it are not in this result");
      }
    } else {
      result.resume_refused = resumed.status().message();
      result.warnings.push_back(result.resume_refused + "; the run started from step 0");
      start_fluid();  // the populations may have been overwritten by the refused file
    }
  }
  // The marking is not in the checkpoint: a resume re-marks the restored
  // positions exactly. Checkpoints fall on marking steps, where the band
  // update of the uninterrupted run equals the exact test on every node
  // (tests/marking), so the resumed run continues bit for bit.
  if (contrast) {
    run.marking_every = marking_interval(n, u_wall_lb, schedule_of(run).sample_steps);
    if (Status s = start_marking(run, *fluid, resume_step / run.marking_every, result); !s.ok()) {
      result.status = Status(s.code(), prefix + "viscosity_ratio: " + s.message());
      return result;
    }
  }

  if (n.single_precision) {
    time_loop<float>(run, *fluid, planes, result, resume_step);
  } else {
    time_loop<double>(run, *fluid, planes, result, resume_step);
  }
  refine_requested = run.refine_requested;
  if (!refine_requested) summarise(run, result);
  if (run.marking) {
    const marking::MarkingStats& stats = run.marking->stats();
    result.marking_updates = stats.updates;
    result.marking_full = stats.full_markings;
    result.marked_nodes = static_cast<std::int64_t>(run.marking->count_inside(0));
    result.marking_s = stats.seconds;
  }
  result.wall_time_s = seconds_since(wall_start);
  return result;
}

// A restart loses what the callbacks have recorded and costs about
// (new / old cells per radius)^5 in run time (docs/shear_flow/large_ca.md:
// 0.5 % in D at Ca = 2), so only a caller that asks for it (on_restart) gets
// one; checkpoints belong to one lattice.
bool restart_allowed(const ShearFlowCallbacks& cb) {
  const ShearFlowCheckpointing& ck = cb.checkpointing;
  if (ck.due || !ck.write_path.empty() || !ck.resume_path.empty()) return false;
  return static_cast<bool>(cb.on_restart);
}

}  // namespace

ShearFlowResult run_shear_flow(const PlannedShearFlow& planned, const ShearFlowCallbacks& callbacks) {
  const auto wall_start = std::chrono::steady_clock::now();
  const bool may_restart = planned.params().numerics.resolve_thickness && restart_allowed(callbacks);
  PlannedShearFlow current = planned;
  std::vector<ShearFlowRestart> restarts;
  while (true) {
    std::optional<PlannedShearFlow> finer;
    ShearFlowRestart pending;
    RefineCheck refine;
    if (may_restart && restarts.size() < static_cast<std::size_t>(kMaxResolutionRestarts)) {
      refine = [&](const ShearFlowSample& s, double thickness_over_kernel) {
        const double old_cpr = current.setup().cells_per_radius;
        if (old_cpr >= kMaxResolvingCellsPerRadius) return false;
        ShearFlowParams p = current.params();
        p.numerics.cells_per_radius =
            std::min(refined_cells_per_radius(old_cpr, thickness_over_kernel), kMaxResolvingCellsPerRadius);
        StatusOr<PlannedShearFlow> plan = plan_shear_flow_run(p, "shear_flow.");
        if (!plan.ok()) return false;  // the finer lattice is refused: stay, and warn at the end
        pending.strain_units = s.strain_units;
        pending.thickness_over_kernel = thickness_over_kernel;
        pending.old_cells_per_radius = old_cpr;
        pending.new_cells_per_radius = plan->setup().cells_per_radius;
        finer.emplace(std::move(*plan));
        return true;
      };
    }
    bool refine_requested = false;
    ShearFlowResult result = run_attempt(current, callbacks, refine, refine_requested);
    if (!refine_requested || !finer) {
      result.restarts = std::move(restarts);
      result.wall_time_s = seconds_since(wall_start);
      return result;
    }
    pending.abandoned_wall_time_s = result.wall_time_s;
    pending.setup = finer->setup();
    if (callbacks.on_restart) callbacks.on_restart(pending);
    restarts.push_back(pending);
    current = std::move(*finer);
  }
}

}  // namespace cellflow::scenes
