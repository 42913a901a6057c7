#include "server/worker_pool.h"

#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>

extern char** environ;

namespace cellflow::server {

WorkerPool::WorkerPool(boost::asio::io_context& io, WorkerPoolOptions options)
    : io_(io), options_(std::move(options)), sigchld_(io, SIGCHLD), kill_timer_(io) {}

WorkerPool::~WorkerPool() {
  for (Slot& slot : slots_) {
    if (slot.pid > 0) {
      ::kill(slot.pid, SIGKILL);
      ::waitpid(slot.pid, nullptr, 0);
    }
  }
}

void WorkerPool::start() {
  slots_.resize(static_cast<std::size_t>(std::max(options_.count, 0)));
  for (Slot& slot : slots_) {
    slot.restart_timer = std::make_unique<boost::asio::steady_timer>(io_);
    slot.next_delay = options_.restart_delay;
  }
  wait_for_children();
  for (std::size_t i = 0; i < slots_.size(); ++i) spawn(i);
}

void WorkerPool::spawn(std::size_t index) {
  Slot& slot = slots_[index];
  const std::string worker_id = "local-" + std::to_string(index);
  std::vector<std::string> args = {options_.worker_path, "--server", options_.server_address, "--name",
                                   worker_id};
  args.insert(args.end(), options_.extra_args.begin(), options_.extra_args.end());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  // The environment of the server without the worker's own settings, plus
  // the credential (the local workers dial a private plaintext socket).
  std::vector<std::string> env_strings;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('='));
    if (name == "CELLFLOW_WORKER_TOKEN" || name == "CELLFLOW_SERVER" || name.rfind("CELLFLOW_TLS_", 0) == 0)
      continue;
    env_strings.push_back(entry);
  }
  if (!options_.worker_token.empty()) env_strings.push_back("CELLFLOW_WORKER_TOKEN=" + options_.worker_token);
  std::vector<char*> envp;
  for (std::string& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);

  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    spdlog::error("cannot fork a worker");
    return;
  }
  if (pid == 0) {
    // Child: only async-signal-safe calls until exec.
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(1);
    ::setpgid(0, 0);  // terminal signals reach the server, which stops the workers itself
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  slot.pid = pid;
  slot.started = std::chrono::steady_clock::now();
  spdlog::info("started worker {} (pid {}): {}", worker_id, pid, options_.worker_path);
}

void WorkerPool::wait_for_children() {
  sigchld_.async_wait([this](const boost::system::error_code& error, int) {
    if (error) return;
    reap();
    wait_for_children();
  });
}

void WorkerPool::reap() {
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    Slot& slot = slots_[i];
    if (slot.pid <= 0) continue;
    int status = 0;
    if (::waitpid(slot.pid, &status, WNOHANG) != slot.pid) continue;
    const pid_t pid = slot.pid;
    slot.pid = -1;
    if (stopping_) continue;
    const auto lived = std::chrono::steady_clock::now() - slot.started;
    if (WIFSIGNALED(status)) {
      spdlog::warn("worker pid {} killed by signal {}", pid, WTERMSIG(status));
    } else {
      spdlog::warn("worker pid {} exited with {}", pid, WEXITSTATUS(status));
    }
    // A worker that keeps dying within a minute waits longer each time.
    if (lived > std::chrono::minutes(1)) slot.next_delay = options_.restart_delay;
    const auto delay = slot.next_delay;
    slot.next_delay = std::min(slot.next_delay * 2, options_.max_restart_delay);
    slot.restart_timer->expires_after(delay);
    slot.restart_timer->async_wait([this, i](const boost::system::error_code& error) {
      if (error || stopping_) return;
      ++restarts_;
      spawn(i);
    });
  }
  maybe_done();
}

void WorkerPool::stop(std::chrono::milliseconds timeout, std::function<void()> done) {
  stopping_ = true;
  on_stopped_ = std::move(done);
  for (Slot& slot : slots_) {
    slot.restart_timer->cancel();
    if (slot.pid > 0) ::kill(slot.pid, SIGTERM);
  }
  kill_timer_.expires_after(timeout);
  kill_timer_.async_wait([this](const boost::system::error_code& error) {
    if (error) return;
    for (Slot& slot : slots_) {
      if (slot.pid > 0) {
        spdlog::warn("worker pid {} did not stop in time; killing it", slot.pid);
        ::kill(slot.pid, SIGKILL);
      }
    }
  });
  maybe_done();
}

void WorkerPool::maybe_done() {
  if (!stopping_ || !on_stopped_) return;
  for (const Slot& slot : slots_) {
    if (slot.pid > 0) return;
  }
  kill_timer_.cancel();
  sigchld_.cancel();
  auto done = std::move(on_stopped_);
  on_stopped_ = nullptr;
  done();
}

std::vector<pid_t> WorkerPool::pids() const {
  std::vector<pid_t> out;
  for (const Slot& slot : slots_) {
    if (slot.pid > 0) out.push_back(slot.pid);
  }
  return out;
}

}  // namespace cellflow::server
