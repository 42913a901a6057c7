// Shear-flow jobs through the service end to end on loopback (real
// cellflow-server, cellflow-worker and SQLite file): submitted, watched,
// cancelled and fetched like compression jobs; the HDF5 result holds the cell
// trajectory, the deformation time series and the fluid velocity; the CLI
// prints, tabulates and plots them; bad flow specs are refused at submit.
#include <hdf5.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include "io/h5md.h"
#include "jobs/job_spec.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

// A tiny flow job: 3 lattice nodes per radius, ~300 vertices, a 5 x 6 x 4 R
// box (15 x 18 x 12 nodes) and 2 strain units, about 1100 time steps: well
// under a second on one core. Ca = 0.2 with E = 50 Pa, R = 4 um in water.
v1::JobSpec small_shear_flow(double capillary_number = 0.2, double max_strain = 2.0) {
  v1::JobSpec spec;
  spec.set_name("small shear flow");
  auto* flow = spec.mutable_shear_flow();
  flow->mutable_cell()->set_radius_m(4e-6);
  flow->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  flow->mutable_cell()->mutable_material()->set_poisson_ratio(0.45);
  flow->mutable_cell()->set_target_vertex_count(300);
  flow->set_capillary_number(capillary_number);
  auto* n = flow->mutable_numerics();
  n->set_cells_per_radius(3);
  n->set_box_x_radii(5);
  n->set_box_y_radii(6);
  n->set_box_z_radii(4);
  n->set_max_strain(max_strain);
  n->set_sample_every_strain(0.1);
  n->set_snapshot_every_strain(0.5);
  n->set_fluid_snapshots(true);
  return spec;
}

std::vector<v1::DeformationSample> deformation_samples(const std::vector<v1::JobEvent>& events) {
  std::vector<v1::DeformationSample> out;
  for (const auto& e : events) {
    if (e.has_deformation_sample()) out.push_back(e.deformation_sample());
  }
  return out;
}

double relative_difference(double a, double b) {
  const double scale = std::max(std::fabs(a), std::fabs(b));
  return scale == 0.0 ? 0.0 : std::fabs(a - b) / scale;
}

