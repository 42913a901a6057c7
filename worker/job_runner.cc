#include "worker/job_runner.h"

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <thread>
#include <vector>

#include "io/h5md.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "jobs/job_spec.h"

namespace cellflow::worker {

namespace {

// What both recorders share: the result file they write and the first write
// that failed (later writes still run, so the file holds all it can).
class ResultRecorder {
 protected:
  explicit ResultRecorder(io::H5mdWriter* writer) : writer_(writer) {}

  void keep(Status s) {
    if (status_.ok() && !s.ok()) status_ = std::move(s);
  }

  // The cell's tetrahedra with their region (as bytes) per tet.
  void write_connectivity(const mesh::TetMesh& mesh) {
    std::vector<std::uint8_t> region(mesh.tet_region.size());
    for (std::size_t i = 0; i < region.size(); ++i) region[i] = static_cast<std::uint8_t>(mesh.tet_region[i]);
    keep(writer_->write_tetrahedra("cell", mesh.tets, region));
  }

  io::H5mdWriter* writer_;
  Status status_;
};

// A result file named by `options`, with the job spec as /parameters.
StatusOr<std::unique_ptr<io::H5mdWriter>> open_result(const v1::JobSpec& spec, const RunOptions& options,
                                                      const io::H5mdCreator& creator) {
  auto writer = io::H5mdWriter::create(options.result_path, creator);
  if (!writer.ok()) return writer.status();
  if (Status s = (*writer)->write_parameters_json(jobs::job_spec_to_json(spec)); !s.ok()) return s;
  return writer;
}

// The run's outcome: the scene's error first, else the result file's.
RunOutcome outcome_of(const Status& scene_status, const Status& written, int samples) {
  RunOutcome outcome;
  outcome.samples = samples;
  outcome.result_written = written.ok();
  outcome.status = !scene_status.ok() ? scene_status : written;
  return outcome;
}

// Writes one quasi-static run: the mesh, chosen position frames and every
// curve point. Frames are kept for the reference state, every k-th load point
// and the last computed point (also when the run stops early).
class QuasiStaticRecorder : public ResultRecorder {
 public:
  QuasiStaticRecorder(io::H5mdWriter* writer, int load_points, int frames, const JobEvents& events,
                      int debug_delay_ms)
      : ResultRecorder(writer), load_points_(load_points), events_(events), debug_delay_ms_(debug_delay_ms) {
    const int wanted = std::max(frames, 1);
    every_ = std::max(1, (load_points + wanted - 1) / wanted);
  }

  scenes::SceneCallbacks callbacks() {
    scenes::SceneCallbacks cb;
    cb.on_mesh = [this](const mesh::TetMesh& mesh) { on_mesh(mesh); };
    cb.on_positions = [this](int index, std::span<const double> x) { on_positions(index, x); };
    cb.on_point = [this](const scenes::CurvePoint& point) { on_point(point); };
    cb.on_progress = [this](double fraction) {
      if (events_.progress) {
        events_.progress(fraction,
                         "load point " + std::to_string(points_) + "/" + std::to_string(load_points_));
      }
    };
    cb.should_stop = [this] { return events_.should_stop && events_.should_stop(); };
    return cb;
  }

  // Writes the last computed state if it is not a frame yet; closes the file.
  Status finish() {
    if (last_index_ >= 0 && last_written_index_ != last_index_) {
      auto found = deformation_.find(last_index_);
      const double time = found != deformation_.end() ? found->second : 0.0;
      keep(writer_->append_positions("cell", last_index_ + 1, time, last_positions_));
    }
    keep(writer_->close());
    return status_;
  }

  int points() const { return points_; }

 private:
  bool chosen(int index) const { return (index + 1) % every_ == 0 || index == load_points_ - 1; }

  void on_mesh(const mesh::TetMesh& mesh) {
    write_connectivity(mesh);
    // Step 0, "time" (the load parameter, deformation) 0: the reference state.
    keep(writer_->append_positions("cell", 0, 0.0, mesh.positions_m));
    keep(writer_->flush());
  }

  void on_positions(int index, std::span<const double> positions_m) {
    last_positions_.assign(positions_m.begin(), positions_m.end());
    last_index_ = index;
    // The point's deformation may arrive before or after its positions.
    if (chosen(index) && deformation_.count(index) != 0) write_frame(index);
  }

