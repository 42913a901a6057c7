#include "server/slurm_executor.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

extern char** environ;

namespace cellflow::server {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using SteadyTime = std::chrono::steady_clock::time_point;

namespace {

// The states in which a submitted worker will still take work or holds its
// node (COMPLETING: ending, it counts against the cap but takes nothing).
bool ended(const std::string& state) {
  static const std::set<std::string> kEnded = {"COMPLETED",     "CANCELLED",    "FAILED",    "TIMEOUT",
                                               "NODE_FAIL",     "PREEMPTED",    "BOOT_FAIL", "DEADLINE",
                                               "OUT_OF_MEMORY", "SPECIAL_EXIT", "REVOKED"};
  return kEnded.count(state) > 0;
}
bool waiting_to_start(const std::string& state) {
  return state == "PENDING" || state == "CONFIGURING" || state == "REQUEUED" || state == "RESIZING";
}

// argv[0] as execve wants it: a path as given, a bare name looked up in PATH
// (here, before fork: the child may only make async-signal-safe calls).
std::string resolve_program(const std::string& name) {
  if (name.find('/') != std::string::npos) return name;
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const std::string candidate = dir + "/" + name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return "";
}

// "0-3,7" (optionally "%N" throttle) -> the task ids.
std::vector<std::string> expand_tasks(const std::string& ranges) {
  std::vector<std::string> out;
  std::stringstream parts(ranges.substr(0, ranges.find('%')));
  std::string part;
  while (std::getline(parts, part, ',')) {
    const auto dash = part.find('-');
    char* end = nullptr;
    const long first = std::strtol(part.c_str(), &end, 10);
    if (end == part.c_str() || first < 0) continue;
    long last = first;
    if (dash != std::string::npos) last = std::strtol(part.c_str() + dash + 1, nullptr, 10);
    for (long t = first; t <= last && out.size() < 100000; ++t) out.push_back(std::to_string(t));
  }
  return out;
}

std::string first_line(const std::string& text) {
  const std::string line = text.substr(0, text.find('\n'));
  return line.size() > 300 ? line.substr(0, 300) + "..." : line;
}

}  // namespace

ProgramResult run_program(const std::vector<std::string>& argv, std::chrono::milliseconds timeout,
                          std::size_t max_output) {
  ProgramResult result;
  if (argv.empty()) return result;
  const std::string program = resolve_program(argv[0]);
  if (program.empty()) {
    result.err = argv[0] + ": not found in PATH";
    return result;
  }
  std::vector<std::string> args = argv;
  std::vector<char*> c_args;
  for (std::string& a : args) c_args.push_back(a.data());
  c_args.push_back(nullptr);
  int out_pipe[2], err_pipe[2];
  if (::pipe2(out_pipe, O_CLOEXEC) != 0) {
    result.err = "pipe failed";
    return result;
  }
  if (::pipe2(err_pipe, O_CLOEXEC) != 0) {
    ::close(out_pipe[0]);
    ::close(out_pipe[1]);
    result.err = "pipe failed";
    return result;
  }
  const pid_t pid = ::fork();
  if (pid < 0) {
    for (int fd : {out_pipe[0], out_pipe[1], err_pipe[0], err_pipe[1]}) ::close(fd);
    result.err = "fork failed";
    return result;
  }
  if (pid == 0) {
    // Child: async-signal-safe calls only, until execve.
    ::setpgid(0, 0);  // its own group: a timeout kills it with whatever it started
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    const int null_fd = ::open("/dev/null", O_RDONLY);
    if (null_fd >= 0) ::dup2(null_fd, 0);
    ::dup2(out_pipe[1], 1);
    ::dup2(err_pipe[1], 2);
    ::execve(program.c_str(), c_args.data(), environ);
    ::_exit(127);
  }
  ::close(out_pipe[1]);
  ::close(err_pipe[1]);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  struct pollfd fds[2] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}};
  std::string* sinks[2] = {&result.out, &result.err};
  int open_fds = 2;
  char buffer[4096];
  while (open_fds > 0) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left <= 0ms) {
      result.timed_out = true;
      break;
    }
    const int ready = ::poll(fds, 2, static_cast<int>(std::min<std::int64_t>(left.count(), 1000)));
    if (ready < 0 && errno != EINTR) break;
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
      const ssize_t n = ::read(fds[i].fd, buffer, sizeof buffer);
      if (n > 0) {
        // Bounded: the rest is read and dropped so the child never blocks.
        const std::size_t room = max_output - std::min(max_output, sinks[i]->size());
        sinks[i]->append(buffer, std::min<std::size_t>(room, static_cast<std::size_t>(n)));
      } else if (n == 0 || errno != EINTR) {
        ::close(fds[i].fd);
        fds[i].fd = -1;
        --open_fds;
      }
    }
  }
  if (result.timed_out) ::kill(-pid, SIGKILL);
  for (auto& fd : fds) {
    if (fd.fd >= 0) ::close(fd.fd);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!result.timed_out && WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  return result;
}

