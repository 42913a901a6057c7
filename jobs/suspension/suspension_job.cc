#include "jobs/suspension/suspension_job.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <vector>

#include "io/h5md.h"
#include "jobs/common/result_file.h"
#include "jobs/shear_flow/flow_recorder.h"
#include "jobs/shear_flow/shear_flow_job.h"
#include "jobs/suspension/suspension_spec.h"

namespace cellflow::jobs {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;

// Writes one suspension run. Every cell's vertices form the one particle
// group "cell" (cells in the suspension's order, their vertices one after
// the other), so the result opens in ParaView through the XDMF sidecar as the
// single-cell result does: /connectivity/cell holds every cell's tetrahedra
// (each kind's mesh, offset to the cell's vertices), /parameters/setup
// cell_kind, cell_vertex_offset and cell_tet_offset say which rows are whose.
// A snapshot frame is written once every cell's positions of it arrived.
class SuspensionRecorder : public FlowRecorderBase {
 public:
  SuspensionRecorder(io::H5mdWriter* writer, const scenes::PlannedSuspension& planned,
                     const JobEvents& events)
      : FlowRecorderBase(writer, planned.setup().flow, planned.params().numerics.flow.max_strain, events),
        planned_(planned) {}

  scenes::SuspensionCallbacks callbacks() {
    scenes::SuspensionCallbacks cb;
    cb.on_meshes = [this](std::span<const mesh::TetMesh> meshes) { on_meshes(meshes); };
    cb.on_positions = [this](int index, double time_s, int cell, std::span<const double> x) {
      on_positions(index, time_s, cell, x);
    };
    cb.on_sample = [this](const scenes::SuspensionSample& sample) { on_sample(sample); };
    add_flow_callbacks(cb);
    return cb;
  }

  // What the plan derived before the first step, so a partial result has it too.
  void write_setup() {
    const scenes::SuspensionSetup& setup = planned_.setup();
    keep(write_flow_setup(*writer_, setup.flow));
    keep(writer_->write_integer("/parameters/setup/cell_count", setup.cell_count));
    keep(writer_->write_scalar("/parameters/setup/volume_fraction", setup.volume_fraction, ""));
    keep(writer_->write_integer("/parameters/setup/memory_bytes",
                                static_cast<std::int64_t>(setup.memory_bytes)));
    const std::vector<int>& kinds = planned_.cell_kinds();
    keep(writer_->write_integers("/parameters/setup/cell_kind",
                                 std::vector<std::int64_t>(kinds.begin(), kinds.end())));
    keep(writer_->flush());
  }