TEST_F(ServiceTest, ShearFlowJobStreamsSamplesAndWritesTrajectoryAndFlow) {
  start_server(1, {"--worker-arg=--threads=1"});
  const v1::JobSpec spec = small_shear_flow();
  const auto submitted = std::chrono::steady_clock::now();
  const std::string id = submit(spec);
  ASSERT_FALSE(id.empty());
  Watcher watcher(*client_, id);
  watcher.join();
  const double service_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - submitted).count();
  ASSERT_TRUE(watcher.status().ok()) << watcher.status().error_message();
  const std::vector<v1::JobEvent> events = watcher.events();
  ASSERT_FALSE(events.empty());
  ASSERT_TRUE(events.back().has_state_change());
  ASSERT_EQ(events.back().state_change().state(), v1::Job::SUCCEEDED)
      << events.back().state_change().reason();

  // Samples: each index once, in order, the strain increasing up to max_strain.
  const std::vector<v1::DeformationSample> samples = deformation_samples(events);
  ASSERT_GE(samples.size(), 20u);
  bool saw_progress = false;
  for (const auto& e : events) saw_progress = saw_progress || e.has_progress();
  EXPECT_TRUE(saw_progress);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i].index(), static_cast<int>(i));
    ASSERT_EQ(samples[i].semi_axes_m_size(), 3);
    if (i > 0) {
      EXPECT_GT(samples[i].strain(), samples[i - 1].strain()) << "sample " << i;
      EXPECT_GT(samples[i].time_s(), samples[i - 1].time_s()) << "sample " << i;
    }
  }
  EXPECT_NEAR(samples.back().strain(), 2.0, 0.01);
  EXPECT_GT(samples.back().taylor_deformation(), 0.1);  // the cell deformed

  // The same spec through the library in this process, on one thread as the worker.
  auto params = jobs::to_params(spec.shear_flow());
  ASSERT_TRUE(params.ok()) << params.status().to_string();
  params->numerics.threads = 1;
  const auto direct_start = std::chrono::steady_clock::now();
  const scenes::ShearFlowResult reference = scenes::run_shear_flow(*params);
  const double direct_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - direct_start).count();
  ASSERT_TRUE(reference.status.ok()) << reference.status.to_string();
  ASSERT_EQ(samples.size(), reference.samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const scenes::ShearFlowSample& r = reference.samples[i];
    EXPECT_LE(relative_difference(samples[i].taylor_deformation(), r.taylor_deformation), 1e-12) << i;
    EXPECT_LE(relative_difference(samples[i].strain(), r.strain_units), 1e-12) << i;
    EXPECT_LE(relative_difference(samples[i].net_strain(), r.net_strain), 1e-12) << i;
    EXPECT_LE(
        relative_difference(samples[i].tank_treading_frequency_per_s(), r.tank_treading_frequency_per_s),
        1e-12)
        << i;
  }
  std::printf("tiny flow job: submit -> SUCCEEDED through the service %.3f s, the scene in-process %.3f s\n",
              service_s, direct_s);

  // The result: trajectory, time series, fluid frames, setup and summary.
  const std::string h5 = (dir_ / "flow.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  const v1::Job job = get(id);
  EXPECT_EQ(job.result_size_bytes(), static_cast<std::int64_t>(fs::file_size(h5)));
  EXPECT_DOUBLE_EQ(job.fraction_done(), 1.0);
  // Snapshots every 0.5 strain over 2: t = 0, 0.5, 1, 1.5, 2.
  auto frames = io::count_position_frames(h5, "cell");
  ASSERT_TRUE(frames.ok()) << frames.status().to_string();
  EXPECT_EQ(*frames, 5);
  auto last = io::read_position_frame(h5, "cell", *frames - 1);
  ASSERT_TRUE(last.ok());
  EXPECT_GT(last->time, 0.0);
  EXPECT_EQ(last->positions_m.size() % 3, 0u);
  auto fluid_frames = io::count_field_frames(h5, "fluid_velocity");
  ASSERT_TRUE(fluid_frames.ok());
  EXPECT_EQ(*fluid_frames, *frames);
  auto d = io::read_observable(h5, "taylor_deformation");
  ASSERT_TRUE(d.ok()) << d.status().to_string();
  ASSERT_EQ(d->value.size(), samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_EQ(d->value[i], samples[i].taylor_deformation());
  for (const char* name :
       {"strain", "inclination_rad", "net_strain", "semi_axes_m", "tank_treading_frequency_per_s"}) {
    auto series = io::read_observable(h5, name);
    ASSERT_TRUE(series.ok()) << name;
    EXPECT_EQ(series->step.size(), samples.size()) << name;
  }
  auto ca = io::read_scalar(h5, "/parameters/setup/capillary_number");
  ASSERT_TRUE(ca.ok());
  EXPECT_NEAR(*ca, 0.2, 1e-12);
  auto stop = io::read_string(h5, "/summary/stop");
  ASSERT_TRUE(stop.ok());
  EXPECT_EQ(*stop, "max_strain");
  auto steady = io::read_scalar(h5, "/summary/steady_taylor_deformation");
  ASSERT_TRUE(steady.ok());
  EXPECT_DOUBLE_EQ(*steady, reference.steady_taylor_deformation);

  int code = 0;
  const std::string dump = run_command(std::string(CELLFLOW_H5DUMP) + " " + h5 + " > /dev/null", &code);
  EXPECT_EQ(code, 0) << dump;
  const std::string header = run_command(std::string(CELLFLOW_H5DUMP) + " -H " + h5, &code);
  ASSERT_EQ(code, 0) << header;
  for (const char* needle : {"GROUP \"particles\"", "GROUP \"connectivity\"", "GROUP \"fields\"",
                             "GROUP \"fluid_velocity\"", "GROUP \"edges\"", "GROUP \"summary\""}) {
    EXPECT_NE(header.find(needle), std::string::npos) << "missing " << needle;
  }

  // The CLI: result with XDMF naming existing datasets, cell and flow together.
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  const fs::path fetched = dir_ / "fetched" / "flow.h5";
  fs::create_directories(fetched.parent_path());
  const std::string printed = run_command(cli + " result " + id + " -o " + fetched.string(), &code);
  ASSERT_EQ(code, 0) << printed;
  const fs::path xdmf = fs::path(fetched).replace_extension(".xdmf");
  ASSERT_TRUE(fs::exists(xdmf)) << printed;
  const std::string xml = read_valid_xml(xdmf);
  EXPECT_NE(xml.find("TopologyType=\"Tetrahedron\""), std::string::npos);
  EXPECT_NE(xml.find("TopologyType=\"3DCoRectMesh\""), std::string::npos);
  // 5 times (cell and fluid snapshots together) x (topology, geometry, region
  // of the cell + the fluid velocity), the file named with a directory part.
  EXPECT_EQ(count_existing_items(fetched, xml, std::regex(R"(>\./flow\.h5:(/[^<]+)</DataItem>)")), 5 * 3 + 5);

  // result --csv: the D(t) table, one row per sample, the same as cellflow-run's.
  const std::string csv = run_command(cli + " result " + id + " --csv", &code);
  ASSERT_EQ(code, 0) << csv;
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "sample,time_s,strain,taylor_deformation,inclination_rad,net_strain,a1_m,a2_m,a3_m,"
            "tank_treading_frequency_per_s,volume_m3");
  EXPECT_EQ(static_cast<std::size_t>(std::count(csv.begin(), csv.end(), '\n')), samples.size() + 1);
#ifdef CELLFLOW_RUN_EXE
  const fs::path spec_json = dir_ / "flow.json";
  {
    std::ofstream out(spec_json);
    out << jobs::job_spec_to_json(spec);
  }
  const std::string local =
      run_command(std::string(CELLFLOW_RUN_EXE) + " -q -j 1 " + spec_json.string() + " 2>/dev/null", &code);
  EXPECT_EQ(code, 0) << local;
  EXPECT_EQ(local, csv) << "cellflow-run and cellflow result --csv differ";
#endif

  // watch prints the deformation samples; plot draws D(t).
  const std::string watched = run_command(cli + " watch " + id, &code);
  EXPECT_EQ(code, 0) << watched;
  std::size_t lines = 0;
  for (std::size_t at = watched.find("taylor_deformation="); at != std::string::npos;
       at = watched.find("taylor_deformation=", at + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, samples.size()) << watched;
  EXPECT_NE(watched.find("strain="), std::string::npos);
  const fs::path svg = dir_ / "d.svg";
  const std::string plotted = run_command(cli + " plot " + id + " -o " + svg.string(), &code);
  ASSERT_EQ(code, 0) << plotted;
  run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + svg.string(), &code);
  EXPECT_EQ(code, 0);
  const std::string drawn = read_text(svg);
  EXPECT_NE(drawn.find("Taylor deformation D"), std::string::npos);
  EXPECT_NE(drawn.find("5/4 Ca"), std::string::npos);
  EXPECT_NE(drawn.find("<polyline"), std::string::npos);
}

