// The SQLite job store without gRPC: migration, idempotent submit, claims,
// lease fencing, expiry and the attempt limit, sample de-duplication across
// attempts, cancellation, paging, and concurrent claims from two connections.
#include "server/store.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <set>
#include <thread>

namespace cellflow::server {
namespace {

namespace fs = std::filesystem;
constexpr std::int64_t kTtl = 1000;  // ms

v1::JobSpec spec_named(const std::string& name) {
  v1::JobSpec spec;
  spec.set_name(name);
  spec.mutable_compression()->set_max_deformation(0.1);
  return spec;
}

v1::JobEvent force_sample(int index) {
  v1::JobEvent event;
  event.mutable_force_sample()->set_index(index);
  event.mutable_force_sample()->set_force_n(1e-9 * index);
  return event;
}

class StoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_store_test_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    options_.path = (dir_ / "jobs.sqlite").string();
    options_.max_attempts = 3;
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::unique_ptr<Store> open() {
    auto store = Store::open(options_);
    EXPECT_TRUE(store.ok()) << store.status().to_string();
    return store.ok() ? std::move(*store) : nullptr;
  }

  static std::int64_t id(const v1::Job& job) { return *parse_job_name(job.id()); }

  fs::path dir_;
  StoreOptions options_;
};

TEST_F(StoreTest, MigratesOnOpenAndKeepsJobsAcrossReopen) {
  {
    auto store = open();
    EXPECT_EQ(store->schema_version(), Store::kSchemaVersion);
    ASSERT_TRUE(store->submit(spec_named("a"), "r1", 0, 1000).ok());
  }
  auto store = open();
  EXPECT_EQ(store->schema_version(), Store::kSchemaVersion);
  auto job = store->get(1);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->spec().name(), "a");
  EXPECT_EQ(job->state(), v1::Job::QUEUED);
  EXPECT_EQ(job->last_sequence(), 1);
}

TEST_F(StoreTest, SameRequestIdGivesSameJob) {
  auto store = open();
  auto first = store->submit(spec_named("a"), "same", 0, 1000);
  auto second = store->submit(spec_named("b"), "same", 0, 2000);
  ASSERT_TRUE(first.ok() && second.ok());
  EXPECT_FALSE(first->existed);
  EXPECT_TRUE(second->existed);
  EXPECT_EQ(first->job.id(), second->job.id());
  EXPECT_EQ(second->job.spec().name(), "a");
  EXPECT_EQ(store->count(v1::Job::QUEUED), 1);
  auto other = store->submit(spec_named("c"), "", 0, 3000);
  auto another = store->submit(spec_named("d"), "", 0, 3000);
  ASSERT_TRUE(other.ok() && another.ok());
  EXPECT_NE(other->job.id(), another->job.id());  // no request_id: always a new job
  EXPECT_EQ(store->count(v1::Job::QUEUED), 3);
}

TEST_F(StoreTest, ClaimTakesOldestWithFreshTokens) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  ASSERT_TRUE(store->submit(spec_named("b"), "", 0, 0).ok());
  auto c1 = store->claim("w1", 100, kTtl);
  auto c2 = store->claim("w2", 100, kTtl);
  auto c3 = store->claim("w3", 100, kTtl);
  ASSERT_TRUE(c1.ok() && c2.ok() && c3.ok());
  ASSERT_TRUE(c1->has_value() && c2->has_value());
  EXPECT_FALSE(c3->has_value());
  EXPECT_EQ((*c1)->job.id(), "job-1");
  EXPECT_EQ((*c2)->job.id(), "job-2");
  EXPECT_EQ((*c1)->job.state(), v1::Job::RUNNING);
  EXPECT_EQ((*c1)->job.attempt(), 1);
  EXPECT_EQ((*c1)->job.worker_id(), "w1");
  EXPECT_EQ((*c1)->lease_token.size(), 32u);
  EXPECT_NE((*c1)->lease_token, (*c2)->lease_token);
  EXPECT_EQ((*c1)->last_delivered_sample_index, -1);
}