  // The averages and why the run stopped; closes the file.
  Status finish(const scenes::SuspensionResult& result) {
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->write_scalar(std::string("/summary/") + name, value, unit));
    };
    if (frame_received_ > 0) keep(incomplete_frame());
    write_stop(result.stop, result.status);
    if (!result.samples.empty()) {
      put("average_taylor_deformation", result.average_taylor_deformation, "");
      put("average_taylor_deformation_error", result.average_taylor_deformation_error, "");
      put("average_relative_viscosity", result.average_relative_viscosity, "");
      put("average_relative_viscosity_error", result.average_relative_viscosity_error, "");
      keep(writer_->write_integer("/summary/max_contact_pairs", result.max_contact_pairs));
      keep(writer_->write_integer("/summary/time_steps", result.time_steps));
      put("wall_time_s", result.wall_time_s, "s");
      put("lattice_s", result.lattice_s, "s");
      put("elastic_s", result.elastic_s, "s");
      put("coupling_s", result.coupling_s, "s");
      put("contact_s", result.contact_s, "s");
      put("marking_s", result.marking_s, "s");
      put("observables_s", result.observables_s, "s");
    }
    return close_with_warnings(result.warnings);
  }

 private:
  void on_meshes(std::span<const mesh::TetMesh> meshes) {
    const std::vector<int>& kinds = planned_.cell_kinds();
    std::vector<std::int32_t> tets;
    std::vector<std::uint8_t> region;
    vertex_offset_.assign(1, 0);
    std::vector<std::int64_t> tet_offset(1, 0);
    for (std::size_t cell = 0; cell < kinds.size(); ++cell) {
      const int kind = kinds[cell];
      if (kind < 0 || static_cast<std::size_t>(kind) >= meshes.size()) {
        keep(Status(StatusCode::kInternal, "suspension: cell " + std::to_string(cell) + " of kind " +
                                               std::to_string(kind) + " has no mesh"));
        return;
      }
      const mesh::TetMesh& m = meshes[static_cast<std::size_t>(kind)];
      const auto base = static_cast<std::int32_t>(vertex_offset_.back());
      for (std::int32_t v : m.tets) tets.push_back(v + base);
      for (mesh::Region r : m.tet_region) region.push_back(static_cast<std::uint8_t>(r));
      vertex_offset_.push_back(vertex_offset_.back() + static_cast<std::int64_t>(m.num_vertices()));
      tet_offset.push_back(tet_offset.back() + static_cast<std::int64_t>(m.tets.size() / 4));
    }
    keep(writer_->write_tetrahedra("cell", tets, region));
    keep(writer_->write_integers("/parameters/setup/cell_vertex_offset", vertex_offset_));
    keep(writer_->write_integers("/parameters/setup/cell_tet_offset", tet_offset));
    write_flow_box();
    frame_.assign(static_cast<std::size_t>(vertex_offset_.back()) * 3, 0.0);
    frame_has_.assign(kinds.size(), 0);
  }

  Status incomplete_frame() {
    return Status(StatusCode::kInternal, "suspension: snapshot " + std::to_string(frame_index_) + " has " +
                                             std::to_string(frame_received_) + " of " +
                                             std::to_string(frame_has_.size()) + " cells");
  }

  void on_positions(int index, double time_s, int cell, std::span<const double> x) {
    const std::size_t cells = frame_has_.size();
    if (cell < 0 || static_cast<std::size_t>(cell) >= cells) {
      keep(Status(StatusCode::kInternal, "suspension: positions of cell " + std::to_string(cell) +
                                             " outside the " + std::to_string(cells) + " cells"));
      return;
    }
    const auto c = static_cast<std::size_t>(cell);
    const auto begin = static_cast<std::size_t>(vertex_offset_[c]) * 3;
    const auto size = static_cast<std::size_t>(vertex_offset_[c + 1]) * 3 - begin;
    if (x.size() != size) {
      keep(Status(StatusCode::kInternal, "suspension: cell " + std::to_string(cell) + " has " +
                                             std::to_string(x.size() / 3) + " positions, its mesh " +
                                             std::to_string(size / 3)));
      return;
    }
    if (frame_received_ > 0 && index != frame_index_) {
      keep(incomplete_frame());
      std::fill(frame_has_.begin(), frame_has_.end(), 0);
      frame_received_ = 0;
    }
    frame_index_ = index;
    std::copy(x.begin(), x.end(), frame_.begin() + static_cast<std::ptrdiff_t>(begin));
    if (!frame_has_[c]) {
      frame_has_[c] = 1;
      ++frame_received_;
    }
    if (static_cast<std::size_t>(frame_received_) == cells) {
      keep(writer_->append_positions("cell", step_of(time_s), time_s, frame_));
      keep(writer_->flush());
      std::fill(frame_has_.begin(), frame_has_.end(), 0);
      frame_received_ = 0;
    }
  }

  void on_sample(const scenes::SuspensionSample& s) {
    const std::int64_t step = s.time_step;
    const double time = s.time_s;
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->append_observable(name, step, time, value, unit));
    };
    put("strain", s.strain_units, "");
    put("mean_taylor_deformation", s.mean_taylor_deformation, "");
    put("mean_inclination_rad", s.mean_inclination_deg * kRadPerDeg, "rad");
    put("relative_viscosity", s.relative_viscosity, "");
    keep(writer_->append_count("contact_pairs", step, time, s.contact_pairs));
    put("average_taylor_deformation", s.average_taylor_deformation, "");
    put("average_taylor_deformation_error", s.average_taylor_deformation_error, "");
    put("average_relative_viscosity", s.average_relative_viscosity, "");
    put("average_relative_viscosity_error", s.average_relative_viscosity_error, "");
    // Per cell: one record of N values (3 N for vectors, cell-major) per sample.
    if (!s.cells.empty()) {
      const std::size_t n = s.cells.size();
      std::vector<double> d(n), inclination(n), strain(n), volume(n), axes(3 * n), centroid(3 * n);
      for (std::size_t i = 0; i < n; ++i) {
        const scenes::SuspendedCellSample& c = s.cells[i];
        d[i] = c.taylor_deformation;
        inclination[i] = c.inclination_deg * kRadPerDeg;
        strain[i] = c.net_strain;
        volume[i] = c.volume_m3;
        std::copy(c.semi_axes_m.begin(), c.semi_axes_m.end(),
                  axes.begin() + static_cast<std::ptrdiff_t>(3 * i));
        std::copy(c.centroid_m.begin(), c.centroid_m.end(),
                  centroid.begin() + static_cast<std::ptrdiff_t>(3 * i));
      }
      keep(writer_->append_observable("cell_taylor_deformation", step, time, d, ""));
      keep(writer_->append_observable("cell_inclination_rad", step, time, inclination, "rad"));
      keep(writer_->append_observable("cell_net_strain", step, time, strain, ""));
      keep(writer_->append_observable("cell_semi_axes_m", step, time, axes, "m"));
      keep(writer_->append_observable("cell_centroid_m", step, time, centroid, "m"));
      keep(writer_->append_observable("cell_volume_m3", step, time, volume, "m+3"));
    }
    keep(writer_->flush());  // a killed job leaves every reported sample readable
    sample_written(s.strain_units);
    if (events_.suspension_sample) events_.suspension_sample(suspension_sample_from(s));
  }

  const scenes::PlannedSuspension& planned_;
  std::vector<std::int64_t> vertex_offset_{0};
  std::vector<double> frame_;
  std::vector<char> frame_has_;
  int frame_index_ = -1;
  int frame_received_ = 0;
};