  void on_point(const scenes::CurvePoint& point) {
    const std::int64_t step = point.index + 1;
    const double time = point.deformation;
    deformation_[point.index] = point.deformation;
    auto put = [&](const char* name, double value) {
      keep(writer_->append_observable(name, step, time, value));
    };
    put("deformation", point.deformation);
    put("displacement_m", point.displacement_m);
    put("force_n", point.force_n);
    put("hertz_force_n", point.hertz_force_n);
    put("taylor_deformation", point.taylor_deformation);
    keep(
        writer_->append_observable("semi_axes_m", step, time, std::span<const double>(point.semi_axes_m, 3)));
    put("volume_m3", point.volume_m3);
    put("elastic_energy_j", point.elastic_energy_j);
    put("max_penetration_m", point.max_penetration_m);
    put("newton_iterations", point.newton_iterations);
    put("cg_iterations", point.cg_iterations);
    put("step_splits", point.step_splits);
    put("residual", point.residual);
    if (last_index_ == point.index && chosen(point.index) && last_written_index_ != point.index) {
      write_frame(point.index);
    }
    keep(writer_->flush());  // a killed job leaves every reported point readable
    ++points_;
    if (events_.force_sample) events_.force_sample(force_sample_from(point));
    delay();
  }

  void write_frame(int index) {
    keep(writer_->append_positions("cell", index + 1, deformation_[index], last_positions_));
    last_written_index_ = index;
  }

  // Testing aid: a pause in 10 ms slices that ends early on should_stop.
  void delay() {
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(debug_delay_ms_);
    while (std::chrono::steady_clock::now() < end) {
      if (events_.should_stop && events_.should_stop()) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

  int load_points_;
  int every_ = 1;
  const JobEvents& events_;
  int debug_delay_ms_;
  std::map<int, double> deformation_;
  std::vector<double> last_positions_;
  int last_index_ = -1;
  int last_written_index_ = -1;
  int points_ = 0;
};

template <class Params>
RunOutcome run_quasi_static(const v1::JobSpec& spec, Params params, const RunOptions& options,
                            const JobEvents& events,
                            scenes::QuasiStaticResult (*scene)(const Params&,
                                                               const scenes::SceneCallbacks&)) {
  RunOutcome outcome;
  if (options.threads > 0) params.numerics.threads = options.threads;
  io::H5mdCreator creator;
  creator.program_version = options.program_version;
  creator.time_unit = "1 (deformation: the load parameter of a quasi-static curve)";
  auto writer = open_result(spec, options, creator);
  if (!writer.ok()) {
    outcome.status = writer.status();
    return outcome;
  }
  QuasiStaticRecorder recorder(writer->get(), params.load_points, options.position_frames, events,
                               options.debug_delay_per_point_ms);
  if (events.progress) events.progress(0.0, "meshing");
  scenes::QuasiStaticResult result = scene(params, recorder.callbacks());
  const Status written = recorder.finish();
  return outcome_of(result.status, written, recorder.points());
}

// Writes one shear-flow run: the mesh connectivity once, the cell positions
// at each snapshot, every deformation sample as time series, the fluid
// velocity snapshots when the spec asks for them, the resolved setup up front
// and the steady values at the end. Time is physical (s); the H5MD step is
// the lattice time step.
class FlowRecorder : public ResultRecorder {
 public:
  FlowRecorder(io::H5mdWriter* writer, const scenes::ShearFlowSetup& setup, double max_strain,
               const JobEvents& events)
      : ResultRecorder(writer), setup_(setup), max_strain_(max_strain), events_(events) {}

  scenes::ShearFlowCallbacks callbacks() {
    scenes::ShearFlowCallbacks cb;
    cb.on_mesh = [this](const mesh::TetMesh& mesh) { on_mesh(mesh); };
    cb.on_positions = [this](int, double time_s, std::span<const double> x) {
      keep(writer_->append_positions("cell", step_of(time_s), time_s, x));
      keep(writer_->flush());
    };
    cb.on_sample = [this](const scenes::ShearFlowSample& sample) { on_sample(sample); };
    cb.on_fluid_velocity = [this](const scenes::FluidVelocitySnapshot& snap) {
      io::UniformGrid grid;
      grid.nx = snap.nx;
      grid.ny = snap.ny;
      grid.nz = snap.nz;
      grid.spacing_m = snap.spacing_m;
      // Lattice node (i, j, k) sits at ((i + 1/2) dx, ...) in box coordinates, as the cell positions.
      for (double& o : grid.origin_m) o = 0.5 * snap.spacing_m;
      keep(writer_->append_vector_field("fluid_velocity", step_of(snap.time_s), snap.time_s, grid,
                                        snap.ux_m_per_s, snap.uy_m_per_s, snap.uz_m_per_s));
      keep(writer_->flush());
    };
    cb.on_progress = [this](double fraction) {
      if (events_.progress) {
        char stage[64];
        std::snprintf(stage, sizeof stage, "strain %.2f/%.4g", last_strain_, max_strain_);
        events_.progress(fraction, stage);
      }
    };
    cb.should_stop = [this] { return events_.should_stop && events_.should_stop(); };
    return cb;
  }

  // What the run derived before the first step, so a partial result has it too.
  void write_setup() {
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->write_scalar(std::string("/parameters/setup/") + name, value, unit));
    };
    put("shear_rate_per_s", setup_.shear_rate_per_s, "1/s");
    put("capillary_number", setup_.capillary_number, "1");
    put("shear_modulus_pa", setup_.shear_modulus_pa, "Pa");
    put("reynolds_number_physical", setup_.reynolds_number_physical, "1");
    put("reynolds_number_simulated", setup_.reynolds_number_simulated, "1");
    put("simulated_density_kg_m3", setup_.simulated_density_kg_m3, "kg/m^3");
    put("lattice_spacing_m", setup_.lattice_spacing_m, "m");
    put("time_step_s", setup_.time_step_s, "s");
    put("nx", setup_.nx, "1");
    put("ny", setup_.ny, "1");
    put("nz", setup_.nz, "1");
    put("wall_speed_m_per_s", setup_.wall_speed_m_per_s, "m/s");
    put("mach_number", setup_.mach_number, "1");
    keep(writer_->flush());
  }

