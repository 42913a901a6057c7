// The curve library of fits in the SQLite store (schema 5): a fit queues one
// child per curve the library lacks and nobody is building, a second fit of
// the same keys queues none and waits for the first's children; a fit is
// leased only when none of the jobs building its curves is queued or
// running; a child that ends leaves its curve (from its force samples,
// checked: a hostile report stores nothing); curves read back are checked
// again and bounded; cancel and delete of a fit cascade to its children;
// a study whose points are fits queues their curves the same way, and its
// cancel and delete reach them.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "server/store.h"

namespace cellflow::server {
namespace {

namespace fs = std::filesystem;
constexpr std::int64_t kTtl = 1000;  // ms
constexpr int kLoadPoints = 4;
constexpr double kModulus = 1000.0, kRadius = 10e-6;

v1::JobSpec fit_spec(const std::string& name) {
  v1::JobSpec spec;
  spec.set_name(name);
  spec.mutable_fit()->set_geometry(v1::FIT_GEOMETRY_PLATES);
  spec.mutable_fit()->set_w_free(true);
  return spec;
}

// Library children of keys "k<i>" at w = 1 - 0.25 i (the server's key texts
// in real use, from w = 1 down), of one base key; the fit needs deformation `needed`.
std::vector<Store::LibraryChild> needs(int n, int first = 0, double needed = 0.5) {
  std::vector<Store::LibraryChild> out;
  for (int i = first; i < first + n; ++i) {
    Store::LibraryChild c;
    c.key = "k" + std::to_string(i);
    c.base = "b";
    c.mooney_rivlin_w = 1.0 - 0.25 * i;
    c.needed_deformation = needed;
    v1::CompressionSpec* s = c.spec.mutable_compression();
    s->mutable_cell()->set_radius_m(kRadius);
    s->mutable_cell()->mutable_material()->set_youngs_modulus_pa(kModulus);
    s->mutable_cell()->mutable_material()->set_mooney_rivlin_w(1.0 - 0.25 * i);
    s->set_max_deformation(0.6);
    s->set_load_points(kLoadPoints);
    c.memory_bytes = 100;
    out.push_back(std::move(c));
  }
  return out;
}

class FitLibraryStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cellflow_fit_library_store_" + std::to_string(getpid()) + "_" +
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

  v1::Job submit_fit(const std::string& name, int n, int first = 0, double needed = 0.5) {
    auto submitted = store_->submit_fit(fit_spec(name), 500, needs(n, first, needed), "", 1000, "alice");
    EXPECT_TRUE(submitted.ok()) << submitted.status().to_string();
    return submitted.ok() ? submitted->job : v1::Job{};
  }
  std::optional<Claim> claim() {
    auto c = store_->claim("w", 2000, kTtl);
    EXPECT_TRUE(c.ok());
    return c.ok() ? *c : std::nullopt;
  }
  // Reports the child's load points (force = f E R^2 with f = eps^1.5 + `shift`) and finishes it;
  // fails it after `points` points when points < kLoadPoints.
  void run_child(const Claim& c, double shift = 0.0, int gap_at = -1, int points = kLoadPoints) {
    const std::int64_t id = *parse_job_name(c.job.id());
    for (int i = 0; i < points; ++i) {
      v1::JobEvent e;
      v1::ForceSample* s = e.mutable_force_sample();
      s->set_index(i == gap_at ? i + 1 : i);
      const double eps = 0.15 * (i + 1);
      s->set_deformation(eps);
      s->set_force_n((std::pow(eps, 1.5) + shift) * kModulus * kRadius * kRadius);
      auto out = store_->append_event(id, c.lease_token, e, s->index(), 2100, kTtl);
      ASSERT_TRUE(out.ok()) << out.status().to_string();
    }
    auto done = points < kLoadPoints ? store_->fail(id, c.lease_token, "element crushed", -1, 2200)
                                     : store_->finish(id, c.lease_token, 10, 2200);
    ASSERT_TRUE(done.ok()) << done.status().to_string();
  }

