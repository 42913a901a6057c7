// The Slurm executor of `cellflow-server --executor slurm`: when jobs are
// queued and no worker is free, it submits cellflow-worker job arrays with
// sbatch, up to a configured number of workers in total (those it submitted
// that are still pending or running, tracked with squeue on the job ids it
// got back); the workers end themselves after an idle time
// (cellflow-worker --idle-exit-s). Every program runs by fork + execve with
// an argument vector, never through a shell; nothing a request carries
// reaches a command line (the executor only sees counts).
//
// It runs on a thread of its own (squeue and sbatch can take seconds when
// slurmctld is busy); tick() is one round, public for tests.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::server {

// What the queue needs, from the job service: queued jobs and workers
// waiting in LeaseJob (free workers).
struct SlurmDemand {
  std::int64_t queued = 0;
  std::int64_t waiting_workers = 0;
};

struct SlurmExecutorOptions {
  int max_workers = 4;            // pending + running workers it submitted, at most
  std::string sbatch = "sbatch";  // a path, or a name looked up in PATH
  std::string squeue = "squeue";
  std::string partition;                 // --partition, if set
  std::vector<std::string> sbatch_args;  // more sbatch options (--time, --cpus-per-task, --output ...)
  std::string job_name = "cellflow-worker";
  std::filesystem::path script;             // the batch script (write_worker_script)
  std::vector<std::string> worker_command;  // one worker's argv: executable and arguments
  std::chrono::milliseconds poll_interval{2000};
  // A worker that Slurm started this recently still counts as free: it has
  // not reached LeaseJob yet (process start, channel, TLS).
  std::chrono::milliseconds startup_grace{30000};
  // After a failed sbatch or workers that failed to start; doubles up to
  // max_backoff, back to initial once a worker lives past min_worker_life.
  std::chrono::milliseconds initial_backoff{5000};
  std::chrono::milliseconds max_backoff{300000};
  std::chrono::milliseconds command_timeout{30000};  // sbatch/squeue taking longer are killed
  // A worker that ends sooner after it started (or before it ran) failed
  // to start: the next submission waits (the backoff).
  std::chrono::milliseconds min_worker_life{5000};
  // A submitted job that squeue has not listed for this long is forgotten
  // (ended, or purged from slurmctld's memory).
  std::chrono::milliseconds forget_after{10000};
};

class SlurmExecutor {
 public:
  using Clock = std::function<std::chrono::steady_clock::time_point()>;
  SlurmExecutor(SlurmExecutorOptions options, std::function<SlurmDemand()> demand,
                Clock now = std::chrono::steady_clock::now);
  ~SlurmExecutor();  // stop()
  SlurmExecutor(const SlurmExecutor&) = delete;
  SlurmExecutor& operator=(const SlurmExecutor&) = delete;

  // adopt(), then ticks every poll_interval on a thread until stop().
  void start();
  // Tracks the workers of an earlier run of this server (squeue --me
  // --name=job_name): a restart does not submit beyond the cap. Returns how many.
  int adopt();
  void stop();
  // One round: squeue on the tracked jobs, then sbatch for what the demand
  // needs. Returns the number of workers submitted this round.
  int tick();

  // Workers of tracked jobs that Slurm lists as not yet ended (the cap counts these).
  int active_workers() const;
  int submitted_workers() const;  // in total, since start
  int failed_submissions() const;

 private:
  struct Element {
    std::string state;  // squeue %T: PENDING, RUNNING, COMPLETING, ...
    std::chrono::steady_clock::time_point running_since{};
  };
  struct Submitted {
    int size = 0;
    std::chrono::steady_clock::time_point submitted{};
    std::chrono::steady_clock::time_point last_listed{};
    std::map<std::string, Element> elements;  // "123_4" -> state
  };
  // The three below run with mutex_ held.
  void refresh();             // squeue on the tracked jobs
  int submit(int count);      // sbatch; returns count on success, 0 on failure
  int free_capacity() const;  // pending + just-started workers

  SlurmExecutorOptions options_;
  std::function<SlurmDemand()> demand_;
  Clock now_;
  mutable std::mutex mutex_;
  std::map<std::string, Submitted> jobs_;  // Slurm job id -> what it holds
  int submitted_ = 0;
  int failures_ = 0;
  std::chrono::milliseconds backoff_;
  std::chrono::steady_clock::time_point retry_at_{};
  std::thread thread_;
  std::mutex wake_mutex_;  // stopping_ and wake_ (not held while a tick runs)
  std::condition_variable wake_;
  bool stopping_ = false;
};

// One Slurm worker's command line, from the server's options.
struct SlurmWorkerSettings {
  std::string path;        // cellflow-worker on the nodes; empty: the caller's default
  std::string server;      // what the workers dial; empty: the caller's default (the bound worker listener)
  std::string token_file;  // the worker token file as the nodes see it (mode 0600)
  double idle_exit_s = 60.0;      // they exit after this long without a job
  std::vector<std::string> args;  // more worker arguments (--threads, --tls-ca ...); not --name
};

// Writes the batch script to data_dir/slurm/cellflow-worker.sbatch and fills
// in options.script and options.worker_command (logging what will not work:
// a loopback address, no credential where tokens are checked).
Status configure_slurm_executor(SlurmExecutorOptions& options, const SlurmWorkerSettings& worker,
                                const std::filesystem::path& data_dir, const std::string& default_worker_path,
                                const std::string& default_worker_address, bool tokens_checked);

// The fixed batch script: one worker per array element, its command line
// given as the script's arguments (sbatch SCRIPT ARGS...), exec'd as "$@"
// so no shell ever parses it. The text depends on nothing from outside.
Status write_worker_script(const std::filesystem::path& path);

// Runs argv[0] (a path, or a name looked up in PATH) with fork + execve:
// stdin /dev/null, stdout and stderr captured up to max_output bytes each,
// killed (its process group) after `timeout`.
struct ProgramResult {
  int exit_code = -1;  // -1: did not run or was killed
  bool timed_out = false;
  std::string out;
  std::string err;
};
ProgramResult run_program(const std::vector<std::string>& argv, std::chrono::milliseconds timeout,
                          std::size_t max_output = 1 << 16);

}  // namespace cellflow::server
