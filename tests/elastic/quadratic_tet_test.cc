// The quadratic 10-node tetrahedron (Element::kQuadraticTet): forces are
// -dE/dy and the tangent is dF/dy (central differences on one curved tet10
// under a large non-affine deformation), a homogeneous deformation of a
// box of tet10s is reproduced exactly (patch test: every quadrature point
// has F = G, interior nodes carry no force, E = V U(G)), and energy and
// forces are invariant under a rigid motion.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/mesh/quadratic_tets.h"
#include "tests/elastic/box_mesh.h"
#include "tests/elastic/elastic_test_util.h"

namespace cellflow::elastic {
namespace {

using testing::finite_difference_forces;
using testing::kBoxSize;
using testing::material;
using testing::max_abs;
using testing::relative_error;

// One tet10: a positively oriented tet with its mid-edge nodes moved off the
// edges by up to 5 % of the edge (a curved element).
mesh::TetMesh curved_tet10(std::mt19937& rng) {
  mesh::TetMesh mesh;
  mesh.positions_m = {kBoxSize,      0, 0, 0, kBoxSize, 0, 0, 0, kBoxSize, 0.1 * kBoxSize, 0.2 * kBoxSize,
                      0.1 * kBoxSize};
  mesh.tets = {0, 1, 2, 3};
  mesh.tet_region = {mesh::Region::kCytoplasm};
  mesh.on_surface = {1, 1, 1, 1};
  mesh::add_mid_edge_nodes(mesh);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::size_t k = 12; k < mesh.positions_m.size(); ++k)
    mesh.positions_m[k] += 0.05 * kBoxSize * unit(rng);
  return mesh;
}

ElasticBody quadratic_body(const mesh::TetMesh& mesh, double w, double nu) {
  ElasticBody body = testing::make_body(mesh, material(w, nu));
  EXPECT_TRUE(body.quadratic());
  return body;
}

// y = G X + a smooth field: large and not affine (G = 1 + up to +-0.2).
std::vector<double> deformed(const mesh::TetMesh& mesh, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  double g[9];
  for (int k = 0; k < 9; ++k) g[k] = (k % 4 == 0 ? 1.0 : 0.0) + 0.2 * unit(rng);
  std::vector<double> y(mesh.positions_m.size());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double* x = mesh.positions_m.data() + 3 * v;
    for (int i = 0; i < 3; ++i) {
      y[3 * v + i] = g[3 * i] * x[0] + g[3 * i + 1] * x[1] + g[3 * i + 2] * x[2] +
                     0.05 * kBoxSize * std::sin(3.0 * x[(i + 1) % 3] / kBoxSize);
    }
  }
  return y;
}

struct Case {
  double w, nu;
};
class QuadraticTetDerivatives : public ::testing::TestWithParam<Case> {};

