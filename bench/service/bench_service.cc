// bench_service: throughput and overhead of the job service on loopback,
// with a real cellflow-server (and worker) process and a SQLite file in a
// temporary directory.
//
//   1. SubmitJob acceptance rate with a small valid spec, 1 and 8 concurrent clients.
//   2. Events per second delivered to 50 concurrent watchers of one job (this
//      program leases the job itself and reports samples as fast as the
//      server acknowledges them).
//   3. Service overhead per job: wall time submit -> SUCCEEDED through the
//      service (one warm local worker) minus run_compression in-process for
//      the same spec (median of several runs).
//   5. A 20-point sweep as one study against 20 separate submits of the same
//      specs (one warm worker, one thread): each wall time from the first
//      submit to the last SUCCEEDED minus the 20 run_compression calls
//      in-process; the study's overhead should be at most the 20 submits'.
//   4. Latency of one GetJob call (sequential, one client), whose difference
//      between the modes is the cost of authentication (and TLS) per call.
//
// 1, 2 and 4 run in three modes: "none" (--auth none, plaintext), "token"
// (bearer tokens checked on every call, plaintext loopback) and "token+tls"
// (tokens over TLS with a CA and a server certificate made here by openssl).
//
//   bench_service [--submits N] [--events N] [--watchers N] [--overhead-runs N] [--get-calls N]
//                 [--sweep-runs N] [--sweep-points N] [--sweep-load-points N] [--only-sweep 1]
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "cellflow/v1/worker.grpc.pb.h"
#include "client/rpc_client.h"
#include "jobs/job_spec.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "rpc/rpc.h"
#include "server/auth.h"
#include "server/store.h"

