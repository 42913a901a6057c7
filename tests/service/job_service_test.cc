// The service logic in one process, without gRPC: validation at submit,
// the memory limit, page tokens, watch replay and live follow, fenced worker
// reports and uploads; and the worker's job runner (spec -> scene -> samples
// and HDF5).
#include "server/job_service.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

#include "io/h5md.h"
#include "jobs/common/result_file.h"
#include "jobs/job_spec.h"
#include "physics/mesh/sphere_mesh.h"
#include "worker/job_runner.h"

namespace cellflow::server {
namespace {

namespace fs = std::filesystem;

v1::JobSpec small_compression(int load_points = 4) {
  v1::JobSpec spec;
  auto* c = spec.mutable_compression();
  c->mutable_cell()->set_radius_m(5e-6);
  c->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1000.0);
  c->mutable_cell()->set_target_vertex_count(300);
  c->set_max_deformation(0.15);
  c->set_load_points(load_points);
  return spec;
}

// FinishJob checks the HDF5 signature of the upload: a stand-in carries it.
const std::string kHdf5StandIn = std::string("\x89HDF\r\n\x1a\n", 8) + " HDF5 stand-in";

class JobServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_job_service_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    StoreOptions store_options;
    store_options.path = (dir_ / "jobs.sqlite").string();
    auto opened = Store::open(store_options);
    ASSERT_TRUE(opened.ok());
    store_ = std::move(opened).value();
    JobServiceOptions options;
    options.data_dir = dir_;
    options.memory_limit_bytes = 200LL << 20;
    options.lease_ttl_s = 5;
    options.download_chunk_bytes = 1000;
    service_ = std::make_unique<JobService>(*store_, notifier_, options);
  }
  void TearDown() override {
    service_.reset();
    store_.reset();
    fs::remove_all(dir_);
  }

  std::string submit(const v1::JobSpec& spec) {
    v1::SubmitJobRequest request;
    *request.mutable_spec() = spec;
    auto response = service_->submit(request);
    EXPECT_TRUE(response.ok()) << response.status().to_string();
    return response.ok() ? response->job().id() : "";
  }

  v1::LeaseJobResponse lease() {
    v1::LeaseJobRequest request;
    request.set_worker_id("test-worker");
    request.set_wait_s(0);
    auto response = service_->lease(request, [] { return false; });
    EXPECT_TRUE(response.ok());
    return *response;
  }

  v1::ReportAck report_sample(const v1::Lease& lease, int index) {
    v1::WorkerReport report;
    *report.mutable_lease() = lease;
    report.set_report_id(index + 1);
    report.mutable_force_sample()->set_index(index);
    report.mutable_force_sample()->set_force_n(1e-9 * index);
    auto ack = service_->report(report);
    EXPECT_TRUE(ack.ok());
    return *ack;
  }

  void upload(const v1::Lease& lease, const std::string& bytes) {
    auto up = service_->begin_upload(lease);
    ASSERT_TRUE(up.ok()) << up.status().to_string();
    ASSERT_TRUE((*up)->write(0, bytes).ok());
    ASSERT_TRUE((*up)->complete().ok());
  }

  fs::path dir_;
  Notifier notifier_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<JobService> service_;
};

TEST_F(JobServiceTest, SubmitValidatesAndEstimatesMemory) {
  const std::string id = submit(small_compression());
  EXPECT_EQ(id, "job-1");
  auto job = service_->get(id);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state(), v1::Job::QUEUED);
  EXPECT_GT(job->estimated_memory_bytes(), 0);

  v1::SubmitJobRequest bad;
  *bad.mutable_spec() = small_compression();
  bad.mutable_spec()->mutable_compression()->set_max_deformation(2.0);
  auto refused = service_->submit(bad);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("max_deformation"), std::string::npos)
      << refused.status().message();

  v1::SubmitJobRequest big;
  *big.mutable_spec() = small_compression();
  big.mutable_spec()->mutable_compression()->mutable_cell()->set_target_vertex_count(20000);
  EXPECT_EQ(service_->submit(big).status().code(), StatusCode::kResourceExhausted);

  v1::SubmitJobRequest long_id;
  *long_id.mutable_spec() = small_compression();
  long_id.set_request_id(std::string(200, 'x'));
  EXPECT_EQ(service_->submit(long_id).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 1);
}

// The result's author (/h5md/author): the spec's when it names one, else the
// submitting user; an oversized one is refused naming the field.
TEST_F(JobServiceTest, SubmitFillsInTheAuthorFromTheCaller) {
  const Identity alice{"alice", false, false};
  v1::SubmitJobRequest unnamed;
  *unnamed.mutable_spec() = small_compression();
  auto filled = service_->submit(unnamed, alice);
  ASSERT_TRUE(filled.ok()) << filled.status().to_string();
  EXPECT_EQ(filled->job().spec().author(), "alice");
  EXPECT_EQ(service_->get(filled->job().id(), alice)->spec().author(), "alice");

  v1::SubmitJobRequest named = unnamed;
  named.mutable_spec()->set_author("Alice Example");
  auto kept = service_->submit(named, alice);
  ASSERT_TRUE(kept.ok());
  EXPECT_EQ(kept->job().spec().author(), "Alice Example");

  v1::SubmitJobRequest oversized = unnamed;
  oversized.mutable_spec()->set_author(std::string(service_->options().max_name_bytes + 1, 'a'));
  auto refused = service_->submit(oversized, alice);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("author"), std::string::npos) << refused.status().message();
}

// Validation and the memory estimate read one conversion of the spec: one
// per submitted spec, for every scene (the long request id is refused before).
TEST_F(JobServiceTest, SubmitConvertsEachSpecOnce) {
  EXPECT_EQ(service_->spec_conversions(), 0);
  submit(small_compression());
  EXPECT_EQ(service_->spec_conversions(), 1);
  v1::JobSpec flow;
  auto* f = flow.mutable_shear_flow();
  f->mutable_cell()->set_radius_m(4e-6);
  f->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  f->mutable_cell()->set_target_vertex_count(300);
  f->set_capillary_number(0.2);
  submit(flow);
  EXPECT_EQ(service_->spec_conversions(), 2);
  v1::SubmitJobRequest bad;
  *bad.mutable_spec() = small_compression();
  bad.mutable_spec()->mutable_compression()->set_max_deformation(2.0);
  EXPECT_FALSE(service_->submit(bad).ok());
  EXPECT_EQ(service_->spec_conversions(), 3);
}