TEST_F(StoreTest, StaleLeaseTokenCannotCompleteOrReport) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  auto first = store->claim("w1", 0, kTtl);
  ASSERT_TRUE(first.ok() && first->has_value());
  const std::string stale = (*first)->lease_token;
  auto expired = store->requeue_expired(kTtl + 1);
  ASSERT_TRUE(expired.ok());
  ASSERT_EQ(expired->size(), 1u);
  EXPECT_EQ((*expired)[0].state(), v1::Job::QUEUED);
  auto second = store->claim("w2", kTtl + 2, kTtl);
  ASSERT_TRUE(second.ok() && second->has_value());
  const std::string fresh = (*second)->lease_token;
  EXPECT_EQ((*second)->job.attempt(), 2);

  // The first worker wakes up: every write it tries is refused.
  auto beat = store->heartbeat(1, stale, kTtl + 3, kTtl);
  ASSERT_TRUE(beat.ok());
  EXPECT_EQ(*beat, LeaseCheck::kLost);
  auto report = store->append_event(1, stale, force_sample(0), 0, kTtl + 3, kTtl);
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->lease, LeaseCheck::kLost);
  EXPECT_EQ(report->sequence, 0);
  auto finished_stale = store->finish(1, stale, 10, kTtl + 4);
  EXPECT_EQ(finished_stale.status().code(), StatusCode::kFailedPrecondition);
  auto failed_stale = store->fail(1, stale, "stale", -1, kTtl + 4);
  EXPECT_EQ(failed_stale.status().code(), StatusCode::kFailedPrecondition);
  bool hook_ran = false;
  auto hooked = store->finish(1, stale, 10, kTtl + 4, [&] {
    hook_ran = true;
    return Status();
  });
  EXPECT_FALSE(hook_ran);  // the result file of a stale attempt is never moved into place
  EXPECT_EQ(store->get(1)->state(), v1::Job::RUNNING);

  // The current lease holder completes it, exactly once.
  auto done = store->finish(1, fresh, 10, kTtl + 5);
  ASSERT_TRUE(done.ok()) << done.status().to_string();
  EXPECT_EQ(done->state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(done->result_size_bytes(), 10);
  EXPECT_EQ(store->finish(1, fresh, 10, kTtl + 6).status().code(), StatusCode::kFailedPrecondition);
}

TEST_F(StoreTest, HeartbeatKeepsLeaseAlive) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  auto claim = store->claim("w1", 0, kTtl);
  ASSERT_TRUE(claim.ok() && claim->has_value());
  auto beat = store->heartbeat(1, (*claim)->lease_token, 900, kTtl);
  ASSERT_TRUE(beat.ok());
  EXPECT_EQ(*beat, LeaseCheck::kValid);
  EXPECT_TRUE(store->requeue_expired(1500)->empty());  // renewed until 1900
  EXPECT_EQ(store->requeue_expired(1901)->size(), 1u);
}

TEST_F(StoreTest, ExpiredLeasesFailTheJobAtTheAttemptLimit) {
  options_.max_attempts = 2;
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  std::int64_t now = 0;
  for (int attempt = 1; attempt <= 2; ++attempt) {
    auto claim = store->claim("w", now, kTtl);
    ASSERT_TRUE(claim.ok() && claim->has_value());
    EXPECT_EQ((*claim)->job.attempt(), attempt);
    now += kTtl + 1;
    auto changed = store->requeue_expired(now);
    ASSERT_TRUE(changed.ok());
    ASSERT_EQ(changed->size(), 1u);
    EXPECT_EQ((*changed)[0].state(), attempt < 2 ? v1::Job::QUEUED : v1::Job::FAILED);
  }
  auto job = store->get(1);
  EXPECT_EQ(job->state(), v1::Job::FAILED);
  EXPECT_NE(job->reason().find("2 attempts"), std::string::npos) << job->reason();
  EXPECT_FALSE(store->claim("w", now, kTtl)->has_value());
}

