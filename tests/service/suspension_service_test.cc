// Suspension jobs through the service end to end on loopback (real
// cellflow-server, cellflow-worker and SQLite file): a tiny suspension of
// three coarse cells is submitted and watched; its streamed samples equal an
// in-process run of the same spec, and its result file holds every cell's
// trajectory and per-cell series; the CLI prints, tabulates and plots it.
#include <hdf5.h>

#include <cmath>
#include <fstream>
#include <regex>

#include "io/h5md.h"
#include "jobs/job_spec.h"
#include "jobs/suspension/suspension_spec.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

// Three cells of ~300 vertices (R = 4 um, E = 50 Pa, Ca = 0.2) in the
// default 5 x 8 x 4 R box at 3 lattice nodes per radius (15 x 24 x 12 nodes),
// 1.5 strain units.
v1::JobSpec small_suspension() {
  v1::JobSpec spec;
  spec.set_name("small suspension");
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
  flow->set_max_strain(1.5);
  flow->set_sample_every_strain(0.1);
  flow->set_snapshot_every_strain(0.5);
  return spec;
}

double relative_difference(double a, double b) {
  const double scale = std::max(std::fabs(a), std::fabs(b));
  return scale == 0.0 ? 0.0 : std::fabs(a - b) / scale;
}

std::vector<std::int64_t> read_int64s(const std::string& h5, const char* dataset) {
  std::vector<std::int64_t> out;
  const hid_t file = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (file < 0) return out;
  const hid_t d = H5Dopen2(file, dataset, H5P_DEFAULT);
  if (d >= 0) {
    const hid_t space = H5Dget_space(d);
    out.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
    if (H5Dread(d, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0) out.clear();
    H5Sclose(space);
    H5Dclose(d);
  }
  H5Fclose(file);
  return out;
}

TEST_F(ServiceTest, SuspensionJobStreamsSamplesEqualToTheSceneAndWritesEveryCell) {
  start_server(1, {"--worker-arg=--threads=1"});
  const v1::JobSpec spec = small_suspension();
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
  std::vector<v1::SuspensionSample> samples;
  for (const auto& e : events) {
    if (e.has_suspension_sample()) samples.push_back(e.suspension_sample());
  }
  ASSERT_GE(samples.size(), 15u);  // every 0.1 strain to 1.5
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i].index(), static_cast<int>(i));
    EXPECT_EQ(samples[i].cell_count(), 3);
    ASSERT_EQ(samples[i].cells_size(), 3);
    if (i > 0) {
      EXPECT_GT(samples[i].strain(), samples[i - 1].strain()) << i;
    }
  }
  EXPECT_NEAR(samples.back().strain(), 1.5, 0.01);
  EXPECT_GT(samples.back().mean_taylor_deformation(), 0.02);  // the cells deformed
  EXPECT_GT(samples.back().relative_viscosity(), 1.0);        // cells add to the wall stress

  // The same spec through the scene in this process, on one thread as the worker.
  StatusOr<scenes::PlannedSuspension> planned = jobs::plan(spec.suspension());
  ASSERT_TRUE(planned.ok()) << planned.status().to_string();
  planned->set_threads(1);
  const auto direct_start = std::chrono::steady_clock::now();
  const scenes::SuspensionResult reference = scenes::run_suspension(*planned);
  const double direct_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - direct_start).count();
  ASSERT_TRUE(reference.status.ok()) << reference.status.to_string();
  ASSERT_EQ(samples.size(), reference.samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const scenes::SuspensionSample& r = reference.samples[i];
    EXPECT_LE(relative_difference(samples[i].mean_taylor_deformation(), r.mean_taylor_deformation), 1e-12)
        << i;
    EXPECT_LE(relative_difference(samples[i].relative_viscosity(), r.relative_viscosity), 1e-12) << i;
    EXPECT_LE(relative_difference(samples[i].strain(), r.strain_units), 1e-12) << i;
    EXPECT_EQ(samples[i].contact_pairs(), r.contact_pairs) << i;
    EXPECT_LE(relative_difference(samples[i].average_taylor_deformation(), r.average_taylor_deformation),
              1e-12)
        << i;
    for (int c = 0; c < 3; ++c) {
      EXPECT_LE(relative_difference(samples[i].cells(c).taylor_deformation(),
                                    r.cells[static_cast<std::size_t>(c)].taylor_deformation),
                1e-12)
          << i << " cell " << c;
      EXPECT_LE(relative_difference(samples[i].cells(c).centroid_m(1),
                                    r.cells[static_cast<std::size_t>(c)].centroid_m[1]),
                1e-12)
          << i << " cell " << c;
    }
  }
  std::printf("tiny suspension job: submit -> SUCCEEDED through the service %.3f s, in-process %.3f s\n",
              service_s, direct_s);

  // The result: every cell's trajectory, the kinds, the per-cell and mean series.
  const std::string h5 = (dir_ / "suspension.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  EXPECT_EQ(*io::read_scalar(h5, "/parameters/setup/cell_count"), 3.0);
  EXPECT_EQ(read_int64s(h5, "/parameters/setup/cell_kind"), (std::vector<std::int64_t>{0, 0, 0}));
  const std::vector<std::int64_t> offsets = read_int64s(h5, "/parameters/setup/cell_vertex_offset");
  ASSERT_EQ(offsets.size(), 4u);
  EXPECT_EQ(offsets[1] * 3, offsets[3]);  // one kind: the same mesh three times
  auto frames = io::count_position_frames(h5, "cell");
  ASSERT_TRUE(frames.ok()) << frames.status().to_string();
  EXPECT_EQ(*frames, 4);  // strain 0, 0.5, 1, 1.5
  auto last = io::read_position_frame(h5, "cell", *frames - 1);
  ASSERT_TRUE(last.ok());
  ASSERT_EQ(last->positions_m.size(), static_cast<std::size_t>(offsets[3]) * 3);
  // Each cell's vertices around its streamed centroid (within 2 R).
  for (int c = 0; c < 3; ++c) {
    double mean_y = 0.0;
    for (std::int64_t v = offsets[c]; v < offsets[c + 1]; ++v)
      mean_y += last->positions_m[static_cast<std::size_t>(3 * v + 1)];
    mean_y /= static_cast<double>(offsets[c + 1] - offsets[c]);
    EXPECT_NEAR(mean_y, samples.back().cells(c).centroid_m(1), 8e-6) << "cell " << c;
  }
  auto mean = io::read_observable(h5, "mean_taylor_deformation");
  ASSERT_TRUE(mean.ok()) << mean.status().to_string();
  ASSERT_EQ(mean->value.size(), samples.size());
  auto per_cell = io::read_observable(h5, "cell_taylor_deformation");
  ASSERT_TRUE(per_cell.ok()) << per_cell.status().to_string();
  ASSERT_EQ(per_cell->width, 3);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(mean->value[i], samples[i].mean_taylor_deformation());
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(per_cell->value[3 * i + static_cast<std::size_t>(c)],
                samples[i].cells(c).taylor_deformation());
  }
  EXPECT_EQ(*io::read_string(h5, "/summary/stop"), "max_strain");
  EXPECT_DOUBLE_EQ(*io::read_scalar(h5, "/summary/average_taylor_deformation"),
                   reference.average_taylor_deformation);
  EXPECT_DOUBLE_EQ(*io::read_scalar(h5, "/summary/average_relative_viscosity"),
                   reference.average_relative_viscosity);

  // The CLI: result with an XDMF of every cell.
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  int code = 0;
  const fs::path fetched = dir_ / "fetched" / "suspension.h5";
  fs::create_directories(fetched.parent_path());
  const std::string printed = run_command(cli + " result " + id + " -o " + fetched.string(), &code);
  ASSERT_EQ(code, 0) << printed;
  const fs::path xdmf = fs::path(fetched).replace_extension(".xdmf");
  ASSERT_TRUE(fs::exists(xdmf)) << printed;
  const std::string xml = read_valid_xml(xdmf);
  EXPECT_NE(xml.find("TopologyType=\"Tetrahedron\""), std::string::npos);
  // 4 frames x (topology, geometry, region), each naming a dataset of the file.
  EXPECT_EQ(count_existing_items(fetched, xml, std::regex(R"(>\./suspension\.h5:(/[^<]+)</DataItem>)")),
            4 * 3);

  // result --csv: one row per sample, the same as cellflow-run's.
  const std::string csv = run_command(cli + " result " + id + " --csv", &code);
  ASSERT_EQ(code, 0) << csv;
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "sample,time_s,strain,cell_count,mean_taylor_deformation,mean_inclination_rad,relative_viscosity,"
            "contact_pairs,average_taylor_deformation,average_taylor_deformation_error,"
            "average_relative_viscosity,average_relative_viscosity_error");
  EXPECT_EQ(static_cast<std::size_t>(std::count(csv.begin(), csv.end(), '\n')), samples.size() + 1);