TEST_F(JobServiceTest, PageTokensAreOpaqueAndBoundToTheFilter) {
  const std::string token = encode_page_token(17, v1::Job::RUNNING);
  EXPECT_EQ(token.find("17"), std::string::npos);  // not the bare id
  auto after = decode_page_token(token, v1::Job::RUNNING);
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(*after, 17);
  EXPECT_EQ(decode_page_token(token, v1::Job::QUEUED).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(decode_page_token("!!", v1::Job::RUNNING).status().code(), StatusCode::kInvalidArgument);

  for (int i = 0; i < 5; ++i) submit(small_compression());
  v1::ListJobsRequest request;
  request.set_page_size(2);
  auto page = service_->list(request);
  ASSERT_TRUE(page.ok());
  EXPECT_EQ(page->jobs_size(), 2);
  EXPECT_FALSE(page->next_page_token().empty());
  request.set_page_size(5000);  // clamped to the maximum, not refused
  request.clear_page_token();
  EXPECT_EQ(service_->list(request)->jobs_size(), 5);
  request.set_page_size(-1);
  EXPECT_EQ(service_->list(request).status().code(), StatusCode::kInvalidArgument);
}

TEST_F(JobServiceTest, WatchReplaysThenFollowsLiveUntilTerminal) {
  const std::string id = submit(small_compression());
  std::vector<v1::JobEvent> events;
  std::atomic<bool> watching{true};
  std::thread watcher([&] {
    v1::WatchJobRequest request;
    request.set_job_id(id);
    Status s = service_->watch(
        request,
        [&](const v1::JobEvent& e) {
          events.push_back(e);
          return true;
        },
        [] { return false; });
    EXPECT_TRUE(s.ok()) << s.to_string();
    watching = false;
  });
  const v1::LeaseJobResponse leased = lease();
  ASSERT_TRUE(leased.found());
  EXPECT_EQ(leased.last_delivered_sample_index(), -1);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(report_sample(leased.lease(), i).lease_valid());
  EXPECT_TRUE(watching.load());
  upload(leased.lease(), kHdf5StandIn);
  v1::FinishJobRequest finish;
  *finish.mutable_lease() = leased.lease();
  auto finished = service_->finish(finish);
  ASSERT_TRUE(finished.ok()) << finished.status().to_string();
  EXPECT_EQ(finished->state(), v1::Job::SUCCEEDED);
  watcher.join();
  // QUEUED, RUNNING, 4 samples, SUCCEEDED; sequences 1..7.
  ASSERT_EQ(events.size(), 7u);
  for (std::size_t i = 0; i < events.size(); ++i)
    EXPECT_EQ(events[i].sequence(), static_cast<std::int64_t>(i + 1));
  EXPECT_EQ(events.back().state_change().state(), v1::Job::SUCCEEDED);

  // Replay after sequence 5, and a replay after the end returns at once.
  std::vector<std::int64_t> tail;
  v1::WatchJobRequest request;
  request.set_job_id(id);
  request.set_after_sequence(5);
  ASSERT_TRUE(service_
                  ->watch(
                      request,
                      [&](const v1::JobEvent& e) {
                        tail.push_back(e.sequence());
                        return true;
                      },
                      [] { return false; })
                  .ok());
  EXPECT_EQ(tail, (std::vector<std::int64_t>{6, 7}));
  request.set_after_sequence(7);
  ASSERT_TRUE(service_
                  ->watch(
                      request, [&](const v1::JobEvent&) { return true; }, [] { return false; })
                  .ok());

  // The result downloads in chunks of the configured size.
  std::string downloaded;
  ASSERT_TRUE(service_
                  ->download(id,
                             [&](const v1::ResultChunk& c) {
                               EXPECT_EQ(c.offset(), static_cast<std::int64_t>(downloaded.size()));
                               downloaded += c.data();
                               return true;
                             })
                  .ok());
  EXPECT_EQ(downloaded, kHdf5StandIn);
}

TEST_F(JobServiceTest, StaleWorkerIsFencedAndFinishNeedsUpload) {
  const std::string id = submit(small_compression());
  const v1::LeaseJobResponse leased = lease();
  v1::FinishJobRequest finish;
  *finish.mutable_lease() = leased.lease();
  EXPECT_EQ(service_->finish(finish).status().code(), StatusCode::kFailedPrecondition);  // nothing uploaded
  v1::Lease stale = leased.lease();
  stale.set_lease_token("0123456789abcdef0123456789abcdef");
  EXPECT_FALSE(report_sample(stale, 0).lease_valid());
  EXPECT_EQ(service_->begin_upload(stale).status().code(), StatusCode::kFailedPrecondition);
  auto up = service_->begin_upload(leased.lease());
  ASSERT_TRUE(up.ok());
  EXPECT_EQ((*up)->write(5, "x").code(), StatusCode::kInvalidArgument);  // offsets must be contiguous
  ASSERT_TRUE(service_->cancel(id).ok());
  const v1::ReportAck ack = report_sample(leased.lease(), 0);
  EXPECT_FALSE(ack.lease_valid());
  EXPECT_TRUE(ack.cancelled());
}

TEST_F(JobServiceTest, ShutdownDrainingRefusesWork) {
  submit(small_compression());
  service_->set_draining(true);
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  EXPECT_FALSE(service_->submit(request).ok());
  EXPECT_FALSE(lease().found());
}

// A worker that cancelled its LeaseJob poll (it got SIGTERM) is handed no
// job: the job stays QUEUED with no attempt used, and the next worker gets it
// as attempt 1. While a poll waits it counts as a free worker.
TEST_F(JobServiceTest, CancelledLeasePollTakesNoJob) {
  const std::string id = submit(small_compression());
  v1::LeaseJobRequest request;
  request.set_worker_id("stopping-worker");
  request.set_wait_s(0);
  auto response = service_->lease(request, [] { return true; });
  ASSERT_TRUE(response.ok());
  EXPECT_FALSE(response->found());
  auto job = service_->get(id);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state(), v1::Job::QUEUED);
  EXPECT_EQ(job->attempt(), 0);
  EXPECT_EQ(service_->queued_jobs(), 1);

  // A poll that waits is a free worker; it is counted until it returns.
  request.set_worker_id("idle-worker");
  request.set_wait_s(2);
  std::atomic<bool> leave{false};
  const v1::LeaseJobResponse leased = lease();  // the queued job, attempt 1
  EXPECT_EQ(leased.lease().attempt(), 1);
  EXPECT_EQ(service_->waiting_workers(), 0);
  std::thread poll([&] { (void)service_->lease(request, [&] { return leave.load(); }); });
  for (int i = 0; i < 100 && service_->waiting_workers() == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(service_->waiting_workers(), 1);
  leave.store(true);
  poll.join();
  EXPECT_EQ(service_->waiting_workers(), 0);
}

// --- hostile input (issue 13) ---

// A spec naming any file of the server's machine is refused at submit:
// INVALID_ARGUMENT naming the field and saying to upload, nothing of the
// file (content, existence, size) in the message, and nothing opened (a FIFO
// would block open(), /dev/zero never ends).
TEST_F(JobServiceTest, SubmitRefusesMeshFilePathsWithoutTouchingThem) {
  const fs::path fifo = dir_ / "fifo.msh";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const fs::path directory = dir_ / "a-directory";
  fs::create_directories(directory);
  const auto started = std::chrono::steady_clock::now();
  for (const std::string& path :
       {std::string("/etc/passwd"), std::string("/proc/self/environ"), directory.string(), fifo.string(),
        std::string("/dev/zero"), std::string("/nonexistent/cell.msh")}) {
    v1::SubmitJobRequest request;
    *request.mutable_spec() = small_compression();
    request.mutable_spec()->mutable_compression()->mutable_cell()->set_mesh_file(path);
    auto refused = service_->submit(request);
    ASSERT_EQ(refused.status().code(), StatusCode::kInvalidArgument) << path;
    const std::string& message = refused.status().message();
    EXPECT_NE(message.find("compression.cell.mesh_file"), std::string::npos) << message;
    EXPECT_NE(message.find("upload"), std::string::npos) << message;
    EXPECT_EQ(message.find(path), std::string::npos) << message;  // not even the path
    EXPECT_EQ(message.find("root:"), std::string::npos) << message;
    EXPECT_EQ(message.find("PATH="), std::string::npos) << message;
  }
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(2));
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 0);
  // Inline bytes are not accepted either.
  v1::SubmitJobRequest inline_bytes;
  *inline_bytes.mutable_spec() = small_compression();
  inline_bytes.mutable_spec()->mutable_compression()->mutable_cell()->set_mesh_bytes("$MeshFormat");
  auto refused = service_->submit(inline_bytes);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("mesh_bytes"), std::string::npos);
}

