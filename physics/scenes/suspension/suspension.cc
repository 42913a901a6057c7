// Suspension scene: run_suspension, the time loop of N cells in one Couette
// fluid (elastic forces, contact repulsion, spreading, collide and stream,
// advection), the numerical-failure checks, samples, time averages and
// snapshots. Plan and placement: suspension_plan.cc; contact:
// cell_contact.h; statistics: suspension_statistics.h.
//
// Viscosity contrast: with a kind of viscosity_ratio lambda != 1 the lattice
// has a phase per distinct lambda (tau_in = 1/2 + lambda (tau - 1/2)) and the
// nodes inside each cell are marked (physics/marking: exact at the start, the
// fast band update every numerics.marking_every_steps steps after the
// vertices moved), and the spreading weighs each phase's nodes by
// contrast_spread_weight(lambda) (serial over the points); with every lambda
// = 1 nothing is marked and the spread is the plain parallel one.
//
// Checkpoint and restart (suspension_checkpoint.h): at sample steps that are
// marking steps, the state the loop carries from step to step; a resume
// restores it, rebuilds the contact list from its build positions and
// re-marks the cells exactly, and continues bit for bit.
#include "physics/scenes/suspension/suspension.h"

#include <algorithm>
#include <chrono>
#include <cmath>
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
#include "physics/marking/marking.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"
#include "physics/observables/shape.h"
#include "physics/scenes/shear_flow/couette_fluid.h"
#include "physics/scenes/shear_flow/flow_limits.h"
#include "physics/scenes/suspension/cell_contact.h"
#include "physics/scenes/suspension/placement.h"
#include "physics/scenes/suspension/suspension_checkpoint.h"
#include "physics/scenes/suspension/suspension_internal.h"
#include "physics/scenes/suspension/suspension_statistics.h"

