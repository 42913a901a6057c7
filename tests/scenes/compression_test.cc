// Compression between plates: small-deformation behaviour against Hertz,
// linear scaling with E, a stiff nucleus, the penetration bound, callbacks,
// and the mesh-convergence check of the force at 50 % compression.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {
namespace {

constexpr double kRadius = 8.6e-6;

CompressionParams cell(int vertices, double w, double max_deformation, int load_points) {
  CompressionParams p;
  p.cell.radius_m = kRadius;
  p.cell.material = {.youngs_modulus_pa = 150.0, .poisson_ratio = 0.48, .mooney_rivlin_w = w};
  p.cell.target_vertex_count = vertices;
  p.max_deformation = max_deformation;
  p.load_points = load_points;
  p.numerics.threads = 1;  // tests run side by side
  return p;
}

const CurvePoint& at(const QuasiStaticResult& r, double deformation) {
  for (const CurvePoint& p : r.curve) {
    if (std::abs(p.deformation - deformation) < 1e-9) return p;
  }
  ADD_FAILURE() << "no point at deformation " << deformation;
  return r.curve.front();
}

double ratio(const CurvePoint& p) {
  return p.force_n / p.hertz_force_n;
}

// F / F_Hertz at eps = 0.02, 0.05, 0.1 on the default 3000-vertex mesh
// (nu = 0.48, w = 1), nodal-averaged volumetric term (the default), with a
// mesh vertex at each pole (physics/mesh/sphere_mesh.h): 1.073, 1.114, 1.153.
// Before the poles were put on mesh vertices the 3000-vertex mesh (geodesic
// frequency 9) had an edge at each pole and a height 0.9977 x 2 R: 1.160,
// 1.167, 1.190. The paper's per-tet term locks (1.53, 1.33, 1.30 then). The
// band asked for at eps = 0.02 is 1.00-1.08.
TEST(Compression, SmallDeformationAgainstHertzOnTheDefaultMesh) {
  const QuasiStaticResult r = run_compression(cell(3000, 1.0, 0.1, 10));
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  const double r02 = ratio(at(r, 0.02)), r05 = ratio(at(r, 0.05)), r10 = ratio(at(r, 0.1));
  std::printf("F/F_Hertz at 0.02 0.05 0.1: %.4f %.4f %.4f\n", r02, r05, r10);
  // the discrete model is stiffer than the continuum, never softer
  EXPECT_GT(r05, 1.0);
  EXPECT_GT(r10, 1.0);
  // and grows with the deformation (finite size of the sphere)
  EXPECT_LT(r02, r05);
  EXPECT_LT(r05, r10);
  // the target band of the small-deformation limit
  EXPECT_GE(r02, 1.00);
  EXPECT_LE(r02, 1.08);
  // measured values, 2 % bands: a change of the element, the contact law or
  // the mesher that moves them shows here
  EXPECT_NEAR(r02, 1.073, 0.021);
  EXPECT_NEAR(r05, 1.114, 0.022);
  EXPECT_NEAR(r10, 1.153, 0.023);
}

TEST(Compression, ForceScalesLinearlyWithYoungsModulus) {
  CompressionParams soft = cell(300, 0.5, 0.4, 4);
  soft.numerics.residual_tolerance = 1e-11;
  CompressionParams stiff = soft;
  stiff.cell.material.youngs_modulus_pa *= 7.3;
  const QuasiStaticResult a = run_compression(soft);
  const QuasiStaticResult b = run_compression(stiff);
  ASSERT_TRUE(a.status.ok()) << a.status.to_string();
  ASSERT_TRUE(b.status.ok()) << b.status.to_string();
  ASSERT_EQ(a.curve.size(), b.curve.size());
  for (std::size_t i = 0; i < a.curve.size(); ++i) {
    EXPECT_NEAR(b.curve[i].force_n / (7.3 * a.curve[i].force_n), 1.0, 1e-6) << "point " << i;
    EXPECT_NEAR(b.curve[i].elastic_energy_j / (7.3 * a.curve[i].elastic_energy_j), 1.0, 1e-6);
  }
}

TEST(Compression, StiffNucleusRaisesTheForce) {
  CompressionParams plain = cell(800, 1.0, 0.5, 5);
  CompressionParams nucleated = plain;
  elastic::Material nucleus_material = plain.cell.material;
  nucleus_material.youngs_modulus_pa *= 10.0;
  nucleated.cell.nucleus = cell::NucleusParams{0.5 * kRadius, nucleus_material};
  const QuasiStaticResult a = run_compression(plain);
  const QuasiStaticResult b = run_compression(nucleated);
  ASSERT_TRUE(a.status.ok()) << a.status.to_string();
  ASSERT_TRUE(b.status.ok()) << b.status.to_string();
  const double gain = at(b, 0.5).force_n / at(a, 0.5).force_n;
  std::printf("force at 0.5 with a 10x stiffer nucleus of radius R/2: x %.3f\n", gain);
  EXPECT_GT(gain, 1.1);
  // and the nucleus does not change the first contact much (at 0.1 it is far from the plates)
  EXPECT_LT(at(b, 0.1).force_n / at(a, 0.1).force_n, gain);
}

// To 80 % with w = 0.5. The most strain-hardening cell of the paper
// (w = 0.25) does not get there with the default contact law: Newton stalls
// at 0.70 (1000 vertices) and 0.66 (3000) with the nodal-averaged volumetric
// term (0.66 at 3000 with the per-tet term too); a contact range of 0.05 R
// (numerics.contact_range_m) takes it to 0.9. Recorded as a known limit.
TEST(Compression, PenetrationStaysBelowHalfAPercentOfTheRadius) {
  const QuasiStaticResult r = run_compression(cell(1000, 0.5, 0.8, 16));
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.curve.size(), 16u);
  double worst = 0.0;
  for (const CurvePoint& p : r.curve) worst = std::max(worst, p.max_penetration_m);
  std::printf("max penetration up to 0.8: %.3e R, force at 0.8 %.3f E R^2\n", worst / kRadius,
              r.curve.back().force_n / (150.0 * kRadius * kRadius));
  EXPECT_LT(worst, 5e-3 * kRadius);
  // the curve is monotone and the plates balance within the residual
  for (std::size_t i = 1; i < r.curve.size(); ++i) EXPECT_GT(r.curve[i].force_n, r.curve[i - 1].force_n);
  for (const CurvePoint& p : r.curve) EXPECT_LE(p.residual, 1e-6);
}

