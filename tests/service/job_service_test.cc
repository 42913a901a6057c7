// The service logic in one process, without gRPC: validation at submit,
// the memory limit, page tokens, watch replay and live follow, fenced worker
// reports and uploads; and the worker's job runner (spec -> scene -> samples
// and HDF5).
#include "server/job_service.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <thread>

#include "io/h5md.h"
#include "jobs/job_spec.h"
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
  upload(leased.lease(), "HDF5 stand-in");
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
  EXPECT_EQ(downloaded, "HDF5 stand-in");
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

// The worker's runner in process: the samples it reports and the file it
// writes hold the library's curve, bit for bit.
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

}  // namespace
}  // namespace cellflow::server