namespace cellflow::scenes {

using namespace suspension_detail;

namespace {

constexpr double kPi = 3.14159265358979323846;
// Fewest samples after average_after_strain before target_standard_error may stop the run.
constexpr int kMinAveragedSamples = 4 * kMinBlocks;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double shear_modulus(const elastic::Material& material) {
  const elastic::Moduli m = elastic::moduli_from(material);
  return m.mu1_pa + m.mu2_pa;
}

struct Kind {
  cell::CellBody body;
  std::vector<int> surface_vertices;
  double radius_m = 0.0;
  double energy_limit_j = 0.0;
};

struct Run {
  const SuspensionParams* params = nullptr;
  const SuspensionCallbacks* callbacks = nullptr;
  const PlannedSuspension* planned = nullptr;
  std::vector<Kind> kinds;
  std::vector<int> cell_kind;
  coupling::ImmersedCells cells;
  std::vector<double> x_si;                             // scratch, one cell
  std::vector<std::vector<double>> last_good_lb;        // every cell at the last sample
  std::vector<double> mean_d_series, viscosity_series;  // after average_after_strain
  int snapshot_index = 0;
  int last_contact_pairs = 0;
  // Viscosity contrast (empty / null without): the phase of each cell.
  std::vector<std::uint8_t> phase_of_cell;
  marking::NodeMarking* marking = nullptr;
  // Checkpoint and restart: what this run's checkpoints must match, the
  // snapshots kept for them (checkpoints are written), the contact list
  // state of a resume (resume_step > 0).
  CheckpointLayout layout;
  bool keep_snapshots = false;
  std::vector<StoredFrame> snapshots;
  std::int64_t resume_step = 0;
  LoopState resumed;
};

// The sample, snapshot and stop schedule (as shear_flow.cc's schedule_of).
struct Schedule {
  std::int64_t sample_steps = 1;
  std::int64_t snapshot_steps = 0;  // 0: no snapshots
  std::int64_t max_steps = 0;
  ShearFlowStop limit_stop = ShearFlowStop::kMaxStrain;
};

Schedule schedule_of(const PlannedSuspension& planned) {
  const ShearFlowNumerics& n = planned.params().numerics.flow;
  const ShearFlowSetup& setup = planned.setup().flow;
  Schedule schedule;
  schedule.sample_steps =
      std::max<std::int64_t>(1, std::llround(n.sample_every_strain * setup.steps_per_strain));
  schedule.snapshot_steps =
      n.snapshot_every_strain > 0.0
          ? std::max<std::int64_t>(1, std::llround(n.snapshot_every_strain * setup.steps_per_strain))
          : 0;
  double max_steps_real = std::ceil(n.max_strain * setup.steps_per_strain);
  if (n.max_time_s > 0.0) {
    const double time_steps = std::ceil(planned.units().time_to_lattice(n.max_time_s));
    if (time_steps < max_steps_real) {
      max_steps_real = time_steps;
      schedule.limit_stop = ShearFlowStop::kMaxTime;
    }
  }
  schedule.max_steps = static_cast<std::int64_t>(std::min(max_steps_real, 9e18));
  return schedule;
}

std::string where(const PlannedSuspension& planned, std::int64_t step) {
  const ShearFlowSetup& setup = planned.setup().flow;
  return "time step " + std::to_string(step) +
         " (t = " + number_text(planned.units().time_to_si(static_cast<double>(step)), 6) + " s, strain " +
         number_text(static_cast<double>(step) * setup.shear_rate_lattice, 6) + ")";
}

void emit_positions(Run& run, double time_s, const std::vector<std::vector<double>>& x_lb) {
  if (run.keep_snapshots) {
    std::size_t values = 0;
    for (const std::vector<double>& x : x_lb) values += x.size();
    if ((run.snapshots.size() + 1) * values * sizeof(double) <= kMaxCheckpointSnapshotBytes) {
      StoredFrame frame{run.snapshot_index, time_s, {}};
      frame.x_lb.reserve(values);
      for (const std::vector<double>& x : x_lb) frame.x_lb.insert(frame.x_lb.end(), x.begin(), x.end());
      run.snapshots.push_back(std::move(frame));
    }
  }
  if (!run.callbacks->on_positions) return;
  const double dx = run.planned->units().dx_m();
  std::vector<double> positions;
  for (std::size_t c = 0; c < x_lb.size(); ++c) {
    positions.resize(x_lb[c].size());
    for (std::size_t i = 0; i < positions.size(); ++i) positions[i] = x_lb[c][i] * dx;
    run.callbacks->on_positions(run.snapshot_index, time_s, static_cast<int>(c), positions);
  }
}

std::vector<std::vector<double>> current_positions(const Run& run) {
  std::vector<std::vector<double>> x;
  x.reserve(run.cells.size());
  for (const coupling::ImmersedCell& cell : run.cells.cells) x.push_back(cell.positions_lattice);
  return x;
}

template <class T>
SuspensionSample take_sample(Run& run, const lb::Fluid& fluid, SuspensionResult& result, std::int64_t step) {
  const PlannedSuspension& planned = *run.planned;
  const ShearFlowSetup& setup = planned.setup().flow;
  const units::Units& u = planned.units();
  const double dx = u.dx_m();
  SuspensionSample s;
  s.index = static_cast<int>(result.samples.size());
  s.time_step = step;
  s.time_s = u.time_to_si(static_cast<double>(step));
  s.strain_units = static_cast<double>(step) * setup.shear_rate_lattice;
  for (std::size_t c = 0; c < run.cells.size(); ++c) {
    const coupling::ImmersedCell& cell = run.cells[c];
    const Kind& kind = run.kinds[run.cell_kind[c]];
    run.x_si.resize(cell.positions_lattice.size());
    for (std::size_t i = 0; i < run.x_si.size(); ++i) run.x_si[i] = cell.positions_lattice[i] * dx;
    const observables::Shape shape = observables::measure_shape(kind.body.mesh, run.x_si.data());
    SuspendedCellSample cs;
    cs.taylor_deformation = shape.taylor_deformation;
    cs.inclination_deg = shape.inclination_rad * 180.0 / kPi;
    cs.net_strain = observables::net_strain(kind.body.mesh, run.x_si.data(), 2.0 * kind.radius_m);
    cs.semi_axes_m = shape.semi_axes_m;
    cs.centroid_m = shape.centroid_m;  // x and z unwrapped: the vertices are never wrapped
    cs.volume_m3 = shape.volume_m3;
    s.mean_taylor_deformation += cs.taylor_deformation;
    s.mean_inclination_deg += cs.inclination_deg;
    s.cells.push_back(cs);
  }
  const double count = static_cast<double>(std::max<std::size_t>(run.cells.size(), 1));
  s.mean_taylor_deformation /= count;
  s.mean_inclination_deg /= count;
  const double u_wall_lb = u.velocity_to_lattice(setup.wall_speed_m_per_s);
  // eta_r = sigma_wall / (eta gammadot): the wall shear rate over the imposed one.
  s.relative_viscosity = couette_wall_shear_rate(fluid, u_wall_lb) / setup.shear_rate_lattice;
  s.contact_pairs = run.last_contact_pairs;
  // Time averages after the transient (block-averaged standard errors).
  if (s.strain_units >= run.params->numerics.average_after_strain - 1e-9) {
    run.mean_d_series.push_back(s.mean_taylor_deformation);
    run.viscosity_series.push_back(s.relative_viscosity);
    const BlockAverage d = block_average(run.mean_d_series);
    const BlockAverage eta = block_average(run.viscosity_series);
    s.average_taylor_deformation = d.mean;
    s.average_taylor_deformation_error = d.standard_error;
    s.average_relative_viscosity = eta.mean;
    s.average_relative_viscosity_error = eta.standard_error;
  }
  result.max_contact_pairs = std::max(result.max_contact_pairs, s.contact_pairs);
  result.samples.push_back(s);
  return s;
}

template <class T>
void time_loop(Run& run, lb::Fluid& fluid, SuspensionResult& result) {
  using Clock = std::chrono::steady_clock;
  const PlannedSuspension& planned = *run.planned;
  const SuspensionNumerics& sn = run.params->numerics;
  const ShearFlowNumerics& n = sn.flow;
  const SuspensionCallbacks& cb = *run.callbacks;
  const ShearFlowSetup& setup = planned.setup().flow;
  const units::Units& u = planned.units();
  const ibm::Kernel kernel = n.ibm_kernel;
  const int width = ibm::kernel_width(kernel);
  std::size_t total_vertices = 0;
  for (const coupling::ImmersedCell& cell : run.cells.cells) total_vertices += cell.mesh->num_vertices();
  const int threads = total_vertices >= kParallelVertices ? n.threads : 1;
  const double dx = u.dx_m();
  coupling::ImmersedCells& cells = run.cells;

  const Schedule schedule = schedule_of(planned);
  const std::int64_t sample_steps = schedule.sample_steps;
  const std::int64_t snapshot_steps = schedule.snapshot_steps;
  const std::int64_t max_steps = schedule.max_steps;
  const ShearFlowStop limit_stop = schedule.limit_stop;
  const ShearFlowCheckpointing& ck = cb.checkpointing;
  const bool checkpoints = ck.due && !ck.write_path.empty();
  const double wall_margin = 0.5 * width;

  // Contact: F0 = contact_strength mu dx^2 (mu of the first kind), range in dx.
  contact_repulsion::RepulsionParams rp;
  rp.range = sn.contact_range_dx;
  rp.strength = u.force_to_lattice(sn.contact_strength * setup.shear_modulus_pa * dx * dx);
  rp.box[0] = setup.nx;
  rp.box[1] = setup.ny;
  rp.box[2] = setup.nz;
  rp.wall_offset = wall_margin;
  contact_repulsion::RepulsionSearch search(rp);
  std::vector<contact_repulsion::ContactCell> contact_cells(cells.size());
  auto bind_contact_cells = [&] {
    for (std::size_t c = 0; c < cells.size(); ++c) {
      contact_cells[c].positions = cells[c].positions_lattice.data();
      contact_cells[c].forces = cells[c].forces_lattice.data();
      contact_cells[c].surface_vertices = run.kinds[run.cell_kind[c]].surface_vertices;
    }
  };

  auto fail = [&](std::int64_t step, const std::string& cause) {
    result.status = numerical_failure(where(planned, step) + ": " + cause);
    result.stop = ShearFlowStop::kFailed;
    result.time_steps = step;
    run.snapshot_index++;
    emit_positions(run, u.time_to_si(static_cast<double>(result.samples.back().time_step)), run.last_good_lb);
  };

  // Writes a checkpoint after `step` and tells the caller.
  auto write_checkpoint_now = [&](std::int64_t step) {
    const auto t0 = Clock::now();
    ShearFlowCheckpointWritten written;
    written.path = ck.write_path;
    written.time_step = step;
    written.last_sample_index = static_cast<int>(result.samples.size()) - 1;
    LoopState loop;
    loop.snapshot_index = run.snapshot_index;
    loop.last_contact_pairs = run.last_contact_pairs;
    loop.contact_list_builds = search.builds();
    loop.marking_updates = run.marking != nullptr ? run.marking->stats().updates : 0;
    loop.contact_built_at = search.built_positions();
    loop.snapshots = std::move(run.snapshots);
    StatusOr<std::uint64_t> bytes =
        write_checkpoint(run.layout, cells, loop, result.samples, fluid, step, ck.write_path);
    run.snapshots = std::move(loop.snapshots);
    if (bytes.ok()) {
      written.bytes = *bytes;
      result.checkpoints_written++;
    } else {
      written.status = bytes.status();
    }
    written.seconds = seconds_since(t0);
    if (ck.on_written) ck.on_written(written);
  };

  std::int64_t step = 0;
  bool stop_pending = false;  // stop at the next checkpoint step, after its checkpoint
  if (run.resume_step > 0) {
    // The restored state: the contact list as it was built, the recorder
    // told what the run had recorded (the meshes went out already).
    step = run.resume_step;
    bind_contact_cells();
    if (!search.restore(contact_cells, run.resumed.contact_built_at, run.resumed.contact_list_builds)) {
      result.status = Status(StatusCode::kInternal, "checkpoint: the contact list does not fit the cells");
      return;
    }
    run.last_contact_pairs = run.resumed.last_contact_pairs;
    run.last_good_lb = current_positions(run);
    if (cb.on_positions) {
      for (const StoredFrame& frame : run.snapshots) {
        std::vector<double> positions;
        std::size_t at = 0;
        for (std::size_t c = 0; c < cells.size(); ++c) {
          positions.resize(cells[c].positions_lattice.size());
          for (double& x : positions) x = frame.x_lb[at++] * dx;
          cb.on_positions(frame.index, frame.time_s, static_cast<int>(c), positions);
        }
      }
    }
    if (cb.on_sample)
      for (const SuspensionSample& s : result.samples) cb.on_sample(s);
  } else {
    const auto t0 = Clock::now();
    const SuspensionSample s = take_sample<T>(run, fluid, result, 0);
    run.last_good_lb = current_positions(run);
    if (cb.on_sample) cb.on_sample(s);
    if (snapshot_steps > 0) {
      emit_positions(run, 0.0, run.last_good_lb);
      if (n.fluid_snapshots) emit_fluid_velocity(fluid, u, run.snapshot_index, 0.0, cb.on_fluid_velocity);
    }
    result.observables_s += seconds_since(t0);
  }
  while (true) {
    if (step >= max_steps) {
      result.stop = limit_stop;
      break;
    }
    // Elastic forces at the vertices of every cell.
    const auto t0 = Clock::now();
    const std::vector<elastic::ElasticEvaluation>& evals = coupling::compute_elastic_forces(cells, threads);
    for (std::size_t c = 0; c < evals.size(); ++c) {
      const elastic::ElasticEvaluation& eval = evals[c];
      if (eval.first_inverted_tet >= 0) {
        fail(step, "cell " + std::to_string(c) + ": tetrahedron " + std::to_string(eval.first_inverted_tet) +
                       " inverted (J <= 0); the explicit update is unstable or the deformation too large");
        return;
      }
      const double limit = run.kinds[run.cell_kind[c]].energy_limit_j;
      if (!(eval.energy_j <= limit)) {
        fail(step, "cell " + std::to_string(c) + ": elastic energy " + number_text(eval.energy_j, 6) +
                       " J exceeds " + number_text(kEnergyBlowUp, 6) + " mu V0 = " + number_text(limit, 6) +
                       " J (blow-up or NaN)");
        return;
      }
    }
    const auto t1 = Clock::now();
    result.elastic_s += std::chrono::duration<double>(t1 - t0).count();

    // Contact repulsion, added to the elastic forces before spreading.
    bind_contact_cells();
    const contact_repulsion::RepulsionReport contact = search.add_forces(contact_cells);
    run.last_contact_pairs = contact.contact_pairs;
    result.contact_list_builds = search.builds();
    const auto t2 = Clock::now();
    result.contact_s += std::chrono::duration<double>(t2 - t1).count();

    coupling::spread_forces(cells, fluid, kernel, threads);
    const auto t3 = Clock::now();
    result.coupling_s += std::chrono::duration<double>(t3 - t2).count();

    lb::collide_stream(fluid);
    const auto t4 = Clock::now();
    result.lattice_s += std::chrono::duration<double>(t4 - t3).count();

    const std::vector<coupling::AdvectReport>& reports =
        coupling::advect_cells(cells, fluid, kernel, threads);
    ++step;
    result.coupling_s += seconds_since(t4);
    for (std::size_t c = 0; c < reports.size(); ++c) {
      const coupling::AdvectReport& moved = reports[c];
      const std::string cell_name = "cell " + std::to_string(c) + ": ";
      if (!std::isfinite(moved.max_speed_lattice)) {
        fail(step, cell_name + "vertex velocity is NaN");
        return;
      }
      if (moved.max_speed_lattice > kRunawaySpeedLattice) {
        fail(step,
             cell_name + "vertex speed " + number_text(moved.max_speed_lattice, 6) +
                 " (lattice units) exceeds " + number_text(kRunawaySpeedLattice, 6) +
                 ": the explicit coupling is unstable; lower suspension.numerics.flow.max_stiffness_ratio, "
                 "suspension.numerics.contact_strength or suspension.numerics.flow.target_reynolds_number");
        return;
      }
      if (moved.lo[1] < wall_margin || moved.hi[1] > fluid.ny() - wall_margin) {
        fail(step, cell_name + "the cell reached the wall region (extent in y " +
                       number_text(moved.lo[1] * dx, 6) + " .. " + number_text(moved.hi[1] * dx, 6) +
                       " m, walls at 0 and " + number_text(setup.box_m[1], 6) +
                       " m); raise suspension.numerics.contact_strength or lower the capillary number");
        return;
      }
      if (moved.hi[0] - moved.lo[0] > fluid.nx() - width || moved.hi[2] - moved.lo[2] > fluid.nz() - width) {
        fail(step, cell_name +
                       "the cell is longer than the periodic box; enlarge "
                       "suspension.numerics.flow.box_x_radii / box_z_radii");
        return;
      }
    }

    if (run.marking != nullptr && step % sn.marking_every_steps == 0) {
      const auto tm = Clock::now();
      marking::update_marking(*run.marking, cells);
      if (Status st = marking::apply_phases(*run.marking, run.phase_of_cell, fluid); !st.ok()) {
        fail(step, "marking: " + st.message());
        return;
      }
      result.marking_s += seconds_since(tm);
      result.marking_updates = run.marking->stats().updates;
      result.marking_full = run.marking->stats().full_markings;
    }
    const bool sample_step = step % sample_steps == 0;
    if (sample_step) {
      const auto ts = Clock::now();
      const SuspensionSample s = take_sample<T>(run, fluid, result, step);
      result.observables_s += seconds_since(ts);
      bool good = std::isfinite(s.mean_taylor_deformation) && std::isfinite(s.relative_viscosity);
      for (const SuspendedCellSample& c : s.cells) good = good && c.volume_m3 > 0.0;
      if (!good) {
        fail(step, "non-finite shape, non-positive volume or non-finite wall stress");
        return;
      }
      run.last_good_lb = current_positions(run);
      if (cb.on_sample) cb.on_sample(s);
      if (cb.on_progress)
        cb.on_progress(std::min(1.0, static_cast<double>(step) / static_cast<double>(max_steps)));
      if (sn.target_standard_error > 0.0 &&
          static_cast<int>(run.mean_d_series.size()) >= kMinAveragedSamples &&
          s.average_taylor_deformation > 0.0 &&
          s.average_taylor_deformation_error < sn.target_standard_error * s.average_taylor_deformation) {
        result.stop = ShearFlowStop::kSteady;
        break;
      }
    }
    if (snapshot_steps > 0 && step % snapshot_steps == 0) {
      run.snapshot_index++;
      const double time_s = u.time_to_si(static_cast<double>(step));
      emit_positions(run, time_s, current_positions(run));
      if (n.fluid_snapshots) emit_fluid_velocity(fluid, u, run.snapshot_index, time_s, cb.on_fluid_velocity);
    }
    // Checkpoints at sample steps that are marking steps (the resume
    // re-marks exactly where the uninterrupted run marked).
    const bool checkpoint_step =
        sample_step && (run.marking == nullptr || step % sn.marking_every_steps == 0);
    bool checkpointed = false;
    if (checkpoints && checkpoint_step && (stop_pending || ck.due())) {
      write_checkpoint_now(step);
      checkpointed = true;
    }
    if (cb.should_stop && (sample_step || step % 256 == 0) && (stop_pending || cb.should_stop())) {
      // A stop that keeps the work (a worker shutting down, not a cancel):
      // on to the next checkpoint step, where a checkpoint can be taken.
      const bool keep = checkpoints && ck.checkpoint_before_stop && ck.checkpoint_before_stop();
      if (keep && !checkpoint_step) {
        stop_pending = true;
        continue;
      }
      if (keep && !checkpointed) write_checkpoint_now(step);
      result.stop = ShearFlowStop::kCancelled;
      result.status = Status(StatusCode::kCancelled, "stopped on request at " + where(planned, step));
      break;
    }
  }
  result.time_steps = step;
  if (result.samples.back().time_step != step) {
    const SuspensionSample s = take_sample<T>(run, fluid, result, step);
    if (cb.on_sample) cb.on_sample(s);
  }
}

}  // namespace

SuspensionResult run_suspension(const PlannedSuspension& planned, const SuspensionCallbacks& callbacks) {
  const auto wall_start = std::chrono::steady_clock::now();
  const std::string prefix = "suspension.";
  const SuspensionParams& params = planned.params();
  SuspensionResult result;
  result.stop = ShearFlowStop::kFailed;
  result.setup = planned.setup();
  Run run;
  run.params = &params;
  run.callbacks = &callbacks;
  run.planned = &planned;
  const units::Units& u = planned.units();
  const ShearFlowNumerics& n = params.numerics.flow;

  // Each kind once: its mesh and body, and the stability check of its cell.
  run.kinds.resize(params.kinds.size());
  std::vector<mesh::TetMesh> kind_meshes;
  for (std::size_t k = 0; k < params.kinds.size(); ++k) {
    const std::string name = prefix + "kinds[" + std::to_string(k) + "].";
    StatusOr<cell::CellBody> built = cell::build_cell_body(params.kinds[k].cell, n.volumetric, name + "cell.",
                                                           cell::Centring::kVolumeCentroid);
    if (!built.ok()) {
      result.status = built.status();
      return result;
    }
    Kind& kind = run.kinds[k];
    kind.body = std::move(*built);
    kind.radius_m = params.kinds[k].cell.radius_m;
    const mesh::TetMesh& mesh = kind.body.mesh;
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      if (mesh.on_surface[v]) kind.surface_vertices.push_back(static_cast<int>(v));
    }
    const mesh::MeshQuality quality = mesh::mesh_quality(mesh);
    const double mu_max =
        std::max(shear_modulus(kind.body.materials[0]), shear_modulus(kind.body.materials[1]));
    kind.energy_limit_j = kEnergyBlowUp * mu_max * quality.volume_m3;
    // Ca of this kind: eta gammadot / mu_k.
    const double ca = params.fluid_viscosity_pa_s * planned.setup().flow.shear_rate_per_s /
                      shear_modulus(params.kinds[k].cell.material);
    double ratio = 0.0;
    // The numerics it names are the suspension's shared flow numerics
    // (prefix + "numerics.flow."), not fields of the kind.
    if (Status st = check_flow_stiffness(flow_params(params, k), u, kind.body.body, mesh.positions_m, prefix,
                                         ca, &ratio);
        !st.ok()) {
      result.status = Status(st.code(), name + "cell (kind " + std::to_string(k) +
                                            "): " + suspension_names(st.message(), prefix));
      return result;
    }
    kind_meshes.push_back(mesh);
  }
  if (callbacks.on_meshes) callbacks.on_meshes(kind_meshes);
  kind_meshes.clear();