// The augmented Lagrangian bounds the gap of every point by its tolerance
// (penetration, and the stand-off of every loaded vertex), where the penalty
// leaves the loaded vertices inside its contact layer; its curve lies above
// the penalty's (no travel lost in the layer).
TEST(Compression, AugmentedLagrangianBoundsTheGapAtEveryPoint) {
  CompressionParams penalty = cell(300, 0.5, 0.6, 6);
  CompressionParams augmented = penalty;
  augmented.numerics.contact_enforcement = ContactEnforcement::kAugmentedLagrangian;
  const QuasiStaticResult p = run_compression(penalty);
  const QuasiStaticResult a = run_compression(augmented);
  ASSERT_TRUE(p.status.ok()) << p.status.to_string();
  ASSERT_TRUE(a.status.ok()) << a.status.to_string();
  ASSERT_EQ(a.curve.size(), 6u);
  for (std::size_t i = 0; i < a.curve.size(); ++i) {
    EXPECT_LE(a.curve[i].max_penetration_m, kDefaultGapToleranceRadii * kRadius) << "point " << i;
    EXPECT_LE(a.curve[i].gap_error_m, kDefaultGapToleranceRadii * kRadius) << "point " << i;
    EXPECT_GT(a.curve[i].force_n, p.curve[i].force_n) << "point " << i;
    if (i > 0) {
      EXPECT_GT(a.curve[i].force_n, a.curve[i - 1].force_n);
    }
  }
}