std::string sphere_msh_bytes(const fs::path& dir, int vertices) {
  mesh::SphereMeshOptions o;
  o.radius_m = 5e-6;
  o.target_vertex_count = vertices;
  auto sphere = mesh::make_sphere_mesh(o);
  EXPECT_TRUE(sphere.ok());
  const fs::path path = dir / "sphere.msh";
  EXPECT_TRUE(mesh::write_gmsh_msh(*sphere, path.string()).ok());
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST_F(JobServiceTest, UploadedMeshIsStoredByHashAndNamedBySpec) {
  const std::string bytes = sphere_msh_bytes(dir_, 300);
  auto ref = service_->upload_mesh(bytes, "sphere.msh");
  ASSERT_TRUE(ref.ok()) << ref.status().to_string();
  EXPECT_EQ(ref->sha256(), sha256_hex(bytes));
  EXPECT_TRUE(is_sha256_hex(ref->sha256()));
  EXPECT_EQ(ref->size_bytes(), static_cast<std::int64_t>(bytes.size()));
  EXPECT_GT(ref->vertex_count(), 200);
  EXPECT_TRUE(fs::exists(dir_ / "meshes" / (ref->sha256() + ".msh")));
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");

  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  request.mutable_spec()->mutable_compression()->mutable_cell()->set_mesh_sha256(ref->sha256());
  auto submitted = service_->submit(request);
  ASSERT_TRUE(submitted.ok()) << submitted.status().to_string();
  // The estimate counts the stored mesh's vertices (its header), not a file size.
  EXPECT_EQ(submitted->job().estimated_memory_bytes(),
            jobs::kBaselineBytes + ref->vertex_count() * jobs::kBytesPerVertex);
  // The stored spec names the hash only; the bytes stay in the mesh store.
  EXPECT_TRUE(submitted->job().spec().compression().cell().mesh_bytes().empty());

  request.mutable_spec()->mutable_compression()->mutable_cell()->set_mesh_sha256(std::string(64, 'a'));
  auto unknown = service_->submit(request);
  EXPECT_EQ(unknown.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(unknown.status().message().find("compression.cell.mesh_sha256"), std::string::npos);
  request.mutable_spec()->mutable_compression()->mutable_cell()->set_mesh_sha256("../../etc/passwd");
  EXPECT_EQ(service_->submit(request).status().code(), StatusCode::kInvalidArgument);

  // The worker fetches the bytes of its leased job's mesh, and only that one.
  const v1::LeaseJobResponse leased = lease();
  ASSERT_TRUE(leased.found());
  v1::FetchMeshRequest fetch;
  *fetch.mutable_lease() = leased.lease();
  fetch.set_sha256(ref->sha256());
  std::string fetched;
  ASSERT_TRUE(service_
                  ->fetch_mesh(fetch,
                               [&](const v1::MeshChunk& c) {
                                 fetched += c.data();
                                 return true;
                               })
                  .ok());
  EXPECT_EQ(fetched, bytes);
  fetch.set_sha256(std::string(64, 'b'));
  EXPECT_FALSE(service_->fetch_mesh(fetch, [](const v1::MeshChunk&) { return true; }).ok());
}

// Declared counts far beyond the bytes (or the limits) are refused before
// anything is allocated; not-a-mesh and oversized uploads too.
TEST_F(JobServiceTest, HostileMeshUploadsAreRefusedBeforeAllocation) {
  const std::string huge =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2000000000 1 2000000000\n2 1 0 2000000000\n";
  const auto started = std::chrono::steady_clock::now();
  auto refused = service_->upload_mesh(huge, "huge.msh");
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(refused.status().code() == StatusCode::kResourceExhausted ||
              refused.status().code() == StatusCode::kInvalidArgument)
      << refused.status().to_string();
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(1));
  auto not_mesh = service_->upload_mesh("root:x:0:0:root:/root:/bin/bash\n", "passwd");
  EXPECT_EQ(not_mesh.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(not_mesh.status().message().find("root:x"), std::string::npos) << not_mesh.status().message();

  MeshStore small(dir_ / "small-meshes", 100);
  EXPECT_EQ(small.put(std::string(101, ' '), "big").status().code(), StatusCode::kResourceExhausted);
  EXPECT_FALSE(fs::exists(dir_ / "meshes") && !fs::is_empty(dir_ / "meshes"));
}

v1::WorkerReport progress_report(const v1::Lease& lease, double fraction) {
  v1::WorkerReport report;
  *report.mutable_lease() = lease;
  report.mutable_progress()->set_fraction_done(fraction);
  report.mutable_progress()->set_elapsed_s(1.0);
  report.mutable_progress()->set_estimated_remaining_s(std::nan(""));
  return report;
}

// Forged samples (an index past the job's range, a gap, a negative index)
// and NaN progress get an error in their ack; the lease, the stream and the
// job go on, and the real samples still arrive in order.
TEST_F(JobServiceTest, UntrustedReportsAreRefusedWithoutHarmingTheJob) {
  const std::string id = submit(small_compression(4));
  const v1::LeaseJobResponse leased = lease();
  ASSERT_TRUE(leased.found());
  for (int forged : {1000, 4, -1, 2}) {
    const v1::ReportAck ack = report_sample(leased.lease(), forged);
    EXPECT_TRUE(ack.lease_valid()) << forged;
    EXPECT_FALSE(ack.error().empty()) << forged;
    EXPECT_NE(ack.error().find("index"), std::string::npos) << ack.error();
  }
  auto nan = service_->report(progress_report(leased.lease(), std::nan("")));
  ASSERT_TRUE(nan.ok());
  EXPECT_TRUE(nan->lease_valid());
  EXPECT_NE(nan->error().find("fraction_done"), std::string::npos);
  auto inf = service_->report(progress_report(leased.lease(), INFINITY));
  ASSERT_TRUE(inf.ok());
  EXPECT_FALSE(inf->error().empty());
  auto good = service_->report(progress_report(leased.lease(), 0.5));
  ASSERT_TRUE(good.ok());
  EXPECT_TRUE(good->error().empty()) << good->error();
  for (int i = 0; i < 4; ++i) {
    const v1::ReportAck ack = report_sample(leased.lease(), i);
    EXPECT_TRUE(ack.lease_valid());
    EXPECT_TRUE(ack.error().empty()) << ack.error();
  }
  // A resend of a delivered index is no error (the reporter resends after a reconnect).
  EXPECT_TRUE(report_sample(leased.lease(), 2).error().empty());
  auto job = service_->get(id);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state(), v1::Job::RUNNING);
  EXPECT_DOUBLE_EQ(job->fraction_done(), 0.5);
  EXPECT_EQ(job->estimated_remaining_s(), -1.0);  // NaN remaining time: unknown
  auto events = store_->events_after(1, 0, 100);
  ASSERT_TRUE(events.ok());
  std::vector<int> indices;
  for (const auto& e : *events)
    if (e.has_force_sample()) indices.push_back(e.force_sample().index());
  EXPECT_EQ(indices, (std::vector<int>{0, 1, 2, 3}));
  upload(leased.lease(), kHdf5StandIn);
  v1::FinishJobRequest finish;
  *finish.mutable_lease() = leased.lease();
  EXPECT_TRUE(service_->finish(finish).ok());
}

TEST_F(JobServiceTest, NonHdf5UploadCannotFinishTheJob) {
  const std::string id = submit(small_compression());
  const v1::LeaseJobResponse leased = lease();
  upload(leased.lease(), std::string("38 bytes of something that is not HDF5"));
  v1::FinishJobRequest finish;
  *finish.mutable_lease() = leased.lease();
  auto refused = service_->finish(finish);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("HDF5"), std::string::npos);
  EXPECT_EQ(service_->get(id)->state(), v1::Job::RUNNING);
  upload(leased.lease(), kHdf5StandIn);  // the real result
  auto finished = service_->finish(finish);
  ASSERT_TRUE(finished.ok()) << finished.status().to_string();
  EXPECT_EQ(finished->state(), v1::Job::SUCCEEDED);
}