  const ShearFlowSetup& setup = planned.setup().flow;
  // One phase per distinct lambda != 1 (phase 0: the suspending fluid).
  std::vector<double> phase_lambdas, phase_taus;
  std::vector<std::uint8_t> phase_of_kind(params.kinds.size(), 0);
  for (std::size_t k = 0; k < params.kinds.size(); ++k) {
    const double lambda = params.kinds[k].viscosity_ratio;
    if (lambda == 1.0) continue;
    auto it = std::find(phase_lambdas.begin(), phase_lambdas.end(), lambda);
    if (it == phase_lambdas.end()) {
      phase_lambdas.push_back(lambda);
      // tau_in - 1/2 = lambda (tau - 1/2)
      phase_taus.push_back(lb::tau_for_viscosity_ratio(n.relaxation_time, lambda));
      it = phase_lambdas.end() - 1;
    }
    phase_of_kind[k] = static_cast<std::uint8_t>(1 + (it - phase_lambdas.begin()));
  }
  StatusOr<lb::Fluid> fluid = make_couette_fluid(setup, u, n, prefix, phase_taus);
  if (!fluid.ok()) {
    result.status = fluid.status();
    return result;
  }
  start_couette_profile(*fluid, u.velocity_to_lattice(setup.wall_speed_m_per_s));

