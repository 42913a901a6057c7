// cellflow-worker: see worker/worker.h and deploy/README.md.
#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <thread>

#include "physics/core/passive_threads.h"
#include "worker/worker.h"

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  cellflow::worker::WorkerOptions options;
  if (const char* env = std::getenv("CELLFLOW_SERVER")) options.server_address = env;
  std::string log_level = "info";
  CLI::App app{"cellflow-worker: runs cellflow jobs leased from a cellflow-server"};
  app.add_option("--server", options.server_address,
                 "the server's worker listener, host:port or unix:PATH (env CELLFLOW_SERVER)")
      ->capture_default_str();
  app.add_option("--name", options.name, "worker name; the worker id is name@host:pid")
      ->capture_default_str();
  app.add_option("--scratch-dir", options.scratch_dir, "where results are written before upload");
  app.add_option("--max-jobs", options.max_jobs, "exit after this many jobs (0: no limit)")
      ->capture_default_str();
  app.add_option("--idle-exit-s,--exit-when-idle-s", options.idle_exit_s,
                 "exit after this long without a job (0: never; Slurm workers end so)")
      ->capture_default_str();
  app.add_option("--threads", options.threads, "OpenMP threads for the physics (0: default)")
      ->capture_default_str();
  app.add_option("--debug-delay-per-point-ms", options.debug_delay_per_point_ms,
                 "testing aid: pause after each load point")
      ->capture_default_str();
  app.add_option("--library-dir", options.library_dir,
                 "fit jobs: the curve library's cache directory (default $CELLFLOW_LIBRARY_DIR, "
                 "$XDG_CACHE_HOME/cellflow/curves or ~/.cache/cellflow/curves)");
  app.add_option("--checkpoint-interval-s", options.checkpoint_interval_s,
                 "flow jobs: upload a checkpoint after this much wall time (at the next sample; 0: never); "
                 "a re-leased job resumes from its last checkpoint")
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  app.add_flag("--keep-results", options.keep_results, "keep the local copy of uploaded results");
  std::string token_file, tls_ca, tls_cert, tls_key;
  app.add_option("--token-file", token_file,
                 "file holding the worker token, mode 0600 (default: env CELLFLOW_WORKER_TOKEN)");
  app.add_option("--tls-ca", tls_ca,
                 "CA certificate (PEM) of the server's certificate: use TLS (env CELLFLOW_TLS_CA)");
  app.add_option("--tls-cert", tls_cert, "client certificate (PEM) for mTLS (env CELLFLOW_TLS_CERT)");
  app.add_option("--tls-key", tls_key, "client key (PEM) for mTLS (env CELLFLOW_TLS_KEY)");
  app.add_option("--tls-server-name", options.channel.tls_server_name,
                 "name to check the server's certificate against (default: the host of --server)");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::from_str(log_level));

  // The credential never travels on the command line (ps shows it): a file
  // of mode 0600 or the environment.
  auto env = [](const char* name) -> std::string {
    const char* value = std::getenv(name);
    return value ? value : "";
  };
  if (!token_file.empty()) {
    if (auto s = cellflow::rpc::read_secret_file(token_file, &options.channel.bearer_token); !s.ok()) {
      spdlog::error("{}", s.message());
      return 1;
    }
  } else {
    options.channel.bearer_token = env("CELLFLOW_WORKER_TOKEN");
  }
  const bool tls_flags = !tls_ca.empty() || !tls_cert.empty();
  if (auto s = cellflow::rpc::load_tls_files(tls_flags ? tls_ca : env("CELLFLOW_TLS_CA"),
                                             tls_flags ? tls_cert : env("CELLFLOW_TLS_CERT"),
                                             tls_flags ? tls_key : env("CELLFLOW_TLS_KEY"), &options.channel);
      !s.ok()) {
    spdlog::error("{}", s.message());
    return 1;
  }

  // SIGTERM/SIGINT: stop the running job, hand it back, exit 0. The signals
  // are blocked in every thread and taken by sigwait in one.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  cellflow::worker::Worker worker(options,
                                  cellflow::worker::Worker::connect(options.server_address, options.channel));
  std::thread([&worker, signals] {
    int received = 0;
    sigwait(&signals, &received);
    spdlog::info("signal {}: stopping", received);
    worker.stop();
  }).detach();
  return worker.run();
}