TEST_P(QuadraticTetDerivatives, ForcesAreMinusEnergyGradientAndTangentIsTheirDerivative) {
  std::mt19937 rng(11);
  const mesh::TetMesh mesh = curved_tet10(rng);
  const ElasticBody body = quadratic_body(mesh, GetParam().w, GetParam().nu);
  const std::vector<double> y = deformed(mesh, rng);
  const std::vector<double> forces = testing::forces_at(body, y);
  const double h = 1e-6 * kBoxSize;
  const std::vector<double> fd = finite_difference_forces(body, y, h);
  // central differences: error O(h^2 / L^2) ~ 1e-12, round-off E eps / h ~ 1e-9 of the force
  EXPECT_LT(relative_error(forces, fd), 1e-7);
  TangentAssembler assembler(body);
  std::vector<double> assembled_forces(y.size(), 0.0);
  const ElasticEvaluation eval = assembler.assemble(y.data(), assembled_forces.data());
  EXPECT_EQ(eval.first_inverted_tet, -1);
  EXPECT_LT(relative_error(assembled_forces, forces), 1e-14);
  EXPECT_NEAR(eval.energy_j, elastic_energy(body, y.data(), 1).energy_j, 1e-14 * std::abs(eval.energy_j));
  const Eigen::MatrixXd k = Eigen::MatrixXd(assembler.stiffness());
  ASSERT_EQ(k.rows(), 30);
  // column c of K = -d f / d y_c by central differences of the forces
  double worst = 0.0;
  for (int c = 0; c < 30; ++c) {
    std::vector<double> plus = y, minus = y;
    plus[c] += h;
    minus[c] -= h;
    const std::vector<double> fp = testing::forces_at(body, plus), fm = testing::forces_at(body, minus);
    for (int r = 0; r < 30; ++r) worst = std::max(worst, std::abs(k(r, c) + (fp[r] - fm[r]) / (2.0 * h)));
  }
  EXPECT_LT(worst / k.cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_LT((k - k.transpose()).cwiseAbs().maxCoeff() / k.cwiseAbs().maxCoeff(), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Materials, QuadraticTetDerivatives,
                         ::testing::Values(Case{1.0, 0.48}, Case{0.25, 0.48}, Case{0.5, 0.3}));

TEST(QuadraticTet, PatchTestHomogeneousDeformationIsExact) {
  for (const double w : {1.0, 0.25}) {
    mesh::TetMesh mesh = testing::make_box_mesh(2, 2, 2, kBoxSize, kBoxSize, kBoxSize);
    mesh::add_mid_edge_nodes(mesh);
    const ElasticBody body = quadratic_body(mesh, w, 0.48);
    // y = G X, a large homogeneous deformation (J < 1: min_volume_ratio reports at most 1)
    const double g[9] = {1.0, 0.2, -0.1, 0.05, 0.8, 0.15, -0.1, 0.1, 1.1};  // det G = 0.8425 < 1
    std::vector<double> y(mesh.positions_m.size());
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      const double* x = mesh.positions_m.data() + 3 * v;
      for (int i = 0; i < 3; ++i) y[3 * v + i] = g[3 * i] * x[0] + g[3 * i + 1] * x[1] + g[3 * i + 2] * x[2];
    }
    const std::vector<double> forces = testing::forces_at(body, y);
    // Interior nodes (neither corner nor mid-edge node on the box's faces) balance exactly.
    double interior = 0.0;
    int interior_nodes = 0;
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      const double* x = mesh.positions_m.data() + 3 * v;
      bool inside = true;
      for (int d = 0; d < 3; ++d) inside = inside && x[d] > 1e-3 * kBoxSize && x[d] < (1 - 1e-3) * kBoxSize;
      if (!inside) continue;
      ++interior_nodes;
      for (int i = 0; i < 3; ++i) interior = std::max(interior, std::abs(forces[3 * v + i]));
    }
    EXPECT_GT(interior_nodes, 10);
    EXPECT_LT(interior / max_abs(forces), 1e-12) << "w = " << w;
    // E = V U(G), with U from the single linear tet of the same G
    mesh::TetMesh one;
    one.positions_m = {kBoxSize, 0, 0, 0, kBoxSize, 0, 0, 0, kBoxSize, 0, 0, 0};
    one.tets = {0, 1, 2, 3};
    one.tet_region = {mesh::Region::kCytoplasm};
    const ElasticBody linear = testing::make_body(one, material(w, 0.48));
    std::vector<double> y1(12);
    for (int v = 0; v < 4; ++v) {
      const double* x = one.positions_m.data() + 3 * v;
      for (int i = 0; i < 3; ++i) y1[3 * v + i] = g[3 * i] * x[0] + g[3 * i + 1] * x[1] + g[3 * i + 2] * x[2];
    }
    const double density = elastic_energy(linear, y1.data(), 1).energy_j / linear.ref_volume_m3[0];
    const double volume = kBoxSize * kBoxSize * kBoxSize;
    EXPECT_NEAR(elastic_energy(body, y.data(), 1).energy_j, density * volume, 1e-12 * density * volume);
    const double det_g = g[0] * (g[4] * g[8] - g[5] * g[7]) - g[1] * (g[3] * g[8] - g[5] * g[6]) +
                         g[2] * (g[3] * g[7] - g[4] * g[6]);
    EXPECT_NEAR(min_volume_ratio(body, y.data()).volume_ratio, det_g, 1e-13);
  }
}

