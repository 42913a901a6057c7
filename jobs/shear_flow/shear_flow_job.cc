#include "jobs/shear_flow/shear_flow_job.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "io/h5md.h"
#include "jobs/common/result_file.h"
#include "jobs/shear_flow/flow_recorder.h"
#include "jobs/shear_flow/shear_flow_spec.h"

namespace cellflow::jobs {
namespace {

// Writes one shear-flow run: the mesh connectivity once, the cell positions
// at each snapshot, every deformation sample as time series, the fluid
// velocity snapshots when the spec asks for them, the resolved setup up front
// and the steady values at the end. Time is physical (s); the H5MD step is
// the lattice time step.
class FlowRecorder : public FlowRecorderBase {
 public:
  FlowRecorder(io::H5mdWriter* writer, const scenes::ShearFlowSetup& setup, double max_strain,
               const JobEvents& events)
      : FlowRecorderBase(writer, setup, max_strain, events) {}

  scenes::ShearFlowCallbacks callbacks() {
    scenes::ShearFlowCallbacks cb;
    cb.on_mesh = [this](const mesh::TetMesh& mesh) { on_mesh(mesh); };
    cb.on_positions = [this](int, double time_s, std::span<const double> x) {
      keep(writer_->append_positions("cell", step_of(time_s), time_s, x));
      keep(writer_->flush());
    };
    cb.on_sample = [this](const scenes::ShearFlowSample& sample) { on_sample(sample); };
    add_flow_callbacks(cb);
    return cb;
  }

  // What the run derived before the first step, so a partial result has it too.
  void write_setup() {
    keep(write_flow_setup(*writer_, setup_));
    keep(writer_->flush());
  }

  // The steady values and why the run stopped; closes the file.
  Status finish(const scenes::ShearFlowResult& result) {
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->write_scalar(std::string("/summary/") + name, value, unit));
    };
    write_stop(result.stop, result.status);
    if (!result.samples.empty()) {
      put("steady_taylor_deformation", result.steady_taylor_deformation, "");
      put("steady_inclination_rad", result.steady_inclination_deg * std::numbers::pi / 180.0, "rad");
      put("steady_net_strain", result.steady_net_strain, "");
      put("tank_treading_frequency_per_s", result.tank_treading_frequency_per_s, "s-1");
      put("steady_relative_change", result.steady_relative_change, "");
      put("reference_taylor_deformation", result.reference_taylor_deformation, "");
      put("stiffness_ratio", result.stiffness_ratio, "");
      put("mesh_spacing_over_dx", result.mesh_spacing_over_dx, "");
      put("thickness_over_kernel", result.thickness_over_kernel, "");
      put("min_thickness_over_kernel", result.min_thickness_over_kernel, "");
      keep(writer_->write_integer("/summary/time_steps", result.time_steps));
      // Viscosity contrast: the marking updates run (0 for lambda = 1) and the nodes inside at the end.
      keep(writer_->write_integer("/summary/marking_updates", result.marking_updates));
      keep(writer_->write_integer("/summary/marked_nodes", result.marked_nodes));
      put("wall_time_s", result.wall_time_s, "s");
    }
    return close_with_warnings(result.warnings);
  }

 private:
  void on_mesh(const mesh::TetMesh& mesh) {
    write_connectivity(mesh);
    write_flow_box();
  }

  void on_sample(const scenes::ShearFlowSample& s) {
    const std::int64_t step = s.time_step;
    const double time = s.time_s;
    const double inclination_rad = s.inclination_deg * std::numbers::pi / 180.0;
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->append_observable(name, step, time, value, unit));
    };
    put("strain", s.strain_units, "");
    put("taylor_deformation", s.taylor_deformation, "");
    put("inclination_rad", inclination_rad, "rad");
    put("net_strain", s.net_strain, "");
    keep(writer_->append_observable("semi_axes_m", step, time, std::span<const double>(s.semi_axes_m), "m"));
    keep(writer_->append_observable("centroid_m", step, time, std::span<const double>(s.centroid_m), "m"));
    put("tank_treading_frequency_per_s", s.tank_treading_frequency_per_s, "s-1");
    put("volume_m3", s.volume_m3, "m+3");
    put("elastic_energy_j", s.elastic_energy_j, "J");
    keep(writer_->flush());  // a killed job leaves every reported sample readable
    sample_written(s.strain_units);
    if (events_.deformation_sample) events_.deformation_sample(deformation_sample_from(s));
  }
};

// One converted shear-flow job: its parameters and the lattice plan derived
// from them (both computed once, at prepare).
class ShearFlowJob final : public PreparedJob {
 public:
  explicit ShearFlowJob(scenes::PlannedShearFlow planned) : planned_(std::move(planned)) {}

  std::string_view scene() const override { return "shear_flow"; }

