// cellflow-server: see server/server.h and deploy/README.md.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "physics/core/passive_threads.h"
#include "server/server.h"

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);  // idle threads sleep: the machine is shared
  cellflow::server::ServerOptions options;
  std::string log_level = "info";
  CLI::App app{"cellflow-server: the cellflow job service (gRPC API, SQLite queue, local worker pool)"};
  app.add_option("--listen", options.listen, "address to listen on, host:port (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--data-dir", options.data_dir, "directory of the database and the result files")
      ->capture_default_str();
  app.add_option("--port-file", options.port_file, "write the port listened on to this file");
  app.add_option("--workers", options.workers, "local cellflow-worker processes to run and supervise")
      ->capture_default_str()
      ->check(CLI::Range(0, 1024));
  app.add_option("--worker-path", options.worker_path,
                 "cellflow-worker executable (default: beside this binary)");
  app.add_option("--worker-arg", options.worker_args, "extra argument for local workers (repeatable)")
      ->allow_extra_args(false);
  app.add_option("--lease-ttl-s", options.lease_ttl_s,
                 "a job whose worker stops reporting for this long is requeued")
      ->capture_default_str()
      ->check(CLI::Range(0.2, 3600.0));
  app.add_option("--heartbeat-interval-s", options.heartbeat_interval_s,
                 "how often workers heartbeat (bounds how fast a cancel reaches them)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 60.0));
  app.add_option("--max-attempts", options.max_attempts, "expired leases before a job FAILS")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--memory-limit-bytes", options.memory_limit_bytes,
                 "refuse jobs whose memory estimate exceeds this (-1: 80 % of RAM, 0: no limit)")
      ->capture_default_str();
  app.add_option("--grace-s", options.grace_s, "on SIGTERM, how long running jobs may finish")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_flag("--sqlite-synchronous-full", options.sqlite_synchronous_full,
               "fsync every commit (survives power loss; default survives process crashes)");
  app.add_option("--max-mesh-bytes", options.max_mesh_bytes, "largest mesh UploadMesh accepts")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1} << 40));
  app.add_option("--max-run-time-s", options.max_run_time_s,
                 "an attempt running longer loses its lease, heartbeats or not (0: no limit)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::from_str(log_level));
  return cellflow::server::run_server(options);
}
