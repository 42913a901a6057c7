// The single-precision force loop (ForcePrecision::kFloat, the flow scenes'
// default) against the double loop: forces and energy to a stated relative
// tolerance on deformed meshes (large and flow-sized strains, far from the
// origin), the float forces still the gradient of the energy (central
// differences of the double energy), the same bits on every SIMD level,
// threads, partial ranges, inverted tets and the float inverse cube root.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/elastic/tet_kernel.h"
#include "tests/elastic/elastic_test_util.h"

namespace cellflow::elastic::testing {
namespace {

struct Evaluated {
  std::vector<double> forces;
  ElasticEvaluation eval;
};

Evaluated evaluate(const ElasticBody& body, const std::vector<double>& y, ForcePrecision precision,
                   int threads = 1) {
  Evaluated r;
  r.forces.assign(y.size(), 0.0);
  r.eval = add_elastic_forces(body, y.data(), r.forces.data(), threads, precision);
  return r;
}

// y = X + offset + amplitude (a smooth field with a shear): flow-sized strains
// for amplitude 0.05 .. 0.3.
std::vector<double> smooth_deformation(const mesh::TetMesh& mesh, double amplitude, double offset_m) {
  std::vector<double> y(mesh.positions_m.size());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double* x = mesh.positions_m.data() + 3 * v;
    for (int i = 0; i < 3; ++i) {
      y[3 * v + i] =
          x[i] + offset_m +
          amplitude * (0.5 * x[(i + 1) % 3] + 0.1 * kBoxSize * std::sin(3.0 * x[(i + 2) % 3] / kBoxSize + i));
    }
  }
  return y;
}

// Tolerances relative to the largest vertex force (and to the energy). The
// float error is set by the bulk term kappa (J - 1) cof F: J carries about
// 1e-7 of float round-off (positions and F), so relative to a stress of
// mu strain the error grows as 1e-7 (kappa / mu) / strain. Measured
// (2026-12-02): strain 0.05 (a Ca 0.05 flow cell's), nu 0.48 (kappa / mu =
// 25): forces 2.7e-4, energy 1.3e-4; nu 0.3: 4e-5; strain 0.3 and the large
// random deformation: 1.2e-5 .. 2.4e-5. The same 1 mm from the origin (the
// loop subtracts the centre of the bounding box in double).
double force_tolerance(double strain) {
  return strain < 0.1 ? 1e-3 : 1e-4;
}
constexpr double kLargeStrain = 1.0;  // the random deformation

class FloatForces : public ::testing::TestWithParam<MaterialCase> {};

TEST_P(FloatForces, MatchDoubleOnDeformedMeshes) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(99);
  const mesh::TetMesh box =
      make_box_mesh(7, 6, 5, kBoxSize, kBoxSize, 0.8 * kBoxSize);  // 1260 tets, 79 blocks
  const ElasticBody body = make_body(box, material(c.w, c.nu), c.volumetric);
  for (const double offset_m : {0.0, 1e-3}) {
    std::vector<std::pair<double, std::vector<double>>> states;
    for (const double amplitude : {0.05, 0.3}) {
      states.emplace_back(amplitude, smooth_deformation(box, amplitude, offset_m));
    }
    std::vector<double> y = random_deformation(box, rng, 0.03 * first_edge_m(box));
    for (double& x : y) x += offset_m;
    states.emplace_back(kLargeStrain, y);
    for (const auto& [strain, state] : states) {
      const Evaluated d = evaluate(body, state, ForcePrecision::kDouble);
      const Evaluated f = evaluate(body, state, ForcePrecision::kFloat);
      ASSERT_EQ(f.eval.first_inverted_tet, -1);
      const double tolerance = force_tolerance(strain);
      EXPECT_LT(relative_error(f.forces, d.forces), tolerance)
          << "strain " << strain << ", offset " << offset_m;
      EXPECT_NEAR(f.eval.energy_j, d.eval.energy_j, tolerance * std::abs(d.eval.energy_j))
          << "strain " << strain;
    }
  }
}

// The float forces are the gradient of the energy to within their tolerance:
// central differences of the double energy (step 1e-5 of an edge, error
// ~1e-10) against the float forces, on the box and on random tets.
TEST_P(FloatForces, AreEnergyGradient) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(1234);
  const mesh::TetMesh box = make_box_mesh(3, 3, 2, kBoxSize, kBoxSize, 0.8 * kBoxSize);
  const mesh::TetMesh tets = random_tets(6, rng);
  for (const mesh::TetMesh* mesh : {&box, &tets}) {
    const ElasticBody body = make_body(*mesh, material(c.w, c.nu), c.volumetric);
    const std::vector<double> y = random_deformation(*mesh, rng, 0.03 * first_edge_m(*mesh));
    const std::vector<double> f = evaluate(body, y, ForcePrecision::kFloat).forces;
    const std::vector<double> f_fd = finite_difference_forces(body, y, 1e-5 * first_edge_m(*mesh));
    EXPECT_LT(relative_error(f, f_fd), force_tolerance(kLargeStrain));
  }
}