TEST_F(ServiceTest, ShearFlowJobsPlotSteadyDeformationAgainstCapillaryNumber) {
  start_server(1, {"--worker-arg=--threads=1"});
  const std::string a = submit(small_shear_flow(0.1));
  const std::string b = submit(small_shear_flow(0.2));
  ASSERT_TRUE(wait_state(a, v1::Job::SUCCEEDED, 30s)) << get(a).reason();
  ASSERT_TRUE(wait_state(b, v1::Job::SUCCEEDED, 30s)) << get(b).reason();
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  const fs::path svg = dir_ / "ca.svg";
  int code = 0;
  const std::string printed =
      run_command(cli + " plot " + a + " " + b + " --against capillary-number -o " + svg.string(), &code);
  ASSERT_EQ(code, 0) << printed;
  // One line per job with its Ca and steady D, then the file.
  EXPECT_NE(printed.find(a + "  Ca 0.1 "), std::string::npos) << printed;
  EXPECT_NE(printed.find(b + "  Ca 0.2 "), std::string::npos) << printed;
  run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + svg.string(), &code);
  EXPECT_EQ(code, 0);
  const std::string drawn = read_text(svg);
  EXPECT_NE(drawn.find("Roscoe"), std::string::npos);
  EXPECT_NE(drawn.find("5/4 Ca"), std::string::npos);
  // One marker per job (radius 4: markers without a line).
  const std::regex marker(R"(<circle [^>]*r="4")");
  EXPECT_EQ(std::distance(std::sregex_iterator(drawn.begin(), drawn.end(), marker), std::sregex_iterator()),
            2);
  // Several jobs without --against: a usage error.
  run_command(cli + " plot " + a + " " + b + " -o " + svg.string(), &code);
  EXPECT_EQ(code, 1);
}

TEST_F(ServiceTest, ShearFlowCancelStopsTheWorkerWhichTakesTheNextJob) {
  start_server(1, {"--worker-arg=--threads=1"});
  // 1000 strain units with the steady stop off: minutes, unless cancelled.
  v1::JobSpec long_job = small_shear_flow(0.2, 1000.0);
  long_job.mutable_shear_flow()->mutable_numerics()->set_steady_tolerance(0.0);
  const std::string a = submit(long_job);
  const std::string b = submit(small_shear_flow());
  Watcher watcher(*client_, a);
  ASSERT_TRUE(eventually([&] { return watcher.max_sample_index() >= 3; }, 30s)) << "no samples";
  double moved_on_s = 0.0;
  ASSERT_NO_FATAL_FAILURE(cancel_and_await_next(a, b, "flow cancel", &moved_on_s));
  EXPECT_TRUE(wait_state(b, v1::Job::SUCCEEDED, 30s));
  watcher.join();
  const std::vector<v1::JobEvent> events = watcher.events();
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().state_change().state(), v1::Job::CANCELLED);
  const v1::Job final_a = get(a);
  EXPECT_EQ(final_a.state(), v1::Job::CANCELLED);
  EXPECT_EQ(final_a.result_size_bytes(), 0);
  EXPECT_LT(final_a.fraction_done(), 0.5);
}

