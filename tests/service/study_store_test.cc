// Studies in the SQLite store: the study and its children inserted in one
// transaction, the study never leased, its state rolled up from its
// children's (RUNNING, SUCCEEDED, FAILED with the count and the first
// reason), ChildUpdate events in the study's log, cancel and delete cascades,
// the children listed by parent, and idempotency over the whole study.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "server/store.h"

namespace cellflow::server {
namespace {

namespace fs = std::filesystem;
constexpr std::int64_t kTtl = 1000;  // ms

v1::JobSpec study_spec() {
  v1::JobSpec spec;
  spec.set_name("sweep");
  auto* study = spec.mutable_study();
  study->mutable_base()->mutable_compression()->set_max_deformation(0.1);
  auto* axis = study->add_axes();
  axis->set_path("compression.maxDeformation");
  for (const char* v : {"0.1", "0.2", "0.3"}) axis->add_values(v);
  return spec;
}

std::vector<Store::StudyChild> children(int n) {
  std::vector<Store::StudyChild> out;
  for (int i = 0; i < n; ++i) {
    Store::StudyChild child;
    child.spec.set_name("child " + std::to_string(i));
    child.spec.mutable_compression()->set_max_deformation(0.1 * (i + 1));
    child.memory_bytes = 1000 * (i + 1);
    out.push_back(std::move(child));
  }
  return out;
}

class StudyStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_study_store_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    options_.path = (dir_ / "jobs.sqlite").string();
    auto store = Store::open(options_);
    ASSERT_TRUE(store.ok()) << store.status().to_string();
    store_ = std::move(*store);
  }
  void TearDown() override {
    store_.reset();
    fs::remove_all(dir_);
  }

  std::int64_t submit_study(int n, const std::string& request_id = "") {
    auto submitted = store_->submit_study(study_spec(), children(n), request_id, 1000, "alice");
    EXPECT_TRUE(submitted.ok()) << submitted.status().to_string();
    return submitted.ok() ? *parse_job_name(submitted->job.id()) : 0;
  }

  Claim claim_one(std::int64_t now = 2000) {
    auto claim = store_->claim("w", now, kTtl);
    EXPECT_TRUE(claim.ok() && claim->has_value());
    return claim.ok() && claim->has_value() ? **claim : Claim{};
  }

  std::vector<v1::ChildUpdate> child_updates(std::int64_t study) {
    std::vector<v1::ChildUpdate> updates;
    auto events = store_->events_after(study, 0, 1000);
    EXPECT_TRUE(events.ok());
    for (const auto& e : *events)
      if (e.has_child_update()) updates.push_back(e.child_update());
    return updates;
  }

  std::vector<v1::Job::State> study_states(std::int64_t study) {
    std::vector<v1::Job::State> states;
    auto events = store_->events_after(study, 0, 1000);
    for (const auto& e : *events)
      if (e.has_state_change()) states.push_back(e.state_change().state());
    return states;
  }

  fs::path dir_;
  StoreOptions options_;
  std::unique_ptr<Store> store_;
};

TEST_F(StudyStoreTest, StudyAndChildrenAreInsertedTogetherAndTheStudyIsNeverLeased) {
  EXPECT_GE(store_->schema_version(), 3);
  const std::int64_t study = submit_study(3);
  auto job = store_->get(study);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state(), v1::Job::QUEUED);
  EXPECT_EQ(job->child_count(), 3);
  EXPECT_EQ(job->children_done(), 0);
  EXPECT_TRUE(job->spec().has_study());
  EXPECT_EQ(job->estimated_memory_bytes(), 3000) << "the largest child's estimate";
  auto listed = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED, nullptr, study);
  ASSERT_TRUE(listed.ok());
  ASSERT_EQ(listed->size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ((*listed)[i].parent_job_id(), job->id());
    EXPECT_EQ((*listed)[i].child_index(), i);
    EXPECT_EQ((*listed)[i].spec().compression().max_deformation(), 0.1 * (i + 1));
    EXPECT_EQ(*store_->job_owner(*parse_job_name((*listed)[i].id())), "alice");
  }
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 3) << "studies are not counted as queued work";
  // Three claims give the three children in point order, a fourth nothing.
  for (int i = 0; i < 3; ++i) EXPECT_EQ(claim_one().job.child_index(), i);
  auto none = store_->claim("w", 2000, kTtl);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  // Expiry and shutdown never touch the study row (it has no lease).
  auto expired = store_->requeue_expired(10'000'000, 1);
  ASSERT_TRUE(expired.ok());
  EXPECT_EQ(expired->size(), 3u);
  for (const auto& j : *expired) EXPECT_FALSE(j.parent_job_id().empty());
}