  // The cells at their places: X = c + Q x / dx, Q the placement's rotation.
  run.cell_kind = planned.cell_kinds();
  run.cells.cells.reserve(run.cell_kind.size());
  for (std::size_t c = 0; c < run.cell_kind.size(); ++c) {
    const Kind& kind = run.kinds[run.cell_kind[c]];
    const CellPlacement& place = planned.placements()[c];
    const double origin[3] = {u.length_to_lattice(place.centre_m[0]), u.length_to_lattice(place.centre_m[1]),
                              u.length_to_lattice(place.centre_m[2])};
    coupling::ImmersedCell& cell = coupling::add_cell(run.cells, kind.body.mesh, kind.body.body, u, origin);
    const std::array<double, 9> q = placement::rotation_matrix(place.rotation_rad);
    const std::vector<double>& x = kind.body.mesh.positions_m;
    for (std::size_t v = 0; v < kind.body.mesh.num_vertices(); ++v) {
      for (int a = 0; a < 3; ++a) {
        const double rotated =
            q[3 * a] * x[3 * v] + q[3 * a + 1] * x[3 * v + 1] + q[3 * a + 2] * x[3 * v + 2];
        cell.positions_lattice[3 * v + a] = origin[a] + u.length_to_lattice(rotated);
      }
    }
    cell.elastic_precision =
        n.elastic_single_precision ? elastic::ForcePrecision::kFloat : elastic::ForcePrecision::kDouble;
    // s = 1 - offset dx / R (numerics.flow.hydrodynamic_radius_offset).
    cell.marker_scale = 1.0 - radius_offset(n) * u.dx_m() / kind.radius_m;
  }
  // lambda != 1: the spread forces' share in each phase as in the single-cell
  // scene (contrast_spread_weight); none with every lambda = 1.
  if (!phase_lambdas.empty()) {
    run.cells.phase_spread_weights = {1.0};
    for (const double lambda : phase_lambdas)
      run.cells.phase_spread_weights.push_back(contrast_spread_weight(lambda));
  }