namespace {

using namespace cellflow;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// How the server is secured in one run of the benchmark.
struct Mode {
  std::string name;          // none, token, token+tls
  bool tokens = false;       // --auth token (else --auth none)
  bool tls = false;          // --tls-cert/--tls-key from cert_dir
  fs::path cert_dir;         // ca.pem, server.pem, server.key
  std::string user_token;    // set by Server
  std::string worker_token;  // set by Server
  std::string ca_pem;
};

Mode make_mode(const std::string& name, bool tokens = false, bool tls = false,
               const fs::path& cert_dir = {}) {
  Mode mode;
  mode.name = name;
  mode.tokens = tokens;
  mode.tls = tls;
  mode.cert_dir = cert_dir;
  return mode;
}

std::string command_output(const std::string& command) {
  std::string out;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buffer[256];
  std::size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) out.append(buffer, n);
  ::pclose(pipe);
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

// A CA and a server certificate for localhost / 127.0.0.1 (EC P-256).
bool make_certificates(const fs::path& dir) {
  fs::create_directories(dir);
  const std::string d = dir.string();
  const std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
  std::ofstream(dir / "san.ext") << "subjectAltName=DNS:localhost,IP:127.0.0.1\nbasicConstraints=CA:FALSE\n";
  for (const std::string& command :
       {"openssl req -x509" + ec + " -days 2 -subj /CN=bench-ca -keyout " + d + "/ca.key -out " + d +
            "/ca.pem",
        "openssl req" + ec + " -subj /CN=localhost -keyout " + d + "/server.key -out " + d + "/server.csr",
        "openssl x509 -req -in " + d + "/server.csr -CA " + d + "/ca.pem -CAkey " + d +
            "/ca.key -CAcreateserial -days 2 -extfile " + d + "/san.ext -out " + d + "/server.pem"}) {
    if (std::system((command + " >/dev/null 2>&1").c_str()) != 0) {
      std::printf("cannot make certificates: %s\n", command.c_str());
      return false;
    }
  }
  return true;
}

struct Server {
  pid_t pid = -1;
  std::string address;
  std::string worker_address;
  Server(const fs::path& dir, int workers, std::vector<std::string> extra = {}, Mode* mode = nullptr) {
    const std::string port_file = (dir / "port").string();
    const std::string worker_port_file = (dir / "worker-port").string();
    const std::string data = (dir / "data").string();
    if (mode && mode->tokens) {
      const std::string create = std::string(CELLFLOW_SERVER_EXE) + " token create --data-dir " + data;
      mode->user_token = command_output(create + " --user bench");
      mode->worker_token = command_output(create + " --worker --user bench-worker");
    }
    if (!mode || !mode->tokens) extra.insert(extra.end(), {"--auth", "none"});
    if (mode && mode->tls) {
      const std::string certs = mode->cert_dir.string();
      extra.insert(extra.end(), {"--tls-cert", certs + "/server.pem", "--tls-key", certs + "/server.key"});
      std::ifstream in(mode->cert_dir / "ca.pem");
      mode->ca_pem.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    std::vector<std::string> args = {CELLFLOW_SERVER_EXE,
                                     "--worker-listen",
                                     "127.0.0.1:0",
                                     "--worker-port-file",
                                     worker_port_file,
                                     "--listen",
                                     "127.0.0.1:0",
                                     "--data-dir",
                                     (dir / "data").string(),
                                     "--port-file",
                                     port_file,
                                     "--workers",
                                     std::to_string(workers),
                                     "--worker-path",
                                     CELLFLOW_WORKER_EXE,
                                     "--log-level",
                                     "warn"};
    args.insert(args.end(), extra.begin(), extra.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid = ::fork();
    if (pid == 0) {
      const int fd = ::open((dir / "server.log").c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      ::dup2(fd, STDOUT_FILENO);
      ::dup2(fd, STDERR_FILENO);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    for (int i = 0; i < 1000 && !(fs::exists(port_file) && fs::exists(worker_port_file)); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    int port = 0, worker_port = 0;
    std::ifstream(port_file) >> port;
    std::ifstream(worker_port_file) >> worker_port;
    address = "127.0.0.1:" + std::to_string(port);
    worker_address = "127.0.0.1:" + std::to_string(worker_port);
  }
  ~Server() {
    ::kill(pid, SIGTERM);
    ::waitpid(pid, nullptr, 0);
  }
};

v1::JobSpec small_compression(int load_points, int vertices) {
  v1::JobSpec spec;
  auto* c = spec.mutable_compression();
  c->mutable_cell()->set_radius_m(5e-6);
  c->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1000.0);
  c->mutable_cell()->mutable_material()->set_poisson_ratio(0.45);
  c->mutable_cell()->set_target_vertex_count(vertices);
  c->set_max_deformation(0.15);
  c->set_load_points(load_points);
  return spec;
}

client::ClientOptions client_options(const std::string& address, const Mode& mode) {
  client::ClientOptions options;
  options.server = address;
  options.timeout_s = 30;
  options.token = mode.user_token;
  options.tls = mode.tls;
  options.tls_ca_pem = mode.ca_pem;
  return options;
}

void bench_submit(const fs::path& dir, int total, int clients, Mode mode) {
  const fs::path sub = dir / ("submit" + std::to_string(clients) + "-" + mode.name);
  fs::create_directories(sub);
  Server server(sub, 0, {}, &mode);
  const v1::JobSpec spec = small_compression(5, 300);
  std::atomic<int> next{0}, errors{0};
  std::vector<std::thread> threads;
  const auto start = Clock::now();
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&] {
      client::Client client(client_options(server.address, mode));  // one channel per client
      while (next.fetch_add(1) < total) {
        v1::SubmitJobRequest request;
        *request.mutable_spec() = spec;
        v1::SubmitJobResponse response;
        if (!client.submit(request, &response).ok()) ++errors;
      }
    });
  }
  for (auto& t : threads) t.join();
  const double elapsed = seconds_since(start);
  std::printf("[%s] SubmitJob, %d client(s): %d jobs in %.3f s = %.0f jobs/s (%d errors)\n",
              mode.name.c_str(), clients, total, elapsed, total / elapsed, errors.load());
}

// Sequential GetJob calls of one client: the latency of a small unary call.
void bench_get_latency(const fs::path& dir, int calls, Mode mode) {
  const fs::path sub = dir / ("get-" + mode.name);
  fs::create_directories(sub);
  Server server(sub, 0, {}, &mode);
  client::Client client(client_options(server.address, mode));
  v1::SubmitJobRequest submit;
  *submit.mutable_spec() = small_compression(5, 300);
  v1::SubmitJobResponse submitted;
  if (!client.submit(submit, &submitted).ok()) {
    std::printf("[%s] GetJob: submit failed\n", mode.name.c_str());
    return;
  }
  v1::Job job;
  for (int i = 0; i < 50; ++i) client.get(submitted.job().id(), &job);  // warm the connection
  // The median of 5 rounds: the machine is shared, single rounds are noisy.
  int errors = 0;
  std::vector<double> per_call;
  for (int round = 0; round < 5; ++round) {
    const auto start = Clock::now();
    for (int i = 0; i < calls; ++i) errors += !client.get(submitted.job().id(), &job).ok();
    per_call.push_back(1e6 * seconds_since(start) / calls);
  }
  std::sort(per_call.begin(), per_call.end());
  std::printf(
      "[%s] GetJob, 1 client, sequential: median of 5 x %d calls = %.1f us/call (min %.1f; %d errors)\n",
      mode.name.c_str(), calls, per_call[2], per_call[0], errors);
}

// The server's own cost of checking a token, in process: SHA-256 of the
// token and the lookup of its hash in SQLite (server/auth.h), per call.
void bench_token_check(const fs::path& dir, int calls) {
  const fs::path sub = dir / "check";
  fs::create_directories(sub);
  server::StoreOptions options;
  options.path = (sub / "cellflow.sqlite").string();
  auto store = server::Store::open(options);
  auto token = server::generate_token();
  if (!store.ok() || !token.ok()) return;
  for (int i = 0; i < 100; ++i) {  // a table with some tokens in it
    auto other = server::generate_token();
    (void)(*store)->add_token("user" + std::to_string(i), "user", server::hash_token(*other), 0);
  }
  (void)(*store)->add_token("bench", "user", server::hash_token(*token), 0);
  server::Authenticator authenticator((*store).get(), server::AuthMode::kToken);
  const std::string header = "Bearer " + *token;
  int refused = 0;
  const auto start = Clock::now();
  for (int i = 0; i < calls; ++i) {
    refused += !authenticator.check(server::Authenticator::Api::kPublic, header).status.ok();
  }
  const double elapsed = seconds_since(start);
  const auto hash_start = Clock::now();
  std::size_t sink = 0;
  for (int i = 0; i < calls; ++i) sink += server::hash_token(header).size();
  const double hashing = seconds_since(hash_start);
  std::printf(
      "Token check in the server (SHA-256 + SQLite lookup, %d calls): %.2f us/call, of which SHA-256 "
      "%.2f us (%d refused, %zu)\n",
      calls, 1e6 * elapsed / calls, 1e6 * hashing / calls, refused, sink % 2);
}

void bench_watchers(const fs::path& dir, int events, int watchers, Mode mode) {
  const fs::path sub = dir / ("watch-" + mode.name);
  fs::create_directories(sub);
  Server server(sub, 0, {}, &mode);
  client::Client client(client_options(server.address, mode));
  v1::SubmitJobRequest submit;
  *submit.mutable_spec() = small_compression(events, 300);
  v1::SubmitJobResponse submitted;
  if (!client.submit(submit, &submitted).ok()) return;
  const std::string job_id = submitted.job().id();

  // This program is the job's worker.
  rpc::ChannelOptions channel;
  channel.bearer_token = mode.worker_token;
  channel.tls = mode.tls;
  channel.tls_ca_pem = mode.ca_pem;
  auto worker = v1::WorkerService::NewStub(rpc::make_channel(server.worker_address, channel));
  v1::LeaseJobRequest lease_request;
  lease_request.set_worker_id("bench");
  lease_request.set_wait_s(5);
  v1::LeaseJobResponse leased;
  {
    grpc::ClientContext context;
    if (!worker->LeaseJob(&context, lease_request, &leased).ok() || !leased.found()) return;
  }

  std::atomic<int> ready{0};
  std::vector<std::atomic<int>> received(watchers);
  std::vector<double> done_at(watchers, 0.0);
  std::vector<std::thread> threads;
  Clock::time_point start;
  std::mutex start_mutex;
  for (int w = 0; w < watchers; ++w) {
    threads.emplace_back([&, w] {
      client::Client c(client_options(server.address, mode));
      bool counted = false;
      c.watch(job_id, 0, [&](const v1::JobEvent& event) {
        if (!counted) {
          counted = true;
          ++ready;
        }
        if (event.has_force_sample()) {
          if (++received[w] == events) {
            std::lock_guard lock(start_mutex);
            done_at[w] = seconds_since(start);
          }
        }
        return !(event.has_state_change() && event.state_change().state() == v1::Job::CANCELLED);
      });
    });
  }
  while (ready.load() < watchers) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  {
    std::lock_guard lock(start_mutex);
    start = Clock::now();
  }
  grpc::ClientContext context;
  auto stream = worker->ReportJob(&context);
  std::thread acks([&] {
    v1::ReportAck ack;
    while (stream->Read(&ack)) {
    }
  });
  for (int i = 0; i < events; ++i) {
    v1::WorkerReport report;
    *report.mutable_lease() = leased.lease();
    report.set_report_id(i + 1);
    report.mutable_force_sample()->set_index(i);
    report.mutable_force_sample()->set_force_n(1e-9 * i);
    report.mutable_force_sample()->set_deformation(0.001 * i);
    stream->Write(report);
  }
  stream->WritesDone();
  acks.join();
  (void)stream->Finish();
  const double reported = seconds_since(start);
  while (true) {
    int complete = 0;
    for (int w = 0; w < watchers; ++w) complete += received[w].load() >= events;
    if (complete == watchers) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const double last = *std::max_element(done_at.begin(), done_at.end());
  v1::Job cancelled;
  client.cancel(job_id, &cancelled);
  for (auto& t : threads) t.join();
  std::printf(
      "[%s] WatchJob fan-out: %d samples reported in %.3f s (%.0f events/s stored); %d watchers received all "
      "in %.3f s = %.0f events/s delivered\n",
      mode.name.c_str(), events, reported, events / reported, watchers, last,
      static_cast<double>(events) * watchers / last);
}

void bench_overhead(const fs::path& dir, int runs) {
  const fs::path sub = dir / "overhead";
  fs::create_directories(sub);
  // One OpenMP thread on both sides: the figure is the service's overhead,
  // not OpenMP contention on a busy machine.
  Mode mode = make_mode("none");
  Server server(sub, 1, {"--worker-arg=--threads=1"}, &mode);
  client::Client client(client_options(server.address, mode));
  const v1::JobSpec spec = small_compression(5, 300);
  auto params = jobs::to_params(spec.compression());
  if (!params.ok()) {
    std::printf("overhead: %s\n", params.status().to_string().c_str());
    return;
  }
  params->numerics.threads = 1;
  std::vector<double> library, service;
  // One job first, so the worker process is up and its first allocation done.
  for (int r = -1; r < runs; ++r) {
    auto t0 = Clock::now();
    const auto result = scenes::run_compression(*params);
    const double in_process = seconds_since(t0);
    if (!result.status.ok()) {
      std::printf("overhead: %s\n", result.status.to_string().c_str());
      return;
    }
    t0 = Clock::now();
    v1::SubmitJobRequest request;
    *request.mutable_spec() = spec;
    v1::SubmitJobResponse response;
    if (!client.submit(request, &response).ok()) return;
    v1::Job::State final_state = v1::Job::STATE_UNSPECIFIED;
    client.watch(response.job().id(), 0, [&](const v1::JobEvent& e) {
      if (e.has_state_change()) final_state = e.state_change().state();
      return true;
    });
    const double through_service = seconds_since(t0);
    if (final_state != v1::Job::SUCCEEDED) {
      std::printf("overhead: job ended %s\n", v1::Job::State_Name(final_state).c_str());
      return;
    }
    if (r >= 0) {
      library.push_back(in_process);
      service.push_back(through_service);
    }
  }
  std::vector<double> overhead(runs);
  for (int r = 0; r < runs; ++r) overhead[r] = service[r] - library[r];
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::printf(
      "Overhead per job (compression, 300 vertices, 5 load points, 1 thread; median of %d): run_compression "
      "%.1f ms, through the service %.1f ms, overhead %.1f ms (target < 100 ms)\n",
      runs, 1e3 * median(library), 1e3 * median(service), 1e3 * median(overhead));
}

// Waits for `job_id` to end; its final state.
v1::Job::State wait_terminal(client::Client& client, const std::string& job_id) {
  v1::Job::State final_state = v1::Job::STATE_UNSPECIFIED;
  client.watch(job_id, 0, [&](const v1::JobEvent& e) {
    if (e.has_state_change()) final_state = e.state_change().state();
    return true;
  });
  return final_state;
}

// The service alone: this program is the worker (lease, `samples` force
// samples, a stand-in HDF5 upload, finish), so the figure holds no physics:
// 20 separate jobs against one study of 20 points, wall time submit -> all done.
void bench_sweep_service_only(const fs::path& dir, int runs, int points, int samples) {
  const fs::path sub = dir / "sweep-service";
  fs::create_directories(sub);
  Mode mode = make_mode("none");
  Server server(sub, 0, {}, &mode);
  client::Client client(client_options(server.address, mode));
  auto worker = v1::WorkerService::NewStub(rpc::make_channel(server.worker_address, rpc::ChannelOptions()));
  const std::string stand_in = std::string("\x89HDF\r\n\x1a\n", 8) + std::string(4096, 'x');
  // Runs `count` jobs from the queue to SUCCEEDED.
  auto work = [&](int count) -> bool {
    for (int done = 0; done < count; ++done) {
      v1::LeaseJobRequest lease_request;
      lease_request.set_worker_id("bench");
      lease_request.set_wait_s(5);
      v1::LeaseJobResponse leased;
      {
        grpc::ClientContext context;
        if (!worker->LeaseJob(&context, lease_request, &leased).ok() || !leased.found()) return false;
      }
      {
        grpc::ClientContext context;
        auto stream = worker->ReportJob(&context);
        for (int i = 0; i < samples; ++i) {
          v1::WorkerReport report;
          *report.mutable_lease() = leased.lease();
          report.set_report_id(i + 1);
          report.mutable_force_sample()->set_index(i);
          report.mutable_force_sample()->set_force_n(1e-9 * i);
          stream->Write(report);
          v1::ReportAck ack;
          if (!stream->Read(&ack)) return false;
        }
        stream->WritesDone();
        (void)stream->Finish();
      }
      {
        grpc::ClientContext context;
        v1::UploadResultResponse uploaded;
        auto stream = worker->UploadResult(&context, &uploaded);
        v1::UploadChunk chunk;
        *chunk.mutable_lease() = leased.lease();
        chunk.set_data(stand_in);
        stream->Write(chunk);
        stream->WritesDone();
        if (!stream->Finish().ok()) return false;
      }
      grpc::ClientContext context;
      v1::FinishJobRequest finish;
      *finish.mutable_lease() = leased.lease();
      v1::FinishJobResponse finished;
      if (!worker->FinishJob(&context, finish, &finished).ok()) return false;
    }
    return true;
  };
  const v1::JobSpec base = small_compression(samples, 300);
  v1::SubmitJobRequest study_request;
  v1::StudySpec* study = study_request.mutable_spec()->mutable_study();
  *study->mutable_base() = base;
  v1::StudyAxis* axis = study->add_axes();
  axis->set_path("compression.cell.material.youngsModulusPa");
  std::vector<v1::JobSpec> specs;
  for (int i = 0; i < points; ++i) {
    axis->add_values(std::to_string(500.0 + 50.0 * i));
    specs.push_back(base);
    specs.back().mutable_compression()->mutable_cell()->mutable_material()->set_youngs_modulus_pa(500.0 +
                                                                                                  50.0 * i);
  }
  std::vector<double> separate, swept;
  for (int r = -1; r < runs; ++r) {
    double twenty = 0, one = 0;
    auto run_separate = [&]() -> bool {
      const auto start = Clock::now();
      std::vector<std::string> ids;
      for (const v1::JobSpec& spec : specs) {
        v1::SubmitJobRequest request;
        *request.mutable_spec() = spec;
        v1::SubmitJobResponse response;
        if (!client.submit(request, &response).ok()) return false;
        ids.push_back(response.job().id());
      }
      if (!work(points)) return false;
      for (const std::string& id : ids)
        if (wait_terminal(client, id) != v1::Job::SUCCEEDED) return false;
      twenty = seconds_since(start);
      return true;
    };
    auto run_study = [&]() -> bool {
      const auto start = Clock::now();
      v1::SubmitJobResponse response;
      if (!client.submit(study_request, &response).ok()) return false;
      if (!work(points)) return false;
      if (wait_terminal(client, response.job().id()) != v1::Job::SUCCEEDED) return false;
      one = seconds_since(start);
      return true;
    };
    const bool ok = r % 2 == 0 ? run_separate() && run_study() : run_study() && run_separate();
    if (!ok) {
      std::printf("sweep (service only): a job or the study did not succeed\n");
      return;
    }
    if (r >= 0) {
      separate.push_back(twenty);
      swept.push_back(one);
    }
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::printf(
      "Sweep of %d points, service only (this program the worker: %d samples, a 4 KiB result per job; median "
      "of "
      "%d): %d separate submits %.1f ms (%.2f ms a job), one study %.1f ms (%.2f ms a child; target <= the "
      "separate submits)\n",
      points, samples, runs, points, 1e3 * median(separate), 1e3 * median(separate) / points,
      1e3 * median(swept), 1e3 * median(swept) / points);

  // The largest study the server takes: expansion, validation of every
  // child and the one insert transaction, in one SubmitJob call.
  v1::SubmitJobRequest largest;
  v1::StudySpec* big = largest.mutable_spec()->mutable_study();
  *big->mutable_base() = base;
  v1::StudyAxis* e_axis = big->add_axes();
  e_axis->set_path("compression.cell.material.youngsModulusPa");
  for (int i = 0; i < 100; ++i) e_axis->add_values(std::to_string(100 + 10 * i));
  v1::StudyAxis* d_axis = big->add_axes();
  d_axis->set_path("compression.maxDeformation");
  for (int i = 0; i < 100; ++i) d_axis->add_values(std::to_string(0.05 + 0.005 * i));
  const auto start = Clock::now();
  v1::SubmitJobResponse response;
  const grpc::Status status = client.submit(largest, &response);
  const double took = seconds_since(start);
  v1::Job cancelled;
  const auto cancel_start = Clock::now();
  if (status.ok()) client.cancel(response.job().id(), &cancelled);
  const double cancel_took = seconds_since(cancel_start);
  std::printf("A study of %d points (the limit): SubmitJob %.2f s (%s), CancelJob of it %.2f s\n",
              response.job().child_count(), took, status.ok() ? "queued" : status.error_message().c_str(),
              cancel_took);
}

void bench_sweep_overhead(const fs::path& dir, int runs, int points, int load_points) {
  const fs::path sub = dir / "sweep";
  fs::create_directories(sub);
  Mode mode = make_mode("none");
  Server server(sub, 1, {"--worker-arg=--threads=1"}, &mode);
  client::Client client(client_options(server.address, mode));
  // The points: E = 500, 550, ... Pa (the cost of a child does not depend on E).
  const v1::JobSpec base = small_compression(load_points, 300);
  std::vector<v1::JobSpec> specs;
  v1::SubmitJobRequest study_request;
  v1::StudySpec* study = study_request.mutable_spec()->mutable_study();
  *study->mutable_base() = base;
  v1::StudyAxis* axis = study->add_axes();
  axis->set_path("compression.cell.material.youngsModulusPa");
  for (int i = 0; i < points; ++i) {
    const double e = 500.0 + 50.0 * i;
    axis->add_values(std::to_string(e));
    specs.push_back(base);
    specs.back().mutable_compression()->mutable_cell()->mutable_material()->set_youngs_modulus_pa(e);
  }
  std::vector<double> library, separate, swept, separate_submit, study_submit;
  for (int r = -1; r < runs; ++r) {  // run -1 warms the worker
    auto t0 = Clock::now();
    for (const v1::JobSpec& spec : specs) {
      auto params = jobs::to_params(spec.compression());
      if (!params.ok()) return;
      params->numerics.threads = 1;
      if (!scenes::run_compression(*params).status.ok()) return;
    }
    const double in_process = seconds_since(t0);

    double twenty = 0, twenty_submit = 0, one_study = 0, one_submit = 0;
    auto run_separate = [&]() -> bool {
      const auto start = Clock::now();
      std::vector<std::string> ids;
      for (const v1::JobSpec& spec : specs) {
        v1::SubmitJobRequest request;
        *request.mutable_spec() = spec;
        v1::SubmitJobResponse response;
        if (!client.submit(request, &response).ok()) return false;
        ids.push_back(response.job().id());
      }
      twenty_submit = seconds_since(start);
      for (const std::string& id : ids) {
        if (wait_terminal(client, id) != v1::Job::SUCCEEDED) return false;
      }
      twenty = seconds_since(start);
      return true;
    };
    auto run_study = [&]() -> bool {
      const auto start = Clock::now();
      v1::SubmitJobResponse response;
      if (!client.submit(study_request, &response).ok()) return false;
      one_submit = seconds_since(start);
      if (wait_terminal(client, response.job().id()) != v1::Job::SUCCEEDED) return false;
      one_study = seconds_since(start);
      return true;
    };
    // Alternate which goes first: the machine's load drifts between runs.
    const bool ok = r % 2 == 0 ? run_separate() && run_study() : run_study() && run_separate();
    if (!ok) {
      std::printf("sweep: a job or the study did not succeed\n");
      return;
    }
    if (r >= 0) {
      library.push_back(in_process);
      separate.push_back(twenty);
      swept.push_back(one_study);
      separate_submit.push_back(twenty_submit);
      study_submit.push_back(one_submit);
      std::printf(
          "  sweep run %d: in-process %.3f s; %d submits %.3f s (submit calls %.1f ms); one study %.3f s "
          "(submit call %.1f ms)\n",
          r, in_process, points, twenty, 1e3 * twenty_submit, one_study, 1e3 * one_submit);
    }
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::vector<double> separate_overhead(runs), study_overhead(runs), paired(runs);
  for (int r = 0; r < runs; ++r) {
    separate_overhead[r] = separate[r] - library[r];
    study_overhead[r] = swept[r] - library[r];
    paired[r] = swept[r] - separate[r];
  }
  std::printf(
      "Sweep of %d points (compression, 300 vertices, %d load points, 1 worker, 1 thread; median of %d): "
      "in-process %.1f ms; %d separate submits %.1f ms (overhead %.1f ms, submit calls %.1f ms); one study "
      "%.1f ms (overhead %.1f ms, submit call %.1f ms); study minus separate, paired: %.1f ms (target <= "
      "0)\n",
      points, load_points, runs, 1e3 * median(library), points, 1e3 * median(separate),
      1e3 * median(separate_overhead), 1e3 * median(separate_submit), 1e3 * median(swept),
      1e3 * median(study_overhead), 1e3 * median(study_submit), 1e3 * median(paired));
}

}  // namespace

int main(int argc, char** argv) {
  int submits = 2000, events = 2000, watchers = 50, overhead_runs = 7, get_calls = 2000;
  int sweep_runs = 7, sweep_points = 20, sweep_load_points = 5, only_sweep = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    const int value = std::atoi(argv[i + 1]);
    if (flag == "--submits") submits = value;
    if (flag == "--events") events = value;
    if (flag == "--watchers") watchers = value;
    if (flag == "--overhead-runs") overhead_runs = value;
    if (flag == "--get-calls") get_calls = value;
    if (flag == "--sweep-runs") sweep_runs = value;
    if (flag == "--sweep-points") sweep_points = value;
    if (flag == "--only-sweep") only_sweep = value;
    if (flag == "--sweep-load-points") sweep_load_points = value;
  }
  const fs::path dir = fs::temp_directory_path() / ("cellflow_bench_service_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  if (only_sweep != 0) {
    bench_sweep_service_only(dir, sweep_runs, sweep_points, sweep_load_points);
    bench_sweep_overhead(dir, sweep_runs, sweep_points, sweep_load_points);
    fs::remove_all(dir);
    return 0;
  }
  std::vector<Mode> modes = {make_mode("none"), make_mode("token", true)};
  if (make_certificates(dir / "certs")) modes.push_back(make_mode("token+tls", true, true, dir / "certs"));
  for (const Mode& mode : modes) {
    bench_submit(dir, submits, 1, mode);
    bench_submit(dir, submits, 8, mode);
    bench_watchers(dir, events, watchers, mode);
    bench_get_latency(dir, get_calls, mode);
  }
  bench_token_check(dir, 20000);
  bench_overhead(dir, overhead_runs);
  bench_sweep_service_only(dir, sweep_runs, sweep_points, sweep_load_points);
  bench_sweep_overhead(dir, sweep_runs, sweep_points, sweep_load_points);
  fs::remove_all(dir);
  return 0;
}