  fs::path dir_;
  StoreOptions options_;
  std::unique_ptr<Store> store_;
};

TEST_F(FitLibraryStoreTest, MissingCurvesBecomeChildrenAndASecondFitReusesThem) {
  EXPECT_EQ(store_->schema_version(), 5);
  const v1::Job first = submit_fit("a", 3);
  EXPECT_EQ(first.child_count(), 3);
  EXPECT_EQ(first.state(), v1::Job::QUEUED);
  // The same keys again while the first's children are queued: built once.
  const v1::Job second = submit_fit("b", 3);
  EXPECT_EQ(second.child_count(), 0) << "the first fit's children build these curves";
  auto listed = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED, nullptr, *parse_job_name(first.id()));
  ASSERT_TRUE(listed.ok());
  ASSERT_EQ(listed->size(), 3u);
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 5) << "two fits and three children";

  // Claims give the children only: both fits wait for them.
  std::vector<Claim> children;
  for (int i = 0; i < 3; ++i) {
    auto c = claim();
    ASSERT_TRUE(c.has_value());
    EXPECT_EQ(c->job.parent_job_id(), first.id());
    children.push_back(*c);
  }
  EXPECT_FALSE(claim().has_value()) << "no fit is leased while its curves are being built";
  run_child(children[0]);
  run_child(children[1]);
  EXPECT_FALSE(claim().has_value()) << "one curve still running";
  auto waiting = store_->get(*parse_job_name(first.id()));
  ASSERT_TRUE(waiting.ok());
  EXPECT_EQ(waiting->state(), v1::Job::QUEUED) << "the roll-up never ends a fit";
  EXPECT_NEAR(waiting->fraction_done(), 2.0 / 3.0, 1e-12);
  run_child(children[2]);
  EXPECT_EQ(store_->count_library_curves(), 3);

  // Now the fits, oldest first, each with the three curves.
  for (const v1::Job* fit : {&first, &second}) {
    auto c = claim();
    ASSERT_TRUE(c.has_value());
    EXPECT_EQ(c->job.id(), fit->id());
    auto library = store_->library_curves_for(*parse_job_name(fit->id()), 1 << 20);
    ASSERT_TRUE(library.ok());
    ASSERT_EQ(library->curves.size(), 3u);
    EXPECT_EQ(library->refused, 0);
    const v1::FitLibraryCurve& curve = library->curves[1];
    EXPECT_EQ(curve.key(), "k1");
    EXPECT_EQ(curve.mooney_rivlin_w(), 0.75);
    ASSERT_EQ(curve.deformation_size(), kLoadPoints);
    EXPECT_NEAR(curve.force_scaled(2), std::pow(0.45, 1.5), 1e-12) << "F / (E R^2)";
    EXPECT_TRUE(curve.failure().empty());
  }
  // A third fit with one known and one new key queues one child.
  EXPECT_EQ(submit_fit("c", 2, 2).child_count(), 1);
  // Byte bound of the read-back: curves that do not fit are left out (counted).
  auto small = store_->library_curves_for(*parse_job_name(first.id()), 1);
  ASSERT_TRUE(small.ok());
  EXPECT_EQ(small->curves.size(), 0u);
  EXPECT_EQ(small->refused, 3);
}

TEST_F(FitLibraryStoreTest, HostileSamplesStoreNoCurveAndTheNextFitQueuesItAgain) {
  const v1::Job fit = submit_fit("a", 3);
  std::vector<Claim> c;
  for (int i = 0; i < 3; ++i) c.push_back(*claim());
  run_child(c[0], /*shift=*/-1.0);     // negative forces
  run_child(c[1], 0.0, /*gap_at=*/2);  // index 2 reported as 3: a gap
  run_child(c[2], /*shift=*/1e9);      // beyond any force of the scene
  EXPECT_EQ(store_->count_library_curves(), 0);
  auto leased = claim();
  ASSERT_TRUE(leased.has_value()) << "its children ended: the fit runs (and simulates what is missing)";
  EXPECT_EQ(leased->job.id(), fit.id());
  auto library = store_->library_curves_for(*parse_job_name(fit.id()), 1 << 20);
  ASSERT_TRUE(library.ok());
  EXPECT_TRUE(library->curves.empty());
  EXPECT_EQ(submit_fit("b", 3).child_count(), 3) << "no curve stored, none being built";

  // A curve corrupted in the database is refused when read back.
  for (int i = 0; i < 3; ++i) run_child(*claim());
  ASSERT_EQ(store_->count_library_curves(), 3);
  store_.reset();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(options_.path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE library_curves SET curve = x'0a03' WHERE key = 'k0'", nullptr, nullptr,
                         nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  auto reopened = Store::open(options_);
  ASSERT_TRUE(reopened.ok());
  store_ = std::move(*reopened);
  const v1::Job third = submit_fit("c", 3);
  EXPECT_EQ(third.child_count(), 0);
  auto back = store_->library_curves_for(*parse_job_name(third.id()), 1 << 20);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->curves.size(), 2u);
  EXPECT_EQ(back->refused, 1) << "the corrupted curve";
}

