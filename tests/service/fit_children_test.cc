// The library simulations of fits as child jobs, on loopback (real server,
// two workers, real SQLite): a fit with w free on an empty library queues
// one compression child per grid w (at most 15), both workers run them, the
// fit runs when they are done and reads their curves from the server; a
// second fit of the same geometry queues none and simulates nothing; two
// fits submitted together build each curve once; cancel and delete of a fit
// cascade to its children; a sweep of fits builds the curves its points
// share once. Tiny library numerics (200 vertices, a few load
// points): a few seconds of simulation.
#include <google/protobuf/util/json_util.h>

#include <cstdlib>
#include <nlohmann/json.hpp>
#include <set>

#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

using json = nlohmann::json;

const std::string kCurve = std::string(CELLFLOW_SOURCE_DIR) + "/examples/fit/synthetic_plates_E150_w0.5_";

json parse_report(const std::string& out) {
  const auto brace = out.find('{');
  if (brace == std::string::npos) return json();
  return json::parse(out.substr(brace), nullptr, false);
}

class FitChildrenTest : public ServiceTest {
 protected:
  void start() {
    // The workers' own caches, empty: every curve comes from the server's library.
    const std::string cache = (dir_ / "worker-cache").string();
    ::setenv("CELLFLOW_LIBRARY_DIR", cache.c_str(), 1);
    // 20 ms a load point: both workers take part.
    start_server(2, {"--worker-arg=--debug-delay-per-point-ms=20"});
    cli_ = std::string(CELLFLOW_CLI_EXE) + " --server " + address_ + " --timeout-s 30";
  }
  std::string fit_args(int curve, int load_points) const {
    return " " + kCurve + std::to_string(curve) + ".csv --geometry plates --radius-m 8.6e-6 --w-free " +
           "--vertices 200 --load-points " + std::to_string(load_points) + " --no-per-curve";
  }
  json fit(int curve, int load_points) {
    int code = 0;
    const std::string out = run_command(cli_ + " fit" + fit_args(curve, load_points) + " --json", &code);
    EXPECT_EQ(code, 0) << out;
    const json report = parse_report(out);
    EXPECT_TRUE(report.is_object()) << out;
    return report;
  }
  // `cellflow fit --print-spec` submitted without waiting; returns the job id.
  std::string submit_fit(int curve, int load_points) {
    int code = 0;
    const std::string text =
        run_command(cli_ + " fit" + fit_args(curve, load_points) + " --print-spec", &code);
    EXPECT_EQ(code, 0) << text;
    v1::JobSpec spec;
    EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(text, &spec).ok()) << text;
    return submit(spec);
  }
  std::vector<v1::Job> children(const std::string& parent) {
    v1::ListJobsRequest request;
    request.set_parent_job_id(parent);
    v1::ListJobsResponse response;
    EXPECT_TRUE(client_->list(request, &response).ok());
    return {response.jobs().begin(), response.jobs().end()};
  }
  std::string cli_;
};

TEST_F(FitChildrenTest, ChildrenOnBothWorkersBuildTheLibraryAndASecondFitQueuesNone) {
  start();
  const json first = fit(1, 6);
  ASSERT_TRUE(first.is_object());
  const std::string fit_id = first["job"].get<std::string>();
  const v1::Job job = get(fit_id);
  EXPECT_EQ(job.state(), v1::Job::SUCCEEDED);
  const int queued = job.child_count();
  std::printf("first fit %s: %d library children, E %.1f Pa, w %.3f\n", fit_id.c_str(), queued,
              first["joint"]["youngs_modulus_pa"]["value"].get<double>(),
              first["joint"]["mooney_rivlin_w"]["value"].get<double>());
  EXPECT_GT(queued, 0);
  EXPECT_LE(queued, 15) << "the issue's bound for one curve with w free";
  EXPECT_EQ(first["simulations_run"].get<int>(), queued) << "every simulation a child, none in the fit";
  EXPECT_EQ(first["library"]["child_simulations"].get<int>(), queued);
  EXPECT_EQ(first["library"]["server_curves"].get<int>(), queued);
  std::set<std::string> workers;
  for (const v1::Job& child : children(fit_id)) {
    EXPECT_EQ(child.state(), v1::Job::SUCCEEDED) << child.id() << ": " << child.reason();
    ASSERT_TRUE(child.spec().has_compression());
    EXPECT_EQ(child.spec().compression().cell().radius_m(), 10e-6) << "the library's reference cell";
    EXPECT_EQ(child.spec().compression().load_points(), 6);
    workers.insert(child.worker_id());
  }
  EXPECT_EQ(workers.size(), 2u) << "the library simulations ran on both workers";
  const double e = first["joint"]["youngs_modulus_pa"]["value"].get<double>();
  EXPECT_TRUE(std::isfinite(e) && e > 0.0);

  // Another curve of the same geometry and numerics: every curve from the server.
  const json second = fit(2, 6);
  ASSERT_TRUE(second.is_object());
  const v1::Job again = get(second["job"].get<std::string>());
  EXPECT_EQ(again.child_count(), 0) << "nothing queued: the server holds the curves";
  EXPECT_EQ(second["simulations_run"].get<int>(), 0);
  EXPECT_EQ(second["library"]["server_curves"].get<int>(), queued);
}

