// The Slurm executor (server/slurm_executor.h) against a fake sbatch and a
// fake squeue: shell scripts written by the test into a temporary folder.
// The fake sbatch records its arguments (one per line, calls separated by
// "--end--"), answers the next job id, or fails while a "fail" file exists;
// the fake squeue prints what the test put in "squeue.out" (and fails with
// the text of "squeue.err" if that exists). The clock is the test's.
#include "server/slurm_executor.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace cellflow::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

void write_file(const fs::path& path, const std::string& text, bool executable = false) {
  std::ofstream(path, std::ios::trunc) << text;
  if (executable) ::chmod(path.c_str(), 0755);
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class SlurmExecutorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_slurm_executor_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const std::string d = dir_.string();
    write_file(dir_ / "sbatch",
               "#!/bin/sh\n"
               "for a in \"$@\"; do printf '%s\\n' \"$a\"; done >> '" +
                   d +
                   "/sbatch.log'\n"
                   "echo --end-- >> '" +
                   d +
                   "/sbatch.log'\n"
                   "if [ -e '" +
                   d +
                   "/fail' ]; then echo 'sbatch: error: Batch job submission failed: "
                   "Invalid partition name specified' >&2; exit 1; fi\n"
                   "n=$(cat '" +
                   d +
                   "/next-id' 2>/dev/null || echo 100)\n"
                   "echo $((n + 1)) > '" +
                   d +
                   "/next-id'\n"
                   "echo \"$n;cluster\"\n",
               true);
    write_file(dir_ / "squeue",
               "#!/bin/sh\n"
               "for a in \"$@\"; do printf '%s\\n' \"$a\"; done > '" +
                   d +
                   "/squeue.args'\n"
                   "if [ -e '" +
                   d + "/squeue.err' ]; then cat '" + d +
                   "/squeue.err' >&2; exit 1; fi\n"
                   "cat '" +
                   d + "/squeue.out' 2>/dev/null\n",
               true);
    options_.sbatch = (dir_ / "sbatch").string();
    options_.squeue = (dir_ / "squeue").string();
    options_.max_workers = 4;
    options_.partition = "compute";
    options_.sbatch_args = {"--time=01:00:00", "--output=" + d + "/worker-%A_%a.log"};
    options_.script = dir_ / "cellflow-worker.sbatch";
    // An argument with shell syntax in it reaches sbatch as one literal argument.
    options_.worker_command = {
        "/opt/cellflow/bin/cellflow-worker",        "--server", "login1:50052", "--idle-exit-s", "60",
        "--tls-ca=/etc/ca dir/ca.pem; rm -rf $HOME"};
    options_.startup_grace = 30s;
    options_.initial_backoff = 5s;
    options_.max_backoff = 60s;
    options_.forget_after = 10s;
  }
  void TearDown() override { fs::remove_all(dir_); }

  SlurmExecutor make() {
    return SlurmExecutor(
        options_, [this] { return demand_; }, [this] { return now_; });
  }
  // Each sbatch call's arguments.
  std::vector<std::vector<std::string>> sbatch_calls() const {
    std::vector<std::vector<std::string>> calls(1);
    std::stringstream lines(read_file(dir_ / "sbatch.log"));
    std::string line;
    while (std::getline(lines, line)) {
      if (line == "--end--") {
        calls.emplace_back();
      } else {
        calls.back().push_back(line);
      }
    }
    calls.pop_back();
    return calls;
  }
  static std::string array_of(const std::vector<std::string>& call) {
    for (const std::string& a : call)
      if (a.rfind("--array=", 0) == 0) return a.substr(8);
    return "";
  }
  void squeue_lists(const std::string& text) { write_file(dir_ / "squeue.out", text); }

  fs::path dir_;
  SlurmExecutorOptions options_;
  SlurmDemand demand_;
  std::chrono::steady_clock::time_point now_{std::chrono::hours(1000)};
};

