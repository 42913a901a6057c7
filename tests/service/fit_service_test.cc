// Fit jobs through the service on loopback (real server, worker, SQLite):
// `cellflow fit` reads the shipped synthetic curves (examples/fit, made by
// tools/fit_data with the same library numerics as here: 1000 vertices, 20
// load points), the worker builds the curve library in a temporary cache
// directory, and the recovered E and w match the truth the curves were made
// from; a second fit reuses the library (0 simulations). Bad input is refused
// by the client naming the file, the sample and the problem, and by the
// server naming the field; nothing is queued.
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "tests/service/service_harness.h"

namespace cellflow::testing {
namespace {

using json = nlohmann::json;

const std::string kExamples = std::string(CELLFLOW_SOURCE_DIR) + "/examples/fit";

std::string example_files() {
  std::string files;
  for (int i = 1; i <= 5; ++i)
    files += " " + kExamples + "/synthetic_plates_E150_w0.5_" + std::to_string(i) + ".csv";
  return files;
}

json parse_report(const std::string& out) {
  const auto brace = out.find('{');
  if (brace == std::string::npos) return json();
  return json::parse(out.substr(brace), nullptr, false);
}

class FitServiceTest : public ServiceTest {
 protected:
  void start(int workers) {
    library_ = (dir_ / "library").string();
    ::setenv("CELLFLOW_LIBRARY_DIR", library_.c_str(), 1);  // the server's workers inherit it
    start_server(workers);
    cli_ = std::string(CELLFLOW_CLI_EXE) + " --server " + address_ + " --timeout-s 30";
  }
  int jobs() {
    v1::ListJobsRequest request;
    v1::ListJobsResponse response;
    EXPECT_TRUE(client_->list(request, &response).ok());
    return response.jobs_size();
  }
  std::string library_, cli_;
};

TEST_F(FitServiceTest, SyntheticCurvesGiveTrueEAndWAndASecondFitReusesTheLibrary) {
  start(1);
  const std::string command =
      cli_ + " fit" + example_files() +
      " --geometry plates --radius-m 8.6e-6 --w-free --vertices 1000 --load-points 20 --json";
  int code = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const std::string out = run_command(command, &code);
  const double cold_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(code, 0) << out;
  const json report = parse_report(out);
  ASSERT_TRUE(report.is_object()) << out;
  const json& joint = report["joint"];
  const double e = joint["youngs_modulus_pa"]["value"].get<double>();
  const double w = joint["mooney_rivlin_w"]["value"].get<double>();
  std::printf("joint fit: E %.2f Pa [%.2f, %.2f], w %.3f [%.3f, %.3f], %d simulations, %.1f s\n", e,
              joint["youngs_modulus_pa"]["lower"].get<double>(),
              joint["youngs_modulus_pa"]["upper"].get<double>(), w,
              joint["mooney_rivlin_w"]["lower"].get<double>(),
              joint["mooney_rivlin_w"]["upper"].get<double>(), report["simulations_run"].get<int>(), cold_s);
  EXPECT_NEAR(e, 150.0, 0.03 * 150.0) << out;
  EXPECT_NEAR(w, 0.5, 0.07) << out;
  EXPECT_LE(joint["youngs_modulus_pa"]["lower"].get<double>(), e);
  EXPECT_GE(joint["youngs_modulus_pa"]["upper"].get<double>(), e);
  EXPECT_GT(report["simulations_run"].get<int>(), 0);
  ASSERT_EQ(report["curves"].size(), 5u);
  for (const json& c : report["curves"]) {
    EXPECT_NE(c["file"].get<std::string>().find("synthetic_plates_E150"), std::string::npos);
    EXPECT_NEAR(c["youngs_modulus_pa"]["value"].get<double>(), 150.0, 0.1 * 150.0) << c.dump();
    EXPECT_TRUE(c["contact_point_m"]["lower"].is_number()) << c.dump();
    EXPECT_TRUE(c["hertz_youngs_modulus_pa"].is_number()) << c.dump();
    EXPECT_TRUE(c["rms_relative_residual"].is_number()) << c.dump();
  }
  const std::string job_id = report["job"].get<std::string>();

  // The second fit finds every curve in the cache (per-curve fits only: the
  // joint fit's profile intervals take most of a minute, see bench/fit).
  const auto t1 = std::chrono::steady_clock::now();
  const std::string again = run_command(command + " --no-joint", &code);
  const double warm_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  ASSERT_EQ(code, 0) << again;
  const json second = parse_report(again);
  std::printf("second fit: %d simulations, %.1f s\n", second["simulations_run"].get<int>(), warm_s);
  EXPECT_EQ(second["simulations_run"].get<int>(), 0) << again;
  ASSERT_EQ(second["curves"].size(), 5u);
  for (std::size_t c = 0; c < 5; ++c) {  // the same curves from the cache: the same fit
    EXPECT_NEAR(second["curves"][c]["youngs_modulus_pa"]["value"].get<double>(),
                report["curves"][c]["youngs_modulus_pa"]["value"].get<double>(), 1e-9 * e);
  }

  // The table, the curves as CSV columns and the plot.
  const std::string table = run_command(
      cli_ + " fit" + example_files() +
          " --geometry plates --radius-m 8.6e-6 --w-free --vertices 1000 --load-points 20 --no-joint",
      &code);
  ASSERT_EQ(code, 0) << table;
  EXPECT_NE(table.find("synthetic_plates_E150_w0.5_5.csv"), std::string::npos) << table;
  EXPECT_NE(table.find("simulations run: 0"), std::string::npos) << table;
  const std::string csv = run_command(cli_ + " result " + job_id + " --csv", &code);
  ASSERT_EQ(code, 0) << csv;
  EXPECT_EQ(csv.rfind("curve,name,sample,indentation_m,deformation,force_n,model_force_n,hertz_force_n,joint_"
                      "model_force_n\n",
                      0),
            0u)
      << csv.substr(0, 300);
  EXPECT_GT(std::count(csv.begin(), csv.end(), '\n'), 500);
  const std::string svg = (dir_ / "fit.svg").string();
  const std::string plotted = run_command(cli_ + " plot " + job_id + " -o " + svg, &code);
  ASSERT_EQ(code, 0) << plotted;
  const std::string lint = run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + svg, &code);
  EXPECT_EQ(code, 0) << lint;
  EXPECT_NE(read_text(svg).find("Hertz"), std::string::npos);
}

TEST_F(FitServiceTest, BadInputIsRefusedNamingFileAndProblemAndNothingIsQueued) {
  start(0);
  const std::string base = " --geometry plates --radius-m 8.6e-6 --w-free";
  auto write = [&](const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  };
  // A curve of 40 samples: zero force before contact, then rising.
  auto curve_text = [](int bad_row, const char* bad) {
    std::string text = "indentation_m,force_n\n";
    for (int i = 0; i < 40; ++i) {
      const double x = (i - 15) * 0.2e-6;
      const double f = x > 0 ? 1e-9 * std::pow(x / 1e-6, 1.5) : 0.0;
      char line[80];
      std::snprintf(line, sizeof line, "%.6e,%.6e\n", x, f);
      text += i == bad_row ? std::string(bad) + "\n" : std::string(line);
    }
    return text;
  };
  struct Case {
    std::string what, args;
    std::vector<std::string> expect;
    int code;
  };
  const std::string good = write("good.csv", curve_text(-1, ""));
  std::string jpk;
  {
    std::ifstream in(std::string(CELLFLOW_AFM_DATA_DIR) + "/fmt-jpk-fd_spot3-0192.jpk-force",
                     std::ios::binary);
    std::stringstream all;
    all << in.rdbuf();
    jpk = all.str().substr(0, all.str().size() / 2);
  }
  const std::vector<Case> cases = {
      {"empty file", write("empty.csv", "") + base, {"empty.csv"}, 2},
      {"unreadable file", (dir_ / "missing.csv").string() + base, {"missing.csv"}, 2},
      {"truncated JPK archive", write("cut.jpk-force", jpk) + base, {"cut.jpk-force"}, 2},
      {"non-monotonic deformation",
       write("backwards.csv", curve_text(30, "1.0e-6,2.0e-9")) + base,
       {"backwards.csv", "sample 30", "non-monotonic"},
       2},
      {"negative force",
       write("negative.csv", curve_text(30, "3.0e-6,-5.0e-9")) + base,
       {"negative.csv", "approach sample 30", "force_n", "negative"},
       2},
      {"deformation >= 1",
       write("deep.csv", curve_text(39, "2.0e-5,9.0e-9")) + base,
       {"deep.csv", "approach sample 39", ">= 1"},
       2},
      {"probe radius missing",
       good + " --geometry probe --radius-m 8.6e-6 --w-free",
       {"--probe-radius-m"},
       1},
      {"fit range with no points",
       good + base + " --range 0.6:0.65",
       {"good.csv", "no sample in the fit range"},
       2},
  };
  for (const Case& c : cases) {
    int code = 0;
    const std::string out = run_command(cli_ + " fit " + c.args, &code);
    EXPECT_EQ(code, c.code) << c.what << ": " << out;
    for (const std::string& e : c.expect) EXPECT_NE(out.find(e), std::string::npos) << c.what << ": " << out;
    std::printf("%-26s -> %s", c.what.c_str(), out.c_str());
  }
  EXPECT_EQ(jobs(), 0) << "a refused fit must queue nothing";

  // The server checks again: a spec sent without the client's checks.
  v1::JobSpec spec;
  auto* fit = spec.mutable_fit();
  fit->set_geometry(v1::FIT_GEOMETRY_PROBE);
  fit->set_radius_m(8.6e-6);
  fit->set_w_free(true);
  auto* curve = fit->add_curves();
  for (double x : {0.0, 1e-6, 2e-6}) curve->add_indentation_m(x);
  for (double f : {0.0, 1e-9, 2e-9}) curve->add_force_n(f);
  v1::SubmitJobRequest request;
  *request.mutable_spec() = spec;
  v1::SubmitJobResponse response;
  grpc::Status status = client_->submit(request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("fit.probe_radius_m"), std::string::npos) << status.error_message();
  fit->set_probe_radius_m(2e-6);
  curve->set_force_n(1, -1e-9);
  *request.mutable_spec() = spec;
  status = client_->submit(request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(status.error_message().find("fit.curves[0].force_n[1]"), std::string::npos)
      << status.error_message();
  curve->set_force_n(1, 1e-9);
  curve->set_indentation_m(2, 0.5e-6);
  *request.mutable_spec() = spec;
  status = client_->submit(request, &response);
  EXPECT_NE(status.error_message().find("fit.curves[0].indentation_m[2]"), std::string::npos)
      << status.error_message();
  EXPECT_EQ(jobs(), 0);
}

}  // namespace
}  // namespace cellflow::testing