TEST_F(JobServiceTest, UploadOverTheJobsLimitIsRefused) {
  JobServiceOptions options = service_->options();
  options.upload_memory_factor = 1e-6;  // about 70 bytes for this job
  options.upload_slack_bytes = 0;
  JobService strict(*store_, notifier_, options);
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  const std::string id = strict.submit(request)->job().id();
  v1::LeaseJobRequest lease_request;
  lease_request.set_worker_id("w");
  const v1::LeaseJobResponse leased = *strict.lease(lease_request, [] { return false; });
  auto up = strict.begin_upload(leased.lease());
  ASSERT_TRUE(up.ok());
  EXPECT_TRUE((*up)->write(0, std::string(50, 'x')).ok());
  EXPECT_EQ((*up)->write(50, std::string(50, 'x')).code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(strict.get(id)->state(), v1::Job::RUNNING);
}

TEST_F(JobServiceTest, FailReasonWithInvalidUtf8IsSanitisedNotRefused) {
  const std::string id = submit(small_compression());
  const v1::LeaseJobResponse leased = lease();
  v1::FailJobRequest fail;
  *fail.mutable_lease() = leased.lease();
  fail.set_reason("load step 3: \xff\xfe\xc0\xaf bad bytes " + std::string(10000, 'x'));
  auto failed = service_->fail(fail);
  ASSERT_TRUE(failed.ok()) << failed.status().to_string();
  EXPECT_EQ(failed->state(), v1::Job::FAILED);
  auto job = service_->get(id);
  ASSERT_TRUE(job.ok());
  EXPECT_LE(job->reason().size(), 4096u);
  EXPECT_EQ(job->reason().rfind("load step 3: ", 0), 0u) << job->reason().substr(0, 40);
  EXPECT_EQ(sanitize_text(job->reason(), 4096), job->reason());  // valid UTF-8: unchanged
  v1::Job parsed;
  EXPECT_TRUE(parsed.ParseFromString(job->SerializeAsString()));  // a client can read it
}

TEST(SanitizeTextTest, ValidUtf8BoundedAtCharacterBoundaries) {
  EXPECT_EQ(sanitize_text("plain", 100), "plain");
  EXPECT_EQ(sanitize_text("\xc3\xa9t\xc3\xa9", 100), "\xc3\xa9t\xc3\xa9");
  EXPECT_EQ(sanitize_text("a\xff"
                          "b",
                          100),
            "a\xef\xbf\xbd"
            "b");
  EXPECT_EQ(sanitize_text("\xc0\xaf", 100), "\xef\xbf\xbd\xef\xbf\xbd");          // overlong '/'
  EXPECT_EQ(sanitize_text("\xed\xa0\x80", 100).find("\xed"), std::string::npos);  // surrogate
  EXPECT_EQ(sanitize_text("a\x01"
                          "b",
                          100),
            "a b");
  const std::string cut = sanitize_text(std::string(10, '\xe2') + "\x82\xac" + std::string(100, 'x'), 8);
  EXPECT_LE(cut.size(), 8u);
  EXPECT_EQ(sanitize_text(cut, 8), cut);
}

TEST_F(JobServiceTest, NamesAreBoundedAtSubmit) {
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  request.mutable_spec()->set_name(std::string(4 << 20, 'n'));
  auto refused = service_->submit(request);
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(refused.status().message().rfind("name:", 0), 0u);
  EXPECT_LT(refused.status().message().size(), 200u);
  request.mutable_spec()->set_name(std::string(1024, 'n'));
  EXPECT_TRUE(service_->submit(request).ok());
}

// A worker that only heartbeats cannot hold a job past --max-run-time-s.
TEST_F(JobServiceTest, HeartbeatsDoNotHoldAJobPastTheRunTimeLimit) {
  std::atomic<std::int64_t> clock{1'000'000};
  JobServiceOptions options = service_->options();
  options.now_ms = [&] { return clock.load(); };
  options.max_run_time_s = 10;
  JobService timed(*store_, notifier_, options);
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  const std::string id = timed.submit(request)->job().id();
  v1::LeaseJobRequest lease_request;
  lease_request.set_worker_id("heartbeats-only");
  const v1::LeaseJobResponse leased = *timed.lease(lease_request, [] { return false; });
  ASSERT_TRUE(leased.found());
  v1::WorkerReport beat;
  *beat.mutable_lease() = leased.lease();
  beat.mutable_heartbeat();
  for (int s = 0; s < 10; ++s) {
    clock += 1000;
    ASSERT_TRUE(timed.report(beat)->lease_valid());
    EXPECT_EQ(timed.reap_expired_leases(), 0);
  }
  clock += 1500;
  EXPECT_TRUE(timed.report(beat)->lease_valid());  // the lease itself is fresh
  EXPECT_EQ(timed.reap_expired_leases(), 1);
  auto job = timed.get(id);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state(), v1::Job::QUEUED);
  EXPECT_NE(job->reason().find("--max-run-time-s"), std::string::npos) << job->reason();
  EXPECT_FALSE(timed.report(beat)->lease_valid());
}

