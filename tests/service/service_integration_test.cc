// The service end to end on loopback: a real cellflow-server, real
// cellflow-worker processes (spawned by the server or separately) and a real
// SQLite file in a temporary directory.
#include <google/protobuf/util/json_util.h>
#include <grpcpp/generic/generic_stub.h>
#include <hdf5.h>

#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <regex>
#include <set>

#include "io/h5md.h"
#include "jobs/job_spec.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "server/store.h"
#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

double relative_difference(double a, double b) {
  const double scale = std::max(std::fabs(a), std::fabs(b));
  return scale == 0.0 ? 0.0 : std::fabs(a - b) / scale;
}

TEST_F(ServiceTest, SubmitWatchSucceedAndCurveEqualsLibrary) {
  start_server(1);
  const v1::JobSpec spec = small_compression(5);
  const std::string id = submit(spec);
  ASSERT_FALSE(id.empty());
  Watcher watcher(*client_, id);
  watcher.join();
  ASSERT_TRUE(watcher.status().ok()) << watcher.status().error_message();
  const auto events = watcher.events();
  ASSERT_FALSE(events.empty());
  ASSERT_TRUE(events.back().has_state_change());
  EXPECT_EQ(events.back().state_change().state(), v1::Job::SUCCEEDED);

  std::vector<v1::ForceSample> samples;
  bool saw_running = false, saw_progress = false;
  for (const auto& e : events) {
    if (e.has_force_sample()) samples.push_back(e.force_sample());
    if (e.has_progress()) saw_progress = true;
    if (e.has_state_change() && e.state_change().state() == v1::Job::RUNNING) saw_running = true;
  }
  EXPECT_TRUE(saw_running);
  EXPECT_TRUE(saw_progress);

  // The same spec through the library in this process.
  auto params = jobs::to_params(spec.compression());
  ASSERT_TRUE(params.ok()) << params.status().to_string();
  const scenes::QuasiStaticResult reference = scenes::run_compression(*params);
  ASSERT_TRUE(reference.status.ok()) << reference.status.to_string();
  ASSERT_EQ(samples.size(), reference.curve.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const scenes::CurvePoint& p = reference.curve[i];
    EXPECT_EQ(samples[i].index(), p.index);
    EXPECT_LE(relative_difference(samples[i].force_n(), p.force_n), 1e-12) << "point " << i;
    EXPECT_LE(relative_difference(samples[i].deformation(), p.deformation), 1e-12) << "point " << i;
    EXPECT_LE(relative_difference(samples[i].hertz_force_n(), p.hertz_force_n), 1e-12) << "point " << i;
    EXPECT_LE(relative_difference(samples[i].taylor_deformation(), p.taylor_deformation), 1e-12)
        << "point " << i;
  }

  // The result file holds the same curve.
  const std::string h5 = (dir_ / "result.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  auto force = io::read_observable(h5, "force_n");
  ASSERT_TRUE(force.ok()) << force.status().to_string();
  ASSERT_EQ(force->value.size(), reference.curve.size());
  for (std::size_t i = 0; i < force->value.size(); ++i) {
    EXPECT_LE(relative_difference(force->value[i], reference.curve[i].force_n), 1e-12) << "point " << i;
  }
  // The client named the author (its user name); the worker wrote the XDMF
  // sidecar, downloadable beside the file under the server's name.
  {
    hid_t file = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t author = H5Aopen_by_name(file, "/h5md/author", "name", H5P_DEFAULT, H5P_DEFAULT);
    hid_t type = H5Aget_type(author);
    std::string name(H5Tget_size(type), '\0');
    H5Aread(author, type, name.data());
    H5Tclose(type);
    H5Aclose(author);
    H5Fclose(file);
    name.resize(name.find('\0') == std::string::npos ? name.size() : name.find('\0'));
    EXPECT_FALSE(name.empty());
    EXPECT_NE(name, "unknown");
    EXPECT_EQ(name, get(id).spec().author());
  }
  const fs::path served = dir_ / (id + ".h5");
  fs::copy_file(h5, served, fs::copy_options::overwrite_existing);
  const fs::path sidecar = dir_ / (id + ".xdmf");
  ASSERT_TRUE(client_->download(id, sidecar.string(), v1::RESULT_PART_XDMF).ok());
  const std::string sidecar_xml = read_valid_xml(sidecar);
  EXPECT_GE(
      count_existing_items(served, sidecar_xml, std::regex(">\\./" + id + R"(\.h5:(/[^<]+)</DataItem>)")), 2);
  EXPECT_NE(sidecar_xml.find("HyperSlab"), std::string::npos);
  const v1::Job job = get(id);
  EXPECT_EQ(job.state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(job.attempt(), 1);
  EXPECT_EQ(job.result_size_bytes(), static_cast<std::int64_t>(fs::file_size(h5)));
  EXPECT_DOUBLE_EQ(job.fraction_done(), 1.0);
}

// Numerical failure is a result: FAILED with the load step and the cause, and
// the partial result (mesh and reference state) is kept.
TEST_F(ServiceTest, NumericalFailureEndsFailedWithReasonAndPartialResult) {
  start_server(1);
  v1::JobSpec spec = small_compression(4);
  spec.mutable_compression()->mutable_numerics()->set_max_newton_iterations(1);
  spec.mutable_compression()->mutable_numerics()->set_max_step_splits(0);
  const std::string id = submit(spec);
  Watcher watcher(*client_, id);
  watcher.join();
  ASSERT_TRUE(watcher.status().ok());
  const std::vector<v1::JobEvent> events = watcher.events();
  ASSERT_FALSE(events.empty());
  const v1::StateChange& last = events.back().state_change();
  EXPECT_EQ(last.state(), v1::Job::FAILED);
  EXPECT_NE(last.reason().find("load step 0"), std::string::npos) << last.reason();
  const v1::Job job = get(id);
  EXPECT_EQ(job.state(), v1::Job::FAILED);
  EXPECT_EQ(job.attempt(), 1);  // a numerical failure is not retried
  EXPECT_EQ(job.reason(), last.reason());
  const std::string h5 = (dir_ / "partial.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  auto frames = io::count_position_frames(h5, "cell");
  ASSERT_TRUE(frames.ok());
  EXPECT_GE(*frames, 1);
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  int code = 0;
  run_command(cli + " watch " + id, &code);
  EXPECT_EQ(code, 3);
}

TEST_F(ServiceTest, SameRequestIdGivesOneJob) {
  start_server(0);
  v1::SubmitJobRequest request;
  *request.mutable_spec() = small_compression();
  request.set_request_id("idempotent-1");
  v1::SubmitJobResponse first, second;
  ASSERT_TRUE(client_->submit(request, &first).ok());
  ASSERT_TRUE(client_->submit(request, &second).ok());
  EXPECT_FALSE(first.already_existed());
  EXPECT_TRUE(second.already_existed());
  EXPECT_EQ(first.job().id(), second.job().id());
  v1::ListJobsRequest list;
  v1::ListJobsResponse jobs;
  ASSERT_TRUE(client_->list(list, &jobs).ok());
  EXPECT_EQ(jobs.jobs_size(), 1);
}

TEST_F(ServiceTest, KilledWorkerJobIsLeasedAgainAndNoSampleSeenTwice) {
  start_server(0, {"--lease-ttl-s", "1"});
  // 300 ms per load point: the job takes ~2.4 s, long enough to kill its worker.
  Process* first = start_worker({"--debug-delay-per-point-ms", "300"});
  const v1::JobSpec spec = small_compression(8);
  const std::string id = submit(spec);
  Watcher watcher(*client_, id);
  ASSERT_TRUE(eventually([&] { return watcher.max_sample_index() >= 2; }, 30s)) << "no samples";
  first->signal(SIGKILL);
  first->wait();
  const int delivered_before_kill = watcher.max_sample_index();
  start_worker();
  watcher.join();
  ASSERT_TRUE(watcher.status().ok()) << watcher.status().error_message();
  const v1::Job job = get(id);
  EXPECT_EQ(job.state(), v1::Job::SUCCEEDED);
  EXPECT_EQ(job.attempt(), 2);

  const std::vector<int> indices = watcher.sample_indices();
  std::vector<int> expected(8);
  for (int i = 0; i < 8; ++i) expected[i] = i;
  EXPECT_EQ(indices, expected) << "each index once, in order";
  EXPECT_GE(delivered_before_kill, 2);
  bool saw_requeue = false;
  for (const auto& e : watcher.events()) {
    if (e.has_state_change() && e.state_change().state() == v1::Job::QUEUED &&
        e.state_change().reason().find("expired") != std::string::npos) {
      saw_requeue = true;
    }
  }
  EXPECT_TRUE(saw_requeue);
  // The result is the second attempt's complete curve.
  const std::string h5 = (dir_ / "retried.h5").string();
  ASSERT_TRUE(client_->download(id, h5).ok());
  auto force = io::read_observable(h5, "force_n");
  ASSERT_TRUE(force.ok());
  EXPECT_EQ(force->value.size(), 8u);
}

TEST_F(ServiceTest, KilledServerLosesNoJob) {
  const std::vector<std::string> options = {"--lease-ttl-s", "1",
                                            "--worker-arg=--debug-delay-per-point-ms=150"};
  start_server(2, options);
  const int port = port_;
  std::vector<std::string> ids;
  for (int i = 0; i < 4; ++i) ids.push_back(submit(small_compression(6), "restart-" + std::to_string(i)));
  // Kill the server while jobs run and others wait.
  ASSERT_TRUE(eventually(
      [&] { return get(ids[0]).state() == v1::Job::RUNNING && get(ids[0]).last_sequence() > 4; }, 30s));
  server_->signal(SIGKILL);
  server_->wait();
  start_server(2, options, port);
  for (const auto& id : ids) {
    EXPECT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s))
        << id << " is " << v1::Job::State_Name(get(id).state());
  }
  // Submitting the same request ids again finds the jobs of the first server.
  v1::SubmitJobRequest again;
  *again.mutable_spec() = small_compression(6);
  again.set_request_id("restart-0");
  v1::SubmitJobResponse response;
  ASSERT_TRUE(client_->submit(again, &response).ok());
  EXPECT_TRUE(response.already_existed());
  EXPECT_EQ(response.job().id(), ids[0]);
}

TEST_F(ServiceTest, CancelStopsRunningJobAndWorkerTakesNext) {
  start_server(1, {"--worker-arg=--debug-delay-per-point-ms=300"});
  const std::string a = submit(small_compression(20));  // ~6 s
  const std::string b = submit(small_compression(3));
  ASSERT_TRUE(
      eventually([&] { return get(a).state() == v1::Job::RUNNING && get(a).last_sequence() >= 4; }, 30s));
  const std::string worker_a = get(a).worker_id();
  // The single worker must stop job a and lease job b.
  double moved_on_s = 0.0;
  ASSERT_NO_FATAL_FAILURE(cancel_and_await_next(a, b, "cancel", &moved_on_s));
  EXPECT_LT(moved_on_s, 2.0);
  EXPECT_EQ(get(b).worker_id(), worker_a);
  EXPECT_TRUE(wait_state(b, v1::Job::SUCCEEDED, 30s));
  const v1::Job final_a = get(a);
  EXPECT_EQ(final_a.state(), v1::Job::CANCELLED);
  EXPECT_EQ(final_a.result_size_bytes(), 0);
  // A cancelled job cannot be un-cancelled; a succeeded one cannot be cancelled.
  v1::Job job;
  EXPECT_EQ(client_->cancel(b, &job).error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  // Watching the cancelled job replays up to CANCELLED and ends.
  Watcher replay(*client_, a);
  replay.join();
  ASSERT_FALSE(replay.events().empty());
  EXPECT_EQ(replay.events().back().state_change().state(), v1::Job::CANCELLED);
  // No sample of a after the cancel: the worker's late reports were fenced.
  std::int64_t cancel_sequence = replay.events().back().sequence();
  EXPECT_EQ(final_a.last_sequence(), cancel_sequence);
}

TEST_F(ServiceTest, ResumedWatcherSeesEveryEventOnceInOrder) {
  start_server(1, {"--worker-arg=--debug-delay-per-point-ms=100"});
  const std::string id = submit(small_compression(8));
  std::vector<v1::JobEvent> seen;
  // First connection: take a few events, then hang up.
  grpc::Status status = client_->watch(id, 0, [&](const v1::JobEvent& e) {
    seen.push_back(e);
    return seen.size() < 4;
  });
  EXPECT_EQ(status.error_code(), grpc::StatusCode::CANCELLED);
  ASSERT_EQ(seen.size(), 4u);
  // Later connections resume after the last sequence seen, twice.
  for (int round = 0; round < 2; ++round) {
    std::size_t taken = 0;
    status = client_->watch(id, seen.back().sequence(), [&](const v1::JobEvent& e) {
      seen.push_back(e);
      return round == 1 || ++taken < 3;
    });
    EXPECT_TRUE(status.ok() || status.error_code() == grpc::StatusCode::CANCELLED) << status.error_message();
  }
  ASSERT_TRUE(seen.back().has_state_change());
  EXPECT_EQ(seen.back().state_change().state(), v1::Job::SUCCEEDED);
  for (std::size_t i = 0; i < seen.size(); ++i)
    EXPECT_EQ(seen[i].sequence(), static_cast<std::int64_t>(i + 1));
  // The full replay afterwards is the same list.
  std::vector<v1::JobEvent> replay;
  ASSERT_TRUE(client_
                  ->watch(id, 0,
                          [&](const v1::JobEvent& e) {
                            replay.push_back(e);
                            return true;
                          })
                  .ok());
  ASSERT_EQ(replay.size(), seen.size());
  for (std::size_t i = 0; i < seen.size(); ++i) {
    EXPECT_EQ(replay[i].SerializeAsString(), seen[i].SerializeAsString()) << "event " << i;
  }
  EXPECT_EQ(get(id).last_sequence(), static_cast<std::int64_t>(seen.size()));
}

struct BadSpec {
  const char* what;
  std::function<void(v1::JobSpec&)> spoil;
  const char* field;  // must appear in the error message
};

TEST_F(ServiceTest, BadSpecsAreRefusedNamingTheFieldAndNothingIsQueued) {
  start_server(0, {"--memory-limit-bytes", "200000000"});
  auto compression = [](v1::JobSpec& s) { return s.mutable_compression(); };
  auto cell = [&](v1::JobSpec& s) { return compression(s)->mutable_cell(); };
  auto material = [&](v1::JobSpec& s) { return cell(s)->mutable_material(); };
  auto indentation = [](v1::JobSpec& s) {
    v1::JobSpec fresh;
    auto* in = fresh.mutable_indentation();
    *in->mutable_cell() = s.compression().cell();
    in->set_probe_radius_m(2e-6);
    in->set_max_indentation_m(1e-6);
    in->set_load_points(4);
    s = fresh;
    return s.mutable_indentation();
  };
  const std::vector<BadSpec> table = {
      {"no scene", [](v1::JobSpec& s) { s.clear_compression(); }, "scene"},
      {"radius zero", [&](v1::JobSpec& s) { cell(s)->set_radius_m(0); }, "radius_m"},
      {"radius negative", [&](v1::JobSpec& s) { cell(s)->set_radius_m(-1e-6); }, "radius_m"},
      {"radius NaN", [&](v1::JobSpec& s) { cell(s)->set_radius_m(std::nan("")); }, "radius_m"},
      {"E zero", [&](v1::JobSpec& s) { material(s)->set_youngs_modulus_pa(0); }, "youngs_modulus_pa"},
      {"E negative", [&](v1::JobSpec& s) { material(s)->set_youngs_modulus_pa(-5); }, "youngs_modulus_pa"},
      {"nu 0.5", [&](v1::JobSpec& s) { material(s)->set_poisson_ratio(0.5); }, "poisson_ratio"},
      {"nu below -1", [&](v1::JobSpec& s) { material(s)->set_poisson_ratio(-1.5); }, "poisson_ratio"},
      {"w above 1", [&](v1::JobSpec& s) { material(s)->set_mooney_rivlin_w(1.5); }, "mooney_rivlin_w"},
      {"w negative", [&](v1::JobSpec& s) { material(s)->set_mooney_rivlin_w(-0.1); }, "mooney_rivlin_w"},
      {"too few vertices", [&](v1::JobSpec& s) { cell(s)->set_target_vertex_count(50); },
       "target_vertex_count"},
      {"too many vertices", [&](v1::JobSpec& s) { cell(s)->set_target_vertex_count(50000); },
       "target_vertex_count"},
      {"deformation zero", [&](v1::JobSpec& s) { compression(s)->set_max_deformation(0); },
       "max_deformation"},
      {"deformation 0.95", [&](v1::JobSpec& s) { compression(s)->set_max_deformation(0.95); },
       "max_deformation"},
      {"load points zero", [&](v1::JobSpec& s) { compression(s)->set_load_points(0); }, "load_points"},
      {"tolerance negative",
       [&](v1::JobSpec& s) { compression(s)->mutable_numerics()->set_residual_tolerance(-1e-6); },
       "residual_tolerance"},
      {"nucleus larger than cell",
       [&](v1::JobSpec& s) {
         cell(s)->mutable_nucleus()->set_radius_m(6e-6);
         cell(s)->mutable_nucleus()->mutable_material()->set_youngs_modulus_pa(2000);
       },
       "nucleus.radius_m"},
      {"missing mesh file", [&](v1::JobSpec& s) { cell(s)->set_mesh_file("/nonexistent/cell.msh"); },
       "mesh_file"},
      {"probe radius zero", [&](v1::JobSpec& s) { indentation(s)->set_probe_radius_m(0); }, "probe_radius_m"},
      {"indentation too deep", [&](v1::JobSpec& s) { indentation(s)->set_max_indentation_m(1e-5); },
       "max_indentation_m"},
      {"shear flow with negative viscosity (more in shear_flow_service_test.cc)",
       [](v1::JobSpec& s) {
         v1::JobSpec fresh;
         auto* flow = fresh.mutable_shear_flow();
         *flow->mutable_cell() = s.compression().cell();
         flow->set_fluid_viscosity_pa_s(-1e-3);
         flow->set_shear_rate_per_s(10);
         s = fresh;
       },
       "shear_flow.fluid_viscosity_pa_s"},
  };
  ASSERT_GE(table.size(), 15u);
  for (const BadSpec& bad : table) {
    v1::JobSpec spec = small_compression();
    bad.spoil(spec);
    v1::SubmitJobRequest request;
    *request.mutable_spec() = spec;
    v1::SubmitJobResponse response;
    const grpc::Status status = client_->submit(request, &response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
        << bad.what << ": " << status.error_message();
    EXPECT_NE(status.error_message().find(bad.field), std::string::npos)
        << bad.what << ": \"" << status.error_message() << "\" does not name " << bad.field;
  }
  // Too large for the server's memory limit (200 MB): refused up front.
  v1::SubmitJobRequest big;
  *big.mutable_spec() = small_compression(5, 20000);
  v1::SubmitJobResponse response;
  const grpc::Status status = client_->submit(big, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  EXPECT_NE(status.error_message().find("memory-limit-bytes"), std::string::npos) << status.error_message();

  v1::ListJobsRequest list;
  v1::ListJobsResponse jobs;
  ASSERT_TRUE(client_->list(list, &jobs).ok());
  EXPECT_EQ(jobs.jobs_size(), 0) << "a refused spec was queued";
}

TEST_F(ServiceTest, ListPagesWithOpaqueTokensAndStateFilter) {
  start_server(0);
  for (int i = 0; i < 7; ++i) submit(small_compression());
  v1::Job cancelled;
  ASSERT_TRUE(client_->cancel("job-3", &cancelled).ok());
  v1::ListJobsRequest request;
  request.set_page_size(3);
  std::vector<std::string> ids;
  int pages = 0;
  do {
    v1::ListJobsResponse response;
    ASSERT_TRUE(client_->list(request, &response).ok());
    for (const auto& job : response.jobs()) ids.push_back(job.id());
    request.set_page_token(response.next_page_token());
    ++pages;
  } while (!request.page_token().empty());
  EXPECT_EQ(pages, 3);
  EXPECT_EQ(ids.size(), 7u);
  request.Clear();
  request.set_state(v1::Job::CANCELLED);
  v1::ListJobsResponse response;
  ASSERT_TRUE(client_->list(request, &response).ok());
  ASSERT_EQ(response.jobs_size(), 1);
  EXPECT_EQ(response.jobs(0).id(), "job-3");
  request.set_page_token("garbage");
  EXPECT_EQ(client_->list(request, &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  v1::Job job;
  EXPECT_EQ(client_->get("job-999", &job).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(client_->get("nonsense", &job).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
}

TEST_F(ServiceTest, ResultIsH5mdWithValidXdmfAndCliWorks) {
  start_server(1);
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  int code = 0;
  // Submit from flags and follow it: exit code 0 on SUCCEEDED.
  const std::string submitted =
      run_command(cli +
                      " submit --request-id cli-1 --watch compression --radius-m 5e-6"
                      " --youngs-modulus-pa 1000 --poisson-ratio 0.45"
                      " --target-vertex-count 300 --max-deformation 0.15 --load-points 4",
                  &code);
  ASSERT_EQ(code, 0) << submitted;
  std::smatch match;
  ASSERT_TRUE(std::regex_search(submitted, match, std::regex("(job-[0-9]+)"))) << submitted;
  const std::string id = match[1];
  EXPECT_NE(submitted.find("state SUCCEEDED"), std::string::npos) << submitted;
  EXPECT_NE(submitted.find("sample index=3"), std::string::npos) << submitted;

  const std::string h5 = (dir_ / "cli.h5").string();
  const std::string fetched = run_command(cli + " result " + id + " -o " + h5, &code);
  ASSERT_EQ(code, 0) << fetched;
  const std::string xdmf = (dir_ / "cli.xdmf").string();
  ASSERT_TRUE(fs::exists(xdmf)) << fetched;

  const std::string header = run_command(std::string(CELLFLOW_H5DUMP) + " -H " + h5, &code);
  ASSERT_EQ(code, 0) << header;
  for (const char* group :
       {"GROUP \"h5md\"", "GROUP \"author\"", "GROUP \"creator\"", "GROUP \"particles\"",
        "GROUP \"position\"", "GROUP \"observables\"", "GROUP \"force_n\"", "GROUP \"hertz_force_n\"",
        "GROUP \"deformation\"", "GROUP \"taylor_deformation\"", "GROUP \"connectivity\"",
        "GROUP \"parameters\""}) {
    EXPECT_NE(header.find(group), std::string::npos) << group;
  }
  auto json = io::read_parameters_json(h5);
  ASSERT_TRUE(json.ok());
  auto spec = jobs::job_spec_from_json(*json);
  ASSERT_TRUE(spec.ok()) << *json;
  EXPECT_EQ(spec->compression().load_points(), 4);
  auto frames = io::count_position_frames(h5, "cell");
  ASSERT_TRUE(frames.ok());
  EXPECT_GE(*frames, 2);  // reference and final at least

  const std::string xml = read_valid_xml(xdmf);
  EXPECT_GE(count_existing_items(h5, xml, std::regex(R"(>\./cli\.h5:(/[^<]+)</DataItem>)")), 2 * *frames);

  // CSV: one line per point, the force column equal to the file's, and the
  // very text cellflow-run writes for the same spec.
  const std::string csv = run_command(cli + " result " + id + " --csv", &code);
  ASSERT_EQ(code, 0) << csv;
  EXPECT_EQ(csv.rfind("point,deformation,displacement_m,force_n,hertz_force_n", 0), 0u) << csv;
#ifdef CELLFLOW_RUN_EXE
  const std::string spec_path = (dir_ / "cli_spec.json").string();
  std::ofstream(spec_path) << *json;
  const std::string local_csv = (dir_ / "local.csv").string();
  const std::string ran =
      run_command(std::string(CELLFLOW_RUN_EXE) + " " + spec_path + " -o " + local_csv + " --quiet", &code);
  ASSERT_EQ(code, 0) << ran;
  std::ifstream local_in(local_csv);
  std::stringstream local_text;
  local_text << local_in.rdbuf();
  EXPECT_EQ(csv, local_text.str()) << "cellflow result --csv differs from cellflow-run";
#endif
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5);
  auto force = io::read_observable(h5, "force_n");
  ASSERT_TRUE(force.ok());
  const std::string last_line = csv.substr(csv.rfind('\n', csv.size() - 2) + 1);
  EXPECT_EQ(std::stod(last_line.substr(0, last_line.find(','))), 3.0);
  std::vector<std::string> fields;
  std::stringstream row(last_line);
  for (std::string f; std::getline(row, f, ',');) fields.push_back(f);
  ASSERT_GT(fields.size(), 4u);
  EXPECT_EQ(std::stod(fields[3]), force->value[3]);  // 17 digits round-trip exactly

  const std::string svg_path = (dir_ / "curve.svg").string();
  run_command(cli + " plot " + id + " -o " + svg_path, &code);
  ASSERT_EQ(code, 0);
  run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + svg_path, &code);
  EXPECT_EQ(code, 0) << "the SVG is not well-formed XML";
  // -o - is stdout, not a file named "-"; a wrong extension is refused naming both.
  const std::string svg_stdout =
      run_command("cd " + dir_.string() + " && " + cli + " plot " + id + " -o -", &code);
  EXPECT_EQ(code, 0);
  EXPECT_EQ(svg_stdout, read_text(svg_path));
  EXPECT_FALSE(fs::exists(dir_ / "-"));
  EXPECT_EQ(run_command(cli + " result " + id + " --csv -o -", &code), csv);
  EXPECT_EQ(code, 0);
  const std::string h5_stdout = run_command(cli + " result " + id + " -o - | cmp - " + h5, &code);
  EXPECT_EQ(code, 0) << h5_stdout;
  const std::string png = run_command(cli + " plot " + id + " -o " + (dir_ / "x.png").string(), &code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(png.find(".png is not SVG output; use .svg"), std::string::npos) << png;
  EXPECT_FALSE(fs::exists(dir_ / "x.png"));
  const std::string txt =
      run_command(cli + " result " + id + " --csv -o " + (dir_ / "x.txt").string(), &code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(txt.find(".txt is not CSV output; use .csv"), std::string::npos) << txt;

  // Exit codes scripts rely on.
  run_command(cli + " get job-999", &code);
  EXPECT_EQ(code, 5);
  run_command(cli + " submit compression --radius-m 5e-6 --youngs-modulus-pa -1 --max-deformation 0.1",
              &code);
  EXPECT_EQ(code, 2);
  run_command(cli + " watch " + id, &code);
  EXPECT_EQ(code, 0);
  const std::string unknown = run_command(cli + " frobnicate", &code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(unknown.find("unknown subcommand 'frobnicate'; the subcommands are submit, sweep, watch"),
            std::string::npos)
      << unknown;
  // A mistyped subcommand or flag is named with the nearest known one.
  const std::string lsit = run_command(cli + " lsit", &code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(lsit.find("unknown subcommand 'lsit'; did you mean 'list'?"), std::string::npos) << lsit;
  const std::string stat = run_command(cli + " list --stat QUEUED", &code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(stat.find("unknown option '--stat' of list; did you mean '--state'?"), std::string::npos) << stat;
  const std::string compresion = run_command(cli + " submit compresion --radius-m 5e-6", &code);
  EXPECT_EQ(code, 1);
  EXPECT_NE(compresion.find("did you mean 'compression'?"), std::string::npos) << compresion;
  // completion bash: a script whose function completes subcommands and their flags.
  const std::string script_path = (dir_ / "cellflow.bash").string();
  run_command(std::string(CELLFLOW_CLI_EXE) + " completion bash > " + script_path, &code);
  ASSERT_EQ(code, 0);
  auto complete = [&](const std::string& words) {
    int rc = 0;
    const std::string out = run_command("bash -c 'source " + script_path + "; COMP_WORDS=(" + words +
                                            "); COMP_CWORD=$((${#COMP_WORDS[@]} - 1)); _cellflow; "
                                            "echo \"${COMPREPLY[*]}\"'",
                                        &rc);
    EXPECT_EQ(rc, 0) << out;
    return out;
  };
  EXPECT_EQ(complete("cellflow li"), "list\n");
  EXPECT_EQ(complete("cellflow --server x:1 res"), "result\n");
  EXPECT_EQ(complete("cellflow submit compression --ra"), "--radius-m\n");
  EXPECT_EQ(complete("cellflow plot job-1 --ag"), "--against\n");
  EXPECT_EQ(complete("cellflow list --st"), "--state\n");
  const std::string list_flags = complete("cellflow list --");
  EXPECT_NE(list_flags.find("--json"), std::string::npos) << list_flags;
  EXPECT_NE(list_flags.find("--server"), std::string::npos) << list_flags;  // global flags work after it too
  EXPECT_EQ(list_flags.find("--version"), std::string::npos) << list_flags;

  // --version: the CMake project version and the configured commit (or "unknown").
  const std::string version = run_command(std::string(CELLFLOW_CLI_EXE) + " --version", &code);
  EXPECT_EQ(code, 0);
  EXPECT_TRUE(std::regex_match(version,
                               std::regex(R"(cellflow \d+\.\d+\.\d+ \(commit ([0-9a-f]{4,40}|unknown)\)\n)")))
      << version;
  run_command(std::string(CELLFLOW_CLI_EXE) + " --server 127.0.0.1:1 --timeout-s 1 get job-1", &code);
  EXPECT_EQ(code, 6);
  const std::string again = run_command(cli +
                                            " submit --request-id cli-1 compression --radius-m 5e-6"
                                            " --youngs-modulus-pa 1000 --max-deformation 0.15",
                                        &code);
  EXPECT_EQ(code, 0);
  EXPECT_NE(again.find(id + " (already submitted)"), std::string::npos) << again;
}

TEST_F(ServiceTest, CliSubmitsJsonSpecListsCancelsAndWatches) {
  start_server(0);
  const std::string cli = std::string(CELLFLOW_CLI_EXE) + " --server " + address_;
  const std::string spec_path = (dir_ / "spec.json").string();
  std::ofstream(spec_path) << R"({"name": "from json", "compression": {"cell": {"radiusM": 5e-6,
      "material": {"youngsModulusPa": 800, "poissonRatio": 0.4}, "targetVertexCount": 300},
      "maxDeformation": 0.1, "loadPoints": 3}})";
  int code = 0;
  const std::string out = run_command(cli + " submit --spec " + spec_path, &code);
  ASSERT_EQ(code, 0) << out;
  EXPECT_EQ(out, "job-1\n");
  const v1::Job job = get("job-1");
  EXPECT_EQ(job.spec().name(), "from json");
  EXPECT_EQ(job.spec().compression().cell().material().youngs_modulus_pa(), 800.0);
  EXPECT_EQ(job.spec().compression().load_points(), 3);

  // --spec - reads stdin; --spec '{...}' is the JSON itself.
  const std::string piped =
      run_command("cat " + spec_path + " | " + cli + " submit --spec - --name piped", &code);
  ASSERT_EQ(code, 0) << piped;
  EXPECT_EQ(piped, "job-2\n");
  EXPECT_EQ(get("job-2").spec().name(), "piped");
  const std::string inline_json = run_command(
      cli + R"( submit --spec '{"name": "inline", "compression": {"cell": {"radiusM": 5e-6, "material": )" +
          R"({"youngsModulusPa": 800}, "targetVertexCount": 300}, "maxDeformation": 0.1, "loadPoints": 3}}')",
      &code);
  ASSERT_EQ(code, 0) << inline_json;
  EXPECT_EQ(inline_json, "job-3\n");
  EXPECT_EQ(get("job-3").spec().name(), "inline");
  run_command(cli + R"( submit --spec '{"compression": {"cell": {"radiusM": "five"}}}')", &code);
  EXPECT_EQ(code, 2);

  const std::string broken_path = (dir_ / "broken.json").string();
  std::ofstream(broken_path) << R"({"compression": {"cell": {"radiusM": "five"}}})";
  run_command(cli + " submit --spec " + broken_path, &code);
  EXPECT_EQ(code, 2);

  const std::string listed = run_command(cli + " list --state queued", &code);
  EXPECT_EQ(code, 0);
  EXPECT_NE(listed.find("job-1  QUEUED  compression"), std::string::npos) << listed;
  EXPECT_EQ(listed.rfind("ID  STATE  SCENE  ATTEMPT  DONE  NAME  REASON\n", 0), 0u) << listed;
  // list --json: one JSON array of jobs in the protobuf JSON mapping.
  const std::string listed_json = run_command(cli + " list --json", &code);
  EXPECT_EQ(code, 0);
  ASSERT_EQ(listed_json.rfind("[", 0), 0u) << listed_json;
  v1::ListJobsResponse parsed_list;
  ASSERT_TRUE(
      google::protobuf::util::JsonStringToMessage("{\"jobs\": " + listed_json + "}", &parsed_list).ok())
      << listed_json;
  ASSERT_EQ(parsed_list.jobs_size(), 3) << listed_json;
  EXPECT_EQ(parsed_list.jobs(0).id(), "job-1");
  EXPECT_EQ(parsed_list.jobs(0).spec().name(), "from json");
  EXPECT_EQ(parsed_list.jobs(2).spec().name(), "inline");
  EXPECT_EQ(run_command(cli + " list --json --state running", &code), "[]\n");
  const std::string cancelled = run_command(cli + " cancel job-1", &code);
  EXPECT_EQ(code, 0);
  EXPECT_NE(cancelled.find("CANCELLED"), std::string::npos) << cancelled;
  const std::string watched = run_command(cli + " watch job-1", &code);
  EXPECT_EQ(code, 4) << watched;  // the documented exit code of a cancelled job
  EXPECT_NE(watched.find("state CANCELLED"), std::string::npos) << watched;
  run_command(cli + " result job-1 --csv", &code);
  EXPECT_EQ(code, 5);  // a cancelled job has no result
}

TEST_F(ServiceTest, ServerRestartsALocalWorkerThatDies) {
  start_server(1, {"--lease-ttl-s", "1", "--worker-arg=--debug-delay-per-point-ms=300"});
  const std::string id = submit(small_compression(8));
  ASSERT_TRUE(wait_state(id, v1::Job::RUNNING, 30s));
  const std::string first_worker = get(id).worker_id();
  const pid_t pid = std::stoi(first_worker.substr(first_worker.rfind(':') + 1));
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  ASSERT_TRUE(wait_state(id, v1::Job::SUCCEEDED, 60s));
  const v1::Job job = get(id);
  EXPECT_EQ(job.attempt(), 2);
  EXPECT_NE(job.worker_id(), first_worker);
  EXPECT_EQ(job.worker_id().rfind("local-0@", 0), 0u) << job.worker_id();  // the same pool slot, restarted
}

// grpc.health.v1.Health/Check and grpc.reflection.v1alpha list_services,
// spoken as raw protobuf bytes (neither .proto is installed by Debian).
TEST_F(ServiceTest, HealthCheckingAndReflectionAreServed) {
  start_server(0);
  auto channel = grpc::CreateChannel(address_, grpc::InsecureChannelCredentials());
  grpc::GenericStub stub(channel);
  grpc::CompletionQueue cq;
  {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + 5s);
    grpc::ByteBuffer request;  // HealthCheckRequest{service = ""}: zero bytes
    grpc::Slice empty("");
    request = grpc::ByteBuffer(&empty, 1);
    auto call = stub.PrepareUnaryCall(&context, "/grpc.health.v1.Health/Check", request, &cq);
    call->StartCall();
    grpc::ByteBuffer reply;
    grpc::Status status;
    call->Finish(&reply, &status, reinterpret_cast<void*>(1));
    void* tag = nullptr;
    bool ok = false;
    ASSERT_TRUE(cq.Next(&tag, &ok));
    ASSERT_TRUE(status.ok()) << status.error_message();
    std::vector<grpc::Slice> slices;
    ASSERT_TRUE(reply.Dump(&slices).ok());
    std::string bytes;
    for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
    EXPECT_EQ(bytes, std::string("\x08\x01", 2));  // status = SERVING
  }
  {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + 5s);
    auto call =
        stub.PrepareCall(&context, "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo", &cq);
    void* tag = nullptr;
    bool ok = false;
    call->StartCall(reinterpret_cast<void*>(1));
    ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
    // ServerReflectionRequest{list_services = ""}: field 7, length 0.
    grpc::Slice list_services(std::string("\x3a\x00", 2));
    grpc::ByteBuffer request(&list_services, 1);
    call->Write(request, reinterpret_cast<void*>(2));
    ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
    grpc::ByteBuffer reply;
    call->Read(&reply, reinterpret_cast<void*>(3));
    ASSERT_TRUE(cq.Next(&tag, &ok) && ok);
    std::vector<grpc::Slice> slices;
    ASSERT_TRUE(reply.Dump(&slices).ok());
    std::string bytes;
    for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
    EXPECT_NE(bytes.find("cellflow.v1.CellflowService"), std::string::npos);
    // The worker API has its own listener: the public one does not list it.
    EXPECT_EQ(bytes.find("cellflow.v1.WorkerService"), std::string::npos);
    EXPECT_NE(bytes.find("grpc.health.v1.Health"), std::string::npos);
    context.TryCancel();
    grpc::Status status;
    call->Finish(&status, reinterpret_cast<void*>(4));
    cq.Next(&tag, &ok);
  }
  cq.Shutdown();
  void* tag = nullptr;
  bool ok = false;
  while (cq.Next(&tag, &ok)) {
  }
}

TEST_F(ServiceTest, SigtermDrainsHandsBackAndExitsZero) {
  start_server(1, {"--grace-s", "0.5", "--worker-arg=--debug-delay-per-point-ms=300"});
  const std::string id = submit(small_compression(30));  // ~9 s: cannot finish within the grace period
  ASSERT_TRUE(wait_state(id, v1::Job::RUNNING, 30s));
  const auto start = std::chrono::steady_clock::now();
  server_->signal(SIGTERM);
  ASSERT_TRUE(server_->wait_for(15s)) << "server did not exit";
  const int status = server_->wait();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << server_->log();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  // The job went back to the queue and no attempt was counted against it.
  server::StoreOptions options;
  options.path = (dir_ / "data" / "cellflow.sqlite").string();
  auto store = server::Store::open(options);
  ASSERT_TRUE(store.ok());
  auto job = (*store)->get(1);
  ASSERT_TRUE(job.ok());
  EXPECT_EQ(job->state(), v1::Job::QUEUED) << job->reason();
}

}  // namespace
}  // namespace cellflow::testing
