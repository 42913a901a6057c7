// Studies (sweeps) end to end on loopback: a real cellflow-server with two
// local workers and a real SQLite file. `cellflow sweep` submits one study of
// three compression points (E = 500, 1000, 2000 Pa); both workers lease its
// children, the study ends SUCCEEDED with every child's result, and the
// force scales with E. Then list/plot of the study, a cancelled study whose
// watch ends CANCELLED, and `submit --set` / `submit shear-flow`; a flow
// sweep whose plot draws steady D against the swept value.
#include <cmath>
#include <set>

#include "io/h5md.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

int count_of(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST_F(ServiceTest, SweepRunsOnEveryWorkerAndForceScalesWithE) {
  // Slowed children (150 ms a point) so that both workers take part and a cancel finds one running.
  start_server(2, {"--worker-arg=--debug-delay-per-point-ms=150"});
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  const std::string base = (dir_ / "base.json").string();
  std::ofstream(base) << R"({"name": "E sweep", "compression": {"cell": {"radiusM": 5e-6,
      "material": {"youngsModulusPa": 1000, "poissonRatio": 0.45}, "targetVertexCount": 300},
      "maxDeformation": 0.15, "loadPoints": 4}})";
  int code = 0;
  const std::string out =
      run_command(cli + " sweep --spec " + base +
                      " --set compression.cell.material.youngsModulusPa=500,1000,2000 --watch",
                  &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(out.rfind("job-1 (3 children)\n", 0), 0u) << out;
  EXPECT_EQ(count_of(out, " state SUCCEEDED"), 4) << "three children and the study: " << out;
  EXPECT_NE(out.find("child job-4 index=2 state SUCCEEDED"), std::string::npos) << out;

  const v1::Job study = get("job-1");
  EXPECT_EQ(study.state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(study.child_count(), 3);
  EXPECT_EQ(study.children_done(), 3);
  EXPECT_EQ(study.spec().study().axes(0).values_size(), 3);

  v1::ListJobsRequest by_parent;
  by_parent.set_parent_job_id("job-1");
  v1::ListJobsResponse children;
  ASSERT_TRUE(client_->list(by_parent, &children).ok());
  ASSERT_EQ(children.jobs_size(), 3);
  std::set<std::string> workers;
  std::vector<std::vector<double>> forces;
  const double moduli[] = {500, 1000, 2000};
  for (int i = 0; i < 3; ++i) {
    const v1::Job& child = children.jobs(i);
    EXPECT_EQ(child.state(), v1::Job::SUCCEEDED);
    EXPECT_EQ(child.parent_job_id(), "job-1");
    EXPECT_EQ(child.child_index(), i);
    EXPECT_EQ(child.spec().compression().cell().material().youngs_modulus_pa(), moduli[i]);
    EXPECT_EQ(child.spec().compression().cell().material().poisson_ratio(), 0.45) << "the base's fields stay";
    workers.insert(child.worker_id());
    const std::string h5 = (dir_ / (child.id() + ".h5")).string();
    ASSERT_TRUE(client_->download(child.id(), h5).ok());
    auto force = io::read_observable(h5, "force_n");
    ASSERT_TRUE(force.ok()) << force.status().to_string();
    ASSERT_EQ(force->value.size(), 4u);
    forces.push_back(force->value);
  }
  EXPECT_EQ(workers.size(), 2u) << "the children ran on both workers";
  // At fixed nu and w the force is proportional to E (the contact stiffness
  // scales with E too); the solves stop at a relative residual of 1e-6.
  for (int i = 1; i < 3; ++i) {
    for (std::size_t k = 0; k < 4; ++k) {
      ASSERT_GT(forces[0][k], 0.0);
      EXPECT_NEAR(forces[i][k] / forces[0][k], moduli[i] / moduli[0], 1e-5 * moduli[i] / moduli[0])
          << "child " << i << " point " << k;
    }
  }

  // list shows parent and children; list --parent only the children.
  const std::string listed = run_command(cli + " list", &code);
  EXPECT_EQ(code, 0);
  EXPECT_NE(listed.find("job-1  SUCCEEDED  study"), std::string::npos) << listed;
  EXPECT_NE(listed.find("study: 3/3 children done"), std::string::npos) << listed;
  const std::string only = run_command(cli + " list --parent job-1", &code);
  EXPECT_EQ(code, 0);
  EXPECT_EQ(count_of(only, "child "), 3) << only;
  EXPECT_EQ(only.find("\njob-1 "), std::string::npos) << "not the study itself: " << only;

  // plot STUDY: the three force curves overlaid, labelled by their point.
  const std::string svg = (dir_ / "sweep.svg").string();
  const std::string plotted = run_command(cli + " plot job-1 -o " + svg, &code);
  ASSERT_EQ(code, 0) << plotted;
  const std::string text = read_text(svg);
  EXPECT_EQ(count_of(text, "<polyline"), 3) << text;
  EXPECT_NE(text.find("youngsModulusPa=2000"), std::string::npos);

  // A second study, cancelled while a child runs: every child ends, the watch ends CANCELLED.
  const std::string second =
      run_command(cli + " sweep --spec " + base +
                      " --set compression.maxDeformation=0.1,0.12 --set compression.loadPoints=6,8",
                  &code);
  ASSERT_EQ(code, 0) << second;
  EXPECT_EQ(second, "job-5 (4 children)\n");
  ASSERT_TRUE(wait_state("job-5", v1::Job::RUNNING, 20s));
  const std::string cancelled = run_command(cli + " cancel job-5", &code);
  EXPECT_EQ(code, 0) << cancelled;
  const std::string watched = run_command(cli + " watch job-5", &code);
  EXPECT_EQ(code, 4) << watched;
  v1::ListJobsResponse second_children;
  by_parent.set_parent_job_id("job-5");
  ASSERT_TRUE(client_->list(by_parent, &second_children).ok());
  ASSERT_EQ(second_children.jobs_size(), 4);
  int stopped = 0;
  for (const auto& child : second_children.jobs()) {
    EXPECT_TRUE(child.state() == v1::Job::CANCELLED || child.state() == v1::Job::SUCCEEDED) << child.id();
    stopped += child.state() == v1::Job::CANCELLED ? 1 : 0;
  }
  EXPECT_GE(stopped, 2) << "the queued children at least";
  // Nothing of the cancelled study is left for the workers.
  ASSERT_TRUE(eventually(
      [&] {
        v1::ListJobsRequest running;
        running.set_state(v1::Job::RUNNING);
        v1::ListJobsResponse r;
        return client_->list(running, &r).ok() && r.jobs_size() == 0;
      },
      10s));

  // A bad path is refused naming the axis, nothing queued.
  const std::string refused =
      run_command(cli + " sweep --spec " + base + " --set compression.cell.youngsModulusPa=1,2 2>&1", &code);
  EXPECT_EQ(code, 2) << refused;
  EXPECT_NE(refused.find("study.axes[0].path"), std::string::npos) << refused;

  // submit --set edits the spec; submit shear-flow builds one from flags.
  const std::string edited =
      run_command(cli + " submit --spec " + base +
                      " --set compression.loadPoints=3 --set compression.cell.material.mooneyRivlinW=0.5",
                  &code);
  ASSERT_EQ(code, 0) << edited;
  const std::string edited_id = edited.substr(0, edited.find('\n'));
  const v1::Job edited_job = get(edited_id);
  EXPECT_EQ(edited_job.spec().compression().load_points(), 3);
  EXPECT_EQ(edited_job.spec().compression().cell().material().mooney_rivlin_w(), 0.5);
  const std::string flow = run_command(
      cli +
          " submit shear-flow --radius-m 4e-6 --youngs-modulus-pa 50 --capillary-number 0.1 "
          "--target-vertex-count 300 --cells-per-radius 3 --max-strain 0.5 --sample-every-strain 0.25",
      &code);
  ASSERT_EQ(code, 0) << flow;
  const v1::Job flow_job = get(flow.substr(0, flow.find('\n')));
  EXPECT_EQ(flow_job.spec().shear_flow().capillary_number(), 0.1);
  EXPECT_EQ(flow_job.spec().shear_flow().numerics().cells_per_radius(), 3.0);
  EXPECT_EQ(flow_job.spec().shear_flow().cell().radius_m(), 4e-6);
  v1::Job ignored;
  ASSERT_TRUE(client_->cancel(flow_job.id(), &ignored).ok() ||
              get(flow_job.id()).state() == v1::Job::SUCCEEDED);
}

// A flow sweep over Ca: two tiny flows (300 vertices, 3 cells per radius, to
// strain 1), the study SUCCEEDED, and plot STUDY draws steady D against Ca
// beside Roscoe; a sweep over another field draws D against that field.
TEST_F(ServiceTest, FlowSweepPlotsSteadyDeformationAgainstTheSweptValue) {
  start_server(2);
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  const std::string base = (dir_ / "flow.json").string();
  std::ofstream(base) << R"({"shearFlow": {"cell": {"radiusM": 4e-6, "material": {"youngsModulusPa": 50,
      "poissonRatio": 0.45}, "targetVertexCount": 300}, "capillaryNumber": 0.1, "numerics": {"cellsPerRadius": 3,
      "boxXRadii": 5, "boxYRadii": 6, "boxZRadii": 4, "maxStrain": 1, "sampleEveryStrain": 0.1,
      "snapshotEveryStrain": 0}}})";
  int code = 0;
  const std::string out =
      run_command(cli + " sweep --spec " + base + " --set shearFlow.capillaryNumber=0.05,0.2 --watch", &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(get("job-1").state(), v1::Job::SUCCEEDED);
  const std::string svg = (dir_ / "d_ca.svg").string();
  const std::string plotted = run_command(cli + " plot job-1 -o " + svg, &code);
  ASSERT_EQ(code, 0) << plotted;
  EXPECT_EQ(count_of(plotted, "steady D "), 2) << plotted;
  const std::string text = read_text(svg);
  EXPECT_NE(text.find("Roscoe"), std::string::npos) << "swept over Ca: beside Roscoe";
  EXPECT_NE(text.find("capillary number"), std::string::npos);

  const std::string radii =
      run_command(cli + " sweep --spec " + base + " --set shearFlow.cell.radiusM=3e-6,4e-6 --watch", &code);
  ASSERT_EQ(code, 0) << radii;
  const std::string radius_svg = (dir_ / "d_r.svg").string();
  const std::string radius_plot = run_command(cli + " plot job-4 -o " + radius_svg, &code);
  ASSERT_EQ(code, 0) << radius_plot;
  const std::string radius_text = read_text(radius_svg);
  EXPECT_NE(radius_text.find("shearFlow.cell.radiusM"), std::string::npos)
      << "the swept path labels the x axis";
  EXPECT_EQ(radius_text.find("Roscoe"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::testing