TEST_F(JobServiceTest, DeleteJobRemovesRowsAndFiles) {
  const std::string id = submit(small_compression());
  EXPECT_EQ(service_->delete_job(id).code(), StatusCode::kFailedPrecondition);  // queued
  const v1::LeaseJobResponse leased = lease();
  EXPECT_EQ(service_->delete_job(id).code(), StatusCode::kFailedPrecondition);  // running
  upload(leased.lease(), kHdf5StandIn);
  v1::FinishJobRequest finish;
  *finish.mutable_lease() = leased.lease();
  ASSERT_TRUE(service_->finish(finish).ok());
  ASSERT_TRUE(fs::exists(service_->result_path(1)));
  ASSERT_TRUE(service_->delete_job(id).ok());
  EXPECT_EQ(service_->get(id).status().code(), StatusCode::kNotFound);
  EXPECT_FALSE(fs::exists(service_->result_path(1)));
  EXPECT_TRUE(store_->events_after(1, 0, 100)->empty());
  EXPECT_EQ(service_->delete_job(id).code(), StatusCode::kNotFound);
}

// A job cancelled and deleted while its worker still runs the attempt: the
// worker's next heartbeat and sample are answered (not failed) with an ack
// that ends the attempt, so the worker stops instead of reconnecting.
TEST_F(JobServiceTest, ReportsForADeletedJobEndTheAttempt) {
  const std::string id = submit(small_compression(4));
  const v1::LeaseJobResponse leased = lease();
  ASSERT_TRUE(leased.found());
  ASSERT_TRUE(service_->cancel(id).ok());
  ASSERT_TRUE(service_->delete_job(id).ok());
  v1::WorkerReport beat;
  *beat.mutable_lease() = leased.lease();
  beat.set_report_id(1);
  beat.mutable_heartbeat();
  auto ack = service_->report(beat);
  ASSERT_TRUE(ack.ok()) << ack.status().to_string();
  EXPECT_FALSE(ack->lease_valid());
  const v1::ReportAck sample_ack = report_sample(leased.lease(), 0);
  EXPECT_FALSE(sample_ack.lease_valid());
  EXPECT_EQ(sample_ack.report_id(), 1);
}

// Uploads of an attempt that lost its lease are removed, and every .part at
// server start or stop.
TEST_F(JobServiceTest, PartialUploadsAreRemoved) {
  const std::string id = submit(small_compression());
  const v1::LeaseJobResponse leased = lease();
  upload(leased.lease(), "partial");
  auto parts = [&] {
    int n = 0;
    for (const auto& entry : fs::directory_iterator(dir_ / "results"))
      n += entry.path().string().ends_with(".part") ? 1 : 0;
    return n;
  };
  EXPECT_EQ(parts(), 1);
  ASSERT_TRUE(service_->cancel(id).ok());
  EXPECT_EQ(parts(), 0);
  std::ofstream(dir_ / "results" / "job-9.attempt-1.0123.h5.part") << "left by a crash";
  EXPECT_EQ(service_->remove_all_uploads(), 1);
  EXPECT_EQ(parts(), 0);
}

// Store: the attempts of jobs RUNNING when the server stopped are not charged.
TEST_F(JobServiceTest, RestartDoesNotChargeTheRunningAttempt) {
  StoreOptions store_options;
  store_options.path = (dir_ / "one-attempt.sqlite").string();
  store_options.max_attempts = 1;
  auto store = Store::open(store_options);
  ASSERT_TRUE(store.ok());
  auto submitted = (*store)->submit(small_compression(), "", 0, 1000);
  ASSERT_TRUE(submitted.ok());
  ASSERT_TRUE((*store)->claim("w", 1000, 1000)->has_value());
  // The server restarts: the lease then expires without a hand-back.
  ASSERT_TRUE((*store)->forgive_running_attempts().ok());
  auto changed = (*store)->requeue_expired(5000);
  ASSERT_TRUE(changed.ok());
  ASSERT_EQ(changed->size(), 1u);
  EXPECT_EQ(changed->front().state(), v1::Job::QUEUED);  // not FAILED: the attempt was not charged
}

// The worker's runner in process: the samples it reports and the file it
// writes hold the library's curve, bit for bit.
// --- studies (sweeps) through the service ---

v1::SubmitJobRequest study_request(const std::vector<std::string>& deformations,
                                   const std::string& request_id = "") {
  v1::SubmitJobRequest request;
  request.set_request_id(request_id);
  auto* study = request.mutable_spec()->mutable_study();
  *study->mutable_base() = small_compression(2);
  auto* axis = study->add_axes();
  axis->set_path("compression.maxDeformation");
  for (const auto& d : deformations) axis->add_values(d);
  return request;
}

