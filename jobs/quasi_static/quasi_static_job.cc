#include "jobs/quasi_static/quasi_static_job.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <thread>
#include <vector>

#include "io/h5md.h"
#include "jobs/common/cell_spec.h"
#include "jobs/common/result_file.h"

namespace cellflow::jobs {
namespace {

// The "meaning" attribute of every time dataset of a quasi-static result.
constexpr const char* kQuasiStaticTimeMeaning =
    "load parameter, not time: the deformation (plate or probe travel / (2 R)) of the load point; "
    "step k >= 1 is load point k - 1, step 0 the reference state";

scenes::QuasiStaticOptions to_numerics(const v1::QuasiStaticNumerics& n) {
  scenes::QuasiStaticOptions options;  // the struct holds the defaults
  if (n.has_residual_tolerance()) options.residual_tolerance = n.residual_tolerance();
  if (n.has_max_newton_iterations()) options.max_newton_iterations = n.max_newton_iterations();
  if (n.has_max_step_splits()) options.max_step_splits = n.max_step_splits();
  if (n.has_contact_stiffness_n_per_m()) options.contact_stiffness_n_per_m = n.contact_stiffness_n_per_m();
  if (n.has_contact_range_m()) options.contact_range_m = n.contact_range_m();
  if (n.volumetric_term() == v1::VOLUMETRIC_TERM_PER_TET) {
    options.volumetric = elastic::VolumetricTerm::kPerTet;
  } else if (n.volumetric_term() == v1::VOLUMETRIC_TERM_NODAL_AVERAGE) {
    options.volumetric = elastic::VolumetricTerm::kNodalAverage;
  }
  if (n.contact_enforcement() == v1::CONTACT_ENFORCEMENT_AUGMENTED_LAGRANGIAN) {
    options.contact_enforcement = scenes::ContactEnforcement::kAugmentedLagrangian;
  }
  if (n.has_contact_gap_tolerance_m()) options.contact_gap_tolerance_m = n.contact_gap_tolerance_m();
  if (n.probe_contact() == v1::PROBE_CONTACT_SURFACE) options.probe_contact = scenes::ProbeContact::kSurface;
  if (n.has_pole_spacing_m()) options.pole_spacing_m = n.pole_spacing_m();
  if (n.has_pole_grading_growth()) options.pole_grading_growth = n.pole_grading_growth();
  if (n.has_pole_ring_jitter()) options.pole_ring_jitter = n.pole_ring_jitter();
  if (n.element() == v1::ELEMENT_QUADRATIC_TET) options.element = elastic::Element::kQuadraticTet;
  return options;
}

Status missing(std::string_view field) {
  return invalid_argument(std::string(field) + " must be set");
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
    // Units in the H5MD units syntax; dimensionless values carry none.
    auto put = [&](const char* name, double value, const char* unit) {
      keep(writer_->append_observable(name, step, time, value, unit));
    };
    auto count = [&](const char* name, std::int64_t value) {
      keep(writer_->append_count(name, step, time, value));
    };
    put("deformation", point.deformation, "");
    put("displacement_m", point.displacement_m, "m");
    put("force_n", point.force_n, "N");
    put("hertz_force_n", point.hertz_force_n, "N");
    put("taylor_deformation", point.taylor_deformation, "");
    keep(writer_->append_observable("semi_axes_m", step, time, std::span<const double>(point.semi_axes_m, 3),
                                    "m"));
    put("volume_m3", point.volume_m3, "m+3");
    put("elastic_energy_j", point.elastic_energy_j, "J");
    put("max_penetration_m", point.max_penetration_m, "m");
    count("newton_iterations", point.newton_iterations);
    count("cg_iterations", point.cg_iterations);
    count("step_splits", point.step_splits);
    put("residual", point.residual, "");
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

// The scene function of one quasi-static job kind.
template <class Params>
using SceneFunction = scenes::QuasiStaticResult (*)(const scenes::Checked<Params>&,
                                                    const scenes::SceneCallbacks&);

// One converted quasi-static job: compression or indentation parameters and
// the scene that runs them.
template <class Params>
class QuasiStaticJob final : public PreparedJob {
 public:
  QuasiStaticJob(std::string_view name, scenes::Checked<Params> checked, SceneFunction<Params> scene)
      : name_(name), checked_(std::move(checked)), scene_(scene) {}

  std::string_view scene() const override { return name_; }

  // The process baseline plus the mesh and its solver per vertex.
  std::int64_t memory_bytes() const override {
    return kBaselineBytes + cell_vertex_bound(checked_.params().cell) * kBytesPerVertex;
  }

  std::int64_t max_sample_index() const override { return checked_.params().load_points - 1; }

  RunOutcome run(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events) override {
    RunOutcome outcome;
    scenes::Checked<Params> checked = checked_;
    if (options.threads > 0) checked.set_threads(options.threads);
    const Params& params = checked.params();
    io::H5mdCreator creator;
    // No physical time: "time" is the load parameter, dimensionless.
    creator.time_unit = "";
    creator.time_meaning = kQuasiStaticTimeMeaning;
    auto writer = open_result(spec, options, creator);
    if (!writer.ok()) {
      outcome.status = writer.status();
      return outcome;
    }
    QuasiStaticRecorder recorder(writer->get(), params.load_points, options.position_frames, events,
                                 options.debug_delay_per_point_ms);
    if (events.progress) events.progress(0.0, "meshing");
    scenes::QuasiStaticResult result = scene_(checked, recorder.callbacks());
    const Status written = recorder.finish();
    return outcome_of(result.status, written, recorder.points());
  }

  Status run_csv(const CsvSink& sink, int threads) override {
    scenes::Checked<Params> checked = checked_;
    checked.set_threads(threads);
    const Params& params = checked.params();
    scenes::SceneCallbacks callbacks;
    callbacks.on_point = [&](const scenes::CurvePoint& p) {
      sink.csv << curve_csv_row(p) << '\n' << std::flush;
      if (sink.progress) {
        char line[200];
        std::snprintf(line, sizeof(line),
                      "point %d/%d  deformation %.4f  force %.4g N  F/F_Hertz %.3f  Newton %d  splits %d\n",
                      p.index + 1, params.load_points, p.deformation, p.force_n,
                      p.hertz_force_n > 0 ? p.force_n / p.hertz_force_n : 0.0, p.newton_iterations,
                      p.step_splits);
        *sink.progress << line << std::flush;
      }
    };
    sink.csv << curve_csv_header() << '\n' << std::flush;
    return scene_(checked, callbacks).status;
  }

 private:
  std::string_view name_;
  scenes::Checked<Params> checked_;
  SceneFunction<Params> scene_;
};

// Converts without validating: unset fields keep the structs' defaults.
StatusOr<scenes::CompressionParams> convert(const v1::CompressionSpec& spec) {
  if (!spec.has_cell()) return missing("compression.cell");
  if (!spec.cell().has_material()) return missing("compression.cell.material");
  scenes::CompressionParams params;
  params.cell = to_cell(spec.cell(), cell::CellParams{});
  params.max_deformation = spec.max_deformation();
  if (spec.has_load_points()) params.load_points = spec.load_points();  // else the struct's default
  params.numerics = to_numerics(spec.numerics());
  return params;
}

StatusOr<scenes::IndentationParams> convert(const v1::IndentationSpec& spec) {
  if (!spec.has_cell()) return missing("indentation.cell");
  if (!spec.cell().has_material()) return missing("indentation.cell.material");
  scenes::IndentationParams params;
  params.cell = to_cell(spec.cell(), cell::CellParams{});
  params.probe_radius_m = spec.probe_radius_m();
  params.max_indentation_m = spec.max_indentation_m();
  if (spec.has_load_points()) params.load_points = spec.load_points();  // else the struct's default
  params.numerics = to_numerics(spec.numerics());
  return params;
}

}  // namespace

StatusOr<scenes::CompressionParams> to_params(const v1::CompressionSpec& spec) {
  StatusOr<scenes::CompressionParams> params = convert(spec);
  if (!params.ok()) return params;
  if (Status s = scenes::validate(*params, "compression."); !s.ok()) return s;
  return params;
}

StatusOr<scenes::IndentationParams> to_params(const v1::IndentationSpec& spec) {
  StatusOr<scenes::IndentationParams> params = convert(spec);
  if (!params.ok()) return params;
  if (Status s = scenes::validate(*params, "indentation."); !s.ok()) return s;
  return params;
}

StatusOr<std::unique_ptr<PreparedJob>> prepare_compression(const v1::JobSpec& spec) {
  StatusOr<scenes::CompressionParams> params = convert(spec.compression());
  if (!params.ok()) return params.status();
  StatusOr<scenes::Checked<scenes::CompressionParams>> checked = scenes::check(*params, "compression.");
  if (!checked.ok()) return checked.status();
  return std::unique_ptr<PreparedJob>(new QuasiStaticJob<scenes::CompressionParams>(
      "compression", std::move(*checked), &scenes::run_compression));
}

StatusOr<std::unique_ptr<PreparedJob>> prepare_indentation(const v1::JobSpec& spec) {
  StatusOr<scenes::IndentationParams> params = convert(spec.indentation());
  if (!params.ok()) return params.status();
  StatusOr<scenes::Checked<scenes::IndentationParams>> checked = scenes::check(*params, "indentation.");
  if (!checked.ok()) return checked.status();
  return std::unique_ptr<PreparedJob>(new QuasiStaticJob<scenes::IndentationParams>(
      "indentation", std::move(*checked), &scenes::run_indentation));
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

std::string curve_csv_header() {
  return "point,deformation,displacement_m,force_n,hertz_force_n,force_over_hertz,taylor_deformation,a1_m,a2_"
         "m,a3_"
         "m,volume_m3,elastic_energy_j,max_penetration_m,newton_iterations,step_splits,residual";
}

std::string curve_csv_row(const scenes::CurvePoint& p) {
  const double ratio = p.hertz_force_n > 0.0 ? p.force_n / p.hertz_force_n : 0.0;
  std::string row = std::to_string(p.index);
  for (double v : {p.deformation, p.displacement_m, p.force_n, p.hertz_force_n, ratio, p.taylor_deformation,
                   p.semi_axes_m[0], p.semi_axes_m[1], p.semi_axes_m[2], p.volume_m3, p.elastic_energy_j,
                   p.max_penetration_m}) {
    row += ',' + csv_number(v);
  }
  row += ',' + std::to_string(p.newton_iterations) + ',' + std::to_string(p.step_splits) + ',' +
         csv_number(p.residual);
  return row;
}

}  // namespace cellflow::jobs