#ifdef CELLFLOW_RUN_EXE
  const fs::path spec_json = dir_ / "suspension.json";
  {
    std::ofstream out(spec_json);
    out << jobs::job_spec_to_json(spec);
  }
  const std::string local =
      run_command(std::string(CELLFLOW_RUN_EXE) + " -q -j 1 " + spec_json.string() + " 2>/dev/null", &code);
  EXPECT_EQ(code, 0) << local;
  EXPECT_EQ(local, csv) << "cellflow-run and cellflow result --csv differ";
#endif

  // watch prints one line per sample; plot draws mean D(t) with the band, and the averages against phi.
  const std::string watched = run_command(cli + " watch " + id, &code);
  EXPECT_EQ(code, 0) << watched;
  std::size_t lines = 0;
  for (std::size_t at = watched.find("mean_taylor_deformation="); at != std::string::npos;
       at = watched.find("mean_taylor_deformation=", at + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, samples.size()) << watched;
  EXPECT_NE(watched.find("relative_viscosity="), std::string::npos);
  const fs::path svg = dir_ / "d.svg";
  ASSERT_EQ((run_command(cli + " plot " + id + " -o " + svg.string(), &code), code), 0);
  run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + svg.string(), &code);
  EXPECT_EQ(code, 0);
  const std::string drawn = read_text(svg);
  EXPECT_NE(drawn.find("mean D over the cells"), std::string::npos);
  EXPECT_NE(drawn.find("min and max over the cells"), std::string::npos);
  EXPECT_NE(drawn.find("time average"), std::string::npos);
  const fs::path phi_svg = dir_ / "phi.svg";
  const std::string by_phi =
      run_command(cli + " plot " + id + " --against volume-fraction -o " + phi_svg.string(), &code);
  ASSERT_EQ(code, 0) << by_phi;
  EXPECT_NE(by_phi.find(id + "  Ca 0.2 "), std::string::npos) << by_phi;
  run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + phi_svg.string(), &code);
  EXPECT_EQ(code, 0);
  const std::string phi_drawn = read_text(phi_svg);
  EXPECT_NE(phi_drawn.find("relative viscosity"), std::string::npos);
  EXPECT_NE(phi_drawn.find("rigid spheres"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::testing