TEST_F(JobServiceTest, StudySubmitValidatesEveryChildBeforeQueuingAny) {
  // The third point is out of range: refused naming the axis value, nothing queued.
  auto refused = service_->submit(study_request({"0.1", "0.2", "2.0"}));
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  const std::string& m = refused.status().message();
  EXPECT_EQ(
      m.rfind("study.axes[0].values[2] (compression.maxDeformation=2.0): compression.max_deformation", 0), 0u)
      << m;
  // A bad path and a nested study.
  v1::SubmitJobRequest bad_path = study_request({"0.1"});
  bad_path.mutable_spec()->mutable_study()->mutable_axes(0)->set_path("compression.maxDeformationX");
  auto path_refused = service_->submit(bad_path);
  ASSERT_FALSE(path_refused.ok());
  EXPECT_EQ(path_refused.status().message().rfind("study.axes[0].path: ", 0), 0u);
  v1::SubmitJobRequest nested = study_request({"0.1"});
  *nested.mutable_spec()->mutable_study()->mutable_base() = study_request({"0.1"}).spec();
  auto nested_refused = service_->submit(nested);
  ASSERT_FALSE(nested_refused.ok());
  EXPECT_NE(nested_refused.status().message().find("nested"), std::string::npos);
  // Memory: a child over the limit is RESOURCE_EXHAUSTED naming its point.
  v1::SubmitJobRequest big = study_request({"0.1"});
  auto* vertices = big.mutable_spec()->mutable_study()->add_axes();
  vertices->set_path("compression.cell.targetVertexCount");
  vertices->add_values("300");
  vertices->add_values("20000");
  auto too_big = service_->submit(big);
  ASSERT_FALSE(too_big.ok());
  EXPECT_EQ(too_big.status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(too_big.status().message().rfind("study.axes[0].values[0], study.axes[1].values[1]", 0), 0u)
      << too_big.status().message();
  // More points than the server's bound.
  std::vector<std::string> many(11, "0.1");
  JobServiceOptions options = service_->options();
  options.max_study_points = 10;
  JobService bounded(*store_, notifier_, options);
  auto too_many = bounded.submit(study_request(many));
  ASSERT_FALSE(too_many.ok());
  EXPECT_NE(too_many.status().message().find("at most 10"), std::string::npos);
  auto listed = service_->list(v1::ListJobsRequest());
  ASSERT_TRUE(listed.ok());
  EXPECT_EQ(listed->jobs_size(), 0) << "nothing of a refused study is queued";
}

// A sweep of fits: each point's library curves are bounded over the whole
// study (distinct probe ratios multiply them), and the curves the points
// share are queued once, as children of the first point.
TEST_F(JobServiceTest, StudyOfFitsBoundsItsLibraryCurvesAndQueuesSharedOnesOnce) {
  v1::SubmitJobRequest request;
  auto* study = request.mutable_spec()->mutable_study();
  v1::FitSpec* fit = study->mutable_base()->mutable_fit();
  fit->set_geometry(v1::FIT_GEOMETRY_PROBE);
  fit->set_radius_m(8.6e-6);
  fit->set_probe_radius_m(2e-6);
  fit->set_w_free(true);
  v1::FitCurve* curve = fit->add_curves();
  for (int i = 0; i < 6; ++i) {
    const double d = 0.3e-6 * i;
    curve->add_indentation_m(d);
    curve->add_force_n(1e-9 * std::pow(d / 1e-6, 1.5));
  }
  auto* axis = study->add_axes();
  axis->set_path("fit.probeRadiusM");
  axis->add_values("1e-6");
  axis->add_values("2e-6");
  JobServiceOptions options = service_->options();
  options.max_fit_library_children = 15;  // one point's 10 grid w pass, two ratios' 20 do not
  JobService bounded(*store_, notifier_, options);
  auto refused = bounded.submit(request);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(
      refused.status().message().rfind(
          "study.axes[0].values[1] (fit.probeRadiusM=2e-6): the study's fit points read more than 15", 0),
      0u)
      << refused.status().message();

  axis->set_path("fit.contactWindowRadii");
  axis->set_values(0, "0.05");
  axis->set_values(1, "0.1");
  auto accepted = bounded.submit(request);
  ASSERT_TRUE(accepted.ok()) << accepted.status().to_string();
  v1::ListJobsRequest children;
  children.set_parent_job_id(accepted->job().id());
  auto points = bounded.list(children);
  ASSERT_TRUE(points.ok());
  ASSERT_EQ(points->jobs_size(), 2);
  EXPECT_EQ(points->jobs(0).child_count(), 10) << "the 10 grid values of w, as children of the first point";
  EXPECT_EQ(points->jobs(1).child_count(), 0) << "the same curves: queued once";
}

// The children's result files name an author: the base spec's, else the
// study's, else the submitting user.
TEST_F(JobServiceTest, StudyChildrenCarryTheAuthor) {
  const Identity alice{"alice", false, false};
  auto by_user = service_->submit(study_request({"0.1"}), alice);
  ASSERT_TRUE(by_user.ok()) << by_user.status().to_string();
  EXPECT_EQ(by_user->job().spec().author(), "alice");
  v1::SubmitJobRequest named = study_request({"0.1"});
  named.mutable_spec()->set_author("Alice Example");
  ASSERT_TRUE(service_->submit(named, alice).ok());
  v1::SubmitJobRequest base_named = study_request({"0.1"});
  base_named.mutable_spec()->mutable_study()->mutable_base()->set_author("Base Author");
  ASSERT_TRUE(service_->submit(base_named, alice).ok());
  std::vector<std::string> authors;
  for (int i = 0; i < 3; ++i) {
    const v1::LeaseJobResponse leased = lease();
    ASSERT_TRUE(leased.found());
    authors.push_back(leased.spec().author());
  }
  EXPECT_EQ(authors, (std::vector<std::string>{"alice", "Alice Example", "Base Author"}));
}

TEST_F(JobServiceTest, StudyRunsItsChildrenAndWatchStreamsTheirProgress) {
  auto submitted = service_->submit(study_request({"0.1", "0.2"}, "sweep-1"));
  ASSERT_TRUE(submitted.ok()) << submitted.status().to_string();
  const std::string study = submitted->job().id();
  EXPECT_EQ(submitted->job().child_count(), 2);
  auto again = service_->submit(study_request({"0.1", "0.2"}, "sweep-1"));
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->already_existed());
  EXPECT_EQ(again->job().id(), study);

  std::vector<v1::JobEvent> events;
  std::thread watcher([&] {
    v1::WatchJobRequest request;
    request.set_job_id(study);
    Status s = service_->watch(
        request,
        [&](const v1::JobEvent& e) {
          events.push_back(e);
          return true;
        },
        [] { return false; });
    EXPECT_TRUE(s.ok()) << s.to_string();
  });
  for (int i = 0; i < 2; ++i) {
    const v1::LeaseJobResponse leased = lease();
    ASSERT_TRUE(leased.found());
    EXPECT_FALSE(leased.spec().has_study()) << "a worker gets a child, never the study";
    EXPECT_EQ(leased.spec().compression().max_deformation(), i == 0 ? 0.1 : 0.2);
    EXPECT_EQ(leased.spec().name(),
              std::string("[compression.maxDeformation=") + (i == 0 ? "0.1" : "0.2") + "]");
    EXPECT_TRUE(report_sample(leased.lease(), 0).lease_valid()) << "sample bounds known for the children";
    upload(leased.lease(), kHdf5StandIn);
    v1::FinishJobRequest finish;
    *finish.mutable_lease() = leased.lease();
    ASSERT_TRUE(service_->finish(finish).ok());
  }
  EXPECT_FALSE(lease().found());
  watcher.join();  // ends at the study's terminal event
  auto job = service_->get(study);
  EXPECT_EQ(job->state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(job->children_done(), 2);
  int updates = 0;
  for (const auto& e : events) updates += e.has_child_update() ? 1 : 0;
  EXPECT_EQ(updates, 4);
  EXPECT_EQ(events.back().state_change().state(), v1::Job::SUCCEEDED);

  // ListJobs by parent, in pages; the token is bound to the parent filter.
  v1::ListJobsRequest by_parent;
  by_parent.set_parent_job_id(study);
  by_parent.set_page_size(1);
  auto page = service_->list(by_parent);
  ASSERT_TRUE(page.ok());
  ASSERT_EQ(page->jobs_size(), 1);
  EXPECT_EQ(page->jobs(0).child_index(), 0);
  by_parent.set_page_token(page->next_page_token());
  auto second = service_->list(by_parent);
  ASSERT_TRUE(second.ok());
  ASSERT_EQ(second->jobs_size(), 1);
  EXPECT_EQ(second->jobs(0).child_index(), 1);
  v1::ListJobsRequest unfiltered;
  unfiltered.set_page_token(page->next_page_token());
  EXPECT_EQ(service_->list(unfiltered).status().code(), StatusCode::kInvalidArgument);
  // Another user sees neither the study nor its children.
  const Identity bob{"bob", false, false};
  EXPECT_EQ(service_->get(study, bob).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(service_->list(by_parent, bob).status().code(), StatusCode::kNotFound);

  // Delete: the study's children and their result files go with it.
  const std::int64_t first_child = *parse_job_name(study) + 1;
  ASSERT_TRUE(fs::exists(service_->result_path(first_child)));
  EXPECT_EQ(service_->delete_job(job_name(first_child)).code(), StatusCode::kFailedPrecondition);
  ASSERT_TRUE(service_->delete_job(study).ok());
  EXPECT_FALSE(fs::exists(service_->result_path(first_child)));
  EXPECT_EQ(service_->get(job_name(first_child)).status().code(), StatusCode::kNotFound);
}

TEST_F(JobServiceTest, CancellingAStudyStopsItsRunningChild) {
  auto submitted = service_->submit(study_request({"0.1", "0.2", "0.3"}));
  ASSERT_TRUE(submitted.ok());
  const v1::LeaseJobResponse running = lease();
  ASSERT_TRUE(running.found());
  auto cancelled = service_->cancel(submitted->job().id());
  ASSERT_TRUE(cancelled.ok());
  EXPECT_EQ(cancelled->state(), v1::Job::CANCELLED);
  const v1::ReportAck ack = report_sample(running.lease(), 0);
  EXPECT_FALSE(ack.lease_valid());
  EXPECT_TRUE(ack.cancelled()) << "the running child's worker is told to stop";
  EXPECT_FALSE(lease().found()) << "the queued children were cancelled too";
}

TEST(JobRunnerTest, ReportsEverySampleAndWritesTheCurve) {
  const jobs::SceneRegistry registry;
  const fs::path path = fs::temp_directory_path() / ("cellflow_runner_" + std::to_string(getpid()) + ".h5");
  const v1::JobSpec spec = small_compression(4);
  std::vector<v1::ForceSample> samples;
  double last_progress = -1;
  worker::JobEvents events;
  events.force_sample = [&](const v1::ForceSample& s) { samples.push_back(s); };
  events.progress = [&](double f, const std::string&) {
    EXPECT_GE(f, last_progress - 1e-12);  // progress does not go backwards
    last_progress = f;
  };
  worker::RunOptions options;
  options.result_path = path.string();
  const worker::RunOutcome outcome = worker::run_job(registry, spec, options, events);
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.to_string();
  EXPECT_EQ(registry.conversions(), 1);  // validation, estimate and run share one conversion
  EXPECT_TRUE(outcome.result_written);
  ASSERT_EQ(samples.size(), 4u);
  EXPECT_DOUBLE_EQ(last_progress, 1.0);
  auto params = jobs::to_params(spec.compression());
  ASSERT_TRUE(params.ok());
  const auto reference = scenes::run_compression(*params);
  ASSERT_EQ(reference.curve.size(), 4u);
  auto force = io::read_observable(path.string(), "force_n");
  ASSERT_TRUE(force.ok());
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(samples[i].index(), i);
    EXPECT_EQ(samples[i].force_n(), reference.curve[i].force_n);  // same code, same inputs: bitwise
    EXPECT_EQ(force->value[i], reference.curve[i].force_n);
    EXPECT_EQ(force->step[i], i + 1);
  }
  auto frames = io::count_position_frames(path.string(), "cell");
  ASSERT_TRUE(frames.ok());
  EXPECT_EQ(*frames, 5);  // reference + every point (4 points <= 10 frames)
  fs::remove(path);
}

TEST(JobRunnerTest, StopsWhenAskedAndKeepsWhatWasComputed) {
  const jobs::SceneRegistry registry;
  const fs::path path =
      fs::temp_directory_path() / ("cellflow_runner_stop_" + std::to_string(getpid()) + ".h5");
  int count = 0;
  worker::JobEvents events;
  events.force_sample = [&](const v1::ForceSample&) { ++count; };
  events.should_stop = [&] { return count >= 2; };
  worker::RunOptions options;
  options.result_path = path.string();
  const worker::RunOutcome outcome = worker::run_job(registry, small_compression(8), options, events);
  EXPECT_EQ(outcome.status.code(), StatusCode::kCancelled) << outcome.status.to_string();
  EXPECT_GE(outcome.samples, 2);
  EXPECT_LT(outcome.samples, 8);
  EXPECT_TRUE(outcome.result_written);
  auto force = io::read_observable(path.string(), "force_n");
  ASSERT_TRUE(force.ok());
  EXPECT_EQ(static_cast<int>(force->value.size()), outcome.samples);
  fs::remove(path);
}

// The runner's flow case: an invalid spec is refused naming the field, a
// tiny valid one runs in-process, reports every sample with increasing strain
// and writes them, the trajectory and the summary.
TEST(JobRunnerTest, ShearFlowRunsAndWritesItsResult) {
  const jobs::SceneRegistry registry;
  v1::JobSpec spec;
  spec.mutable_shear_flow()->set_fluid_viscosity_pa_s(1e-3);
  worker::RunOptions options;
  options.result_path =
      (fs::temp_directory_path() / ("cellflow_runner_flow_" + std::to_string(::getpid()) + ".h5")).string();
  const worker::RunOutcome refused = worker::run_job(registry, spec, options, {});
  EXPECT_EQ(refused.status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status.message().find("shear_flow.cell"), std::string::npos)
      << refused.status.to_string();
  EXPECT_EQ(worker::run_job(registry, v1::JobSpec(), options, {}).status.code(),
            StatusCode::kInvalidArgument);

  auto* flow = spec.mutable_shear_flow();
  flow->mutable_cell()->set_radius_m(4e-6);
  flow->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  flow->mutable_cell()->set_target_vertex_count(300);
  flow->set_capillary_number(0.2);
  auto* n = flow->mutable_numerics();
  n->set_cells_per_radius(3);
  n->set_box_x_radii(5);
  n->set_box_y_radii(6);
  n->set_box_z_radii(4);
  n->set_max_strain(1.0);
  options.threads = 1;
  std::vector<v1::DeformationSample> samples;
  worker::JobEvents events;
  events.deformation_sample = [&](const v1::DeformationSample& s) { samples.push_back(s); };
  const worker::RunOutcome outcome = worker::run_job(registry, spec, options, events);
  ASSERT_TRUE(outcome.status.ok()) << outcome.status.to_string();
  EXPECT_TRUE(outcome.result_written);
  ASSERT_EQ(outcome.samples, static_cast<int>(samples.size()));
  ASSERT_GE(samples.size(), 10u);  // every 0.1 strain to 1
  for (std::size_t i = 1; i < samples.size(); ++i) EXPECT_GT(samples[i].strain(), samples[i - 1].strain());
  auto strain = io::read_observable(options.result_path, "strain");
  ASSERT_TRUE(strain.ok()) << strain.status().to_string();
  ASSERT_EQ(strain->value.size(), samples.size());
  EXPECT_EQ(strain->value.back(), samples.back().strain());
  // Snapshots every strain unit (the default): t = 0 and t = 1.
  auto frames = io::count_position_frames(options.result_path, "cell");
  ASSERT_TRUE(frames.ok());
  EXPECT_EQ(*frames, 2);
  EXPECT_EQ(*io::count_field_frames(options.result_path, "fluid_velocity"), 0);  // not asked for
  EXPECT_EQ(*io::read_string(options.result_path, "/summary/stop"), "max_strain");
  fs::remove(options.result_path);
}

// Checkpoints (server/job_service_checkpoints.cc): fenced by the lease,
// replacing the previous one, announced to the next attempt, fetched by it
// only, removed when the job ends.
class CheckpointServiceTest : public JobServiceTest {
 protected:
  Status upload_checkpoint(JobService& service, const v1::Lease& lease, const std::string& bytes,
                           std::int64_t step, int sample) {
    auto up = service.begin_checkpoint_upload(lease);
    if (!up.ok()) return up.status();
    if (Status s = (*up)->write(0, bytes); !s.ok()) return s;
    v1::CheckpointInfo info;
    info.set_time_step(step);
    info.set_last_sample_index(sample);
    auto size = service.commit_checkpoint(lease, info, **up);
    return size.ok() ? Status() : size.status();
  }
  StatusOr<std::string> fetch(const v1::Lease& lease, v1::CheckpointInfo* info = nullptr) {
    v1::FetchCheckpointRequest request;
    *request.mutable_lease() = lease;
    std::string bytes;
    Status s = service_->fetch_checkpoint(request, [&](const v1::CheckpointChunk& chunk) {
      if (chunk.has_info() && info) *info = chunk.info();
      bytes += chunk.data();
      return true;
    });
    if (!s.ok()) return s;
    return bytes;
  }
  fs::path stored(int job) const { return service_->checkpoint_path(job); }
  static std::string read_text(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
};

TEST_F(CheckpointServiceTest, FencedReplacedAnnouncedFetchedAndRemovedAtTheEnd) {
  const std::string id = submit(small_compression());
  const v1::LeaseJobResponse first = lease();
  EXPECT_FALSE(first.has_checkpoint());
  ASSERT_TRUE(upload_checkpoint(*service_, first.lease(), "first", 10, 1).ok());
  EXPECT_EQ(read_text(stored(1)), "first");
  ASSERT_TRUE(upload_checkpoint(*service_, first.lease(), "second!", 20, 2).ok());
  EXPECT_EQ(read_text(stored(1)), "second!");  // replaced
  // A stale token, a sample index beyond the job's range and an empty upload are refused.
  v1::Lease stale = first.lease();
  stale.set_lease_token("0123456789abcdef0123456789abcdef");
  EXPECT_EQ(upload_checkpoint(*service_, stale, "forged", 30, 3).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(upload_checkpoint(*service_, first.lease(), "x", 30, 99).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(upload_checkpoint(*service_, first.lease(), "", 30, 3).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(read_text(stored(1)), "second!");

  // Handed back, leased again: the new attempt is told and fetches it; the old lease cannot.
  v1::ReleaseJobRequest release;
  *release.mutable_lease() = first.lease();
  ASSERT_TRUE(service_->release(release).ok());
  const v1::LeaseJobResponse second = lease();
  ASSERT_TRUE(second.has_checkpoint());
  EXPECT_EQ(second.checkpoint().size_bytes(), 7);
  EXPECT_EQ(second.checkpoint().attempt(), first.lease().attempt());
  EXPECT_EQ(second.checkpoint().time_step(), 20);
  EXPECT_EQ(second.checkpoint().last_sample_index(), 2);
  v1::CheckpointInfo info;
  auto bytes = fetch(second.lease(), &info);
  ASSERT_TRUE(bytes.ok()) << bytes.status().to_string();
  EXPECT_EQ(*bytes, "second!");
  EXPECT_EQ(info.time_step(), 20);
  EXPECT_EQ(fetch(first.lease()).status().code(), StatusCode::kFailedPrecondition);

  // The job succeeds: the checkpoint and its record are gone.
  upload(second.lease(), kHdf5StandIn);
  v1::FinishJobRequest finish;
  *finish.mutable_lease() = second.lease();
  ASSERT_TRUE(service_->finish(finish).ok());
  EXPECT_FALSE(fs::exists(stored(1)));
  EXPECT_FALSE(store_->checkpoint(1)->has_value());
}

TEST_F(CheckpointServiceTest, OverTheLimitRefusedAndCancelOrDeleteRemovesIt) {
  JobServiceOptions options = service_->options();
  options.max_checkpoint_bytes = 10;
  JobService strict(*store_, notifier_, options);
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  const std::string id = strict.submit(request)->job().id();
  v1::LeaseJobRequest lease_request;
  lease_request.set_worker_id("w");
  const v1::LeaseJobResponse leased = *strict.lease(lease_request, [] { return false; });
  EXPECT_EQ(upload_checkpoint(strict, leased.lease(), std::string(11, 'x'), 10, 1).code(),
            StatusCode::kResourceExhausted);
  EXPECT_FALSE(fs::exists(stored(1)));
  ASSERT_TRUE(upload_checkpoint(strict, leased.lease(), std::string(10, 'x'), 10, 1).ok());
  EXPECT_TRUE(fs::exists(stored(1)));
  ASSERT_TRUE(strict.cancel(id).ok());
  EXPECT_FALSE(fs::exists(stored(1)));
  EXPECT_FALSE(store_->checkpoint(1)->has_value());
  ASSERT_TRUE(strict.delete_job(id).ok());  // no row left to block the delete
  for (const auto& entry : fs::directory_iterator(dir_ / "checkpoints"))
    ADD_FAILURE() << "left behind: " << entry.path();
}

}  // namespace
}  // namespace cellflow::server