  // The steady values and why the run stopped; closes the file.
  Status finish(const scenes::ShearFlowResult& result) {
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->write_scalar(std::string("/summary/") + name, value, unit));
    };
    keep(writer_->write_string("/summary/stop", scenes::stop_name(result.stop)));
    if (!result.status.ok()) keep(writer_->write_string("/summary/status", result.status.to_string()));
    if (!result.samples.empty()) {
      put("steady_taylor_deformation", result.steady_taylor_deformation, "1");
      put("steady_inclination_rad", result.steady_inclination_deg * std::numbers::pi / 180.0, "rad");
      put("steady_net_strain", result.steady_net_strain, "1");
      put("tank_treading_frequency_per_s", result.tank_treading_frequency_per_s, "1/s");
      put("steady_relative_change", result.steady_relative_change, "1");
      put("reference_taylor_deformation", result.reference_taylor_deformation, "1");
      put("stiffness_ratio", result.stiffness_ratio, "1");
      put("mesh_spacing_over_dx", result.mesh_spacing_over_dx, "1");
      put("thickness_over_kernel", result.thickness_over_kernel, "1");
      put("time_steps", static_cast<double>(result.time_steps), "1");
      put("wall_time_s", result.wall_time_s, "s");
    }
    std::string warnings;
    for (const std::string& w : result.warnings) warnings += (warnings.empty() ? "" : "\n") + w;
    if (!warnings.empty()) keep(writer_->write_string("/summary/warnings", warnings));
    keep(writer_->close());
    return status_;
  }

  int samples() const { return samples_; }

 private:
  std::int64_t step_of(double time_s) const {
    return setup_.time_step_s > 0.0 ? std::llround(time_s / setup_.time_step_s) : 0;
  }

  void on_mesh(const mesh::TetMesh& mesh) {
    write_connectivity(mesh);
    keep(writer_->flush());
  }

  void on_sample(const scenes::ShearFlowSample& s) {
    const std::int64_t step = s.time_step;
    const double time = s.time_s;
    const double inclination_rad = s.inclination_deg * std::numbers::pi / 180.0;
    auto put = [&](const char* name, double value) {
      keep(writer_->append_observable(name, step, time, value));
    };
    put("strain", s.strain_units);
    put("taylor_deformation", s.taylor_deformation);
    put("inclination_rad", inclination_rad);
    put("net_strain", s.net_strain);
    keep(writer_->append_observable("semi_axes_m", step, time, std::span<const double>(s.semi_axes_m)));
    keep(writer_->append_observable("centroid_m", step, time, std::span<const double>(s.centroid_m)));
    put("tank_treading_frequency_per_s", s.tank_treading_frequency_per_s);
    put("volume_m3", s.volume_m3);
    put("elastic_energy_j", s.elastic_energy_j);
    keep(writer_->flush());  // a killed job leaves every reported sample readable
    ++samples_;
    last_strain_ = s.strain_units;
    if (events_.deformation_sample) events_.deformation_sample(deformation_sample_from(s));
  }