TEST(QuadraticTet, RigidMotionChangesNeitherEnergyNorForceMagnitudes) {
  std::mt19937 rng(5);
  const mesh::TetMesh mesh = curved_tet10(rng);
  const ElasticBody body = quadratic_body(mesh, 0.25, 0.48);
  const std::vector<double> y = deformed(mesh, rng);
  // rotation about (1, 2, 3) / |.| by 0.7 rad (Rodrigues), then a translation
  const double n[3] = {1.0 / std::sqrt(14.0), 2.0 / std::sqrt(14.0), 3.0 / std::sqrt(14.0)};
  const double c = std::cos(0.7), s = std::sin(0.7);
  double r[9];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r[3 * i + j] = (i == j ? c : 0.0) + (1 - c) * n[i] * n[j];
  }
  r[1] -= s * n[2], r[2] += s * n[1], r[3] += s * n[2], r[5] -= s * n[0], r[6] -= s * n[1], r[7] += s * n[0];
  std::vector<double> moved(y.size());
  for (std::size_t v = 0; v < y.size() / 3; ++v) {
    for (int i = 0; i < 3; ++i) {
      moved[3 * v + i] = r[3 * i] * y[3 * v] + r[3 * i + 1] * y[3 * v + 1] + r[3 * i + 2] * y[3 * v + 2] +
                         (i + 1) * 0.3 * kBoxSize;
    }
  }
  const double e0 = elastic_energy(body, y.data(), 1).energy_j;
  EXPECT_NEAR(elastic_energy(body, moved.data(), 1).energy_j, e0, 1e-13 * std::abs(e0));
  // forces rotate with the body: f(R y + t) = R f(y); they sum to zero
  const std::vector<double> f0 = testing::forces_at(body, y), f1 = testing::forces_at(body, moved);
  std::vector<double> rotated(f0.size());
  double sum[3] = {0, 0, 0};
  for (std::size_t v = 0; v < f0.size() / 3; ++v) {
    for (int i = 0; i < 3; ++i) {
      rotated[3 * v + i] = r[3 * i] * f0[3 * v] + r[3 * i + 1] * f0[3 * v + 1] + r[3 * i + 2] * f0[3 * v + 2];
      sum[i] += f1[3 * v + i];
    }
  }
  EXPECT_LT(relative_error(f1, rotated), 1e-12);
  for (const double component : sum) EXPECT_LT(std::abs(component), 1e-12 * max_abs(f1));
  // the reference state is stress-free
  const std::vector<double> f_ref = testing::forces_at(body, mesh.positions_m);
  EXPECT_LT(max_abs(f_ref), 1e-12 * max_abs(f0));
}

TEST(QuadraticTet, MidEdgeNodesOnTheSphereAndSubTriangles) {
  // a tet with its corners on the unit sphere: every face is a boundary face
  mesh::TetMesh mesh;
  const double a = 1.0 / std::sqrt(3.0);
  mesh.positions_m = {a, a, a, -a, -a, a, -a, a, -a, a, -a, -a};
  mesh.tets = {0, 1, 2, 3};
  double e[3][3];
  for (int k = 0; k < 3; ++k) {
    for (int d = 0; d < 3; ++d) e[k][d] = mesh.positions_m[3 * k + d] - mesh.positions_m[9 + d];
  }
  const double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                     e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                     e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
  if (det < 0.0) std::swap(mesh.tets[0], mesh.tets[1]);
  mesh::MidEdgeProjection projection;
  projection.sphere_centre_m = std::array<double, 3>{0.0, 0.0, 0.0};
  mesh::add_mid_edge_nodes(mesh, projection);
  ASSERT_EQ(mesh.num_vertices(), 10u);
  ASSERT_EQ(mesh.quadratic_tets.size(), 10u);
  for (int node = 4; node < 10; ++node) {
    const double* p = mesh.positions_m.data() + 3 * node;
    EXPECT_NEAR(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), 1.0, 1e-15);
    EXPECT_EQ(mesh.on_surface[node], 1);
  }
  // node 4 + e sits on edge kQuadraticTetEdges[e] (VTK order)
  for (int edge = 0; edge < 6; ++edge) {
    const double* p = mesh.positions_m.data() + 3 * mesh.quadratic_tets[4 + edge];
    const double* pa = mesh.positions_m.data() + 3 * mesh.quadratic_tets[mesh::kQuadraticTetEdges[edge][0]];
    const double* pb = mesh.positions_m.data() + 3 * mesh.quadratic_tets[mesh::kQuadraticTetEdges[edge][1]];
    const double mid[3] = {pa[0] + pb[0], pa[1] + pb[1], pa[2] + pb[2]};
    const double norm = std::sqrt(mid[0] * mid[0] + mid[1] * mid[1] + mid[2] * mid[2]);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(p[d], mid[d] / norm, 1e-15);
  }
  const std::int32_t triangle[3] = {mesh.tets[0], mesh.tets[1], mesh.tets[2]};
  const std::vector<std::int32_t> split = mesh::split_at_mid_edge_nodes(mesh, triangle);
  ASSERT_EQ(split.size(), 12u);
  EXPECT_EQ(split[0], triangle[0]);
  EXPECT_EQ(split[4], triangle[1]);
  EXPECT_EQ(split[8], triangle[2]);
  // its quadratic body is bigger than the straight-sided tet: the faces bulge out to the sphere
  ElasticBody body = quadratic_body(mesh, 1.0, 0.3);
  double volume = 0.0;
  for (const double w : body.quadrature_weights_m3) volume += w;
  EXPECT_GT(volume, body.ref_volume_m3[0]);
}

}  // namespace
}  // namespace cellflow::elastic