  // The baseline, the D3Q19 lattice as physics/lb allocates it (in-place AA
  // streaming: ONE population array of 19 values per node, plus the force and
  // velocity fields, 3 values each, in the storage precision;
  // setup.lattice_bytes), the largest of the transient per-node buffers in
  // double (the Couette start profile, 2 values; the velocity field update
  // after it and the fluid velocity snapshots, 3 values each, one at a
  // time), the snapshot positions a checkpointed run keeps (a fixed
  // budget), and the cell mesh at the quasi-static rate per vertex.
  std::int64_t memory_bytes() const override {
    const scenes::ShearFlowSetup& setup = planned_.setup();
    // A checkpointed run keeps the snapshot positions, up to a fixed budget.
    const double kept_snapshots = kept_snapshot_bytes(
        planned_.params().numerics, static_cast<double>(cell_vertex_bound(planned_.params().cell)));
    const double bytes =
        static_cast<double>(setup.lattice_bytes) + flow_transient_bytes(setup) + kept_snapshots;
    return kBaselineBytes + static_cast<std::int64_t>(std::min(bytes, 9e18)) +
           cell_vertex_bound(planned_.params().cell) * kBytesPerVertex;
  }

  // One sample every sample_every_strain up to max_strain, and the final one.
  std::int64_t max_sample_index() const override {
    const auto& numerics = planned_.params().numerics;
    const double samples = numerics.max_strain / numerics.sample_every_strain;
    return samples < 1e12 ? static_cast<std::int64_t>(samples) + 2 : -1;
  }

  RunOutcome run(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events) override {
    RunOutcome outcome;
    scenes::PlannedShearFlow planned = planned_;
    if (options.threads > 0) planned.set_threads(options.threads);
    io::H5mdCreator creator;  // time in s
    auto writer = open_result(spec, options, creator);
    if (!writer.ok()) {
      outcome.status = writer.status();
      return outcome;
    }
    FlowRecorder recorder(writer->get(), planned.setup(), planned.params().numerics.max_strain, events);
    recorder.write_setup();
    if (events.progress) events.progress(0.0, "meshing");
    scenes::ShearFlowCallbacks callbacks = recorder.callbacks();
    add_flow_checkpointing(callbacks.checkpointing, spec, options, events);
    const scenes::ShearFlowResult result = scenes::run_shear_flow(planned, callbacks);
    const Status written = recorder.finish(result);
    outcome = outcome_of(result.status, written, recorder.samples());
    outcome.resumed_from_step = result.resumed_from_step;
    outcome.resume_refused = result.resume_refused;
    if (outcome.status.ok() && events.progress)
      events.progress(1.0, std::string(scenes::stop_name(result.stop)));
    return outcome;
  }

  Status run_csv(const CsvSink& sink, int threads) override {
    scenes::PlannedShearFlow planned = planned_;
    planned.set_threads(threads);
    const scenes::ShearFlowParams& params = planned.params();
    sink.csv << deformation_csv_header() << '\n' << std::flush;
    scenes::ShearFlowCallbacks callbacks;
    callbacks.on_sample = [&](const scenes::ShearFlowSample& s) {
      sink.csv << deformation_csv_row(s) << '\n' << std::flush;
      if (sink.progress) {
        char line[200];
        std::snprintf(line, sizeof(line), "sample %d  strain %.2f/%.4g  D %.4f  inclination %.2f deg\n",
                      s.index, s.strain_units, params.numerics.max_strain, s.taylor_deformation,
                      s.inclination_deg);
        *sink.progress << line << std::flush;
      }
    };
    const scenes::ShearFlowResult result = scenes::run_shear_flow(planned, callbacks);
    if (sink.progress && !result.samples.empty()) {
      char line[300];
      std::snprintf(
          line, sizeof(line),
          "stopped: %s after %lld steps (%.1f s); Ca %.4g, lambda %.4g, steady D %.5f (5/4 Ca = %.5f), "
          "inclination %.2f deg\n",
          std::string(scenes::stop_name(result.stop)).c_str(), static_cast<long long>(result.time_steps),
          result.wall_time_s, result.setup.capillary_number, result.setup.viscosity_ratio,
          result.steady_taylor_deformation,
          scenes::small_ca_taylor_deformation(result.setup.capillary_number), result.steady_inclination_deg);
      *sink.progress << line;
      for (const std::string& w : result.warnings) *sink.progress << "warning: " << w << '\n';
      *sink.progress << std::flush;
    }
    return result.status;
  }

 private:
  scenes::PlannedShearFlow planned_;
};

}  // namespace