TEST_F(StoreTest, ReleasedAttemptDoesNotCount) {
  options_.max_attempts = 1;
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  auto first = store->claim("w1", 0, kTtl);
  ASSERT_TRUE(first.ok() && first->has_value());
  auto released = store->release(1, (*first)->lease_token, "worker stopping", 10);
  ASSERT_TRUE(released.ok());
  EXPECT_EQ(released->state(), v1::Job::QUEUED);
  auto second = store->claim("w2", 20, kTtl);
  ASSERT_TRUE(second.ok() && second->has_value());
  EXPECT_EQ((*second)->job.attempt(), 2);
  // One counted attempt (the released one is not) reaches the limit of 1.
  auto changed = store->requeue_expired(20 + kTtl + 1);
  ASSERT_EQ(changed->size(), 1u);
  EXPECT_EQ((*changed)[0].state(), v1::Job::FAILED);
}

TEST_F(StoreTest, RetriedAttemptDoesNotRepeatSamples) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  auto first = store->claim("w1", 0, kTtl);
  ASSERT_TRUE(first.ok() && first->has_value());
  for (int i = 0; i < 3; ++i) {
    auto r = store->append_event(1, (*first)->lease_token, force_sample(i), i, 10, kTtl);
    ASSERT_TRUE(r.ok());
    EXPECT_GT(r->sequence, 0);
  }
  // A resent report of the same attempt is dropped, the lease still renewed.
  auto resent = store->append_event(1, (*first)->lease_token, force_sample(2), 2, 20, kTtl);
  ASSERT_TRUE(resent.ok());
  EXPECT_EQ(resent->lease, LeaseCheck::kValid);
  EXPECT_EQ(resent->sequence, 0);

  ASSERT_EQ(store->requeue_expired(20 + kTtl + 1)->size(), 1u);
  auto second = store->claim("w2", 2000, kTtl);
  ASSERT_TRUE(second.ok() && second->has_value());
  EXPECT_EQ((*second)->last_delivered_sample_index, 2);
  for (int i = 0; i < 5; ++i) {
    auto r = store->append_event(1, (*second)->lease_token, force_sample(i), i, 2010, kTtl);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->sequence > 0, i >= 3) << "sample " << i;
  }
  auto events = store->events_after(1, 0, 1000);
  ASSERT_TRUE(events.ok());
  std::vector<int> indices;
  std::int64_t expected_sequence = 1;
  for (const auto& e : *events) {
    EXPECT_EQ(e.sequence(), expected_sequence++);  // gapless
    if (e.has_force_sample()) indices.push_back(e.force_sample().index());
  }
  EXPECT_EQ(indices, (std::vector<int>{0, 1, 2, 3, 4}));
  // Replay from the middle.
  auto tail = store->events_after(1, 4, 1000);
  ASSERT_TRUE(tail.ok());
  EXPECT_EQ(tail->front().sequence(), 5);
}

TEST_F(StoreTest, CancelEndsTheLease) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  ASSERT_TRUE(store->submit(spec_named("b"), "", 0, 0).ok());
  auto claim = store->claim("w1", 0, kTtl);
  ASSERT_TRUE(claim.ok() && claim->has_value());
  auto cancelled = store->cancel(1, "by test", 5);
  ASSERT_TRUE(cancelled.ok());
  EXPECT_EQ(cancelled->state(), v1::Job::CANCELLED);
  EXPECT_EQ(*store->heartbeat(1, (*claim)->lease_token, 6, kTtl), LeaseCheck::kCancelled);
  EXPECT_EQ(store->append_event(1, (*claim)->lease_token, force_sample(0), 0, 6, kTtl)->lease,
            LeaseCheck::kCancelled);
  EXPECT_EQ(store->finish(1, (*claim)->lease_token, 1, 7).status().code(), StatusCode::kFailedPrecondition);
  EXPECT_TRUE(store->cancel(1, "again", 8).ok());  // cancelling a cancelled job returns it
  // A queued job is cancelled before any worker sees it.
  EXPECT_EQ(store->cancel(2, "queued", 9)->state(), v1::Job::CANCELLED);
  EXPECT_FALSE(store->claim("w2", 10, kTtl)->has_value());
  EXPECT_EQ(store->cancel(99, "missing", 10).status().code(), StatusCode::kNotFound);
}