  // Checkpoint and restart (suspension_checkpoint.h).
  const ShearFlowCheckpointing& ck = callbacks.checkpointing;
  {
    const Schedule schedule = schedule_of(planned);
    CheckpointLayout& layout = run.layout;
    layout.spec_hash = ck.spec_hash;
    layout.cells_hash = cells_hash(run.cells, run.cell_kind);
    for (int kind : run.cell_kind) layout.contact_vertices += run.kinds[kind].surface_vertices.size();
    layout.marking = !phase_taus.empty();
    layout.sample_steps = schedule.sample_steps;
    layout.snapshot_steps = schedule.snapshot_steps;
    layout.max_steps = schedule.max_steps;
    layout.marking_every = params.numerics.marking_every_steps;
  }
  run.keep_snapshots = ck.due && !ck.write_path.empty();
  if (!ck.resume_path.empty()) {
    StatusOr<RestoredState> restored = read_checkpoint(ck.resume_path, run.layout, run.cells, *fluid);
    if (restored.ok()) {
      run.resume_step = restored->step;
      result.resumed_from_step = restored->step;
      for (std::size_t c = 0; c < run.cells.size(); ++c)
        run.cells[c].positions_lattice = std::move(restored->positions[c]);
      result.samples = std::move(restored->samples);
      // The averaging series and the largest contact count, as take_sample built them.
      for (const SuspensionSample& s : result.samples) {
        if (s.strain_units >= params.numerics.average_after_strain - 1e-9) {
          run.mean_d_series.push_back(s.mean_taylor_deformation);
          run.viscosity_series.push_back(s.relative_viscosity);
        }
        result.max_contact_pairs = std::max(result.max_contact_pairs, s.contact_pairs);
      }
      run.snapshot_index = restored->loop.snapshot_index;
      run.snapshots = std::move(restored->loop.snapshots);
      run.resumed = std::move(restored->loop);
      const std::string resumed_after =
          "resumed from the checkpoint after time step " + std::to_string(run.resume_step);
      if (n.snapshot_every_strain > 0.0 &&
          run.snapshots.size() < static_cast<std::size_t>(run.snapshot_index) + 1) {
        result.warnings.push_back(
            resumed_after + ": " + std::to_string(run.snapshot_index + 1 - run.snapshots.size()) +
            " position frames before it (beyond the checkpoint's frame budget) are not in "
            "this result");
      }
      if (n.fluid_snapshots && n.snapshot_every_strain > 0.0) {
        result.warnings.push_back(resumed_after +
                                  ": the fluid velocity frames before it are not in this result");
      }
    } else {
      result.resume_refused = restored.status().message();
      result.warnings.push_back(result.resume_refused + "; the run started from step 0");
      // The populations may have been overwritten by the refused file.
      start_couette_profile(*fluid, u.velocity_to_lattice(setup.wall_speed_m_per_s));
    }
  }