TEST_F(SlurmExecutorTest, ScalesUpWhenJobsAreQueuedUpToTheCap) {
  ASSERT_TRUE(write_worker_script(options_.script).ok());
  SlurmExecutor executor = make();
  demand_ = {3, 0};
  EXPECT_EQ(executor.tick(), 3);
  auto calls = sbatch_calls();
  ASSERT_EQ(calls.size(), 1u);
  // The argument vector as built: options, the script, the worker command verbatim.
  const std::vector<std::string> expected = {"--parsable",
                                             "--job-name=cellflow-worker",
                                             "--array=0-2",
                                             "--partition=compute",
                                             "--time=01:00:00",
                                             "--output=" + dir_.string() + "/worker-%A_%a.log",
                                             options_.script.string(),
                                             "/opt/cellflow/bin/cellflow-worker",
                                             "--server",
                                             "login1:50052",
                                             "--idle-exit-s",
                                             "60",
                                             "--tls-ca=/etc/ca dir/ca.pem; rm -rf $HOME"};
  EXPECT_EQ(calls[0], expected);
  EXPECT_EQ(executor.active_workers(), 3);

  // Pending workers will take the queued jobs: nothing more to submit.
  squeue_lists("100_0|PENDING\n100_1|PENDING\n100_2|PENDING\n");
  now_ += 2s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(read_file(dir_ / "squeue.args"), "--noheader\n--array\n--format=%i|%T\n--jobs=100\n");
  EXPECT_EQ(sbatch_calls().size(), 1u);

  // Six queued, three on the way: three more are needed, the cap (4) allows one.
  demand_ = {6, 0};
  EXPECT_EQ(executor.tick(), 1);
  calls = sbatch_calls();
  ASSERT_EQ(calls.size(), 2u);
  EXPECT_EQ(array_of(calls[1]), "0-0");
  squeue_lists("100_0|RUNNING\n100_1|RUNNING\n100_2|RUNNING\n101_0|PENDING\n");
  now_ += 2s;
  EXPECT_EQ(executor.tick(), 0);  // at the cap
  EXPECT_EQ(executor.active_workers(), 4);
  EXPECT_EQ(read_file(dir_ / "squeue.args"), "--noheader\n--array\n--format=%i|%T\n--jobs=100,101\n");

  // Past the start-up grace the running workers are busy (none waits in
  // LeaseJob), but the cap still holds.
  now_ += 60s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(sbatch_calls().size(), 2u);

  // Two workers ended (idle exit or scancel): room for two more.
  squeue_lists("100_0|RUNNING\n101_0|RUNNING\n100_1|COMPLETING\n");
  now_ += 2s;
  demand_ = {4, 0};
  EXPECT_EQ(executor.active_workers(), 4);  // the last listing until the next tick
  // 4 queued - 1 free (101_0 has just started); room 4 - 3 (COMPLETING holds its node).
  EXPECT_EQ(executor.tick(), 1);
  EXPECT_EQ(executor.submitted_workers(), 5);
}

TEST_F(SlurmExecutorTest, NoSubmissionWhileWorkersAreFree) {
  SlurmExecutor executor = make();
  demand_ = {2, 2};  // two free workers waiting in LeaseJob take the two jobs
  EXPECT_EQ(executor.tick(), 0);
  demand_ = {0, 0};  // nothing queued
  EXPECT_EQ(executor.tick(), 0);
  demand_ = {3, 1};  // one free worker: two more
  EXPECT_EQ(executor.tick(), 2);
  EXPECT_EQ(sbatch_calls().size(), 1u);
  EXPECT_EQ(array_of(sbatch_calls()[0]), "0-1");
  // The two just started still count as free within the grace: no more.
  squeue_lists("100_0|RUNNING\n100_1|RUNNING\n");
  now_ += 5s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(sbatch_calls().size(), 1u);
}