// FNV-1a 64 of the spec's deterministic serialisation: the identity a
// checkpoint carries, so that a checkpoint of another spec is refused.
std::uint64_t checkpoint_spec_hash(const v1::JobSpec& spec) {
  std::string bytes;
  {
    google::protobuf::io::StringOutputStream stream(&bytes);
    google::protobuf::io::CodedOutputStream coded(&stream);
    coded.SetSerializationDeterministic(true);
    spec.SerializeToCodedStream(&coded);
  }
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (unsigned char c : bytes) {
    hash ^= c;
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

// Checkpoints every options.checkpoint_interval_s of wall time; resume from options.resume_path.
void add_flow_checkpointing(scenes::ShearFlowCheckpointing& ck, const v1::JobSpec& spec,
                            const RunOptions& options, const JobEvents& events) {
  ck.spec_hash = checkpoint_spec_hash(spec);
  ck.resume_path = options.resume_path;
  if (options.checkpoint_interval_s > 0.0 && !options.checkpoint_path.empty()) {
    using Clock = std::chrono::steady_clock;
    const auto interval = std::chrono::duration<double>(options.checkpoint_interval_s);
    ck.write_path = options.checkpoint_path;
    ck.due = [interval, last = Clock::now()]() mutable {
      if (Clock::now() - last < interval) return false;
      last = Clock::now();
      return true;
    };
    if (events.checkpoint_before_stop) ck.checkpoint_before_stop = events.checkpoint_before_stop;
    ck.on_written = [&events](const scenes::ShearFlowCheckpointWritten& w) {
      if (events.checkpoint_written)
        events.checkpoint_written({w.path, w.time_step, w.last_sample_index, w.bytes, w.seconds,
                                   w.status.ok() ? std::string() : w.status.to_string()});
    };
  }
}

Status append_fluid_velocity(io::H5mdWriter& writer, const scenes::FluidVelocitySnapshot& snap,
                             std::int64_t step) {
  io::UniformGrid grid;
  grid.nx = snap.nx;
  grid.ny = snap.ny;
  grid.nz = snap.nz;
  grid.spacing_m = snap.spacing_m;
  // Lattice node (i, j, k) sits at ((i + 1/2) dx, ...) in box coordinates, as the cell positions.
  for (double& o : grid.origin_m) o = 0.5 * snap.spacing_m;
  return writer.append_vector_field("fluid_velocity", step, snap.time_s, grid, snap.ux_m_per_s,
                                    snap.uy_m_per_s, snap.uz_m_per_s, "m s-1");
}

Status write_flow_setup(io::H5mdWriter& writer, const scenes::ShearFlowSetup& setup) {
  Status first;
  auto keep = [&](Status s) {
    if (first.ok() && !s.ok()) first = std::move(s);
  };
  auto put = [&](const char* name, double value, const char* unit) {
    keep(writer.write_scalar(std::string("/parameters/setup/") + name, value, unit));
  };
  // Units in the H5MD units syntax; dimensionless values carry none.
  put("shear_rate_per_s", setup.shear_rate_per_s, "s-1");
  put("capillary_number", setup.capillary_number, "");
  put("shear_modulus_pa", setup.shear_modulus_pa, "Pa");
  put("reynolds_number_physical", setup.reynolds_number_physical, "");
  put("reynolds_number_simulated", setup.reynolds_number_simulated, "");
  put("simulated_density_kg_m3", setup.simulated_density_kg_m3, "kg m-3");
  put("lattice_spacing_m", setup.lattice_spacing_m, "m");
  put("time_step_s", setup.time_step_s, "s");
  keep(writer.write_integer("/parameters/setup/nx", setup.nx));
  keep(writer.write_integer("/parameters/setup/ny", setup.ny));
  keep(writer.write_integer("/parameters/setup/nz", setup.nz));
  put("cells_per_radius", setup.cells_per_radius, "");
  put("predicted_thickness_over_kernel", setup.predicted_thickness_over_kernel, "");
  put("wall_speed_m_per_s", setup.wall_speed_m_per_s, "m s-1");
  put("mach_number", setup.mach_number, "");
  put("viscosity_ratio", setup.viscosity_ratio, "");
  put("inner_relaxation_time", setup.inner_relaxation_time, "");
  return first;
}

StatusOr<std::unique_ptr<PreparedJob>> prepare_shear_flow(const v1::JobSpec& spec) {
  StatusOr<scenes::ShearFlowParams> params = convert(spec.shear_flow());
  if (!params.ok()) return params.status();
  // Fields, ranges, Mach number and memory; the stability check needs the
  // mesh and runs at the start of run_shear_flow.
  StatusOr<scenes::PlannedShearFlow> planned = scenes::plan_shear_flow_run(*params, "shear_flow.");
  if (!planned.ok()) return planned.status();
  return std::unique_ptr<PreparedJob>(new ShearFlowJob(std::move(*planned)));
}

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

std::string deformation_csv_header() {
  return "sample,time_s,strain,taylor_deformation,inclination_rad,net_strain,a1_m,a2_m,a3_m,"
         "tank_treading_frequency_per_s,volume_m3";
}

std::string deformation_csv_row(const scenes::ShearFlowSample& s) {
  std::string row = std::to_string(s.index);
  for (double v : {s.time_s, s.strain_units, s.taylor_deformation,
                   s.inclination_deg * std::numbers::pi / 180.0, s.net_strain, s.semi_axes_m[0],
                   s.semi_axes_m[1], s.semi_axes_m[2], s.tank_treading_frequency_per_s, s.volume_m3}) {
    row += ',' + csv_number(v);
  }
  return row;
}

}  // namespace cellflow::jobs
