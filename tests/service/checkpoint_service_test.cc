// Checkpoint and restart through the service (issue 16 item 4): a real
// server, a real worker running a flow job with a checkpoint every second,
// the worker killed with SIGKILL at about 60 % of the run (after at least one
// checkpoint reached the server), a new worker resumes from that checkpoint.
// The resumed run is bit-identical to an uninterrupted one (every D sample
// and the final positions; the scene has no random numbers and the worker
// runs on one thread like the reference), each sample index reaches the
// watcher once, the resumed attempt computes only what was left, and the
// checkpoint is deleted when the job succeeds. The same for a suspension
// job (three coarse cells): killed after its first checkpoint upload, it
// completes on another worker from that checkpoint, bit-identical too.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <regex>

#include "io/h5md.h"
#include "jobs/job_spec.h"
#include "jobs/suspension/suspension_spec.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

// The tiny flow of service_shear_flow_test (3 nodes per radius, 15 x 18 x 12
// nodes, 300 vertices) with the steady stop off: about 550 time steps per
// strain unit, 0.15-0.3 s per strain unit on one core.
v1::JobSpec checkpointed_flow(double max_strain = 16.0) {
  v1::JobSpec spec;
  spec.set_name("checkpointed shear flow");
  auto* flow = spec.mutable_shear_flow();
  flow->mutable_cell()->set_radius_m(4e-6);
  flow->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  flow->mutable_cell()->mutable_material()->set_poisson_ratio(0.45);
  flow->mutable_cell()->set_target_vertex_count(300);
  flow->set_capillary_number(0.2);
  auto* n = flow->mutable_numerics();
  n->set_cells_per_radius(3);
  n->set_box_x_radii(5);
  n->set_box_y_radii(6);
  n->set_box_z_radii(4);
  n->set_max_strain(max_strain);
  n->set_sample_every_strain(0.1);
  n->set_snapshot_every_strain(1.0);
  n->set_steady_tolerance(0.0);
  return spec;
}

// The tiny suspension of service_suspension_test (three cells of ~300
// vertices, 15 x 24 x 12 nodes) run longer, every 0.1 strain sampled.
v1::JobSpec checkpointed_suspension(double max_strain) {
  v1::JobSpec spec;
  spec.set_name("checkpointed suspension");
  auto* s = spec.mutable_suspension();
  auto* cells = s->add_cells();
  cells->mutable_cell()->set_radius_m(4e-6);
  cells->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  cells->mutable_cell()->set_target_vertex_count(300);
  cells->set_count(3);
  s->set_capillary_number(0.2);
  auto* n = s->mutable_numerics();
  n->set_average_after_strain(0.5);
  auto* flow = n->mutable_flow();
  flow->set_cells_per_radius(3);
  flow->set_max_strain(max_strain);
  flow->set_sample_every_strain(0.1);
  flow->set_snapshot_every_strain(0.5);
  return spec;
}

// The steps after which the worker's log says a checkpoint was uploaded, in order.
std::vector<std::int64_t> uploaded_checkpoint_steps(const std::string& log) {
  std::vector<std::int64_t> steps;
  static const std::regex uploaded(R"(checkpoint after step (\d+) \(sample \d+\): \d+ bytes)");
  for (std::sregex_iterator it(log.begin(), log.end(), uploaded), end; it != end; ++it)
    steps.push_back(std::stoll((*it)[1]));
  return steps;
}

// "finished ok (N sample(s), X s)" of the worker log: the attempt's wall time.
double attempt_seconds(const std::string& log) {
  std::smatch m;
  static const std::regex finished(R"(finished ok \(\d+ sample\(s\), ([0-9.]+) s\))");
  return std::regex_search(log, m, finished) ? std::stod(m[1]) : -1.0;
}

