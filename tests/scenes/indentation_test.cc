// Colloidal-probe indentation of a cell resting on a plate: the force against
// the two-contact Hertz law at small indentation, a monotone curve, the probe
// force balanced by the plate.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {
namespace {

// The hydrogel particle of paper section 5.2 (Neubauer et al.): Rc = 40 um,
// probe Rp = 26.5 um.
IndentationParams particle(int vertices, double max_indentation_radii, int load_points) {
  IndentationParams p;
  p.cell.radius_m = 40e-6;
  p.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = vertices;
  p.probe_radius_m = 26.5e-6;
  p.max_indentation_m = max_indentation_radii * p.cell.radius_m;
  p.load_points = load_points;
  p.numerics.threads = 1;
  return p;
}

// F / F_Hertz(probe) on the default mesh at indentations 0.04 R ... 0.2 R,
// nodal-averaged volumetric term, a mesh vertex under the probe
// (physics/mesh/sphere_mesh.h). Measured: 3000 vertices 1.013, 1.072, 1.063,
// 1.073, 1.110; 6000: 1.054, 1.060, 1.074, 1.093, 1.085; 12000: 1.033, 1.067,
// 1.063, 1.088, 1.094: the ratio rises slowly with depth (finite cell, the
// bottom plate) and the 3000-vertex mesh stays within 2 % of 12000. Before the
// pole vertex (an edge under the probe) the default mesh gave 1.33, 1.20,
// 1.16, 1.16, 1.16. With the default pole grading of the indentation mesh
// (issue 11; 3000 vertices, 3733 after grading, 2026-12-02): 1.048, 1.062,
// 1.095, 1.108, 1.118. Asserted: every point within [1.00, 1.12], and the
// ratio at 0.2 R above the one at 0.04 R.
TEST(Indentation, ForceAgainstHertzAtSmallIndentation) {
  const QuasiStaticResult r = run_indentation(particle(3000, 0.2, 5));
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.curve.size(), 5u);
  for (const CurvePoint& p : r.curve) {
    const double ratio = p.force_n / p.hertz_force_n;
    std::printf("indentation %.3f R: F/F_Hertz %.4f\n", p.displacement_m / 40e-6, ratio);
    EXPECT_GE(ratio, 1.00);
    EXPECT_LE(ratio, 1.12);
  }
  EXPECT_GT(r.curve.back().force_n / r.curve.back().hertz_force_n,
            r.curve.front().force_n / r.curve.front().hertz_force_n);
}

// A probe (2.5 um) not much wider than the mesh edge (1.8 um on 1000
// vertices, R = 8.6 um) pushed to half the diameter: at 0.25 the pole vertex
// slips sideways off the probe and the converged force falls by 4 %. The run
// must end there with the cause, keeping the increasing part of the curve
// (bench/stability reported this curve as WRONG before the guard).
TEST(Indentation, ProbeSlippingBetweenVerticesEndsTheRunInsteadOfAWrongCurve) {
  IndentationParams p;
  p.cell.radius_m = 8.6e-6;
  p.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = 1000;
  p.probe_radius_m = 2.5e-6;
  p.max_indentation_m = 2.0 * 0.5 * p.cell.radius_m;
  p.load_points = 20;
  p.numerics.threads = 1;
  // The uniform mesh: the default indentation mesh is graded to the probe's
  // contact radius at the poles and no longer slips here.
  p.numerics.pole_spacing_m = 0.0;
  const QuasiStaticResult r = run_indentation(p);
  ASSERT_EQ(r.status.code(), StatusCode::kNumericalFailure) << r.status.to_string();
  EXPECT_NE(r.status.message().find("the force fell"), std::string::npos) << r.status.message();
  EXPECT_NE(r.status.message().find("cell.target_vertex_count"), std::string::npos) << r.status.message();
  ASSERT_GE(r.curve.size(), 5u);
  for (std::size_t i = 1; i < r.curve.size(); ++i) EXPECT_GT(r.curve[i].force_n, r.curve[i - 1].force_n);
}