// A coarse strain-hardening cell (300 vertices, w = 0.25) compressed to 0.9:
// at 0.87 an element gives up its volume (J = 0.12; eq. 5's volumetric energy
// is bounded as J -> 0). The run must end there naming the element, not
// return a curve whose force drops (bench/stability found such curves before
// the guard).
TEST(Compression, CrushedElementEndsTheRunInsteadOfAWrongCurve) {
  const QuasiStaticResult r = run_compression(cell(300, 0.25, 0.9, 30));
  ASSERT_EQ(r.status.code(), StatusCode::kNumericalFailure) << r.status.to_string();
  EXPECT_NE(r.status.message().find("is compressed to J = "), std::string::npos) << r.status.message();
  ASSERT_GT(r.curve.size(), 20u);  // the points before it are kept
  for (std::size_t i = 1; i < r.curve.size(); ++i) EXPECT_GT(r.curve[i].force_n, r.curve[i - 1].force_n);
}

TEST(Compression, CallbacksAndCancellation) {
  int points = 0, meshes = 0, positions = 0;
  double last_progress = 0.0;
  SceneCallbacks callbacks;
  callbacks.on_point = [&](const CurvePoint& p) { EXPECT_EQ(p.index, points++); };
  callbacks.on_mesh = [&](const mesh::TetMesh& m) {
    ++meshes;
    EXPECT_GT(m.num_vertices(), 100u);
  };
  callbacks.on_positions = [&](int index, std::span<const double> y) {
    EXPECT_EQ(index, positions++);
    EXPECT_GT(y.size(), 300u);
  };
  callbacks.on_progress = [&](double f) {
    EXPECT_GT(f, last_progress);
    last_progress = f;
  };
  callbacks.should_stop = [&] { return points == 2; };
  const QuasiStaticResult r = run_compression(cell(300, 1.0, 0.3, 5), callbacks);
  EXPECT_EQ(r.status.code(), StatusCode::kCancelled);
  EXPECT_EQ(r.curve.size(), 2u);
  EXPECT_EQ(points, 2);
  EXPECT_EQ(meshes, 1);
  EXPECT_EQ(positions, 2);
  EXPECT_DOUBLE_EQ(last_progress, 0.4);
}

TEST(Compression, UnconvergedStepEndsTheRunNamingTheLoadStep) {
  CompressionParams p = cell(300, 1.0, 0.4, 4);
  p.numerics.max_newton_iterations = 2;
  p.numerics.max_step_splits = 0;
  const QuasiStaticResult r = run_compression(p);
  EXPECT_EQ(r.status.code(), StatusCode::kNumericalFailure);
  EXPECT_NE(r.status.message().find("load step 0 of 4 (target deformation 0.1)"), std::string::npos)
      << r.status.message();
  EXPECT_NE(r.status.message().find("did not converge"), std::string::npos) << r.status.message();
  EXPECT_TRUE(r.curve.empty());
}

// Force at 50 % compression (w = 0.5) on 800 and 3000 vertices.
// Mean edges scale like N^-1/3: h_800 / h_3000 = 1.55, h_3000 / h_12000 = 1.59.
// With a first-order error C h, the required change of at most 2 % between
// 3000 and 12000 vertices (compression_long_test.cc) predicts at most
// 2 % x (1.55 - 1) / (1 - 1 / 1.59) = 3.0 % between 800 and 3000.
// Measured with the nodal-averaged volumetric term and a mesh vertex at each
// pole: 0.73 % (800 -> 3000; the 800-vertex force is the lower one: the
// nodal-averaged element is not an upper bound, so the test does not ask for
// convergence from the stiff side). Before the poles were put on vertices:
// 1.49 % (800 -> 3000) and 1.66 % (3000 -> 12000, the long test); with the
// per-tet term 4.0 % and 2.85 % (locking of linear tetrahedra at nu = 0.48).
// This default-suite check is the coarse pair against the 3 % that the 2 %
// target implies.
TEST(Compression, CoarseMeshConvergenceAtHalfCompression) {
  const QuasiStaticResult coarse = run_compression(cell(800, 0.5, 0.5, 10));
  const QuasiStaticResult fine = run_compression(cell(3000, 0.5, 0.5, 10));
  ASSERT_TRUE(coarse.status.ok()) << coarse.status.to_string();
  ASSERT_TRUE(fine.status.ok()) << fine.status.to_string();
  const double change = std::abs(at(coarse, 0.5).force_n / at(fine, 0.5).force_n - 1.0);
  std::printf("force at 0.5: 800 -> 3000 vertices changes by %.4f\n", change);
  EXPECT_LT(change, 0.03);
}

}  // namespace
}  // namespace cellflow::scenes