Status write_worker_script(const fs::path& path) {
  // Constant text: nothing in it comes from options or requests.
  static const char* kScript =
      "#!/bin/sh\n"
      "# Written by cellflow-server --executor slurm (server/slurm_executor.cc): one\n"
      "# cellflow-worker per array element. The worker's command line is this\n"
      "# script's arguments, run as \"$@\" (no shell parses it); its name says\n"
      "# which Slurm job and array element it is.\n"
      "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-1}\"\n"
      "export OMP_WAIT_POLICY=passive\n"
      "exec \"$@\" --name \"slurm-${SLURM_ARRAY_JOB_ID:-${SLURM_JOB_ID:-0}}_${SLURM_ARRAY_TASK_ID:-0}\"\n";
  std::error_code error;
  fs::create_directories(path.parent_path(), error);
  const fs::path temporary = path.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << kScript;
    if (!out) return {StatusCode::kInternal, "cannot write " + temporary.string()};
  }
  if (::chmod(temporary.c_str(), 0755) != 0 || ::rename(temporary.c_str(), path.c_str()) != 0)
    return {StatusCode::kInternal, "cannot install " + path.string()};
  return {};
}

Status configure_slurm_executor(SlurmExecutorOptions& options, const SlurmWorkerSettings& worker,
                                const fs::path& data_dir, const std::string& default_worker_path,
                                const std::string& default_worker_address, bool tokens_checked) {
  options.script = fs::absolute(data_dir) / "slurm" / "cellflow-worker.sbatch";
  if (Status s = write_worker_script(options.script); !s.ok()) return s;
  const std::string address = worker.server.empty() ? default_worker_address : worker.server;
  std::ostringstream idle;
  idle << worker.idle_exit_s;
  options.worker_command = {worker.path.empty() ? default_worker_path : worker.path, "--server", address,
                            "--idle-exit-s", idle.str()};
  if (!worker.token_file.empty()) {
    options.worker_command.push_back("--token-file");
    options.worker_command.push_back(worker.token_file);
  }
  options.worker_command.insert(options.worker_command.end(), worker.args.begin(), worker.args.end());
  const std::string host = address.substr(0, address.rfind(':'));
  if (host == "127.0.0.1" || host == "localhost" || host == "[::1]" || address.rfind("unix", 0) == 0)
    spdlog::warn(
        "--executor slurm: workers dial {}: only those on this node can reach it; set --worker-listen "
        "and --slurm-worker-server",
        address);
  if (tokens_checked && worker.token_file.empty() && std::getenv("CELLFLOW_WORKER_TOKEN") == nullptr)
    spdlog::warn(
        "--executor slurm: no --slurm-worker-token-file (nor CELLFLOW_WORKER_TOKEN to export): the "
        "workers will be refused");
  return {};
}

SlurmExecutor::SlurmExecutor(SlurmExecutorOptions options, std::function<SlurmDemand()> demand, Clock now)
    : options_(std::move(options)),
      demand_(std::move(demand)),
      now_(std::move(now)),
      backoff_(options_.initial_backoff) {}

SlurmExecutor::~SlurmExecutor() {
  stop();
}

void SlurmExecutor::start() {
  spdlog::info("slurm executor: up to {} worker(s), sbatch {} {}", options_.max_workers, options_.sbatch,
               options_.script.string());
  adopt();
  thread_ = std::thread([this] {
    std::unique_lock lock(wake_mutex_);
    while (!stopping_) {
      lock.unlock();
      tick();
      lock.lock();
      wake_.wait_for(lock, options_.poll_interval, [this] { return stopping_; });
    }
  });
}