TEST_F(StudyStoreTest, AFailedInsertLeavesNothing) {
  // A study without children is refused inside the transaction: no row stays.
  auto refused = store_->submit_study(study_spec(), {}, "r", 1000, "alice");
  ASSERT_FALSE(refused.ok());
  auto all = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED);
  ASSERT_TRUE(all.ok());
  EXPECT_TRUE(all->empty());
}

TEST_F(StudyStoreTest, RequestIdCoversTheWholeStudy) {
  const std::int64_t study = submit_study(3, "sweep-1");
  auto again = store_->submit_study(study_spec(), children(3), "sweep-1", 5000, "alice");
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->existed);
  EXPECT_EQ(again->job.id(), job_name(study));
  auto all = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED);
  EXPECT_EQ(all->size(), 4u) << "one study, three children, nothing added by the repeat";
}

TEST_F(StudyStoreTest, StateRollsUpToSucceededWithChildUpdates) {
  const std::int64_t study = submit_study(2);
  Claim a = claim_one(2000);
  EXPECT_EQ(store_->get(study)->state(), v1::Job::RUNNING);
  Claim b = claim_one(2100);
  ASSERT_TRUE(store_->finish(*parse_job_name(a.job.id()), a.lease_token, 10, 3000).ok());
  auto mid = store_->get(study);
  EXPECT_EQ(mid->state(), v1::Job::RUNNING);
  EXPECT_EQ(mid->children_done(), 1);
  EXPECT_DOUBLE_EQ(mid->fraction_done(), 0.5);
  ASSERT_TRUE(store_->finish(*parse_job_name(b.job.id()), b.lease_token, 10, 4000).ok());
  auto done = store_->get(study);
  EXPECT_EQ(done->state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(done->children_done(), 2);
  EXPECT_EQ(done->end_time().seconds(), 4);
  EXPECT_EQ(study_states(study),
            (std::vector<v1::Job::State>{v1::Job::QUEUED, v1::Job::RUNNING, v1::Job::SUCCEEDED}));
  const auto updates = child_updates(study);
  ASSERT_EQ(updates.size(), 4u);  // two leases, two finishes
  EXPECT_EQ(updates[0].child_job_id(), a.job.id());
  EXPECT_EQ(updates[0].state(), v1::Job::RUNNING);
  EXPECT_EQ(updates[2].state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(updates[3].child_index(), 1);
  // The terminal state event is the study's last event: a watcher stops there.
  auto events = store_->events_after(study, 0, 1000);
  EXPECT_TRUE(events->back().has_state_change());
  EXPECT_EQ(events->back().sequence(), done->last_sequence());
}

TEST_F(StudyStoreTest, AnyFailedChildFailsTheStudyOnceAllAreTerminal) {
  const std::int64_t study = submit_study(3);
  Claim a = claim_one();
  Claim b = claim_one();
  Claim c = claim_one();
  ASSERT_TRUE(store_->fail(*parse_job_name(b.job.id()), b.lease_token, "Newton diverged", -1, 3000).ok());
  EXPECT_EQ(store_->get(study)->state(), v1::Job::RUNNING) << "two children still run";
  ASSERT_TRUE(store_->finish(*parse_job_name(a.job.id()), a.lease_token, 10, 3100).ok());
  // A child handed back (released) goes back to QUEUED; the study waits for it.
  ASSERT_TRUE(store_->release(*parse_job_name(c.job.id()), c.lease_token, "worker stopping", 3200).ok());
  EXPECT_EQ(child_updates(study).back().state(), v1::Job::QUEUED);
  Claim c2 = claim_one(3300);
  EXPECT_EQ(c2.job.id(), c.job.id());
  ASSERT_TRUE(store_->finish(*parse_job_name(c2.job.id()), c2.lease_token, 10, 3400).ok());
  auto job = store_->get(study);
  EXPECT_EQ(job->state(), v1::Job::FAILED);
  EXPECT_EQ(job->reason(),
            "1 of 3 children failed; first: " + b.job.id() + " (point 1, failed): Newton diverged");
}

TEST_F(StudyStoreTest, CancellingAStudyCancelsItsQueuedAndRunningChildren) {
  const std::int64_t study = submit_study(3);
  Claim a = claim_one();
  Claim b = claim_one();
  ASSERT_TRUE(store_->finish(*parse_job_name(a.job.id()), a.lease_token, 10, 3000).ok());
  std::vector<Store::CancelledChild> cancelled;
  auto job = store_->cancel(study, "by the client", 4000, &cancelled);
  ASSERT_TRUE(job.ok()) << job.status().to_string();
  EXPECT_EQ(job->state(), v1::Job::CANCELLED);
  ASSERT_EQ(cancelled.size(), 2u) << "the running and the queued child, not the succeeded one";
  EXPECT_TRUE(cancelled[0].was_running);
  EXPECT_FALSE(cancelled[1].was_running);
  EXPECT_EQ(cancelled[0].last_sequence, store_->get(cancelled[0].id)->last_sequence());
  EXPECT_EQ(store_->get(*parse_job_name(a.job.id()))->state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(store_->get(*parse_job_name(b.job.id()))->state(), v1::Job::CANCELLED);
  EXPECT_EQ(*store_->check_lease(*parse_job_name(b.job.id()), b.lease_token), LeaseCheck::kCancelled)
      << "the running child's worker learns it at its next heartbeat";
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 0);
  // The children's updates come before the study's CANCELLED event, which ends the log.
  auto events = store_->events_after(study, 0, 1000);
  ASSERT_TRUE(events.ok());
  EXPECT_EQ(events->back().state_change().state(), v1::Job::CANCELLED);
  const auto updates = child_updates(study);
  EXPECT_EQ(updates[updates.size() - 1].state(), v1::Job::CANCELLED);
  EXPECT_EQ(updates[updates.size() - 2].state(), v1::Job::CANCELLED);
  // A cancelled child alone (the study not cancelled) fails the study at the end.
  const std::int64_t second = submit_study(2);
  auto kids = store_->list(0, 10, v1::Job::STATE_UNSPECIFIED, nullptr, second);
  ASSERT_TRUE(store_->cancel(*parse_job_name((*kids)[0].id()), "one point", 5000).ok());
  Claim last = claim_one();
  ASSERT_TRUE(store_->finish(*parse_job_name(last.job.id()), last.lease_token, 10, 6000).ok());
  auto rolled = store_->get(second);
  EXPECT_EQ(rolled->state(), v1::Job::FAILED);
  EXPECT_EQ(rolled->reason().rfind("0 of 2 children failed, 1 cancelled; first: ", 0), 0u)
      << rolled->reason();
}

TEST_F(StudyStoreTest, DeletingAFinishedStudyDeletesItsChildren) {
  v1::JobSpec plain;
  plain.mutable_compression()->set_max_deformation(0.1);
  auto unrelated = store_->submit(plain, "", 0, 1000);
  ASSERT_TRUE(unrelated.ok());
  const std::int64_t other = *parse_job_name(unrelated->job.id());
  const std::int64_t study = submit_study(2);
  auto kids = store_->list(0, 10, v1::Job::STATE_UNSPECIFIED, nullptr, study);
  EXPECT_EQ(store_->delete_job(study).code(), StatusCode::kFailedPrecondition) << "still queued";
  ASSERT_TRUE(store_->cancel(study, "stop", 2000).ok());
  EXPECT_EQ(store_->delete_job(*parse_job_name((*kids)[0].id())).code(), StatusCode::kFailedPrecondition)
      << "a child goes with its study";
  std::vector<std::int64_t> deleted;
  ASSERT_TRUE(store_->delete_job(study, &deleted).ok());
  EXPECT_EQ(deleted.size(), 2u);
  for (const auto& kid : *kids)
    EXPECT_EQ(store_->get(*parse_job_name(kid.id())).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store_->get(study).status().code(), StatusCode::kNotFound);
  EXPECT_TRUE(store_->get(other).ok()) << "an unrelated job stays";
  EXPECT_TRUE(store_->events_after(study, 0, 10)->empty());
}

TEST_F(StudyStoreTest, LeaseExpiryOfAChildIsAChildUpdateAndCanFailTheStudy) {
  options_.max_attempts = 1;
  store_.reset();
  auto reopened = Store::open(options_);
  ASSERT_TRUE(reopened.ok());
  store_ = std::move(reopened).value();
  const std::int64_t study = submit_study(1);
  claim_one(2000);
  auto changed = store_->requeue_expired(2000 + kTtl + 1);
  ASSERT_TRUE(changed.ok());
  ASSERT_EQ(changed->size(), 1u);
  EXPECT_EQ((*changed)[0].state(), v1::Job::FAILED);
  auto job = store_->get(study);
  EXPECT_EQ(job->state(), v1::Job::FAILED);
  EXPECT_NE(job->reason().find("1 of 1 children failed"), std::string::npos);
  EXPECT_NE(job->reason().find("expired"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::server
