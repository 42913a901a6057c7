// cellflow-run SPEC.json [-o curve.csv | -r result.h5 [--checkpoint FILE] [--checkpoint-every-s S]
// [--resume FILE]] [--quiet] [--threads N]: runs a job spec locally and writes its
// force-deformation curve (quasi-static) or its deformation time series (shear flow,
// suspension) as CSV, or the result file; flow jobs run to a result file checkpoint and resume.
#include <CLI/CLI.hpp>
#include <fstream>
#include <iostream>

#include "physics/core/passive_threads.h"
#include "tools/run_job.h"

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  CLI::App app{
      "Run a cellflow job spec (protobuf JSON mapping) locally; the force curve (compression,\n"
      "indentation), the deformation time series D(t) (shear flow) or the mean D and relative\n"
      "viscosity over time (suspension) goes to CSV.\n"
      "Exit codes: 0 done, 1 usage, 2 invalid spec, 3 numerical failure (rows so far written)."};
  std::string spec_path, output_path, result_path;
  bool quiet = false;
  int threads = 0;
  app.add_option("spec", spec_path, "job spec JSON, e.g. examples/compression.json")->required();
  app.add_option("-o,--output", output_path, "curve CSV file (default: stdout)");
  app.add_option("-r,--result", result_path,
                 "write the result file (H5MD, as a worker does) and its XDMF sidecar beside it "
                 "(FILE.xdmf) instead of the CSV")
      ->excludes("--output");
  app.add_flag("-q,--quiet", quiet, "no progress lines on stderr");
  app.add_option("-j,--threads", threads, "OpenMP threads of the solve (default: the OpenMP default)")
      ->check(CLI::NonNegativeNumber);
  cellflow::tools::CheckpointOptions checkpoints;
  app.add_option("--checkpoint", checkpoints.checkpoint_path,
                 "flow jobs with --result: write a checkpoint to FILE at the first sample after each "
                 "--checkpoint-every-s of wall time")
      ->needs("--result");
  app.add_option("--checkpoint-every-s", checkpoints.checkpoint_interval_s,
                 "wall time between checkpoints (default 300; > 0)")
      ->needs("--checkpoint")
      ->check(CLI::PositiveNumber);
  app.add_option("--resume", checkpoints.resume_path,
                 "flow jobs with --result: resume from this checkpoint of the same spec (a refused one: "
                 "from the start)")
      ->needs("--result");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : cellflow::tools::kExitUsage;
  }
  if (!result_path.empty()) {
    const cellflow::tools::RunOutcome outcome = cellflow::tools::run_spec_file_to_result(
        spec_path, result_path, quiet ? nullptr : &std::cerr, threads, checkpoints);
    if (!outcome.status.ok()) std::cerr << "cellflow-run: " << outcome.status.to_string() << '\n';
    return outcome.exit_code;
  }
  std::ofstream file;
  if (!output_path.empty()) {
    file.open(output_path);
    if (!file) {
      std::cerr << "cellflow-run: cannot write '" << output_path << "'\n";
      return cellflow::tools::kExitUsage;
    }
  }
  std::ostream& csv = output_path.empty() ? std::cout : file;
  const cellflow::tools::RunOutcome outcome =
      cellflow::tools::run_spec_file(spec_path, csv, quiet ? nullptr : &std::cerr, threads);
  if (!outcome.status.ok()) std::cerr << "cellflow-run: " << outcome.status.to_string() << '\n';
  return outcome.exit_code;
}
