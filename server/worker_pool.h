// The local worker pool of `cellflow-server --workers N`: spawns N
// cellflow-worker processes that dial the server like remote ones, restarts
// one that dies (with a growing delay while it keeps dying quickly) and stops
// them on shutdown. Runs on the server's Boost.Asio io_context (SIGCHLD and
// restart timers). Each worker gets PR_SET_PDEATHSIG, so a killed server
// takes its local workers with it; their leases then expire as usual.
#pragma once

#include <sys/types.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace cellflow::server {

struct WorkerPoolOptions {
  int count = 0;
  std::string worker_path;     // the cellflow-worker executable
  std::string server_address;  // what the workers dial, host:port or unix-abstract:NAME
  // The workers' credential, passed in their environment as
  // CELLFLOW_WORKER_TOKEN (never on the command line, which ps shows).
  std::string worker_token;
  std::vector<std::string> extra_args;  // appended to every worker's command line
  std::chrono::milliseconds restart_delay{500};
  std::chrono::milliseconds max_restart_delay{30000};
};

class WorkerPool {
 public:
  WorkerPool(boost::asio::io_context& io, WorkerPoolOptions options);
  ~WorkerPool();

  void start();
  // SIGTERM to every worker (each hands its job back and exits), SIGKILL to
  // those still alive after `timeout`, then `done`.
  void stop(std::chrono::milliseconds timeout, std::function<void()> done);
  std::vector<pid_t> pids() const;
  int restarts() const { return restarts_; }

 private:
  struct Slot {
    pid_t pid = -1;
    std::chrono::steady_clock::time_point started;
    std::chrono::milliseconds next_delay{0};
    std::unique_ptr<boost::asio::steady_timer> restart_timer;
  };
  void spawn(std::size_t slot);
  void wait_for_children();
  void reap();
  void maybe_done();

  boost::asio::io_context& io_;
  WorkerPoolOptions options_;
  boost::asio::signal_set sigchld_;
  boost::asio::steady_timer kill_timer_;
  std::vector<Slot> slots_;
  bool stopping_ = false;
  int restarts_ = 0;
  std::function<void()> on_stopped_;
};

}  // namespace cellflow::server
