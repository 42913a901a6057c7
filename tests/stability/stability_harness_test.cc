// Default-suite smoke test of the stability matrix (bench/stability): the
// child-process runner reports a hang, a crash, a wrong number and an
// unnamed failure as such; the checks reject broken curves; a few fast real
// cases run through the program and end as they must.
#include "bench/stability/stability_harness.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <string>

#include "physics/elastic/material.h"

namespace cellflow::stability {
namespace {

std::string fresh_dir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("stability_harness_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

const Case& find_case(const std::vector<Case>& cases, const std::string& name) {
  for (const Case& c : cases) {
    if (c.name == name) return c;
  }
  throw std::runtime_error("no case " + name);
}

TEST(StabilityHarness, HangCrashWrongAndUnnamedFailureAreReportedAsSuch) {
  const std::vector<Case> cases = make_cases(true);
  const std::string dir = fresh_dir("self");

  const CaseRecord hang = run_case_in_child(STABILITY_MATRIX, find_case(cases, "selftest/hang"), dir, 1.0);
  EXPECT_EQ(hang.outcome, Outcome::kHang) << hang.cause << " " << hang.detail;
  EXPECT_GE(hang.wall_s, 1.0);
  EXPECT_LT(hang.wall_s, 10.0);  // killed at the limit, not waited for

  const CaseRecord crash = run_case_in_child(STABILITY_MATRIX, find_case(cases, "selftest/crash"), dir, 30.0);
  EXPECT_EQ(crash.outcome, Outcome::kCrash);
  EXPECT_NE(crash.cause.find("signal"), std::string::npos) << crash.cause;

  const CaseRecord wrong = run_case_in_child(STABILITY_MATRIX, find_case(cases, "selftest/wrong"), dir, 30.0);
  EXPECT_EQ(wrong.outcome, Outcome::kWrong);
  EXPECT_NE(wrong.cause.find("non-finite"), std::string::npos) << wrong.cause;

  const CaseRecord unnamed =
      run_case_in_child(STABILITY_MATRIX, find_case(cases, "selftest/unnamed-failure"), dir, 30.0);
  EXPECT_EQ(unnamed.outcome, Outcome::kFailed);
  EXPECT_FALSE(acceptable(unnamed.outcome, unnamed.cause));

  for (const CaseRecord* r : {&hang, &crash, &wrong}) EXPECT_FALSE(acceptable(r->outcome, r->cause));
  std::filesystem::remove_all(dir);
}

TEST(StabilityHarness, TheMatrixHasAtLeastFortyUniquelyNamedCases) {
  const std::vector<Case> cases = make_cases(false);
  EXPECT_GE(cases.size(), 40u);
  std::map<std::string, int> seen;
  int anchors = 0;
  for (const Case& c : cases) {
    EXPECT_EQ(++seen[c.name], 1) << "duplicate " << c.name;
    EXPECT_EQ(c.name.rfind("selftest/", 0), std::string::npos);
    EXPECT_GT(c.time_limit_s, 0.0);
    anchors += c.anchor ? 1 : 0;
  }
  EXPECT_GE(anchors, 2);  // one per scene at least
}

TEST(StabilityChecks, FailureCausesAreNamed) {
  EXPECT_EQ(failure_cause(numerical_failure(
                "load step 3 of 30 (target deformation 0.4): Newton did not converge in 40 iterations")),
            "non-convergence");
  EXPECT_EQ(failure_cause(numerical_failure("no admissible Newton step: every shorter trial still inverts "
                                            "tetrahedron 12 (J <= 0) or raises the energy")),
            "inverted element");
  EXPECT_EQ(failure_cause(numerical_failure("time step 10: vertex velocity is NaN")), "NaN guard");
  EXPECT_EQ(
      failure_cause(numerical_failure("load step 9 of 20 (target deformation 0.25): the force fell from "
                                      "8.9e-07 N to 8.5e-07 N with more travel")),
      "force drop guard (obstacle slipped between vertices)");
  EXPECT_EQ(failure_cause(invalid_argument("Mach number u / c_s = 0.7 exceeds shear_flow.numerics.max_mach")),
            "Mach limit (refused)");
  EXPECT_EQ(failure_cause(invalid_argument("the explicit elastic update would be unstable: ...")),
            "stiffness limit (refused)");
  EXPECT_EQ(failure_cause(Status(StatusCode::kInternal, "boom")), "");
}

scenes::CompressionParams small_compression() {
  scenes::CompressionParams p;
  p.cell.radius_m = 8.6e-6;
  p.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.max_deformation = 0.3;
  p.load_points = 3;
  return p;
}

scenes::QuasiStaticResult curve(std::initializer_list<double> forces) {
  scenes::QuasiStaticResult r;
  int i = 0;
  for (double f : forces) {
    scenes::CurvePoint p;
    p.index = i;
    p.deformation = 0.1 * (i + 1);
    p.displacement_m = p.deformation * 2 * 8.6e-6;
    p.force_n = f;
    p.hertz_force_n = 1e-9 * std::pow(p.deformation / 0.1, 1.5);
    r.curve.push_back(p);
    ++i;
  }
  return r;
}

TEST(StabilityChecks, CompressionCurvesMustBeFinitePositiveAndIncreasing) {
  const scenes::CompressionParams p = small_compression();
  CompressionCheck no_volume;
  no_volume.check_volume = false;
  EXPECT_FALSE(check_compression(p, curve({1e-9, 3e-9, 6e-9}), no_volume).has_value());
  EXPECT_TRUE(check_compression(p, curve({1e-9, 3e-9, 2e-9}), no_volume).has_value());   // not monotone
  EXPECT_TRUE(check_compression(p, curve({-1e-9, 3e-9, 6e-9}), no_volume).has_value());  // negative
  EXPECT_TRUE(check_compression(p, curve({1e-9, std::numeric_limits<double>::infinity(), 6e-9}), no_volume)
                  .has_value());
  EXPECT_TRUE(check_compression(p, curve({1e-12, 3e-12, 6e-12}), no_volume).has_value());  // 1000x too soft
  EXPECT_TRUE(check_compression(p, curve({1e-9, 3e-9}), no_volume).has_value());  // ok status, points missing
}

TEST(StabilityChecks, VolumeChangeMustMatchTheVirialOfThePlateForce) {
  const scenes::CompressionParams p = small_compression();
  scenes::QuasiStaticResult r = curve({1e-9});
  r.curve.resize(1);
  scenes::CompressionParams one = p;
  one.load_points = 1;
  const elastic::Moduli m = elastic::moduli_from(p.cell.material);
  const double v0 = 4.0 / 3.0 * std::numbers::pi * std::pow(8.6e-6, 3);
  const double height = 2 * 8.6e-6 - r.curve[0].displacement_m;
  const double uniform = -r.curve[0].force_n * height / (3 * m.kappa_pa);  // dV if J were uniform
  CompressionCheck check;
  check.initial_height_m = 2 * 8.6e-6;
  check.initial_volume_m3 = v0;
  check.points = {ElementVolumes{.min_j = 0.9, .squared_deviation_m3 = -0.5 * uniform, .height_m = height}};
  r.curve[0].volume_m3 = v0 + 1.2 * uniform;  // within [P - S, P]
  EXPECT_FALSE(check_compression(one, r, check).has_value());
  r.curve[0].volume_m3 = v0 + 0.5 * uniform;  // less volume lost than the force implies
  EXPECT_TRUE(check_compression(one, r, check).has_value());
  r.curve[0].volume_m3 = v0 + 2.0 * uniform;  // more than the element spread allows
  EXPECT_TRUE(check_compression(one, r, check).has_value());
  r.curve[0].volume_m3 = v0 + 1.2 * uniform;
  check.points[0].min_j = 0.05;  // one crushed sliver: not a wrong result
  check.points[0].crushed_fraction = 1e-6;
  EXPECT_FALSE(check_compression(one, r, check).has_value());
  check.points[0].crushed_fraction = 0.01;  // 1 % of the cell collapsed
  EXPECT_TRUE(check_compression(one, r, check).has_value());
  check.points[0].crushed_fraction = 0.0;
  check.points[0].squared_deviation_m3 = -5.0 * uniform;
  r.curve[0].volume_m3 = v0 + 3.5 * uniform;  // consistent with the virial, but a local collapse
  EXPECT_TRUE(check_compression(one, r, check).has_value());
}

TEST(StabilityChecks, FlowDeformationMustBeFiniteInTheUnitInterval) {
  scenes::ShearFlowResult r;
  r.setup.capillary_number = 0.8;
  r.stop = scenes::ShearFlowStop::kMaxStrain;
  for (double d : {0.0, 0.2, 0.4}) {
    scenes::ShearFlowSample s;
    s.taylor_deformation = d;
    s.volume_m3 = 1e-15;
    r.samples.push_back(s);
  }
  r.steady_taylor_deformation = 0.4;
  EXPECT_FALSE(check_shear_flow(r).has_value());
  r.samples[2].taylor_deformation = std::nan("");
  EXPECT_TRUE(check_shear_flow(r).has_value());
  r.samples[2].taylor_deformation = 1.0;
  EXPECT_TRUE(check_shear_flow(r).has_value());
}

// A few fast real cases through the program (child processes, CSV report).
TEST(StabilityMatrixProgram, FastCasesEndAsTheyMust) {
  const std::string dir = fresh_dir("program");
  const std::string csv = dir + "/report.csv";
  const std::string command = std::string(STABILITY_MATRIX) +
                              " --filter '^(compression/mesh/(inverted-element|coarse200-w1)|"
                              "flow/stiffness/default-limit-ca0.003|flow/timestep/reynolds1|"
                              "flow/modulus/E1e\\+05-rate10)$' --work-dir " +
                              dir + " --csv " + csv + " > " + dir + "/out.txt 2>&1";
  const auto start = std::chrono::steady_clock::now();
  const int rc = std::system(command.c_str());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::ifstream out_text(dir + "/out.txt");
  std::stringstream out;
  out << out_text.rdbuf();
  EXPECT_EQ(rc, 0) << out.str();
  std::ifstream in(csv);
  std::string line;
  std::map<std::string, std::string> outcome;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    const std::size_t a = line.find("\",");
    const std::size_t b = line.find(',', a + 2);
    outcome[line.substr(1, a - 1)] = line.substr(a + 2, b - a - 2) + " " + line.substr(b + 1);
  }
  ASSERT_EQ(outcome.size(), 5u) << out.str();
  EXPECT_EQ(outcome["compression/mesh/inverted-element"].rfind("FAILED \"invalid mesh", 0), 0u)
      << outcome["compression/mesh/inverted-element"];
  EXPECT_EQ(outcome["compression/mesh/coarse200-w1"].rfind("CONVERGED", 0), 0u)
      << outcome["compression/mesh/coarse200-w1"];
  EXPECT_EQ(outcome["flow/stiffness/default-limit-ca0.003"].rfind("FAILED \"stiffness limit", 0), 0u)
      << outcome["flow/stiffness/default-limit-ca0.003"];
  EXPECT_EQ(outcome["flow/timestep/reynolds1"].rfind("FAILED \"Mach limit", 0), 0u)
      << outcome["flow/timestep/reynolds1"];
  EXPECT_EQ(outcome["flow/modulus/E1e+05-rate10"].rfind("FAILED \"stiffness limit", 0), 0u)
      << outcome["flow/modulus/E1e+05-rate10"];
  EXPECT_LT(seconds, 60.0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace cellflow::stability
