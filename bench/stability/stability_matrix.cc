// The stability stress matrix (issue 5, item 2). Runs every case (or those
// whose name matches --filter) in its own child process under a wall-clock
// limit and writes the report: every case, its outcome (CONVERGED,
// FAILED(cause), HANG, CRASH, WRONG) and its time.
//
//   stability_matrix [--filter REGEX] [--report stability_report.md]
//                    [--csv stability_report.csv] [--work-dir DIR]
//                    [--time-limit-scale 1] [--list] [--self-test]
//
// Exit status 0 when every case is CONVERGED or FAILED with a named cause and
// every anchor case converged; 1 otherwise; 2 on bad arguments.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "bench/stability/stability_harness.h"
#include "physics/core/passive_threads.h"

namespace {

using cellflow::stability::Case;
using cellflow::stability::CaseRecord;

std::string self_executable(const char* argv0) {
  std::error_code error;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
  return error ? std::string(argv0) : self.string();
}

}  // namespace

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  namespace stability = cellflow::stability;
  CLI::App app{"Numerical stability stress matrix of the cellflow scenes"};
  std::string filter, report_path, csv_path, work_dir, run_case, result_file;
  double time_limit_scale = 1.0;
  bool list = false, self_test = false;
  app.add_option("--filter", filter, "ECMAScript regex; only cases whose name contains a match");
  app.add_option("--report", report_path, "Markdown report file");
  app.add_option("--csv", csv_path, "CSV report file");
  app.add_option("--work-dir", work_dir,
                 "folder for case logs and generated meshes (default: a temp folder)");
  app.add_option("--time-limit-scale", time_limit_scale, "multiplies every case's wall-clock limit")
      ->check(CLI::PositiveNumber);
  app.add_flag("--list", list, "list the selected cases and exit");
  app.add_flag("--self-test", self_test, "add the harness self-test cases (hang, crash, wrong, unnamed)");
  // Child mode (internal): run one case and write its result file.
  app.add_option("--run-case", run_case, "internal: run this case in this process")->group("");
  app.add_option("--result-file", result_file, "internal: result file of --run-case")->group("");
  CLI11_PARSE(app, argc, argv);

  const std::vector<Case> all = stability::make_cases(self_test || !run_case.empty());
  if (!run_case.empty()) {
    for (const Case& c : all) {
      if (c.name == run_case) return stability::run_case_here(c, result_file, work_dir);
    }
    std::fprintf(stderr, "no case named '%s'\n", run_case.c_str());
    return 2;
  }

  std::vector<const Case*> selected;
  try {
    const std::regex pattern(filter.empty() ? std::string(".") : filter);
    for (const Case& c : all) {
      if (std::regex_search(c.name, pattern)) selected.push_back(&c);
    }
  } catch (const std::regex_error& e) {
    std::fprintf(stderr, "--filter '%s' is not a valid regex: %s\n", filter.c_str(), e.what());
    return 2;
  }
  if (list) {
    for (const Case* c : selected) std::printf("%s\t%s\n", c->name.c_str(), c->description.c_str());
    return 0;
  }
  if (selected.empty()) {
    std::fprintf(stderr, "no case matches --filter '%s'\n", filter.c_str());
    return 2;
  }
  if (work_dir.empty()) {
    std::string pattern = (std::filesystem::temp_directory_path() / "stability_matrix.XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) {
      std::perror("mkdtemp");
      return 2;
    }
    work_dir = pattern;
  } else {
    std::filesystem::create_directories(work_dir);
  }
  const std::string executable = self_executable(argv[0]);
  std::printf("%zu cases, logs in %s\n", selected.size(), work_dir.c_str());
  std::fflush(stdout);

  const auto start = std::chrono::steady_clock::now();
  std::vector<CaseRecord> records;
  bool all_acceptable = true;
  for (const Case* c : selected) {
    CaseRecord r = stability::run_case_in_child(executable, *c, work_dir, c->time_limit_s * time_limit_scale);
    const bool ok = stability::acceptable(r.outcome, r.cause) &&
                    !(r.anchor && r.outcome != stability::Outcome::kConverged);
    all_acceptable = all_acceptable && ok;
    std::printf("%-45s %-9s %7.1f s  %s%s%s\n", r.name.c_str(),
                std::string(stability::outcome_name(r.outcome)).c_str(), r.wall_s, r.cause.c_str(),
                r.cause.empty() ? "" : ": ", r.detail.c_str());
    if (!ok) std::printf("  ^ not acceptable%s\n", r.anchor ? " (anchor case must converge)" : "");
    std::fflush(stdout);
    records.push_back(std::move(r));
  }
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("total wall time %.1f s; %s\n", total,
              all_acceptable ? "all acceptable" : "NOT all acceptable");
  if (!report_path.empty()) std::ofstream(report_path) << stability::markdown_report(records, total);
  if (!csv_path.empty()) std::ofstream(csv_path) << stability::csv_report(records);
  return all_acceptable ? 0 : 1;
}