TEST_F(StoreTest, CannotCancelFinishedJob) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  auto claim = store->claim("w1", 0, kTtl);
  ASSERT_TRUE(store->finish(1, (*claim)->lease_token, 1, 5).ok());
  EXPECT_EQ(store->cancel(1, "late", 6).status().code(), StatusCode::kFailedPrecondition);
}

TEST_F(StoreTest, ListPagesAndFilters) {
  auto store = open();
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(store->submit(spec_named(std::to_string(i)), "", 0, i).ok());
  ASSERT_TRUE(store->claim("w", 10, kTtl)->has_value());  // job-1 running
  auto page1 = store->list(0, 2, v1::Job::STATE_UNSPECIFIED);
  ASSERT_TRUE(page1.ok());
  ASSERT_EQ(page1->size(), 2u);
  EXPECT_EQ((*page1)[1].id(), "job-2");
  auto page2 = store->list(2, 2, v1::Job::STATE_UNSPECIFIED);
  EXPECT_EQ((*page2)[0].id(), "job-3");
  auto queued = store->list(0, 10, v1::Job::QUEUED);
  EXPECT_EQ(queued->size(), 4u);
  auto running = store->list(0, 10, v1::Job::RUNNING);
  ASSERT_EQ(running->size(), 1u);
  EXPECT_EQ((*running)[0].id(), "job-1");
}

TEST_F(StoreTest, RestartExtendsRunningLeases) {
  auto store = open();
  ASSERT_TRUE(store->submit(spec_named("a"), "", 0, 0).ok());
  ASSERT_TRUE(store->claim("w", 0, kTtl)->has_value());
  // The server was down from t = 500 to t = 5000: the worker gets a full TTL to reconnect.
  ASSERT_TRUE(store->extend_running_leases(5000, kTtl).ok());
  EXPECT_TRUE(store->requeue_expired(5500)->empty());
  EXPECT_EQ(store->requeue_expired(6001)->size(), 1u);
}

// Two connections (as two processes would have) claim at once: BEGIN
// IMMEDIATE with the busy timeout serialises them, no job is claimed twice and
// no claim fails with "database is locked".
TEST_F(StoreTest, ConcurrentClaimsFromTwoConnections) {
  constexpr int kJobs = 200;
  auto a = open();
  auto b = open();
  for (int i = 0; i < kJobs; ++i) ASSERT_TRUE(a->submit(spec_named("j"), "", 0, 0).ok());
  std::mutex mutex;
  std::multiset<std::string> claimed;
  std::atomic<int> errors{0};
  auto worker = [&](Store* store, const std::string& name) {
    while (true) {
      auto claim = store->claim(name, 0, kTtl);
      if (!claim.ok()) {
        ++errors;
        continue;
      }
      if (!claim->has_value()) return;
      std::lock_guard lock(mutex);
      claimed.insert((*claim)->job.id());
    }
  };
  std::thread t1(worker, a.get(), "a");
  std::thread t2(worker, b.get(), "b");
  t1.join();
  t2.join();
  EXPECT_EQ(errors.load(), 0);
  EXPECT_EQ(claimed.size(), static_cast<std::size_t>(kJobs));
  EXPECT_EQ(std::set<std::string>(claimed.begin(), claimed.end()).size(), static_cast<std::size_t>(kJobs));
}

TEST(JobName, RoundTrip) {
  EXPECT_EQ(job_name(42), "job-42");
  EXPECT_EQ(parse_job_name("job-42"), 42);
  EXPECT_EQ(parse_job_name("42"), 42);
  EXPECT_FALSE(parse_job_name("job-").has_value());
  EXPECT_FALSE(parse_job_name("job-4x").has_value());
  EXPECT_FALSE(parse_job_name("0").has_value());
}

}  // namespace
}  // namespace cellflow::server