TEST_F(SlurmExecutorTest, FailedSbatchIsRetriedWithBackoff) {
  SlurmExecutor executor = make();
  write_file(dir_ / "fail", "");
  demand_ = {2, 0};
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(executor.failed_submissions(), 1);
  EXPECT_EQ(sbatch_calls().size(), 1u);
  // Within the 5 s backoff: no call.
  now_ += 4s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(sbatch_calls().size(), 1u);
  now_ += 2s;  // 6 s: tried again, fails again; the wait doubles to 10 s
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(sbatch_calls().size(), 2u);
  EXPECT_EQ(executor.failed_submissions(), 2);
  now_ += 9s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(sbatch_calls().size(), 2u);
  fs::remove(dir_ / "fail");
  now_ += 2s;  // 11 s: the cluster is back
  EXPECT_EQ(executor.tick(), 2);
  EXPECT_EQ(sbatch_calls().size(), 3u);
  EXPECT_EQ(executor.active_workers(), 2);
  EXPECT_EQ(executor.failed_submissions(), 2);
}

TEST_F(SlurmExecutorTest, EndedAndPurgedJobsAreForgotten) {
  SlurmExecutor executor = make();
  demand_ = {4, 0};
  EXPECT_EQ(executor.tick(), 4);
  // A collapsed pending array is counted element by element.
  squeue_lists("100_[0-3%4]|PENDING\n");
  now_ += 2s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(executor.active_workers(), 4);
  // slurmctld forgot the job: squeue refuses the id list. The workers are gone.
  write_file(dir_ / "squeue.err", "slurm_load_jobs error: Invalid job id specified\n");
  now_ += 2s;
  demand_ = {0, 0};
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(executor.active_workers(), 0);  // listed before, gone now: ended
  now_ += 11s;
  demand_ = {1, 0};
  EXPECT_EQ(executor.tick(), 1);
  EXPECT_EQ(executor.active_workers(), 1);
  // Any other squeue failure keeps the last known counts (no blind submission).
  write_file(dir_ / "squeue.err", "squeue: error: Unable to contact slurm controller\n");
  now_ += 60s;
  demand_ = {9, 0};
  EXPECT_EQ(executor.tick(), 3);  // the one tracked job (not listed yet) + 3 = the cap
  EXPECT_EQ(executor.active_workers(), 4);
}

// Workers that die at once (a wrong token, address or path) do not make every
// round submit new ones: the next sbatch waits, longer each time, until a
// worker lives past min_worker_life.
TEST_F(SlurmExecutorTest, WorkersThatEndAtStartBackOff) {
  SlurmExecutor executor = make();
  demand_ = {2, 0};
  EXPECT_EQ(executor.tick(), 2);
  squeue_lists("100_0|RUNNING\n100_1|RUNNING\n");
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);  // starting: counted as free
  squeue_lists("");               // both exited after 1 s
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(executor.failed_submissions(), 1);
  now_ += 6s;  // past the 5 s backoff
  EXPECT_EQ(executor.tick(), 2);
  squeue_lists("101_0|PENDING\n101_1|PENDING\n");
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);
  squeue_lists("");  // ended before they ran
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(executor.failed_submissions(), 2);
  now_ += 6s;  // the backoff is 10 s now
  EXPECT_EQ(executor.tick(), 0);
  now_ += 5s;
  EXPECT_EQ(executor.tick(), 2);
  // These live past min_worker_life (5 s): the set-up works, the backoff is back to 5 s.
  squeue_lists("102_0|RUNNING\n102_1|RUNNING\n");
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);  // starting
  now_ += 6s;
  EXPECT_EQ(executor.tick(), 0);  // 7 s: alive, still within the start-up grace
  squeue_lists("");               // they end (idle exit): no failure, new workers at once
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 2);
  EXPECT_EQ(executor.failed_submissions(), 2);
  squeue_lists("103_0|RUNNING\n103_1|RUNNING\n");
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);
  squeue_lists("");  // a quick exit again: the backoff starts over at 5 s, not 20 s
  now_ += 1s;
  EXPECT_EQ(executor.tick(), 0);
  EXPECT_EQ(executor.failed_submissions(), 3);
  now_ += 6s;
  EXPECT_EQ(executor.tick(), 2);
  EXPECT_EQ(sbatch_calls().size(), 5u);
}

