#include "tools/run_job.h"

#include <fstream>
#include <sstream>

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

}  // namespace

RunOutcome run_spec_file(const std::string& spec_path, std::ostream& csv, std::ostream* progress,
                         int threads) {
  std::ifstream in(spec_path);
  if (!in) return outcome_for(invalid_argument("spec file '" + spec_path + "' cannot be opened for reading"));
  std::stringstream text;
  text << in.rdbuf();
  StatusOr<v1::JobSpec> spec = jobs::job_spec_from_json(text.str());
  if (!spec.ok()) return outcome_for(spec.status());
  return run_job(*spec, csv, progress, threads);
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