TEST_F(FitLibraryStoreTest, ACurveEndingEarlyCancelsTheSmallerWOnlyDeeperFitsNeed) {
  const v1::Job fit = submit_fit("a", 3, 0, /*needed=*/0.5);  // w = 1, 0.75, 0.5
  const Claim w1 = *claim(), w075 = *claim();
  // w = 0.75 fails after two points (eps 0.3 < 0.5): the fit searches w above it, w = 0.5 is useless.
  run_child(w075, 0.0, -1, /*points=*/2);
  auto library = store_->library_curves_for(*parse_job_name(fit.id()), 1 << 20);
  ASSERT_TRUE(library.ok());
  ASSERT_EQ(library->curves.size(), 1u);
  EXPECT_EQ(library->curves[0].failure(), "element crushed") << "the partial curve keeps its failure";
  EXPECT_EQ(library->curves[0].deformation_size(), 2);
  auto kids = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED, nullptr, *parse_job_name(fit.id()));
  ASSERT_TRUE(kids.ok());
  ASSERT_EQ(kids->size(), 3u);
  EXPECT_EQ((*kids)[2].state(), v1::Job::CANCELLED);
  EXPECT_NE((*kids)[2].reason().find("not needed"), std::string::npos) << (*kids)[2].reason();
  EXPECT_EQ((*kids)[0].state(), v1::Job::RUNNING) << "a larger w is still needed";
  run_child(w1);
  auto leased = claim();
  ASSERT_TRUE(leased.has_value());
  EXPECT_EQ(leased->job.id(), fit.id());

  // A fit that needs only eps 0.2 of the key reads the smaller w (k3 w 0.25, k4 0, k5 -0.25: test
  // keys); one that needs 0.5 queues none of them (below w = 0.75, which ends at 0.3) and they are
  // not cancelled when k3 ends at 0.3 too: the shallow fit may still use them.
  const v1::Job shallow = submit_fit("shallow", 3, 3, 0.2);
  EXPECT_EQ(shallow.child_count(), 3);
  EXPECT_EQ(submit_fit("deep", 3, 3, 0.5).child_count(), 0);
  run_child(*claim(), 0.0, -1, /*points=*/2);
  auto rest = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED, nullptr, *parse_job_name(shallow.id()));
  ASSERT_TRUE(rest.ok());
  ASSERT_EQ(rest->size(), 3u);
  EXPECT_EQ((*rest)[1].state(), v1::Job::QUEUED) << "the shallow fit may still use it";
  EXPECT_EQ((*rest)[2].state(), v1::Job::QUEUED);

  // Later fits: w = 0.5 lies below the stored curve of w = 0.75 that ends at 0.3.
  EXPECT_EQ(submit_fit("again", 3, 0, 0.5).child_count(), 0) << "a fit needing 0.5 never reads w = 0.5";
  EXPECT_EQ(submit_fit("shallow first", 3, 0, 0.2).child_count(), 1) << "one needing 0.2 does";
}

TEST_F(FitLibraryStoreTest, CancelAndDeleteOfAFitCascadeToItsChildren) {
  const v1::Job fit = submit_fit("a", 3);
  auto running = claim();  // one child running, two queued
  ASSERT_TRUE(running.has_value());
  std::vector<Store::CancelledChild> cancelled;
  auto job = store_->cancel(*parse_job_name(fit.id()), "by the user", 3000, &cancelled);
  ASSERT_TRUE(job.ok()) << job.status().to_string();
  EXPECT_EQ(job->state(), v1::Job::CANCELLED);
  ASSERT_EQ(cancelled.size(), 3u);
  int was_running = 0;
  for (const auto& c : cancelled) {
    was_running += c.was_running ? 1 : 0;
    EXPECT_EQ(store_->get(c.id)->state(), v1::Job::CANCELLED);
  }
  EXPECT_EQ(was_running, 1);
  EXPECT_FALSE(claim().has_value());
  std::vector<std::int64_t> deleted;
  ASSERT_TRUE(store_->delete_job(*parse_job_name(fit.id()), &deleted).ok());
  EXPECT_EQ(deleted.size(), 3u);
  for (std::int64_t id : deleted) EXPECT_EQ(store_->get(id).status().code(), StatusCode::kNotFound);
  // Its needs went with it: a new fit of the keys queues them again.
  EXPECT_EQ(submit_fit("b", 3).child_count(), 3);
}

