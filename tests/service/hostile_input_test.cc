// Hostile input through the real service on loopback (issue 13): specs that
// name files of the server's machine, forged worker calls, a second server
// on the same data directory, a server crash with a job running, worker
// scratch directories. Every case is a regression test of an outside
// tester's finding.
#include <grpcpp/grpcpp.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <cmath>
#include <fstream>

#include "cellflow/v1/worker.grpc.pb.h"
#include "jobs/scene.h"
#include "physics/mesh/sphere_mesh.h"
#include "rpc/rpc.h"
#include "server/store.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

// A worker-API stub with the worker credential: the forger below is a
// compromised worker, the strongest caller the worker listener admits.
std::unique_ptr<v1::WorkerService::Stub> worker_stub(const std::string& address, const std::string& token) {
  rpc::ChannelOptions channel;
  channel.bearer_token = token;
  return v1::WorkerService::NewStub(rpc::make_channel(address, channel));
}

template <class Call>
grpc::Status with_deadline(Call call) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  return call(context);
}

// A spec naming /etc/passwd, /proc/self/environ, a directory, a FIFO or
// /dev/zero is refused at once, with nothing of the file in the answer, and
// the server still stops at SIGTERM within its grace period.
TEST_F(ServiceTest, MeshFilePathsAreRefusedQuicklyAndSigtermStillExits) {
  start_server(0, {"--grace-s", "1"});
  const fs::path fifo = dir_ / "cell.msh";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto started = std::chrono::steady_clock::now();
  for (const std::string& path : {std::string("/etc/passwd"), std::string("/proc/self/environ"),
                                  dir_.string(), fifo.string(), std::string("/dev/zero")}) {
    v1::SubmitJobRequest request;
    *request.mutable_spec() = small_compression();
    request.mutable_spec()->mutable_compression()->mutable_cell()->set_mesh_file(path);
    v1::SubmitJobResponse response;
    const grpc::Status status = client_->submit(request, &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << path;
    EXPECT_NE(status.error_message().find("compression.cell.mesh_file"), std::string::npos)
        << status.error_message();
    EXPECT_NE(status.error_message().find("upload"), std::string::npos) << status.error_message();
    EXPECT_EQ(status.error_message().find(path), std::string::npos) << status.error_message();
    EXPECT_EQ(status.error_message().find("root:"), std::string::npos) << status.error_message();
  }
  // Every cell of a scene is checked: a suspension's second kind, and bytes smuggled into its first.
  {
    v1::SubmitJobRequest request;
    auto* suspension = request.mutable_spec()->mutable_suspension();
    suspension->set_capillary_number(0.1);
    for (int k = 0; k < 2; ++k) {
      auto* cells = suspension->add_cells();
      *cells->mutable_cell() = small_compression().compression().cell();
      cells->set_count(1);
    }
    suspension->mutable_cells(1)->mutable_cell()->set_mesh_file("/etc/passwd");
    v1::SubmitJobResponse response;
    grpc::Status status = client_->submit(request, &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(status.error_message().find("suspension.cells[1].cell.mesh_file"), std::string::npos)
        << status.error_message();
    EXPECT_EQ(status.error_message().find("/etc/passwd"), std::string::npos) << status.error_message();
    suspension->mutable_cells(1)->mutable_cell()->clear_mesh_file();
    suspension->mutable_cells(0)->mutable_cell()->set_mesh_bytes("$MeshFormat\n");
    status = client_->submit(request, &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(status.error_message().find("suspension.cells[0].cell.mesh_bytes"), std::string::npos)
        << status.error_message();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - started, 5s);
  v1::ListJobsResponse jobs;
  ASSERT_TRUE(client_->list(v1::ListJobsRequest(), &jobs).ok());
  EXPECT_EQ(jobs.jobs_size(), 0);
  // A hostile mesh upload (a count the bytes cannot hold) is refused too.
  v1::MeshRef ref;
  const grpc::Status huge = client_->upload_mesh(
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2000000000 1 2000000000\n", "huge.msh", &ref);
  EXPECT_TRUE(huge.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED ||
              huge.error_code() == grpc::StatusCode::INVALID_ARGUMENT)
      << huge.error_message();

  const auto stopping = std::chrono::steady_clock::now();
  server_->signal(SIGTERM);
  ASSERT_TRUE(server_->wait_for(10s)) << "server ignored SIGTERM";
  const int status = server_->wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_LT(std::chrono::steady_clock::now() - stopping, 5s);
}

std::string write_sphere_msh(const fs::path& path) {
  mesh::SphereMeshOptions options;
  options.radius_m = 5e-6;
  options.target_vertex_count = 300;
  auto sphere = mesh::make_sphere_mesh(options);
  EXPECT_TRUE(sphere.ok());
  EXPECT_TRUE(mesh::write_gmsh_msh(*sphere, path.string()).ok());
  return path.string();
}

// `cellflow submit --mesh-file` uploads the mesh and names its hash; the
// worker fetches the bytes; `cellflow delete` removes the finished job.
TEST_F(ServiceTest, CliUploadsTheMeshAWorkerRunsItAndDeleteRemovesTheJob) {
  start_server(1);
  const std::string mesh = write_sphere_msh(dir_ / "sphere.msh");
  int code = -1;
  const std::string out = run_command(std::string(CELLFLOW_CLI_EXE) + " --server " + address_ +
                                          " submit compression --radius-m 5e-6 --youngs-modulus-pa 1000"
                                          " --max-deformation 0.1 --load-points 3 --mesh-file " +
                                          mesh,
                                      &code);
  ASSERT_EQ(code, 0) << out;
  const std::string id = out.substr(0, out.find_first_of(" \n"));
  ASSERT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s)) << get(id).reason();
  const v1::Job job = get(id);
  EXPECT_TRUE(job.spec().compression().cell().mesh_file().empty());
  EXPECT_EQ(job.spec().compression().cell().mesh_sha256().size(), 64u);
  EXPECT_TRUE(
      fs::exists(dir_ / "data" / "meshes" / (job.spec().compression().cell().mesh_sha256() + ".msh")));
  const fs::path result = dir_ / "data" / "results" / (id + ".h5");
  EXPECT_TRUE(fs::exists(result));

  const std::string deleted =
      run_command(std::string(CELLFLOW_CLI_EXE) + " --server " + address_ + " delete " + id, &code);
  EXPECT_EQ(code, 0) << deleted;
  v1::Job gone;
  EXPECT_EQ(client_->get(id, &gone).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_FALSE(fs::exists(result));
}

// Forged worker calls with a valid lease token: a sample index past the
// job's range, NaN progress, a non-HDF5 upload finished as SUCCEEDED, a
// hand-back reason of invalid UTF-8. Each is refused or sanitised and the
// real worker then runs the job to its correct end, every sample seen once.
TEST_F(ServiceTest, ForgedWorkerCallsDoNotHarmTheJob) {
  start_server(0);
  const std::string id = submit(small_compression(4));
  auto stub = worker_stub(worker_address_, worker_token_);
  v1::LeaseJobRequest lease_request;
  lease_request.set_worker_id("forger");
  lease_request.set_wait_s(5);
  v1::LeaseJobResponse leased;
  ASSERT_TRUE(
      with_deadline([&](grpc::ClientContext& c) { return stub->LeaseJob(&c, lease_request, &leased); }).ok());
  ASSERT_TRUE(leased.found());
  Watcher watcher(*client_, id);

  {
    grpc::ClientContext context;
    auto stream = stub->ReportJob(&context);
    v1::WorkerReport forged;
    *forged.mutable_lease() = leased.lease();
    forged.set_report_id(1);
    forged.mutable_force_sample()->set_index(1000);
    ASSERT_TRUE(stream->Write(forged));
    v1::ReportAck ack;
    ASSERT_TRUE(stream->Read(&ack));
    EXPECT_TRUE(ack.lease_valid());
    EXPECT_NE(ack.error().find("index"), std::string::npos) << ack.error();
    v1::WorkerReport nan;
    *nan.mutable_lease() = leased.lease();
    nan.set_report_id(2);
    nan.mutable_progress()->set_fraction_done(std::nan(""));
    ASSERT_TRUE(stream->Write(nan));
    ASSERT_TRUE(stream->Read(&ack));  // the stream goes on
    EXPECT_TRUE(ack.lease_valid());
    EXPECT_NE(ack.error().find("fraction_done"), std::string::npos) << ack.error();
    stream->WritesDone();
    EXPECT_TRUE(stream->Finish().ok());
  }
  {
    v1::UploadResultResponse response;
    grpc::ClientContext context;
    auto writer = stub->UploadResult(&context, &response);
    v1::UploadChunk chunk;
    *chunk.mutable_lease() = leased.lease();
    chunk.set_data("38 bytes of something that is not HDF5");
    writer->Write(chunk);
    writer->WritesDone();
    ASSERT_TRUE(writer->Finish().ok());
    v1::FinishJobRequest finish;
    *finish.mutable_lease() = leased.lease();
    v1::FinishJobResponse finished;
    const grpc::Status status =
        with_deadline([&](grpc::ClientContext& c) { return stub->FinishJob(&c, finish, &finished); });
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  }
  EXPECT_EQ(get(id).state(), v1::Job::RUNNING);
  v1::ReleaseJobRequest release;
  *release.mutable_lease() = leased.lease();
  release.set_reason("stopping \xff\xfe\xc0 now");
  v1::FinishJobResponse released;
  const grpc::Status status =
      with_deadline([&](grpc::ClientContext& c) { return stub->ReleaseJob(&c, release, &released); });
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(released.state(), v1::Job::QUEUED);

  start_worker();
  ASSERT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s)) << get(id).reason();
  watcher.join();
  EXPECT_EQ(watcher.sample_indices(), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_GT(get(id).result_size_bytes(), 1000);
}

// A suspension sample is bounded like a request: more cells than are ever
// streamed, a cell index outside the suspension or a centroid that is not
// 3 values are refused (the stream and the lease go on); a retried sample
// is stored once.
TEST_F(ServiceTest, ForgedSuspensionSamplesAreRefusedAndRetriesStoredOnce) {
  start_server(0);
  const std::string id = submit(small_compression(4));
  auto stub = worker_stub(worker_address_, worker_token_);
  v1::LeaseJobRequest lease_request;
  lease_request.set_worker_id("forger");
  lease_request.set_wait_s(5);
  v1::LeaseJobResponse leased;
  ASSERT_TRUE(
      with_deadline([&](grpc::ClientContext& c) { return stub->LeaseJob(&c, lease_request, &leased); }).ok());
  ASSERT_TRUE(leased.found());
  Watcher watcher(*client_, id);

  auto sample_of = [&](int cells, int cell_count) {
    v1::WorkerReport report;
    *report.mutable_lease() = leased.lease();
    v1::SuspensionSample* s = report.mutable_suspension_sample();
    s->set_index(0);
    s->set_cell_count(cell_count);
    s->set_mean_taylor_deformation(0.1);
    for (int i = 0; i < cells; ++i) {
      v1::SuspendedCellState* c = s->add_cells();
      c->set_cell(i);
      c->set_taylor_deformation(0.1);
      for (int d = 0; d < 3; ++d) c->add_centroid_m(1e-6);
    }
    return report;
  };
  grpc::ClientContext context;
  auto stream = stub->ReportJob(&context);
  auto send = [&](v1::WorkerReport report, int report_id) {
    report.set_report_id(report_id);
    EXPECT_TRUE(stream->Write(report));
    v1::ReportAck ack;
    EXPECT_TRUE(stream->Read(&ack));
    EXPECT_TRUE(ack.lease_valid());
    return ack.error();
  };
  // 257 cells (one more than jobs::kMaxStreamedSuspensionCells) of a 1000-cell suspension.
  EXPECT_NE(send(sample_of(jobs::kMaxStreamedSuspensionCells + 1, 1000), 1).find("suspension_sample.cells"),
            std::string::npos);
  EXPECT_NE(send(sample_of(4, 2), 2).find("more cells than cell_count"), std::string::npos);
  v1::WorkerReport outside = sample_of(2, 2);
  outside.mutable_suspension_sample()->mutable_cells(1)->set_cell(7);
  EXPECT_NE(send(outside, 3).find("cells[1].cell"), std::string::npos);
  v1::WorkerReport flat = sample_of(2, 2);
  flat.mutable_suspension_sample()->mutable_cells(0)->add_centroid_m(0.0);
  EXPECT_NE(send(flat, 4).find("cells[0].centroid_m"), std::string::npos);
  // A good sample, then its retry: both acknowledged, stored once.
  EXPECT_EQ(send(sample_of(2, 2), 5), "");
  EXPECT_EQ(send(sample_of(2, 2), 6), "");
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
  ASSERT_TRUE(eventually([&] { return watcher.max_sample_index() >= 0; }, 10s));

  v1::Job cancelled;
  ASSERT_TRUE(client_->cancel(id, &cancelled).ok());
  watcher.join();
  int suspension_samples = 0;
  for (const v1::JobEvent& e : watcher.events()) {
    if (!e.has_suspension_sample()) continue;
    ++suspension_samples;
    EXPECT_EQ(e.suspension_sample().cells_size(), 2);
  }
  EXPECT_EQ(suspension_samples, 1);
}

TEST_F(ServiceTest, SecondServerOnTheSameDataDirIsRefused) {
  start_server(0);
  Process second({CELLFLOW_SERVER_EXE, "--listen", "127.0.0.1:0", "--data-dir", (dir_ / "data").string()},
                 (dir_ / "second.log").string());
  ASSERT_TRUE(second.wait_for(10s)) << "the second server started";
  const int status = second.wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1);
  EXPECT_NE(second.log().find("in use by another cellflow-server"), std::string::npos) << second.log();
  EXPECT_EQ(get(submit(small_compression())).state(), v1::Job::QUEUED);  // the first serves on
}

// A server crash while a job runs, and its worker stops meanwhile (the
// hand-back never reaches the server, and the worker logs that it failed):
// the attempt is not charged (--max-attempts 1).
// Unfinished uploads of the crashed server are removed at start.
TEST_F(ServiceTest, ServerCrashDoesNotChargeTheRunningAttempt) {
  const std::vector<std::string> options = {"--lease-ttl-s", "1", "--max-attempts", "1"};
  start_server(0, options);
  const int port = port_;
  const std::string id = submit(small_compression(30));
  Process* worker = start_worker({"--debug-delay-per-point-ms", "200"});
  ASSERT_TRUE(
      eventually([&] { return get(id).state() == v1::Job::RUNNING && get(id).last_sequence() > 3; }, 30s));
  server_->signal(SIGKILL);
  server_->wait();
  // The worker stops while the server is down: its hand-back cannot arrive,
  // and it says so instead of "handed back".
  worker->signal(SIGTERM);
  ASSERT_TRUE(worker->wait_for(20s));
  EXPECT_NE(worker->log().find("hand-back failed"), std::string::npos) << worker->log();
  EXPECT_EQ(worker->log().find("handed back"), std::string::npos) << worker->log();
  const fs::path stale = dir_ / "data" / "results" / "job-1.attempt-1.0123456789abcdef.h5.part";
  std::ofstream(stale) << "left behind";
  start_server(0, options, port);
  EXPECT_FALSE(fs::exists(stale));
  // The lease expires (1 s): requeued, not failed, then run to the end.
  ASSERT_TRUE(eventually([&] { return get(id).state() != v1::Job::RUNNING; }, 20s));
  EXPECT_EQ(get(id).state(), v1::Job::QUEUED) << get(id).reason();
  start_worker();
  EXPECT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s)) << get(id).reason();
}

// A worker removes its scratch directory on exit and those of dead workers at start.
TEST_F(ServiceTest, WorkerRemovesItsScratchAndThoseOfDeadWorkers) {
  start_server(0);
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  ::waitpid(dead, nullptr, 0);
  // A temporary folder of this test's own: workers of tests running beside
  // it sweep the shared one too, and the one that comes first says so.
  const fs::path tmp = dir_ / "tmp";
  fs::create_directories(tmp);
  const fs::path stale = tmp / ("cellflow-worker-" + std::to_string(dead));
  fs::create_directories(stale);
  std::ofstream(stale / "job-3.attempt-1.h5.tmp") << "left by a killed worker";
  Process* worker = start_worker({"--idle-exit-s", "1"},
                                 {"CELLFLOW_WORKER_TOKEN=" + worker_token_, "TMPDIR=" + tmp.string()});
  const fs::path own = tmp / ("cellflow-worker-" + std::to_string(worker->pid()));
  ASSERT_TRUE(worker->wait_for(20s));
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_FALSE(fs::exists(own));
  EXPECT_NE(worker->log().find("removed stale scratch directory"), std::string::npos) << worker->log();
}

}  // namespace
}  // namespace cellflow::testing
