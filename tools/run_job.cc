#include "tools/run_job.h"

#include <pwd.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "io/xdmf.h"
#include "jobs/registry.h"
#include "jobs/spec_json.h"

namespace cellflow::tools {

namespace {

RunOutcome outcome_for(const Status& status) {
  RunOutcome outcome;
  outcome.status = status;
  switch (status.code()) {
    case StatusCode::kOk:
      outcome.exit_code = kExitOk;
      break;
    case StatusCode::kInvalidArgument:
    case StatusCode::kNotFound:
    case StatusCode::kFailedPrecondition:
    case StatusCode::kResourceExhausted:
      outcome.exit_code = kExitInvalidSpec;
      break;
    default:
      outcome.exit_code = kExitNumericalFailure;
      break;
  }
  return outcome;
}

// $USER, else the account's name (a shell without USER, a cron job); empty if neither.
std::string login_name() {
  if (const char* user = std::getenv("USER"); user != nullptr && *user != '\0') return user;
  if (const passwd* entry = ::getpwuid(::getuid()); entry != nullptr && entry->pw_name != nullptr)
    return entry->pw_name;
  return {};
}

StatusOr<v1::JobSpec> read_spec_file(const std::string& spec_path) {
  std::ifstream in(spec_path);
  if (!in) return invalid_argument("spec file '" + spec_path + "' cannot be opened for reading");
  std::stringstream text;
  text << in.rdbuf();
  return jobs::job_spec_from_json(text.str());
}

}  // namespace

RunOutcome run_spec_file(const std::string& spec_path, std::ostream& csv, std::ostream* progress,
                         int threads) {
  StatusOr<v1::JobSpec> spec = read_spec_file(spec_path);
  if (!spec.ok()) return outcome_for(spec.status());
  return run_job(*spec, csv, progress, threads);
}

RunOutcome run_spec_file_to_result(const std::string& spec_path, const std::string& h5_path,
                                   std::ostream* progress, int threads,
                                   const CheckpointOptions& checkpoints) {
  if (threads < 0)
    return outcome_for(invalid_argument("--threads = " + std::to_string(threads) + " must be >= 0"));
  if (!checkpoints.checkpoint_path.empty() && !(checkpoints.checkpoint_interval_s > 0.0)) {
    return outcome_for(invalid_argument(
        "--checkpoint-every-s = " + std::to_string(checkpoints.checkpoint_interval_s) + " must be > 0"));
  }
  StatusOr<v1::JobSpec> spec = read_spec_file(spec_path);
  if (!spec.ok()) return outcome_for(spec.status());
  const jobs::SceneRegistry registry;
  auto prepared = registry.prepare(*spec);
  if (!prepared.ok()) return outcome_for(prepared.status());
  jobs::RunOptions options;
  options.result_path = h5_path;
  options.threads = threads;
  options.default_author = login_name();
  if (!checkpoints.checkpoint_path.empty()) {
    options.checkpoint_path = checkpoints.checkpoint_path;
    options.checkpoint_interval_s = checkpoints.checkpoint_interval_s;
  }
  options.resume_path = checkpoints.resume_path;
  jobs::JobEvents events;
  if (progress != nullptr) {
    events.progress = [progress](double fraction, const std::string& stage) {
      *progress << "progress " << static_cast<int>(100.0 * fraction) << " % " << stage << '\n';
    };
    events.checkpoint_written = [progress](const jobs::CheckpointWritten& w) {
      if (!w.error.empty()) {
        *progress << "checkpoint after step " << w.time_step << " not written: " << w.error << '\n';
        return;
      }
      *progress << "checkpoint after step " << w.time_step << " (sample " << w.last_sample_index
                << "): " << w.bytes << " bytes in " << w.seconds << " s to " << w.path << '\n';
    };
  }
  const jobs::RunOutcome outcome = (*prepared)->run(*spec, options, events);
  if (progress != nullptr) {
    if (outcome.resumed_from_step >= 0)
      *progress << "resumed after step " << outcome.resumed_from_step << '\n';
    if (!outcome.resume_refused.empty()) *progress << outcome.resume_refused << "; ran from the start\n";
  }
  if (!outcome.result_written) return outcome_for(outcome.status);
  const std::string xdmf = std::filesystem::path(h5_path).replace_extension(".xdmf").string();
  if (Status s = io::write_xdmf(h5_path, xdmf); !s.ok() && s.code() != StatusCode::kNotFound) {
    return outcome_for(outcome.status.ok() ? s : outcome.status);
  }
  return outcome_for(outcome.status);
}

RunOutcome run_job(const v1::JobSpec& spec, std::ostream& csv, std::ostream* progress, int threads) {
  if (threads < 0)
    return outcome_for(invalid_argument("--threads = " + std::to_string(threads) + " must be >= 0"));
  const jobs::SceneRegistry registry;
  auto prepared = registry.prepare(spec);
  if (!prepared.ok()) return outcome_for(prepared.status());
  return outcome_for((*prepared)->run_csv(jobs::CsvSink{csv, progress}, threads));
}

}  // namespace cellflow::tools