  scenes::ShearFlowSetup setup_;
  double max_strain_;
  const JobEvents& events_;
  double last_strain_ = 0.0;
  int samples_ = 0;
};

RunOutcome run_shear_flow_job(const v1::JobSpec& spec, scenes::ShearFlowParams params,
                              const RunOptions& options, const JobEvents& events) {
  RunOutcome outcome;
  if (options.threads > 0) params.numerics.threads = options.threads;
  const StatusOr<scenes::ShearFlowSetup> setup = scenes::plan_shear_flow(params);
  if (!setup.ok()) {
    outcome.status = setup.status();
    return outcome;
  }
  io::H5mdCreator creator;
  creator.program_version = options.program_version;
  auto writer = open_result(spec, options, creator);
  if (!writer.ok()) {
    outcome.status = writer.status();
    return outcome;
  }
  FlowRecorder recorder(writer->get(), *setup, params.numerics.max_strain, events);
  recorder.write_setup();
  if (events.progress) events.progress(0.0, "meshing");
  const scenes::ShearFlowResult result = scenes::run_shear_flow(params, recorder.callbacks());
  const Status written = recorder.finish(result);
  outcome = outcome_of(result.status, written, recorder.samples());
  if (outcome.status.ok() && events.progress)
    events.progress(1.0, std::string(scenes::stop_name(result.stop)));
  return outcome;
}

}  // namespace

v1::DeformationSample deformation_sample_from(const scenes::ShearFlowSample& s) {
  v1::DeformationSample sample;
  sample.set_index(s.index);
  sample.set_time_s(s.time_s);
  sample.set_strain(s.strain_units);
  sample.set_taylor_deformation(s.taylor_deformation);
  for (double a : s.semi_axes_m) sample.add_semi_axes_m(a);
  sample.set_inclination_rad(s.inclination_deg * std::numbers::pi / 180.0);
  sample.set_net_strain(s.net_strain);
  sample.set_volume_m3(s.volume_m3);
  sample.set_tank_treading_frequency_per_s(s.tank_treading_frequency_per_s);
  return sample;
}

v1::ForceSample force_sample_from(const scenes::CurvePoint& point) {
  v1::ForceSample sample;
  sample.set_index(point.index);
  sample.set_deformation(point.deformation);
  sample.set_displacement_m(point.displacement_m);
  sample.set_force_n(point.force_n);
  sample.set_hertz_force_n(point.hertz_force_n);
  sample.set_taylor_deformation(point.taylor_deformation);
  for (double a : point.semi_axes_m) sample.add_semi_axes_m(a);
  sample.set_volume_m3(point.volume_m3);
  sample.set_elastic_energy_j(point.elastic_energy_j);
  sample.set_max_penetration_m(point.max_penetration_m);
  sample.set_newton_iterations(point.newton_iterations);
  sample.set_cg_iterations(point.cg_iterations);
  sample.set_step_splits(point.step_splits);
  sample.set_residual(point.residual);
  return sample;
}

RunOutcome run_job(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events) {
  switch (spec.scene_case()) {
    case v1::JobSpec::kCompression: {
      auto params = jobs::to_params(spec.compression());
      if (!params.ok()) return {params.status()};
      return run_quasi_static(spec, std::move(*params), options, events, &scenes::run_compression);
    }
    case v1::JobSpec::kIndentation: {
      auto params = jobs::to_params(spec.indentation());
      if (!params.ok()) return {params.status()};
      return run_quasi_static(spec, std::move(*params), options, events, &scenes::run_indentation);
    }
    case v1::JobSpec::kShearFlow: {
      auto params = jobs::to_params(spec.shear_flow());
      if (!params.ok()) return {params.status()};
      return run_shear_flow_job(spec, std::move(*params), options, events);
    }
    case v1::JobSpec::SCENE_NOT_SET:
      break;
  }
  return {invalid_argument("scene: the job spec names no scene")};
}

}  // namespace cellflow::worker