// One converted suspension job: its parameters, plan and placement (computed once, at prepare).
class SuspensionJob final : public PreparedJob {
 public:
  explicit SuspensionJob(scenes::PlannedSuspension planned) : planned_(std::move(planned)) {}

  std::string_view scene() const override { return "suspension"; }

  // The baseline, the plan's estimate (setup.memory_bytes: the lattice and
  // every cell's mesh, body and coupling state), the recorder's snapshot
  // frame and combined connectivity (every cell's positions, 3 doubles per
  // vertex, and its tetrahedra, about 5 per vertex of 4 int32 each), and the
  // largest transient per-node buffer in double (a fluid velocity snapshot,
  // 3 values), and the snapshot positions a checkpointed run keeps (every
  // cell's positions per frame, up to a fixed budget).
  std::int64_t memory_bytes() const override {
    const scenes::SuspensionSetup& setup = planned_.setup();
    double vertices = 0.0;
    for (int kind : planned_.cell_kinds())
      vertices += static_cast<double>(
          cell_vertex_bound(planned_.params().kinds[static_cast<std::size_t>(kind)].cell));
    const double recorder = vertices * (3.0 * 8.0 + 5.0 * 4.0 * 4.0);
    const double kept_snapshots = kept_snapshot_bytes(planned_.params().numerics.flow, vertices);
    const double bytes = static_cast<double>(setup.memory_bytes) + flow_transient_bytes(setup.flow) +
                         recorder + kept_snapshots;
    return kBaselineBytes + static_cast<std::int64_t>(std::min(bytes, 9e18));
  }

  // One sample every sample_every_strain up to max_strain, and the final one.
  std::int64_t max_sample_index() const override {
    const auto& flow = planned_.params().numerics.flow;
    const double samples = flow.max_strain / flow.sample_every_strain;
    return samples < 1e12 ? static_cast<std::int64_t>(samples) + 2 : -1;
  }

  RunOutcome run(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events) override {
    RunOutcome outcome;
    scenes::PlannedSuspension planned = planned_;
    if (options.threads > 0) planned.set_threads(options.threads);
    io::H5mdCreator creator;  // time in s
    auto writer = open_result(spec, options, creator);
    if (!writer.ok()) {
      outcome.status = writer.status();
      return outcome;
    }
    SuspensionRecorder recorder(writer->get(), planned, events);
    recorder.write_setup();
    if (events.progress) events.progress(0.0, "meshing and placing");
    scenes::SuspensionCallbacks callbacks = recorder.callbacks();
    add_flow_checkpointing(callbacks.checkpointing, spec, options, events);
    const scenes::SuspensionResult result = scenes::run_suspension(planned, callbacks);
    const Status written = recorder.finish(result);
    outcome = outcome_of(result.status, written, recorder.samples());
    outcome.resumed_from_step = result.resumed_from_step;
    outcome.resume_refused = result.resume_refused;
    if (outcome.status.ok() && events.progress)
      events.progress(1.0, std::string(scenes::stop_name(result.stop)));
    return outcome;
  }