TEST_F(ServiceTest, KilledFlowWorkerIsResumedFromItsCheckpointBitIdentically) {
  // Long enough that the fixed costs (process starts, the 1 s lease expiry)
  // are small against the run.
  const v1::JobSpec spec = checkpointed_flow(24.0);

  // The uninterrupted run in this process, on one thread as the worker.
  auto params = jobs::to_params(spec.shear_flow());
  ASSERT_TRUE(params.ok()) << params.status().to_string();
  params->numerics.threads = 1;
  std::vector<double> reference_last_frame;
  scenes::ShearFlowCallbacks reference_callbacks;
  reference_callbacks.on_positions = [&](int, double, std::span<const double> x) {
    reference_last_frame.assign(x.begin(), x.end());
  };
  const auto reference_start = std::chrono::steady_clock::now();
  const scenes::ShearFlowResult reference = scenes::run_shear_flow(*params, reference_callbacks);
  const double reference_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - reference_start).count();
  ASSERT_TRUE(reference.status.ok()) << reference.status.to_string();
  const int total_samples = static_cast<int>(reference.samples.size());
  ASSERT_GE(total_samples, 241);  // every 0.1 strain and the final one

  start_server(0, {"--lease-ttl-s", "1"});
  const fs::path checkpoint = dir_ / "data" / "checkpoints" / "job-1.ckpt";
  const auto submitted = std::chrono::steady_clock::now();
  const std::string id = submit(spec);
  ASSERT_EQ(id, "job-1");
  Watcher watcher(*client_, id);
  // A checkpoint every sixth of the in-process run's wall time, at most a
  // second (as the suspension test below: on a fast machine the whole run
  // takes about 3 s).
  const std::string interval = std::to_string(std::min(1.0, reference_s / 6.0));
  Process* first = start_worker({"--threads", "1", "--checkpoint-interval-s", interval});
  // Kill at 60 % of the samples, once a checkpoint is on the server and the
  // worker has logged its upload (the server commits it before the worker
  // logs it: a kill that falls in between leaves no logged upload to resume
  // from, which is what the assertions below compare with).
  ASSERT_TRUE(eventually(
      [&] {
        return watcher.max_sample_index() >= (6 * total_samples) / 10 && fs::exists(checkpoint) &&
               !uploaded_checkpoint_steps(first->log()).empty();
      },
      120s))
      << "samples " << watcher.max_sample_index() << ", checkpoint " << fs::exists(checkpoint) << "\n"
      << first->log();
  first->signal(SIGKILL);
  first->wait();
  const double killed_after_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - submitted).count();
  const int delivered_before_kill = watcher.max_sample_index();
  EXPECT_LT(delivered_before_kill, total_samples - 1) << "the run ended before the kill";
  EXPECT_NE(first->log().find("checkpoint after step"), std::string::npos) << first->log();

  Process* second = start_worker({"--threads", "1", "--checkpoint-interval-s", interval});
  watcher.join();
  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - submitted).count();
  ASSERT_TRUE(watcher.status().ok()) << watcher.status().error_message();
  const v1::Job job = get(id);
  ASSERT_EQ(job.state(), v1::Job::SUCCEEDED) << job.reason();
  EXPECT_EQ(job.attempt(), 2);
  ASSERT_TRUE(eventually([&] { return !second->log().empty() && attempt_seconds(second->log()) > 0; }, 10s));
  const std::string log = second->log();
  EXPECT_NE(log.find("resuming from the checkpoint of attempt 1"), std::string::npos) << log;
  EXPECT_NE(log.find("resumed after step"), std::string::npos) << log;

  // Each sample index once, in order; every D bit-identical to the uninterrupted run.
  std::vector<v1::DeformationSample> samples;
  for (const v1::JobEvent& e : watcher.events())
    if (e.has_deformation_sample()) samples.push_back(e.deformation_sample());
  ASSERT_EQ(static_cast<int>(samples.size()), total_samples);
  for (int i = 0; i < total_samples; ++i) {
    EXPECT_EQ(samples[i].index(), i);
    EXPECT_EQ(samples[i].taylor_deformation(), reference.samples[i].taylor_deformation) << "sample " << i;
  }

  // The result file: the whole run (every sample and frame), final positions equal.
  const std::string h5 = (dir_ / "resumed.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  auto frames = io::count_position_frames(h5, "cell");
  ASSERT_TRUE(frames.ok()) << frames.status().to_string();
  EXPECT_EQ(*frames, 25);  // strain 0, 1, ..., 24
  auto last = io::read_position_frame(h5, "cell", *frames - 1);
  ASSERT_TRUE(last.ok()) << last.status().to_string();
  EXPECT_EQ(last->positions_m, reference_last_frame);

  // The checkpoint is gone with the job's end.
  EXPECT_FALSE(fs::exists(checkpoint));

  // Work. The resumed attempt stepped only from the checkpoint on: a step
  // count, immune to the load of a shared machine (a restart from zero would
  // resume after step 0). The times are printed, not bounded: the attempt's
  // wall time against the in-process run's depends on what else the machine
  // runs meanwhile (it failed once beside two long tests), and the whole,
  // total_s, carries fixed costs (the 1 s lease expiry, two worker starts)
  // that do not shrink with the run.
  std::smatch resumed;
  ASSERT_TRUE(std::regex_search(log, resumed, std::regex(R"(resumed after step (\d+))")));
  const std::int64_t resumed_step = std::stoll(resumed[1]);
  // From the last checkpoint that reached the server: the last one the
  // killed worker logged or, when the server committed another between the
  // worker's upload and its log line (the SIGKILL can fall in between), a
  // later one, which is still a checkpoint the first attempt took.
  const std::vector<std::int64_t> uploaded = uploaded_checkpoint_steps(first->log());
  ASSERT_FALSE(uploaded.empty());
  EXPECT_GE(resumed_step, uploaded.back());
  EXPECT_GT(resumed_step, 0);
  EXPECT_LT(resumed_step, reference.time_steps);
  const double second_attempt_s = attempt_seconds(log);
  std::printf(
      "checkpointed flow: uninterrupted in-process %.2f s; through the service with a SIGKILL at sample %d "
      "of %d "
      "(%.2f s after submit) %.2f s in all (%.2f runs); the resumed attempt stepped from %lld of %lld steps "
      "in "
      "%.2f s (%.2f runs)\n",
      reference_s, delivered_before_kill, total_samples, killed_after_s, total_s, total_s / reference_s,
      static_cast<long long>(resumed_step), static_cast<long long>(reference.time_steps), second_attempt_s,
      second_attempt_s / reference_s);
}

