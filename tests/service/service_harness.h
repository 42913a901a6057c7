// Integration-test harness: real cellflow-server and cellflow-worker
// processes on 127.0.0.1 with an ephemeral port and a SQLite file in a
// temporary directory. Executable paths come from CMake (compile definitions).
//
// Authentication is on (--auth token): before the first start the harness
// creates a user token and a worker token with the real
// `cellflow-server token create`, gives the user token to client_ and, via
// CELLFLOW_TOKEN, to the CLI runs of the tests; workers started here dial the
// worker listener (--worker-listen 127.0.0.1:0) with CELLFLOW_WORKER_TOKEN.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "client/rpc_client.h"

extern char** environ;
#include "tests/io/h5_test_util.h"  // run_command, read_text

namespace cellflow::testing {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A child process with stdout and stderr in `log_path`; `env` is added to
// (or replaces entries of) the environment of this process.
class Process {
 public:
  Process(const std::vector<std::string>& argv, const std::string& log_path,
          const std::vector<std::string>& env = {})
      : log_path_(log_path) {
    std::vector<std::string> args = argv;
    std::vector<char*> raw;
    for (auto& a : args) raw.push_back(a.data());
    raw.push_back(nullptr);
    std::vector<std::string> env_strings;
    for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
      const std::string entry = *e;
      bool replaced = false;
      for (const auto& add : env)
        replaced |= add.substr(0, add.find('=') + 1) == entry.substr(0, add.find('=') + 1);
      if (!replaced) env_strings.push_back(entry);
    }
    env_strings.insert(env_strings.end(), env.begin(), env.end());
    std::vector<char*> envp;
    for (auto& e : env_strings) envp.push_back(e.data());
    envp.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, STDOUT_FILENO);
        ::dup2(fd, STDERR_FILENO);
      }
      ::execve(raw[0], raw.data(), envp.data());
      ::_exit(127);
    }
  }
  ~Process() {
    if (running()) {
      ::kill(pid_, SIGKILL);
      wait();
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  bool running() {
    if (exited_) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exited_ = true;
      status_ = status;
      return false;
    }
    return true;
  }
  void signal(int number) { ::kill(pid_, number); }
  // Waits for the exit; returns the raw wait status.
  int wait() {
    if (!exited_) {
      ::waitpid(pid_, &status_, 0);
      exited_ = true;
    }
    return status_;
  }
  // Waits up to `timeout`; true if it exited.
  bool wait_for(std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      if (!running()) return true;
      std::this_thread::sleep_for(10ms);
    }
    return !running();
  }
  std::string log() const {
    std::ifstream in(log_path_);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  }

 private:
  pid_t pid_ = -1;
  std::string log_path_;
  bool exited_ = false;
  int status_ = 0;
};

// Polls `condition` every 20 ms until true or the timeout; returns its last value.
inline bool eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(20ms);
  }
  return condition();
}

class ServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_service_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }

  void TearDown() override {
    if (HasFailure()) {
      if (server_) std::fprintf(stderr, "---- server log ----\n%s\n", server_->log().c_str());
      for (std::size_t i = 0; i < workers_.size(); ++i) {
        std::fprintf(stderr, "---- worker %zu log ----\n%s\n", i, workers_[i]->log().c_str());
      }
    }
    workers_.clear();
    server_.reset();
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // `cellflow-server token create --user USER FLAGS` on this test's database;
  // returns the token (the command's only output).
  std::string create_token(const std::string& user, const std::string& flags = "") {
    int code = 0;
    std::string out = run_command(std::string(CELLFLOW_SERVER_EXE) + " token create --user " + user + " " +
                                      flags + " --data-dir " + (dir_ / "data").string(),
                                  &code);
    EXPECT_EQ(code, 0) << out;
    while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
    EXPECT_EQ(out.size(), 43u) << "a token is 32 bytes in base64url: " << out;
    return out;
  }

  // Options of a client of this server with `token` (and the TLS settings of this test).
  client::ClientOptions client_options(const std::string& token) const {
    client::ClientOptions options = client_base_;
    options.server = address_;
    options.timeout_s = 10;
    options.reconnect_s = 30;
    options.token = token;
    return options;
  }

  // Starts the server on `port` (0: ephemeral) with `workers` local workers.
  void start_server(int workers, std::vector<std::string> extra = {}, int port = 0) {
    const std::string port_file = (dir_ / "port").string();
    const std::string worker_port_file = (dir_ / "worker-port").string();
    fs::remove(port_file);
    fs::remove(worker_port_file);
    if (auth_ && token_.empty()) {
      token_ = create_token("test-user");
      worker_token_ = create_token("test-worker", "--worker");
    }
    // For the CLI runs of the tests (run_command inherits the environment).
    if (auth_) {
      ::setenv("CELLFLOW_TOKEN", token_.c_str(), 1);
    } else {
      ::unsetenv("CELLFLOW_TOKEN");
    }
    std::vector<std::string> argv = {CELLFLOW_SERVER_EXE,
                                     "--listen",
                                     "127.0.0.1:" + std::to_string(port),
                                     "--data-dir",
                                     (dir_ / "data").string(),
                                     "--port-file",
                                     port_file,
                                     "--workers",
                                     std::to_string(workers),
                                     "--worker-path",
                                     CELLFLOW_WORKER_EXE,
                                     "--log-level",
                                     "debug",
                                     "--worker-listen",
                                     "127.0.0.1:0",
                                     "--worker-port-file",
                                     worker_port_file};
    if (!auth_) argv.insert(argv.end(), {"--auth", "none"});
    argv.insert(argv.end(), extra.begin(), extra.end());
    server_ = std::make_unique<Process>(argv, (dir_ / "server.log").string());
    ASSERT_TRUE(eventually([&] { return fs::exists(port_file) && fs::exists(worker_port_file); }, 20s))
        << server_->log();
    std::ifstream in(port_file);
    in >> port_;
    ASSERT_GT(port_, 0);
    std::ifstream worker_in(worker_port_file);
    worker_in >> worker_port_;
    ASSERT_GT(worker_port_, 0);
    address_ = "127.0.0.1:" + std::to_string(port_);
    worker_address_ = "127.0.0.1:" + std::to_string(worker_port_);
    client_ = std::make_unique<client::Client>(client_options(token_));
  }

  // A worker on the worker listener with the worker token (or `env`, e.g.
  // no credential or another one).
  Process* start_worker(std::vector<std::string> extra = {}, std::vector<std::string> env = {"default"}) {
    std::vector<std::string> argv = {CELLFLOW_WORKER_EXE, "--server", worker_address_, "--log-level",
                                     "debug"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    if (env.size() == 1 && env[0] == "default") env = {"CELLFLOW_WORKER_TOKEN=" + worker_token_};
    workers_.push_back(std::make_unique<Process>(
        argv, (dir_ / ("worker" + std::to_string(workers_.size()) + ".log")).string(), env));
    return workers_.back().get();
  }

  v1::Job get(const std::string& id) {
    v1::Job job;
    const grpc::Status status = client_->get(id, &job);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return job;
  }

  bool wait_state(const std::string& id, v1::Job::State state, std::chrono::milliseconds timeout) {
    return eventually([&] { return get(id).state() == state; }, timeout);
  }

  // Cancels running job `running` and waits (2 s at most) for the worker to
  // lease queued job `next`; *moved_on_s is how long that took (also printed).
  void cancel_and_await_next(const std::string& running, const std::string& next, const char* what,
                             double* moved_on_s) {
    const auto cancelled_at = std::chrono::steady_clock::now();
    v1::Job job;
    ASSERT_TRUE(client_->cancel(running, &job).ok());
    EXPECT_EQ(job.state(), v1::Job::CANCELLED);
    ASSERT_TRUE(eventually([&] { return get(next).state() != v1::Job::QUEUED; }, std::chrono::seconds(2)))
        << "worker did not move on";
    *moved_on_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - cancelled_at).count();
    std::printf("%s -> the worker leased the next job after %.3f s\n", what, *moved_on_s);
  }

  std::string submit(const v1::JobSpec& spec, const std::string& request_id = "") {
    v1::SubmitJobRequest request;
    *request.mutable_spec() = spec;
    request.set_request_id(request_id);
    v1::SubmitJobResponse response;
    const grpc::Status status = client_->submit(request, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return response.job().id();
  }

  fs::path dir_;
  std::unique_ptr<Process> server_;
  std::vector<std::unique_ptr<Process>> workers_;
  int port_ = 0;
  int worker_port_ = 0;
  std::string address_;                // the public listener
  std::string worker_address_;         // the worker listener
  bool auth_ = true;                   // false: --auth none (set before start_server)
  std::string token_;                  // the user token of client_ and of CELLFLOW_TOKEN
  std::string worker_token_;           // the worker token of start_worker
  client::ClientOptions client_base_;  // TLS settings of the clients (client_options)
  std::unique_ptr<client::Client> client_;
};

// Collects a job's events on a thread until its terminal state.
class Watcher {
 public:
  Watcher(client::Client& client, std::string job_id) {
    thread_ = std::thread([this, &client, job_id] {
      status_ = client.watch(job_id, 0, [this](const v1::JobEvent& event) {
        std::lock_guard lock(mutex_);
        events_.push_back(event);
        return true;
      });
      done_ = true;
    });
  }
  ~Watcher() { join(); }
  void join() {
    if (thread_.joinable()) thread_.join();
  }
  std::vector<v1::JobEvent> events() {
    std::lock_guard lock(mutex_);
    return events_;
  }
  // Indices of the samples seen: force samples (quasi-static) and deformation samples (flow).
  std::vector<int> sample_indices() {
    std::vector<int> out;
    for (const auto& e : events()) {
      if (e.has_force_sample()) out.push_back(e.force_sample().index());
      if (e.has_deformation_sample()) out.push_back(e.deformation_sample().index());
      if (e.has_suspension_sample()) out.push_back(e.suspension_sample().index());
    }
    return out;
  }
  int max_sample_index() {
    int best = -1;
    for (int i : sample_indices()) best = std::max(best, i);
    return best;
  }
  const grpc::Status& status() const { return status_; }
  bool done() const { return done_; }

 private:
  std::mutex mutex_;
  std::vector<v1::JobEvent> events_;
  grpc::Status status_;
  std::atomic<bool> done_{false};
  std::thread thread_;
};

// A small compression job: a few hundred vertices and few load points, so
// that one run takes well under a second.
inline v1::JobSpec small_compression(int load_points = 5, int vertices = 300) {
  v1::JobSpec spec;
  spec.set_name("small compression");
  auto* c = spec.mutable_compression();
  c->mutable_cell()->set_radius_m(5e-6);
  c->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1000.0);
  c->mutable_cell()->mutable_material()->set_poisson_ratio(0.45);
  c->mutable_cell()->set_target_vertex_count(vertices);
  c->set_max_deformation(0.15);
  c->set_load_points(load_points);
  return spec;
}

}  // namespace cellflow::testing
