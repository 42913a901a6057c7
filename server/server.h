// cellflow-server: the gRPC services over the SQLite queue, the lease reaper,
// graceful shutdown and the local worker pool, all driven by one Boost.Asio
// io_context on the main thread.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "server/slurm_executor.h"

namespace cellflow::server {

struct ServerOptions {
  std::string listen = "127.0.0.1:50051";  // host:port; port 0 picks a free port
  std::string data_dir = "cellflow-data";  // cellflow.sqlite and results/
  std::string port_file;                   // if set, the chosen port is written here
  // The worker API (cellflow.v1.WorkerService) listens here only, never on
  // `listen`; host:port (port 0: any free port) or unix:PATH.
  std::string worker_listen = "127.0.0.1:50052";
  std::string worker_port_file;  // if set, the worker listener's port is written here
  std::string auth = "token";    // "token": bearer tokens on every call; "none": loopback only
  std::string tls_cert;          // PEM certificate chain of both listeners: TLS on
  std::string tls_key;           // its private key
  std::string tls_client_ca;     // if set, clients and workers must present a certificate it signed (mTLS)
  bool insecure_listen = false;  // allow a non-loopback listener without TLS
  int workers = 0;               // local cellflow-worker processes
  std::string worker_path;       // default: cellflow-worker beside this binary
  std::vector<std::string> worker_args;  // extra arguments for local workers
  double lease_ttl_s = 10.0;
  double heartbeat_interval_s = 0.25;
  int max_attempts = 3;
  std::int64_t memory_limit_bytes = -1;  // -1: 80 % of physical memory; 0: no limit
  double grace_s = 30.0;                 // how long running jobs may finish on SIGTERM
  bool sqlite_synchronous_full = false;
  std::int64_t max_mesh_bytes = 64LL << 20;  // UploadMesh size limit
  double max_run_time_s = 86400.0;           // an attempt leased longer ago loses its lease; 0: no limit
  // "local": only the --workers pool; "slurm": also submits workers with
  // sbatch when jobs wait and no worker is free (server/slurm_executor.h).
  std::string executor = "local";
  SlurmExecutorOptions slurm;        // sbatch/squeue, cap, partition, sbatch_args, timing
  SlurmWorkerSettings slurm_worker;  // the command line of the workers it submits
  std::int64_t max_checkpoint_bytes = 0;     // UploadCheckpoint size limit; 0: the result upload's limit
};

// Runs until SIGINT/SIGTERM; returns the process exit code (0 after a clean
// shutdown).
int run_server(const ServerOptions& options);

}  // namespace cellflow::server