// After a restart the server adopts its workers still in squeue (this
// user's jobs of its job name) and counts them against the cap.
TEST_F(SlurmExecutorTest, AdoptsItsWorkersAfterARestart) {
  SlurmExecutor executor = make();
  squeue_lists("200_0|RUNNING\n200_1|RUNNING\n201_[0-1]|PENDING\n");
  EXPECT_EQ(executor.adopt(), 4);
  EXPECT_EQ(read_file(dir_ / "squeue.args"),
            "--noheader\n--array\n--me\n--name=cellflow-worker\n--format=%i|%T\n");
  EXPECT_EQ(executor.active_workers(), 4);
  demand_ = {10, 0};
  now_ += 2s;
  EXPECT_EQ(executor.tick(), 0);  // at the cap
  EXPECT_EQ(read_file(dir_ / "squeue.args"), "--noheader\n--array\n--format=%i|%T\n--jobs=200,201\n");
  EXPECT_FALSE(fs::exists(dir_ / "sbatch.log"));
}

// The batch script runs the worker command as given, argument by argument
// (no shell parses it), and names the worker after the array element.
TEST_F(SlurmExecutorTest, BatchScriptRunsTheCommandVerbatim) {
  SlurmExecutorOptions options;
  SlurmWorkerSettings worker;
  worker.token_file = "/home/u/.config/cellflow/worker-token";
  worker.idle_exit_s = 6;
  worker.args = {"--threads=8"};
  ASSERT_TRUE(configure_slurm_executor(options, worker, dir_ / "data", "/opt/bin/cellflow-worker",
                                       "login1:50052", true)
                  .ok());
  EXPECT_EQ(options.script, fs::absolute(dir_ / "data") / "slurm" / "cellflow-worker.sbatch");
  const std::vector<std::string> expected = {"/opt/bin/cellflow-worker",
                                             "--server",
                                             "login1:50052",
                                             "--idle-exit-s",
                                             "6",
                                             "--token-file",
                                             "/home/u/.config/cellflow/worker-token",
                                             "--threads=8"};
  EXPECT_EQ(options.worker_command, expected);
  ::setenv("SLURM_ARRAY_JOB_ID", "77", 1);
  ::setenv("SLURM_ARRAY_TASK_ID", "3", 1);
  ::setenv("SLURM_CPUS_PER_TASK", "4", 1);
  const ProgramResult ran =
      run_program({options.script.string(), "/bin/sh", "-c", "printf '%s|' \"$OMP_NUM_THREADS\" \"$@\"", "sh",
                   " a b; $(touch " + (dir_ / "pwned").string() + ") `id` *"},
                  5s);
  ::unsetenv("SLURM_ARRAY_JOB_ID");
  ::unsetenv("SLURM_ARRAY_TASK_ID");
  ::unsetenv("SLURM_CPUS_PER_TASK");
  EXPECT_EQ(ran.exit_code, 0) << ran.err;
  EXPECT_EQ(ran.out, "4| a b; $(touch " + (dir_ / "pwned").string() + ") `id` *|--name|slurm-77_3|");
  EXPECT_FALSE(fs::exists(dir_ / "pwned"));
}

TEST(RunProgram, CapturesOutputAndKillsOnTimeout) {
  ProgramResult ok = run_program({"sh", "-c", "printf 'out'; printf 'err' >&2; exit 3"}, 5s);
  EXPECT_EQ(ok.exit_code, 3);
  EXPECT_EQ(ok.out, "out");
  EXPECT_EQ(ok.err, "err");
  const auto started = std::chrono::steady_clock::now();
  ProgramResult slow = run_program({"sleep", "30"}, 300ms);
  EXPECT_TRUE(slow.timed_out);
  EXPECT_EQ(slow.exit_code, -1);
  EXPECT_LT(std::chrono::steady_clock::now() - started, 5s);
  ProgramResult missing = run_program({"cellflow-no-such-program"}, 1s);
  EXPECT_EQ(missing.exit_code, -1);
  ProgramResult bounded = run_program({"sh", "-c", "head -c 100000 /dev/zero"}, 5s, 1000);
  EXPECT_EQ(bounded.exit_code, 0);
  EXPECT_EQ(bounded.out.size(), 1000u);
}

}  // namespace
}  // namespace cellflow::server