// Every SIMD level gives the same bits in float too (full and partial
// blocks: ranges that start and end inside a block), and the range pieces
// add up to the whole to float round-off.
TEST_P(FloatForces, SameBitsOnEveryLevel) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(7);
  const mesh::TetMesh box = make_box_mesh(5, 4, 3, kBoxSize, kBoxSize, kBoxSize);  // 360 tets
  const ElasticBody body = make_body(box, material(c.w, c.nu), c.volumetric);
  const std::vector<double> y = random_deformation(box, rng, 0.03 * first_edge_m(box));
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  for (const auto [begin, end] : {std::pair<std::int64_t, std::int64_t>{0, num_tets}, {5, 203}, {17, 30}}) {
    std::vector<double> generic(y.size(), 0.0);
    const ElasticEvaluation e_generic = add_elastic_forces_of_range(
        body, y.data(), generic.data(), begin, end, TetSimd::kGeneric, ForcePrecision::kFloat);
    for (const TetSimd level : {TetSimd::kAvx2, TetSimd::kAvx512, TetSimd::kAuto}) {
      if (!tet_simd_supported(level)) continue;
      std::vector<double> other(y.size(), 0.0);
      const ElasticEvaluation e_other = add_elastic_forces_of_range(body, y.data(), other.data(), begin, end,
                                                                    level, ForcePrecision::kFloat);
      EXPECT_EQ(e_other.energy_j, e_generic.energy_j) << tet_simd_name(level);
      for (std::size_t k = 0; k < y.size(); ++k)
        ASSERT_EQ(other[k], generic[k]) << tet_simd_name(level) << " " << k;
    }
  }
  std::vector<double> pieces(y.size(), 0.0);
  add_elastic_forces_of_range(body, y.data(), pieces.data(), 0, 100, TetSimd::kAuto, ForcePrecision::kFloat);
  add_elastic_forces_of_range(body, y.data(), pieces.data(), 100, num_tets, TetSimd::kAuto,
                              ForcePrecision::kFloat);
  EXPECT_LT(relative_error(pieces, evaluate(body, y, ForcePrecision::kFloat).forces), 1e-6);
}

INSTANTIATE_TEST_SUITE_P(Cases, FloatForces, ::testing::ValuesIn(kMaterialCases), case_name);

// Two threads (two float accumulators, added in double) against one.
TEST(FloatForcesParallel, TwoThreadsMatchOne) {
  std::mt19937 rng(3);
  const mesh::TetMesh box =
      make_box_mesh(16, 16, 8, kBoxSize, kBoxSize, kBoxSize);  // 12288 tets: 3 teams of 4096
  const ElasticBody body = make_body(box, material(1.0, 0.48));
  const std::vector<double> y = random_deformation(box, rng, 0.03 * first_edge_m(box));
  const Evaluated one = evaluate(body, y, ForcePrecision::kFloat, 1);
  const Evaluated two = evaluate(body, y, ForcePrecision::kFloat, 2);
  EXPECT_LT(relative_error(two.forces, one.forces), 1e-6);
  EXPECT_NEAR(two.eval.energy_j, one.eval.energy_j, 1e-9 * std::abs(one.eval.energy_j));
  // the caller's forces are added to, not overwritten
  std::vector<double> preset(y.size(), 1e-9);
  add_elastic_forces(body, y.data(), preset.data(), 2, ForcePrecision::kFloat);
  for (std::size_t k = 0; k < y.size(); ++k)
    ASSERT_NEAR(preset[k] - 1e-9, two.forces[k], 1e-6 * max_abs(one.forces));
}

// An inverted tet is reported by the float loop as by the double one.
TEST(FloatForcesInversion, FirstInvertedTetOfAMesh) {
  const mesh::TetMesh box = make_box_mesh(4, 4, 4, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(box, material(0.5, 0.48));
  std::vector<double> y = box.positions_m;
  const std::int32_t* v = body.tets.data() + 4 * 200;
  // move vertex 4 of tet 200 through the face of the other three
  for (int i = 0; i < 3; ++i) {
    const double centroid = (y[3 * v[0] + i] + y[3 * v[1] + i] + y[3 * v[2] + i]) / 3.0;
    y[3 * v[3] + i] = 2.0 * centroid - y[3 * v[3] + i];
  }
  const Evaluated d = evaluate(body, y, ForcePrecision::kDouble);
  const Evaluated f = evaluate(body, y, ForcePrecision::kFloat);
  ASSERT_GE(d.eval.first_inverted_tet, 0);
  EXPECT_EQ(f.eval.first_inverted_tet, d.eval.first_inverted_tet);
}

// x^-1/3 in float within 2 ulp (2.4e-7 relative) over [1e-6, 1e6].
TEST(FloatInverseCubeRoot, WithinTwoUlp) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> exponent(-6.0, 6.0);
  double worst = 0.0;
  for (int k = 0; k < 200000; ++k) {
    const float x = static_cast<float>(std::pow(10.0, exponent(rng)));
    const double exact = 1.0 / std::cbrt(static_cast<double>(x));
    worst = std::max(worst, std::abs(kernel::inverse_cube_root(x) - exact) / exact);
  }
  EXPECT_LT(worst, 2.0 * std::numeric_limits<float>::epsilon());
}

}  // namespace
}  // namespace cellflow::elastic::testing
