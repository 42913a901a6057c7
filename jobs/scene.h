// What every scene offers the programs that run it (the server, the worker,
// cellflow-run): a job spec converted and validated once into the scene's
// physics parameters (PreparedJob), its memory estimate, and two ways to run
// it — recording the HDF5 result while streaming samples (worker), or writing
// CSV rows (cellflow-run). Scenes register in jobs/registry.cc; nothing else
// looks at which scene a spec names.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <string_view>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// What a running job reports. All optional.
struct JobEvents {
  std::function<void(const v1::ForceSample&)> force_sample;
  std::function<void(const v1::DeformationSample&)> deformation_sample;
  std::function<void(double fraction_done, const std::string& stage)> progress;
  std::function<bool()> should_stop;  // true: stop at the next check, outcome kCancelled
};

struct RunOptions {
  std::string result_path;   // the HDF5 file to write (the caller picks a temporary name)
  int position_frames = 10;  // quasi-static: frames between the reference and the final state, at most
                             // (a flow job writes every snapshot of numerics.snapshot_every_strain)
  int threads = 0;           // OpenMP threads for the physics; 0: the spec's / default
  int debug_delay_per_point_ms = 0;  // testing aid: a cancellable pause after each load point (quasi-static)
  // /h5md/creator version; empty: this build's, "<version> (git <commit>)".
  std::string program_version;
  // /h5md/author name when the spec names none (cellflow-run: $USER); empty: "unknown".
  std::string default_author;
  // fit: the curve library's cache directory; empty: jobs::default_library_dir()
  // ($CELLFLOW_LIBRARY_DIR, $XDG_CACHE_HOME/cellflow/curves, ~/.cache/cellflow/curves).
  std::string library_dir;
};

struct RunOutcome {
  Status status;                // OK; kCancelled when should_stop said so; otherwise the failure
  bool result_written = false;  // the result file exists and holds what was computed
  int samples = 0;
};

// Where cellflow-run writes: CSV rows as the run goes (a failed run keeps its
// rows), human-readable progress lines when `progress` is not null.
struct CsvSink {
  std::ostream& csv;
  std::ostream* progress = nullptr;
};

// One job, converted from its spec and validated. The parameters live inside;
// running does not convert or validate the spec again.
class PreparedJob {
 public:
  virtual ~PreparedJob() = default;

  // The scene's name as the spec's oneof field ("compression", "shear_flow").
  virtual std::string_view scene() const = 0;

  // An upper estimate of the run's peak memory (see each scene's estimate).
  virtual std::int64_t memory_bytes() const = 0;

  // The highest sample index a run can report (quasi-static: load_points - 1);
  // < 0: no bound known. The server refuses reports beyond it.
  virtual std::int64_t max_sample_index() const { return -1; }

  // Runs the scene, streams samples and progress to `events` and writes the
  // result file named by options.result_path; `spec` is stored in it as
  // /parameters (the spec this job was prepared from).
  virtual RunOutcome run(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events) = 0;

  // Runs the scene and writes the CSV header and one row per sample.
  // threads > 0 overrides the OpenMP thread count.
  virtual Status run_csv(const CsvSink& sink, int threads) = 0;
};

// One scene as the registry lists it.
struct SceneEntry {
  v1::JobSpec::SceneCase scene_case;
  std::string_view name;  // the oneof field name in spec.proto
  // Converts and validates the scene's part of `spec`; INVALID_ARGUMENT or
  // RESOURCE_EXHAUSTED names the field path.
  StatusOr<std::unique_ptr<PreparedJob>> (*prepare)(const v1::JobSpec& spec);
};

}  // namespace cellflow::jobs
