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

// A checkpoint file a running job wrote (flow jobs; RunOptions.checkpoint_path).
struct CheckpointWritten {
  std::string path;
  std::int64_t time_step = 0;  // the run resumes after this step
  int last_sample_index = -1;  // samples 0 .. this are inside
  std::uint64_t bytes = 0;
  double seconds = 0.0;  // wall time of the write
  std::string error;     // non-empty: the write failed (the run goes on, the previous checkpoint stays)
};

// A suspension sample streams at most this many of its cells (the result
// file holds every cell); the server refuses a report with more.
inline constexpr int kMaxStreamedSuspensionCells = 256;

// What a running job reports. All optional.
struct JobEvents {
  std::function<void(const v1::ForceSample&)> force_sample;
  std::function<void(const v1::DeformationSample&)> deformation_sample;
  std::function<void(const v1::SuspensionSample&)> suspension_sample;
  std::function<void(double fraction_done, const std::string& stage)> progress;
  std::function<bool()> should_stop;  // true: stop at the next check, outcome kCancelled
  // A complete checkpoint is at written.path (called on the physics thread;
  // the file is rewritten at the next checkpoint, so copy or upload it here).
  std::function<void(const CheckpointWritten&)> checkpoint_written;
  // When should_stop is true: true (a shutdown that hands the job back, not a
  // cancel) lets a checkpointing run go on to its next sample and checkpoint there.
  std::function<bool()> checkpoint_before_stop;
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
  // Checkpoint and restart (flow jobs: the single cell and the suspension; other scenes ignore these).
  // checkpoint_interval_s > 0 and checkpoint_path set: a checkpoint at the
  // first sample step after each interval of wall time (from the start).
  double checkpoint_interval_s = 0.0;
  std::string checkpoint_path;
  std::string resume_path;  // non-empty: resume from this checkpoint (validated by the scene)
};

struct RunOutcome {
  Status status;                // OK; kCancelled when should_stop said so; otherwise the failure
  bool result_written = false;  // the result file exists and holds what was computed
  int samples = 0;
  std::int64_t resumed_from_step = -1;  // the checkpoint's step it resumed after; -1: from the start
  std::string resume_refused;           // why resume_path was not used (the run started from 0)
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
