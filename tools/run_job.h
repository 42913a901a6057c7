// The logic of `cellflow-run SPEC.json`: read a job spec in the protobuf JSON
// mapping, prepare it through the scene registry (one conversion) and run it,
// writing CSV: the force curve of a quasi-static scene, the deformation time
// series D(t) of a shear flow. main() only parses the command line
// (tools/cellflow_run_main.cc).
#pragma once

#include <ostream>
#include <string>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::tools {

// Exit codes of cellflow-run.
enum ExitCode : int {
  kExitOk = 0,
  kExitUsage = 1,             // bad command line
  kExitInvalidSpec = 2,       // unreadable or invalid spec, bad mesh file; the message names the field
  kExitNumericalFailure = 3,  // the run failed (curve so far still written)
};

struct RunOutcome {
  ExitCode exit_code = kExitOk;
  Status status;
};

// Reads the file at spec_path (JSON) and runs it. threads > 0 overrides the
// OpenMP thread count of the solve (0: the OpenMP default).
RunOutcome run_spec_file(const std::string& spec_path, std::ostream& csv, std::ostream* progress,
                         int threads = 0);
// Checkpoint and restart of a flow job (the single cell, the suspension;
// other scenes ignore it) run to a result file: a checkpoint at the first
// checkpoint step after each interval of wall time to checkpoint_path
// (empty: none), resume from resume_path (empty: from the start; a refused
// file means a run from the start, said on the progress stream).
struct CheckpointOptions {
  std::string checkpoint_path;
  double checkpoint_interval_s = 300.0;  // > 0
  std::string resume_path;
};

// Reads the spec at spec_path and runs it as a worker does: the result file
// (H5MD) at h5_path, author $USER unless the spec names one, and its XDMF
// sidecar beside it (h5_path with the extension .xdmf) for ParaView.
// Checkpoints written and a resume are reported on `progress`.
RunOutcome run_spec_file_to_result(const std::string& spec_path, const std::string& h5_path,
                                   std::ostream* progress, int threads = 0,
                                   const CheckpointOptions& checkpoints = {});

// Validates and runs `spec`; writes the CSV header and one row per converged
// point (flow: per sample) to `csv` as the run goes (so a failed run keeps its
// curve), progress lines to `progress` when it is not null.
RunOutcome run_job(const v1::JobSpec& spec, std::ostream& csv, std::ostream* progress, int threads = 0);

}  // namespace cellflow::tools