  Status run_csv(const CsvSink& sink, int threads) override {
    scenes::PlannedSuspension planned = planned_;
    planned.set_threads(threads);
    const double max_strain = planned.params().numerics.flow.max_strain;
    sink.csv << suspension_csv_header() << '\n' << std::flush;
    scenes::SuspensionCallbacks callbacks;
    callbacks.on_sample = [&](const scenes::SuspensionSample& s) {
      sink.csv << suspension_csv_row(s) << '\n' << std::flush;
      if (sink.progress) {
        char line[200];
        std::snprintf(line, sizeof(line),
                      "sample %d  strain %.2f/%.4g  mean D %.4f  relative viscosity %.4f  contacts %d\n",
                      s.index, s.strain_units, max_strain, s.mean_taylor_deformation, s.relative_viscosity,
                      s.contact_pairs);
        *sink.progress << line << std::flush;
      }
    };
    const scenes::SuspensionResult result = scenes::run_suspension(planned, callbacks);
    if (sink.progress && !result.samples.empty()) {
      char line[400];
      std::snprintf(line, sizeof(line),
                    "stopped: %s after %lld steps (%.1f s); %d cells, volume fraction %.4g, Ca %.4g; "
                    "mean D %.5f +- %.2g, relative viscosity %.5f +- %.2g\n",
                    std::string(scenes::stop_name(result.stop)).c_str(),
                    static_cast<long long>(result.time_steps), result.wall_time_s, result.setup.cell_count,
                    result.setup.volume_fraction, result.setup.flow.capillary_number,
                    result.average_taylor_deformation, result.average_taylor_deformation_error,
                    result.average_relative_viscosity, result.average_relative_viscosity_error);
      *sink.progress << line;
      for (const std::string& w : result.warnings) *sink.progress << "warning: " << w << '\n';
      *sink.progress << std::flush;
    }
    return result.status;
  }

 private:
  scenes::PlannedSuspension planned_;
};

}  // namespace

StatusOr<std::unique_ptr<PreparedJob>> prepare_suspension(const v1::JobSpec& spec) {
  StatusOr<scenes::PlannedSuspension> planned = plan(spec.suspension(), "suspension.");
  if (!planned.ok()) return planned.status();
  return std::unique_ptr<PreparedJob>(new SuspensionJob(std::move(*planned)));
}

v1::SuspensionSample suspension_sample_from(const scenes::SuspensionSample& s) {
  v1::SuspensionSample sample;
  sample.set_index(s.index);
  sample.set_time_s(s.time_s);
  sample.set_strain(s.strain_units);
  sample.set_cell_count(static_cast<int>(s.cells.size()));
  sample.set_mean_taylor_deformation(s.mean_taylor_deformation);
  sample.set_mean_inclination_rad(s.mean_inclination_deg * kRadPerDeg);
  sample.set_relative_viscosity(s.relative_viscosity);
  sample.set_contact_pairs(s.contact_pairs);
  const std::size_t streamed =
      std::min(s.cells.size(), static_cast<std::size_t>(kMaxStreamedSuspensionCells));
  for (std::size_t i = 0; i < streamed; ++i) {
    const scenes::SuspendedCellSample& c = s.cells[i];
    v1::SuspendedCellState* cell = sample.add_cells();
    cell->set_cell(static_cast<int>(i));
    cell->set_taylor_deformation(c.taylor_deformation);
    cell->set_inclination_rad(c.inclination_deg * kRadPerDeg);
    cell->set_net_strain(c.net_strain);
    for (double x : c.centroid_m) cell->add_centroid_m(x);
  }
  sample.set_average_taylor_deformation(s.average_taylor_deformation);
  sample.set_average_taylor_deformation_error(s.average_taylor_deformation_error);
  sample.set_average_relative_viscosity(s.average_relative_viscosity);
  sample.set_average_relative_viscosity_error(s.average_relative_viscosity_error);
  return sample;
}

std::string suspension_csv_header() {
  return "sample,time_s,strain,cell_count,mean_taylor_deformation,mean_inclination_rad,relative_viscosity,"
         "contact_pairs,average_taylor_deformation,average_taylor_deformation_error,"
         "average_relative_viscosity,average_relative_viscosity_error";
}

std::string suspension_csv_row(const scenes::SuspensionSample& s) {
  std::string row = std::to_string(s.index);
  row += ',' + csv_number(s.time_s) + ',' + csv_number(s.strain_units) + ',' + std::to_string(s.cells.size());
  row += ',' + csv_number(s.mean_taylor_deformation) + ',' + csv_number(s.mean_inclination_deg * kRadPerDeg);
  row += ',' + csv_number(s.relative_viscosity) + ',' + std::to_string(s.contact_pairs);
  for (double v : {s.average_taylor_deformation, s.average_taylor_deformation_error,
                   s.average_relative_viscosity, s.average_relative_viscosity_error}) {
    row += ',' + csv_number(v);
  }
  return row;
}

}  // namespace cellflow::jobs