// A study whose points are fits (a sweep of fits): each point reads the
// library like a submitted fit; curves two points share are built once, the
// points keep consecutive ids after the study's and wait for their curves.
TEST_F(FitLibraryStoreTest, AStudyOfFitsQueuesEachCurveOnceAndItsPointsWaitForThem) {
  v1::JobSpec study_spec;
  study_spec.set_name("sweep of fits");
  std::vector<Store::StudyChild> points;
  points.push_back({fit_spec("p0"), 500, needs(3)});     // k0, k1, k2
  points.push_back({fit_spec("p1"), 500, needs(3, 1)});  // k1, k2 shared; k3 new
  auto submitted = store_->submit_study(study_spec, points, "", 1000, "alice");
  ASSERT_TRUE(submitted.ok()) << submitted.status().to_string();
  const v1::Job study = submitted->job;
  EXPECT_EQ(study.child_count(), 2);
  const std::int64_t study_id = *parse_job_name(study.id());
  auto fits = store_->list(0, 100, v1::Job::STATE_UNSPECIFIED, nullptr, study_id);
  ASSERT_TRUE(fits.ok());
  ASSERT_EQ(fits->size(), 2u) << "the library simulations are the points' children, not the study's";
  EXPECT_EQ(*parse_job_name((*fits)[0].id()), study_id + 1);
  EXPECT_EQ(*parse_job_name((*fits)[1].id()), study_id + 2);
  EXPECT_EQ((*fits)[0].child_count(), 3);
  EXPECT_EQ((*fits)[1].child_count(), 1) << "k1 and k2 are built for the first point";
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 6) << "two fits and four library simulations";

  std::vector<Claim> library;
  for (int i = 0; i < 4; ++i) {
    auto c = claim();
    ASSERT_TRUE(c.has_value());
    EXPECT_TRUE(c->job.parent_job_id() == (*fits)[0].id() || c->job.parent_job_id() == (*fits)[1].id())
        << c->job.parent_job_id();
    library.push_back(*c);
  }
  EXPECT_FALSE(claim().has_value()) << "no point is leased while its curves are being built";
  for (const Claim& c : library) run_child(c);
  EXPECT_EQ(store_->count_library_curves(), 4);
  auto started = store_->get(study_id);
  ASSERT_TRUE(started.ok());
  EXPECT_EQ(started->state(), v1::Job::QUEUED) << "library simulations do not start the study";

  for (int i = 0; i < 2; ++i) {
    auto c = claim();
    ASSERT_TRUE(c.has_value());
    EXPECT_EQ(c->job.id(), (*fits)[static_cast<std::size_t>(i)].id());
    auto curves = store_->library_curves_for(*parse_job_name(c->job.id()), 1 << 20);
    ASSERT_TRUE(curves.ok());
    ASSERT_EQ(curves->curves.size(), 3u);
    EXPECT_EQ(curves->curves[0].key(), i == 0 ? "k0" : "k1");
    ASSERT_TRUE(store_->finish(*parse_job_name(c->job.id()), c->lease_token, 10, 2300).ok());
  }
  auto done = store_->get(study_id);
  ASSERT_TRUE(done.ok());
  EXPECT_EQ(done->state(), v1::Job::SUCCEEDED) << done->reason();
  EXPECT_EQ(done->fraction_done(), 1.0);
}

TEST_F(FitLibraryStoreTest, CancelAndDeleteOfAStudyOfFitsReachTheLibrarySimulations) {
  std::vector<Store::StudyChild> points;
  points.push_back({fit_spec("p0"), 500, needs(3)});
  points.push_back({fit_spec("p1"), 500, needs(3, 1)});
  auto submitted = store_->submit_study(v1::JobSpec{}, points, "", 1000, "alice");
  ASSERT_TRUE(submitted.ok()) << submitted.status().to_string();
  const std::int64_t study_id = *parse_job_name(submitted->job.id());
  auto running = claim();  // one library simulation running, three queued
  ASSERT_TRUE(running.has_value());
  std::vector<Store::CancelledChild> cancelled;
  auto job = store_->cancel(study_id, "by the user", 3000, &cancelled);
  ASSERT_TRUE(job.ok()) << job.status().to_string();
  EXPECT_EQ(job->state(), v1::Job::CANCELLED);
  ASSERT_EQ(cancelled.size(), 6u) << "two points and their four library simulations";
  int was_running = 0;
  for (const auto& c : cancelled) {
    was_running += c.was_running ? 1 : 0;
    EXPECT_EQ(store_->get(c.id)->state(), v1::Job::CANCELLED) << job_name(c.id);
  }
  EXPECT_EQ(was_running, 1) << "the worker of the running simulation is told";
  EXPECT_FALSE(claim().has_value());
  EXPECT_EQ(store_->count(v1::Job::QUEUED), 0);

  std::vector<std::int64_t> deleted;
  ASSERT_TRUE(store_->delete_job(study_id, &deleted).ok());
  EXPECT_EQ(deleted.size(), 6u);
  for (std::int64_t id : deleted) EXPECT_EQ(store_->get(id).status().code(), StatusCode::kNotFound);
  // The points' needs went with them: a new fit of the keys queues them again.
  EXPECT_EQ(submit_fit("b", 4).child_count(), 4);
}

}  // namespace
}  // namespace cellflow::server