// SIGTERM (Slurm's warning before a time limit or a preemption): the worker
// runs on to its next sample, uploads a checkpoint there, hands the job back;
// the next worker resumes from it, and the result is again bit-identical.
TEST_F(ServiceTest, StoppedFlowWorkerCheckpointsBeforeHandingTheJobBack) {
  const v1::JobSpec spec = checkpointed_flow(8.0);
  auto params = jobs::to_params(spec.shear_flow());
  ASSERT_TRUE(params.ok()) << params.status().to_string();
  params->numerics.threads = 1;
  const scenes::ShearFlowResult reference = scenes::run_shear_flow(*params);
  ASSERT_TRUE(reference.status.ok()) << reference.status.to_string();
  const int total_samples = static_cast<int>(reference.samples.size());

  start_server(0, {"--lease-ttl-s", "1"});
  const std::string id = submit(spec);
  Watcher watcher(*client_, id);
  // No periodic checkpoint: the only one is taken at the stop.
  Process* first = start_worker({"--threads", "1", "--checkpoint-interval-s", "1000"});
  ASSERT_TRUE(eventually([&] { return watcher.max_sample_index() >= total_samples / 2; }, 120s))
      << first->log();
  first->signal(SIGTERM);
  ASSERT_TRUE(first->wait_for(30s));
  const std::string first_log = first->log();
  EXPECT_NE(first_log.find("checkpoint after step"), std::string::npos) << first_log;
  EXPECT_NE(first_log.find("handed back"), std::string::npos) << first_log;
  EXPECT_TRUE(fs::exists(dir_ / "data" / "checkpoints" / "job-1.ckpt"));

  Process* second = start_worker({"--threads", "1", "--checkpoint-interval-s", "1000"});
  watcher.join();
  const v1::Job job = get(id);
  ASSERT_EQ(job.state(), v1::Job::SUCCEEDED) << job.reason();
  ASSERT_TRUE(eventually([&] { return attempt_seconds(second->log()) > 0; }, 10s));
  EXPECT_NE(second->log().find("resumed after step"), std::string::npos) << second->log();
  std::vector<v1::DeformationSample> samples;
  for (const v1::JobEvent& e : watcher.events())
    if (e.has_deformation_sample()) samples.push_back(e.deformation_sample());
  ASSERT_EQ(static_cast<int>(samples.size()), total_samples);
  for (int i = 0; i < total_samples; ++i) {
    EXPECT_EQ(samples[i].index(), i);
    EXPECT_EQ(samples[i].taylor_deformation(), reference.samples[i].taylor_deformation) << "sample " << i;
  }
  EXPECT_FALSE(fs::exists(dir_ / "data" / "checkpoints" / "job-1.ckpt"));
}