struct BadFlowSpec {
  const char* what;
  std::function<void(v1::ShearFlowSpec&)> spoil;
  grpc::StatusCode code;
  const char* field;  // must appear in the error message
};

TEST_F(ServiceTest, BadShearFlowSpecsAreRefusedAtSubmitNamingTheField) {
  start_server(0, {"--memory-limit-bytes", "200000000"});
  const std::vector<BadFlowSpec> cases = {
      {"negative viscosity", [](auto& f) { f.set_fluid_viscosity_pa_s(-1e-3); },
       grpc::StatusCode::INVALID_ARGUMENT, "shear_flow.fluid_viscosity_pa_s"},
      {"negative shear rate", [](auto& f) { f.set_shear_rate_per_s(-4.0); },
       grpc::StatusCode::INVALID_ARGUMENT, "shear_flow.shear_rate_per_s"},
      {"no drive", [](auto& f) { f.clear_drive(); }, grpc::StatusCode::INVALID_ARGUMENT,
       "shear_flow.capillary_number"},
      {"box smaller than the cell", [](auto& f) { f.mutable_numerics()->set_box_y_radii(1.5); },
       grpc::StatusCode::INVALID_ARGUMENT, "shear_flow.numerics.box_y_radii"},
      {"unknown kernel", [](auto& f) { f.mutable_numerics()->set_ibm_kernel("gauss"); },
       grpc::StatusCode::INVALID_ARGUMENT, "shear_flow.numerics.ibm_kernel"},
      // Re_p raised to 1 puts the wall at lattice speed 0.17, Mach 0.29.
      {"Mach number", [](auto& f) { f.mutable_numerics()->set_target_reynolds_number(1.0); },
       grpc::StatusCode::INVALID_ARGUMENT, "shear_flow.numerics.max_mach"},
      {"lattice above the spec's memory limit",
       [](auto& f) {
         f.mutable_numerics()->set_cells_per_radius(40);  // 4.8e7 nodes, ~5.6 GB
         f.mutable_numerics()->set_box_x_radii(10);
         f.mutable_numerics()->set_box_y_radii(15);
         f.mutable_numerics()->set_box_z_radii(5);
       },
       grpc::StatusCode::RESOURCE_EXHAUSTED, "shear_flow.numerics.memory_limit_bytes"},
      {"lattice above the server's memory limit",
       [](auto& f) {
         f.mutable_numerics()->set_cells_per_radius(16);  // 3.1e6 nodes, ~360 MB
         f.mutable_numerics()->set_box_x_radii(10);
         f.mutable_numerics()->set_box_y_radii(15);
         f.mutable_numerics()->set_box_z_radii(5);
       },
       grpc::StatusCode::RESOURCE_EXHAUSTED, "memory"},
      {"no cell", [](auto& f) { f.clear_cell(); }, grpc::StatusCode::INVALID_ARGUMENT, "shear_flow.cell"},
  };
  for (const BadFlowSpec& c : cases) {
    v1::SubmitJobRequest request;
    *request.mutable_spec() = small_shear_flow();
    c.spoil(*request.mutable_spec()->mutable_shear_flow());
    v1::SubmitJobResponse response;
    const grpc::Status status = client_->submit(request, &response);
    EXPECT_EQ(status.error_code(), c.code) << c.what << ": " << status.error_message();
    EXPECT_NE(status.error_message().find(c.field), std::string::npos)
        << c.what << ": " << status.error_message();
  }
  v1::ListJobsRequest list;
  v1::ListJobsResponse jobs;
  ASSERT_TRUE(client_->list(list, &jobs).ok());
  EXPECT_EQ(jobs.jobs_size(), 0);
  // The valid job is accepted; its estimate counts one population array of
  // 19 floats, the coupling fields and the buffers: well under 1 MiB of
  // lattice for 15 x 18 x 12 nodes, above the 64 MiB process baseline.
  const std::string id = submit(small_shear_flow());
  ASSERT_FALSE(id.empty());
  const v1::Job job = get(id);
  EXPECT_GT(job.estimated_memory_bytes(), 64LL << 20);
  EXPECT_LT(job.estimated_memory_bytes(), (64LL << 20) + 300 * (16LL << 10) + (1LL << 20));
}

}  // namespace
}  // namespace cellflow::testing