TEST_F(FitChildrenTest, TwoFitsAtOnceBuildEachCurveOnceAndCancelAndDeleteCascade) {
  start();
  // The first queues the curves; the second, submitted while they run, waits for them.
  const std::string a = submit_fit(1, 5);
  const json b = fit(3, 5);
  ASSERT_TRUE(b.is_object());
  ASSERT_TRUE(wait_state(a, v1::Job::SUCCEEDED, 60s)) << get(a).reason();
  EXPECT_GT(get(a).child_count(), 0);
  EXPECT_EQ(get(b["job"].get<std::string>()).child_count(), 0) << "no curve queued twice";
  EXPECT_EQ(b["simulations_run"].get<int>(), 0);
  EXPECT_EQ(b["library"]["server_curves"].get<int>(), get(a).child_count());

  // New numerics: a fit with fresh children, cancelled at once, then deleted.
  const std::string c = submit_fit(1, 7);
  v1::Job cancelled;
  ASSERT_TRUE(client_->cancel(c, &cancelled).ok());
  EXPECT_EQ(cancelled.state(), v1::Job::CANCELLED);
  const std::vector<v1::Job> kids = children(c);
  ASSERT_FALSE(kids.empty());
  for (const v1::Job& kid : kids) EXPECT_EQ(kid.state(), v1::Job::CANCELLED) << kid.id();
  ASSERT_TRUE(client_->delete_job(c).ok());
  for (const v1::Job& kid : kids) {
    v1::Job gone;
    EXPECT_EQ(client_->get(kid.id(), &gone).error_code(), grpc::StatusCode::NOT_FOUND) << kid.id();
  }
}

// A sweep of fits (a study whose base is a fit): its points read the library
// like submitted fits. Two points that differ only in the contact window
// read the same curves: the first point's library children build them once,
// the second queues none, and both fits run after the curves exist.
TEST_F(FitChildrenTest, ASweepOfFitsBuildsTheSharedCurvesOnceAsChildrenOfItsFirstPoint) {
  start();
  int code = 0;
  const std::string text = run_command(cli_ + " fit" + fit_args(1, 5) + " --print-spec", &code);
  ASSERT_EQ(code, 0) << text;
  v1::JobSpec base;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(text, &base).ok()) << text;
  v1::JobSpec study;
  study.set_name("fit sweep");
  *study.mutable_study()->mutable_base() = base;
  v1::StudyAxis* axis = study.mutable_study()->add_axes();
  axis->set_path("fit.contactWindowRadii");
  axis->add_values("0.05");
  axis->add_values("0.1");
  const std::string id = submit(study);
  ASSERT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 90s)) << get(id).reason();
  const std::vector<v1::Job> points = children(id);
  ASSERT_EQ(points.size(), 2u);
  for (const v1::Job& point : points) {
    EXPECT_EQ(point.state(), v1::Job::SUCCEEDED) << point.id() << ": " << point.reason();
    ASSERT_TRUE(point.spec().has_fit());
  }
  const int queued = points[0].child_count();
  EXPECT_GT(queued, 0) << "the first point queues the curves the server lacks";
  EXPECT_LE(queued, 15);
  EXPECT_EQ(points[1].child_count(), 0) << "the second point reads the same curves: none queued twice";
  for (const v1::Job& sim : children(points[0].id())) {
    EXPECT_EQ(sim.state(), v1::Job::SUCCEEDED) << sim.id() << ": " << sim.reason();
    EXPECT_TRUE(sim.spec().has_compression());
  }
  // The server now holds the curves: a plain fit of the same geometry simulates nothing.
  const json again = fit(2, 5);
  ASSERT_TRUE(again.is_object());
  EXPECT_EQ(again["simulations_run"].get<int>(), 0);
  EXPECT_EQ(again["library"]["server_curves"].get<int>(), queued);
}

}  // namespace
}  // namespace cellflow::testing