// A suspension job: the worker is killed right after its first checkpoint
// upload; the next worker resumes from that checkpoint (its start step > 0)
// and the samples it reports continue the first attempt's: each index once,
// every value bit-identical to an uninterrupted in-process run.
TEST_F(ServiceTest, KilledSuspensionWorkerIsResumedFromItsCheckpoint) {
  const v1::JobSpec spec = checkpointed_suspension(4.0);
  StatusOr<scenes::PlannedSuspension> planned = jobs::plan(spec.suspension());
  ASSERT_TRUE(planned.ok()) << planned.status().to_string();
  planned->set_threads(1);  // as the worker
  const auto reference_start = std::chrono::steady_clock::now();
  const scenes::SuspensionResult reference = scenes::run_suspension(*planned);
  const double reference_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - reference_start).count();
  ASSERT_TRUE(reference.status.ok()) << reference.status.to_string();
  const int total_samples = static_cast<int>(reference.samples.size());
  ASSERT_EQ(total_samples, 41);  // every 0.1 strain to 4

  start_server(0, {"--lease-ttl-s", "1"});
  const fs::path checkpoint = dir_ / "data" / "checkpoints" / "job-1.ckpt";
  const std::string id = submit(spec);
  ASSERT_EQ(id, "job-1");
  Watcher watcher(*client_, id);
  // A checkpoint every sixth of the in-process run's wall time (at most a
  // second: on a fast machine the whole run takes well under one, and a
  // fixed second let it end before the first checkpoint); killed once the
  // first is on the server and its upload finished (the worker logs it
  // after the server committed it).
  const std::string interval = std::to_string(std::min(1.0, reference_s / 6.0));
  Process* first = start_worker({"--threads", "1", "--checkpoint-interval-s", interval});
  const bool uploaded_one = eventually(
      [&] { return fs::exists(checkpoint) && !uploaded_checkpoint_steps(first->log()).empty(); }, 120s);
  first->signal(SIGKILL);
  first->wait();
  const int delivered_before_kill = watcher.max_sample_index();
  const std::vector<std::int64_t> uploaded = uploaded_checkpoint_steps(first->log());
  // The next worker before any assertion: the watcher ends with the job.
  Process* second = start_worker({"--threads", "1", "--checkpoint-interval-s", interval});
  ASSERT_TRUE(uploaded_one) << first->log();
  ASSERT_FALSE(uploaded.empty()) << first->log();
  EXPECT_LT(delivered_before_kill, total_samples - 1) << "the run ended before the kill";
  watcher.join();
  ASSERT_TRUE(watcher.status().ok()) << watcher.status().error_message();
  const v1::Job job = get(id);
  ASSERT_EQ(job.state(), v1::Job::SUCCEEDED) << job.reason();
  EXPECT_EQ(job.attempt(), 2);
  ASSERT_TRUE(eventually([&] { return attempt_seconds(second->log()) > 0; }, 10s)) << second->log();
  const std::string log = second->log();
  EXPECT_NE(log.find("resuming from the checkpoint of attempt 1"), std::string::npos) << log;
  std::smatch resumed;
  ASSERT_TRUE(std::regex_search(log, resumed, std::regex(R"(resumed after step (\d+))"))) << log;
  const std::int64_t resumed_step = std::stoll(resumed[1]);
  EXPECT_GT(resumed_step, 0);
  EXPECT_LT(resumed_step, reference.time_steps);
  // From the last checkpoint that reached the server: the first one or,
  // when another finished between the poll and the kill, a later one.
  EXPECT_GE(resumed_step, uploaded.front());

  // Each sample index once, in order: the first attempt's, then the resumed
  // attempt's from its checkpoint on, every value equal to the uninterrupted run.
  std::vector<v1::SuspensionSample> samples;
  for (const v1::JobEvent& e : watcher.events())
    if (e.has_suspension_sample()) samples.push_back(e.suspension_sample());
  ASSERT_EQ(static_cast<int>(samples.size()), total_samples);
  for (int i = 0; i < total_samples; ++i) {
    const scenes::SuspensionSample& r = reference.samples[static_cast<std::size_t>(i)];
    EXPECT_EQ(samples[i].index(), i);
    EXPECT_EQ(samples[i].strain(), r.strain_units) << "sample " << i;
    EXPECT_EQ(samples[i].mean_taylor_deformation(), r.mean_taylor_deformation) << "sample " << i;
    EXPECT_EQ(samples[i].relative_viscosity(), r.relative_viscosity) << "sample " << i;
    EXPECT_EQ(samples[i].average_taylor_deformation(), r.average_taylor_deformation) << "sample " << i;
    EXPECT_EQ(samples[i].contact_pairs(), r.contact_pairs) << "sample " << i;
    ASSERT_EQ(samples[i].cells_size(), 3);
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(samples[i].cells(c).centroid_m(0), r.cells[static_cast<std::size_t>(c)].centroid_m[0])
          << "sample " << i << " cell " << c;
  }

  // The result file holds the whole run: every frame, strain 0, 0.5, ..., 4.
  const std::string h5 = (dir_ / "suspension.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  auto frames = io::count_position_frames(h5, "cell");
  ASSERT_TRUE(frames.ok()) << frames.status().to_string();
  EXPECT_EQ(*frames, 9);
  EXPECT_FALSE(fs::exists(checkpoint));
  std::printf(
      "checkpointed suspension: uninterrupted in-process %.2f s; killed after the first upload (step %lld, "
      "%d of %d samples delivered), resumed after step %lld of %lld in %.2f s\n",
      reference_s, static_cast<long long>(uploaded.front()), delivered_before_kill + 1, total_samples,
      static_cast<long long>(resumed_step), static_cast<long long>(reference.time_steps),
      attempt_seconds(log));
}

}  // namespace
}  // namespace cellflow::testing