// The same probe acting on the surface triangles (closest points) meets a
// continuous surface: nothing to slip between, the whole curve is monotone,
// with no step larger than twice the one before it.
TEST(Indentation, ProbeOnTheSurfaceTrianglesDoesNotSlip) {
  IndentationParams p;
  p.cell.radius_m = 8.6e-6;
  p.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  p.cell.target_vertex_count = 1000;
  p.probe_radius_m = 2.5e-6;
  p.max_indentation_m = 2.0 * 0.5 * p.cell.radius_m;
  p.load_points = 20;
  p.numerics.threads = 1;
  p.numerics.probe_contact = ProbeContact::kSurface;
  p.numerics.contact_enforcement = ContactEnforcement::kAugmentedLagrangian;
  p.numerics.pole_spacing_m = 0.0;  // the uniform mesh of the test above
  const QuasiStaticResult r = run_indentation(p);
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.curve.size(), 20u);
  for (std::size_t i = 1; i < r.curve.size(); ++i) {
    EXPECT_GT(r.curve[i].force_n, r.curve[i - 1].force_n) << "point " << i;
    EXPECT_LE(r.curve[i].max_penetration_m, kDefaultGapToleranceRadii * p.cell.radius_m) << "point " << i;
  }
}

TEST(Indentation, CurveIsMonotoneAndBalanced) {
  const QuasiStaticResult r = run_indentation(particle(800, 0.6, 6));
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.curve.size(), 6u);
  for (std::size_t i = 1; i < r.curve.size(); ++i) {
    EXPECT_GT(r.curve[i].force_n, r.curve[i - 1].force_n) << "point " << i;
    EXPECT_GT(r.curve[i].elastic_energy_j, r.curve[i - 1].elastic_energy_j);
    EXPECT_GT(r.curve[i].hertz_force_n, r.curve[i - 1].hertz_force_n);
  }
  for (const CurvePoint& p : r.curve) {
    EXPECT_LE(p.residual, 1e-6);
    EXPECT_LT(p.max_penetration_m, 5e-3 * 40e-6);
    EXPECT_NEAR(p.deformation, p.displacement_m / 80e-6, 1e-15);
  }
}

}  // namespace
}  // namespace cellflow::scenes

namespace cellflow::scenes {
namespace {

std::size_t mesh_vertices(const IndentationParams& p) {
  std::size_t vertices = 0;
  SceneCallbacks callbacks;
  callbacks.on_mesh = [&vertices](const mesh::TetMesh& m) { vertices = m.num_vertices(); };
  const QuasiStaticResult r = run_indentation(p, callbacks);
  EXPECT_TRUE(r.status.ok()) << r.status.to_string();
  return vertices;
}

// The default indentation mesh is graded where the first contact radius is
// below the uniform spacing (a 2.5 um probe on 8 um, 0.1 um first point:
// a/3 = 0.1 um against 2 um on 300 vertices), numerics.pole_spacing_m = 0
// forces the uniform mesh; a compression grades only when asked.
TEST(Indentation, DefaultMeshIsGradedOnlyForProbesSmallerThanTheMesh) {
  IndentationParams small;
  small.cell.radius_m = 8e-6;
  small.cell.material = {.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 1.0};
  small.cell.target_vertex_count = 300;
  small.probe_radius_m = 2.5e-6;
  small.max_indentation_m = 0.2e-6;
  small.load_points = 2;
  small.numerics.threads = 1;
  EXPECT_GT(default_pole_spacing_m(small), 0.0);
  const std::size_t graded = mesh_vertices(small);
  small.numerics.pole_spacing_m = 0.0;
  const std::size_t uniform = mesh_vertices(small);
  EXPECT_LT(uniform, 330u);
  EXPECT_GT(graded, uniform + 200);

  // A tiny first load point asks for at most 10 x the uniform resolution;
  // a mesh file is used as it is.
  IndentationParams many = small;
  many.numerics.pole_spacing_m.reset();
  many.load_points = 1000;
  EXPECT_DOUBLE_EQ(default_pole_spacing_m(many), 0.1 * mesh::sphere_mesh_spacing_m(8e-6, 300));
  IndentationParams file = many;
  file.cell.mesh_file = "cell.msh";
  EXPECT_EQ(default_pole_spacing_m(file), 0.0);

  CompressionParams plates;
  plates.cell = small.cell;
  plates.max_deformation = 0.02;
  plates.load_points = 1;
  plates.numerics.threads = 1;
  std::size_t plate_vertices = 0;
  SceneCallbacks callbacks;
  callbacks.on_mesh = [&plate_vertices](const mesh::TetMesh& m) { plate_vertices = m.num_vertices(); };
  ASSERT_TRUE(run_compression(plates, callbacks).status.ok());
  EXPECT_EQ(plate_vertices, uniform);
  plates.numerics.pole_spacing_m = 0.3e-6;
  ASSERT_TRUE(run_compression(plates, callbacks).status.ok());
  EXPECT_GT(plate_vertices, uniform + 200);
}

}  // namespace
}  // namespace cellflow::scenes