void SlurmExecutor::stop() {
  {
    std::lock_guard lock(wake_mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

namespace {

// squeue's lines "123_4|RUNNING" (or "123_[0-3%2]|PENDING", "123|RUNNING")
// -> job -> element -> state, for the jobs `keep` accepts.
std::map<std::string, std::map<std::string, std::string>> parse_squeue(
    const std::string& text, const std::function<bool(const std::string&)>& keep) {
  std::map<std::string, std::map<std::string, std::string>> seen;
  std::stringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    const auto bar = line.find('|');
    if (bar == std::string::npos) continue;
    const std::string element = line.substr(0, bar);
    std::string state = line.substr(bar + 1);
    while (!state.empty() && (state.back() == '\r' || state.back() == ' ')) state.pop_back();
    const auto underscore = element.find('_');
    const std::string job = element.substr(0, underscore);
    if (job.empty() || job.find_first_not_of("0123456789") != std::string::npos || !keep(job)) continue;
    if (underscore == std::string::npos) {
      seen[job][job] = state;
    } else if (element.size() > underscore + 1 && element[underscore + 1] == '[') {
      const std::string ranges = element.substr(underscore + 2, element.find(']') - underscore - 2);
      for (const std::string& task : expand_tasks(ranges)) seen[job][job + "_" + task] = state;
    } else {
      seen[job][element] = state;
    }
  }
  return seen;
}

}  // namespace

int SlurmExecutor::adopt() {
  // Workers of an earlier run of this server: this user's jobs of our job name.
  const ProgramResult listed = run_program(
      {options_.squeue, "--noheader", "--array", "--me", "--name=" + options_.job_name, "--format=%i|%T"},
      options_.command_timeout);
  if (listed.exit_code != 0) {
    spdlog::warn("slurm executor: squeue failed ({}): {}", listed.exit_code, first_line(listed.err));
    return 0;
  }
  std::lock_guard lock(mutex_);
  const SteadyTime now = now_();
  int adopted = 0;
  for (const auto& [id, elements] : parse_squeue(listed.out, [](const std::string&) { return true; })) {
    Submitted& job = jobs_[id];
    job.submitted = now;
    job.last_listed = now;
    job.size = static_cast<int>(elements.size());
    for (const auto& [name, state] : elements) {
      // Running before we looked: past its start-up (busy or idle, LeaseJob tells).
      job.elements[name] = Element{state, now - options_.startup_grace - options_.min_worker_life};
      adopted += ended(state) ? 0 : 1;
    }
  }
  if (adopted > 0) spdlog::info("slurm executor: adopted {} worker(s) already in squeue", adopted);
  return adopted;
}

void SlurmExecutor::refresh() {
  if (jobs_.empty()) return;
  std::string ids;
  for (const auto& [id, job] : jobs_) ids += (ids.empty() ? "" : ",") + id;
  const ProgramResult listed =
      run_program({options_.squeue, "--noheader", "--array", "--format=%i|%T", "--jobs=" + ids},
                  options_.command_timeout);
  const SteadyTime now = now_();
  std::map<std::string, std::map<std::string, std::string>> seen;  // job -> element -> state
  if (listed.exit_code != 0) {
    // squeue refuses a list of ids that are all unknown (purged): they ended.
    if (listed.err.find("Invalid job id") == std::string::npos) {
      spdlog::warn("slurm executor: squeue failed ({}): {}", listed.exit_code, first_line(listed.err));
      return;  // keep the last known states
    }
  } else {
    seen = parse_squeue(listed.out, [this](const std::string& job) { return jobs_.count(job) > 0; });
  }
  // Workers that ended before they could have done anything (a wrong token,
  // address or path makes them exit at once): slow down, or every round
  // would submit a new batch of them.
  int quick_exits = 0;
  bool healthy = false;
  for (auto it = jobs_.begin(); it != jobs_.end();) {
    Submitted& job = it->second;
    auto found = seen.find(it->first);
    static const std::map<std::string, std::string> kNone;
    const auto& listed_now = found != seen.end() ? found->second : kNone;
    for (const auto& [name, before] : job.elements) {
      auto after = listed_now.find(name);
      const bool gone = after == listed_now.end() || ended(after->second);
      if (!gone || ended(before.state)) continue;
      if (waiting_to_start(before.state) ||
          (before.state == "RUNNING" && now - before.running_since < options_.min_worker_life))
        ++quick_exits;
    }
    if (found != seen.end()) {
      std::map<std::string, Element> elements;
      for (const auto& [name, state] : found->second) {
        Element element{state, {}};
        if (state == "RUNNING") {
          auto before = job.elements.find(name);
          element.running_since = before != job.elements.end() && before->second.state == "RUNNING"
                                      ? before->second.running_since
                                      : now;
          if (now - element.running_since >= options_.min_worker_life) healthy = true;
        }
        elements.emplace(name, element);
      }
      job.elements = std::move(elements);
      job.last_listed = now;
      ++it;
      continue;
    }
    job.elements.clear();
    const SteadyTime last = std::max(job.last_listed, job.submitted);
    if (now - last > options_.forget_after) {
      spdlog::info("slurm executor: job {} ended", it->first);
      it = jobs_.erase(it);
    } else {
      ++it;
    }
  }
  if (quick_exits > 0) {
    ++failures_;
    retry_at_ = now + backoff_;
    spdlog::warn(
        "slurm executor: {} worker(s) ended within {} ms of their start (see their Slurm output: token, "
        "--slurm-worker-server, --slurm-worker-path?); next submission in {} ms",
        quick_exits, options_.min_worker_life.count(), backoff_.count());
    backoff_ = std::min(backoff_ * 2, options_.max_backoff);
  } else if (healthy) {
    backoff_ = options_.initial_backoff;  // workers live: the set-up works
  }
}

int SlurmExecutor::active_workers() const {
  std::lock_guard lock(mutex_);
  int active = 0;
  for (const auto& [id, job] : jobs_) {
    if (job.last_listed == SteadyTime{}) {
      active += job.size;  // not listed yet: as submitted
      continue;
    }
    for (const auto& [name, element] : job.elements) active += ended(element.state) ? 0 : 1;
  }
  return active;
}

int SlurmExecutor::free_capacity() const {
  const SteadyTime now = now_();
  int free = 0;
  for (const auto& [id, job] : jobs_) {
    if (job.last_listed == SteadyTime{}) {
      free += job.size;
      continue;
    }
    for (const auto& [name, element] : job.elements) {
      if (waiting_to_start(element.state) ||
          (element.state == "RUNNING" && now - element.running_since < options_.startup_grace))
        ++free;
    }
  }
  return free;
}

int SlurmExecutor::submitted_workers() const {
  std::lock_guard lock(mutex_);
  return submitted_;
}

int SlurmExecutor::failed_submissions() const {
  std::lock_guard lock(mutex_);
  return failures_;
}

int SlurmExecutor::tick() {
  const SlurmDemand demand = demand_();
  int active = 0;
  int free = 0;
  {
    std::lock_guard lock(mutex_);
    refresh();
    free = free_capacity();
  }
  active = active_workers();
  // Free workers take queued jobs; pending and just-started ones will.
  const std::int64_t need = demand.queued - demand.waiting_workers - free;
  const int room = options_.max_workers - active;
  const int count = static_cast<int>(std::min<std::int64_t>(need, room));
  if (count <= 0) return 0;
  std::lock_guard lock(mutex_);
  if (now_() < retry_at_) return 0;  // backing off after a failed sbatch
  return submit(count);
}

int SlurmExecutor::submit(int count) {
  std::vector<std::string> argv = {options_.sbatch, "--parsable", "--job-name=" + options_.job_name,
                                   "--array=0-" + std::to_string(count - 1)};
  if (!options_.partition.empty()) argv.push_back("--partition=" + options_.partition);
  argv.insert(argv.end(), options_.sbatch_args.begin(), options_.sbatch_args.end());
  argv.push_back(options_.script.string());
  argv.insert(argv.end(), options_.worker_command.begin(), options_.worker_command.end());
  const ProgramResult result = run_program(argv, options_.command_timeout);
  // --parsable prints "ID" or "ID;CLUSTER".
  const std::string id = result.out.substr(0, result.out.find_first_not_of("0123456789"));
  if (result.exit_code != 0 || id.empty()) {
    ++failures_;
    retry_at_ = now_() + backoff_;
    spdlog::warn("slurm executor: sbatch of {} worker(s) failed ({}{}): {}; next try in {} ms", count,
                 result.timed_out ? "timed out" : "exit " + std::to_string(result.exit_code),
                 id.empty() && result.exit_code == 0 ? ", no job id" : "",
                 first_line(result.err.empty() ? result.out : result.err), backoff_.count());
    backoff_ = std::min(backoff_ * 2, options_.max_backoff);
    return 0;
  }
  retry_at_ = {};  // the backoff itself resets once a worker lives (refresh)
  Submitted job;
  job.size = count;
  job.submitted = now_();
  jobs_[id] = job;
  submitted_ += count;
  spdlog::info("slurm executor: submitted job {} ({} worker(s))", id, count);
  return count;
}

}  // namespace cellflow::server