  // The marking is not in the checkpoint: a resume marks the restored
  // positions exactly (as the start does), at a marking step of the
  // uninterrupted run, whose band update there equals the exact test.
  std::optional<marking::NodeMarking> node_marking;
  if (!phase_taus.empty()) {
    const auto tm = std::chrono::steady_clock::now();
    for (int kind : run.cell_kind) run.phase_of_cell.push_back(phase_of_kind[kind]);
    marking::MarkingParams mp;
    // The band must exceed the surface displacement between two updates
    // (at most the wall speed per step); the update falls back to the exact
    // test of a cell that moved farther.
    const double u_wall_lb = u.velocity_to_lattice(setup.wall_speed_m_per_s);
    mp.band_lattice = std::clamp(1.0 + 2.0 * u_wall_lb * params.numerics.marking_every_steps, 1.0, 8.0);
    StatusOr<marking::NodeMarking> made = marking::make_marking(run.cells, *fluid, mp);
    if (!made.ok()) {
      result.status = Status(made.status().code(), prefix + "numerics.marking: " + made.status().message());
      return result;
    }
    node_marking = std::move(*made);
    node_marking->set_update_count(run.resumed.marking_updates);
    if (Status st = marking::apply_phases(*node_marking, run.phase_of_cell, *fluid); !st.ok()) {
      result.status = st;
      return result;
    }
    run.marking = &*node_marking;
    result.marking_s += seconds_since(tm);
  }

  if (n.single_precision) {
    time_loop<float>(run, *fluid, result);
  } else {
    time_loop<double>(run, *fluid, result);
  }
  if (!result.samples.empty()) {
    const SuspensionSample& last = result.samples.back();
    result.average_taylor_deformation = last.average_taylor_deformation;
    result.average_taylor_deformation_error = last.average_taylor_deformation_error;
    result.average_relative_viscosity = last.average_relative_viscosity;
    result.average_relative_viscosity_error = last.average_relative_viscosity_error;
    if (run.mean_d_series.empty()) {
      result.warnings.push_back("the run ended at strain " + number_text(last.strain_units, 4) +
                                ", before numerics.average_after_strain = " +
                                number_text(params.numerics.average_after_strain) + ": no time averages");
    }
  }
  result.wall_time_s = seconds_since(wall_start);
  return result;
}

}  // namespace cellflow::scenes
