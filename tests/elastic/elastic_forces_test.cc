// Vertex forces of the Mooney-Rivlin body: gradient of the energy, invariances,
// the neo-Hookean path, inverted elements and the body construction.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "tests/elastic/elastic_test_util.h"

namespace cellflow::elastic::testing {
namespace {

class ElasticForcesAreEnergyGradient : public ::testing::TestWithParam<MaterialCase> {};

// f = -dE/dy against central differences (step 1e-5 of an edge: truncation and
// rounding both ~1e-10), on a box mesh and on random tetrahedra.
TEST_P(ElasticForcesAreEnergyGradient, BoxAndRandomTets) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(1234);
  const mesh::TetMesh box = make_box_mesh(3, 3, 2, kBoxSize, kBoxSize, 0.8 * kBoxSize);
  const mesh::TetMesh tets = random_tets(6, rng);
  for (const mesh::TetMesh* mesh : {&box, &tets}) {
    const ElasticBody body = make_body(*mesh, material(c.w, c.nu), c.volumetric);
    EXPECT_EQ(body.neo_hookean, c.w == 1.0);
    for (int sample = 0; sample < 2; ++sample) {
      const std::vector<double> y = random_deformation(*mesh, rng, 0.03 * first_edge_m(*mesh));
      const std::vector<double> f = forces_at(body, y);
      const std::vector<double> f_fd = finite_difference_forces(body, y, 1e-5 * first_edge_m(*mesh));
      EXPECT_LT(relative_error(f, f_fd), 1e-6);
      // add_elastic_forces returns the same energy as elastic_energy (one code path)
      std::vector<double> scratch(y.size(), 0.0);
      const double e_forces = add_elastic_forces(body, y.data(), scratch.data(), 1).energy_j;
      const double e_energy = elastic_energy(body, y.data()).energy_j;
      EXPECT_NEAR(e_forces, e_energy, 1e-14 * std::abs(e_energy));
      EXPECT_GT(e_energy, 0.0);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, ElasticForcesAreEnergyGradient, ::testing::ValuesIn(kMaterialCases),
                         case_name);

class ElasticRigidMotion : public ::testing::TestWithParam<MaterialCase> {};

// Zero energy and forces in the reference state, after a translation and after
// a rotation. Scales: energy mu V, force mu h^2 (h the element edge).
TEST_P(ElasticRigidMotion, NoEnergyNoForce) {
  const MaterialCase c = GetParam();
  const mesh::TetMesh mesh = make_box_mesh(3, 3, 3, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(mesh, material(c.w, c.nu), c.volumetric);
  const Moduli moduli = moduli_from(material(c.w, c.nu));
  const double mu = moduli.mu1_pa + moduli.mu2_pa;
  const double energy_scale = mu * kBoxSize * kBoxSize * kBoxSize;
  const double h = kBoxSize / 3.0;
  const double force_scale = mu * h * h;
  // Rotation by 1.1 rad about the axis (1, 2, 2)/3 (Rodrigues), then a shift of 3 box sizes.
  const double axis[3] = {1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0};
  const double angle = 1.1, cs = std::cos(angle), sn = std::sin(angle);
  double rotation[9];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      rotation[3 * i + j] = (i == j ? cs : 0.0) + (1.0 - cs) * axis[i] * axis[j];
    }
  }
  rotation[1] -= sn * axis[2];
  rotation[2] += sn * axis[1];
  rotation[3] += sn * axis[2];
  rotation[5] -= sn * axis[0];
  rotation[6] -= sn * axis[1];
  rotation[7] += sn * axis[0];
  const double shift[3] = {3.0 * kBoxSize, -2.0 * kBoxSize, 0.5 * kBoxSize};

  std::vector<double> reference = mesh.positions_m, translated = mesh.positions_m, rotated = mesh.positions_m;
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double* x = mesh.positions_m.data() + 3 * v;
    for (int i = 0; i < 3; ++i) {
      translated[3 * v + i] = x[i] + shift[i];
      rotated[3 * v + i] =
          rotation[3 * i] * x[0] + rotation[3 * i + 1] * x[1] + rotation[3 * i + 2] * x[2] + shift[i];
    }
  }
  for (const std::vector<double>* y : {&reference, &translated, &rotated}) {
    std::vector<double> f(y->size(), 0.0);
    const ElasticEvaluation eval = add_elastic_forces(body, y->data(), f.data(), 1);
    EXPECT_EQ(eval.first_inverted_tet, -1);
    EXPECT_LT(std::abs(eval.energy_j), 1e-12 * energy_scale);
    EXPECT_LT(max_abs(f), 1e-10 * force_scale);
  }
}

// Translation and rotation invariance of E: the forces of any deformation sum to
// zero and have no net torque about the origin, sum y x f = 0.
TEST_P(ElasticRigidMotion, NoNetForceOrTorque) {
  const MaterialCase c = GetParam();
  std::mt19937 rng(99);
  const mesh::TetMesh mesh = make_box_mesh(4, 3, 3, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(mesh, material(c.w, c.nu), c.volumetric);
  for (int sample = 0; sample < 3; ++sample) {
    const std::vector<double> y = random_deformation(mesh, rng, 0.05 * kBoxSize / 4);
    const std::vector<double> f = forces_at(body, y);
    double net[3] = {0, 0, 0}, torque[3] = {0, 0, 0}, y_max = 0.0;
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      const double* p = y.data() + 3 * v;
      const double* fv = f.data() + 3 * v;
      for (int i = 0; i < 3; ++i) {
        net[i] += fv[i];
        y_max = std::max(y_max, std::abs(p[i]));
      }
      torque[0] += p[1] * fv[2] - p[2] * fv[1];
      torque[1] += p[2] * fv[0] - p[0] * fv[2];
      torque[2] += p[0] * fv[1] - p[1] * fv[0];
    }
    const double f_max = max_abs(f);
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT(std::abs(net[i]), 1e-12 * f_max);
      EXPECT_LT(std::abs(torque[i]), 1e-12 * f_max * y_max);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, ElasticRigidMotion, ::testing::ValuesIn(kMaterialCases), case_name);

// w = 1 takes the kernel without the K-term; the general kernel with mu2 = 0
// must give the same numbers (to rounding, 1e-13 relative).
TEST(ElasticNeoHookeanPath, EqualsGeneralPathWithZeroMu2) {
  std::mt19937 rng(7);
  const mesh::TetMesh mesh = make_box_mesh(3, 3, 3, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody neo = make_body(mesh, material(1.0, 0.45));
  ASSERT_TRUE(neo.neo_hookean);
  ElasticBody general = neo;
  general.neo_hookean = false;  // forces the Mooney-Rivlin kernel, with every mu2 = 0
  const std::vector<double> y = random_deformation(mesh, rng, 0.02 * kBoxSize);
  const std::vector<double> f_neo = forces_at(neo, y);
  const std::vector<double> f_general = forces_at(general, y);
  EXPECT_LT(relative_error(f_neo, f_general), 1e-13);
  const double e_neo = elastic_energy(neo, y.data()).energy_j;
  EXPECT_NEAR(e_neo, elastic_energy(general, y.data()).energy_j, 1e-13 * e_neo);
  TangentAssembler k_neo(neo), k_general(general);
  k_neo.assemble(y.data());
  k_general.assemble(y.data());
  const Eigen::MatrixXd dense_neo(k_neo.stiffness()), dense_general(k_general.stiffness());
  EXPECT_LT((dense_neo - dense_general).cwiseAbs().maxCoeff(), 1e-13 * dense_general.cwiseAbs().maxCoeff());
}

// Two OpenMP threads (private force buffers) give the forces of one thread.
TEST(ElasticParallel, TwoThreadsMatchOne) {
  std::mt19937 rng(5);
  const mesh::TetMesh mesh = make_box_mesh(12, 12, 12, kBoxSize, kBoxSize, kBoxSize);  // 10368 tets
  for (const double w : {1.0, 0.5}) {
    const ElasticBody body = make_body(mesh, material(w, 0.45));
    const std::vector<double> y = random_deformation(mesh, rng, 0.02 * kBoxSize / 12);
    const std::vector<double> f1 = forces_at(body, y, 1);
    const std::vector<double> f2 = forces_at(body, y, 2);
    EXPECT_LT(relative_error(f2, f1), 1e-13);
    // Static partition: the same thread count gives bitwise the same forces.
    EXPECT_EQ(forces_at(body, y, 2), f2);
    const double e1 = elastic_energy(body, y.data(), 1).energy_j;
    EXPECT_NEAR(elastic_energy(body, y.data(), 2).energy_j, e1, 1e-13 * e1);
  }
}

// Determinant of the deformed edge matrix of tet t: sign of J = det F.
double deformed_det(const mesh::TetMesh& mesh, const std::vector<double>& y, std::size_t t) {
  const std::int32_t* v = mesh.tets.data() + 4 * t;
  double e[3][3];
  for (int a = 0; a < 3; ++a) {
    for (int d = 0; d < 3; ++d) e[a][d] = y[3 * v[a] + d] - y[3 * v[3] + d];
  }
  return e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
         e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
         e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
}

TEST(ElasticInversion, SingleTetReflectedOrFlat) {
  std::mt19937 rng(3);
  const mesh::TetMesh mesh = random_tets(1, rng);
  const ElasticBody body = make_body(mesh, material(0.5, 0.45));
  // Reflect vertex 1 through the plane of the others: J < 0.
  std::vector<double> y = mesh.positions_m;
  const double* x = y.data();
  double e1[3], e2[3], n[3], d[3];
  for (int i = 0; i < 3; ++i) {
    e1[i] = x[6 + i] - x[i];
    e2[i] = x[9 + i] - x[i];
    d[i] = x[3 + i] - x[i];
  }
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
  const double along = (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  std::vector<double> reflected = y;
  for (int i = 0; i < 3; ++i) reflected[3 + i] -= 2.0 * along * n[i];
  ASSERT_LT(deformed_det(mesh, reflected, 0), 0.0);
  // Squashed flat (all four vertices in the plane z = 0): J = 0 exactly.
  std::vector<double> squashed = y;
  for (int a = 0; a < 4; ++a) squashed[3 * a + 2] = 0.0;
  ASSERT_EQ(deformed_det(mesh, squashed, 0), 0.0);
  for (const std::vector<double>* state : {&reflected, &squashed}) {
    std::vector<double> f(12, 0.0);
    EXPECT_EQ(add_elastic_forces(body, state->data(), f.data(), 1).first_inverted_tet, 0);
    EXPECT_EQ(elastic_energy(body, state->data()).first_inverted_tet, 0);
    TangentAssembler tangent(body);
    EXPECT_EQ(tangent.assemble(state->data()).first_inverted_tet, 0);
  }
}

TEST(ElasticInversion, FirstInvertedTetOfAMesh) {
  const mesh::TetMesh mesh = make_box_mesh(12, 12, 12, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(mesh, material(0.5, 0.45));
  // Push an interior vertex two cells along x, through its neighbours.
  std::vector<double> y = mesh.positions_m;
  const std::size_t vertex = 5 + 13 * (6 + 13 * 6);
  y[3 * vertex] += 2.0 * kBoxSize / 12;
  std::int64_t expected = -1;
  for (std::size_t t = 0; t < mesh.num_tets() && expected < 0; ++t) {
    if (deformed_det(mesh, y, t) <= 0.0) expected = static_cast<std::int64_t>(t);
  }
  ASSERT_GE(expected, 0);
  for (const int threads : {1, 2}) {
    std::vector<double> f(y.size(), 0.0);
    EXPECT_EQ(add_elastic_forces(body, y.data(), f.data(), threads).first_inverted_tet, expected);
    EXPECT_EQ(elastic_energy(body, y.data(), threads).first_inverted_tet, expected);
    TangentAssembler tangent(body);
    tangent.set_threads(threads);
    EXPECT_EQ(tangent.assemble(y.data()).first_inverted_tet, expected);
  }
}

// A NaN position is not an inversion and is not hidden: the energy is NaN.
TEST(ElasticInversion, NaNPositionGivesNaNEnergy) {
  const mesh::TetMesh mesh = make_box_mesh(2, 2, 2, kBoxSize, kBoxSize, kBoxSize);
  const ElasticBody body = make_body(mesh, material(0.5, 0.45));
  std::vector<double> y = mesh.positions_m;
  y[7] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> f(y.size(), 0.0);
  const ElasticEvaluation eval = add_elastic_forces(body, y.data(), f.data(), 1);
  EXPECT_TRUE(std::isnan(eval.energy_j));
  EXPECT_TRUE(std::isnan(f[7]));
}

TEST(ElasticMakeBody, ReferenceDataOfOneTet) {
  // Unit right tetrahedron scaled by s: J = s 1, B = 1/s, V0 = s^3 / 6.
  const double s = 2e-6;
  mesh::TetMesh mesh;
  mesh.positions_m = {s, 0, 0, 0, s, 0, 0, 0, s, 0, 0, 0};
  mesh.tets = {0, 1, 2, 3};
  mesh.tet_region = {mesh::Region::kCytoplasm};
  const ElasticBody body = make_body(mesh, material(0.25, 0.3));
  ASSERT_EQ(body.num_tets(), 1u);
  EXPECT_NEAR(body.ref_volume_m3[0], s * s * s / 6.0, 1e-15 * s * s * s);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(body.b_matrix[k], k % 4 == 0 ? 1.0 / s : 0.0, 1e-12 / s);
  const Moduli moduli = moduli_from(material(0.25, 0.3));
  EXPECT_EQ(body.mu1_pa[0], moduli.mu1_pa);
  EXPECT_EQ(body.mu2_pa[0], moduli.mu2_pa);
  EXPECT_EQ(body.kappa_pa[0], moduli.kappa_pa);
  EXPECT_FALSE(body.neo_hookean);
}

TEST(ElasticMakeBody, RegionsTakeTheirMaterial) {
  mesh::TetMesh mesh = make_box_mesh(2, 2, 2, kBoxSize, kBoxSize, kBoxSize);
  for (std::size_t t = 0; t < mesh.num_tets(); t += 3) mesh.tet_region[t] = mesh::Region::kNucleus;
  const Material materials[] = {material(1.0, 0.45), Material{5.0 * kYoungsModulus, 0.4, 0.5}};
  StatusOr<ElasticBody> body = make_elastic_body(mesh, materials);
  ASSERT_TRUE(body.ok()) << body.status().to_string();
  EXPECT_FALSE(body->neo_hookean);
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const Moduli expected = moduli_from(materials[t % 3 == 0 ? 1 : 0]);
    EXPECT_EQ(body->mu1_pa[t], expected.mu1_pa);
    EXPECT_EQ(body->mu2_pa[t], expected.mu2_pa);
    EXPECT_EQ(body->kappa_pa[t], expected.kappa_pa);
  }
  // Forces stay the gradient of the energy with two materials.
  std::mt19937 rng(11);
  const std::vector<double> y = random_deformation(mesh, rng, 0.01 * kBoxSize);
  EXPECT_LT(relative_error(forces_at(*body, y), finite_difference_forces(*body, y, 1e-5 * kBoxSize / 2)),
            1e-6);
  // A region without a material is refused.
  const Material only_cytoplasm[] = {material(1.0, 0.45)};
  StatusOr<ElasticBody> missing = make_elastic_body(mesh, only_cytoplasm);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(missing.status().message().find("region 1"), std::string::npos) << missing.status().message();
}

// The nodal-averaged volumetric term equals the per-tet one wherever J is
// uniform (a homogeneous deformation: Jbar_a = J_t = det F), and differs
// otherwise; its forces run the same on one and two threads.
TEST(ElasticNodalAverage, EqualsPerTetForHomogeneousDeformation) {
  const mesh::TetMesh mesh = make_box_mesh(3, 3, 2, kBoxSize, kBoxSize, 0.8 * kBoxSize);
  const ElasticBody per_tet = make_body(mesh, material(0.5, 0.48));
  const ElasticBody nodal = make_body(mesh, material(0.5, 0.48), VolumetricTerm::kNodalAverage);
  // F = [[1.1, 0.2, 0], [0, 0.93, 0.05], [0.03, 0, 0.97]], y = F x
  const double f[9] = {1.1, 0.2, 0.0, 0.0, 0.93, 0.05, 0.03, 0.0, 0.97};
  std::vector<double> y(mesh.positions_m.size());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double* x = mesh.positions_m.data() + 3 * v;
    for (int i = 0; i < 3; ++i) y[3 * v + i] = f[3 * i] * x[0] + f[3 * i + 1] * x[1] + f[3 * i + 2] * x[2];
  }
  const double e_tet = elastic_energy(per_tet, y.data(), 1).energy_j;
  EXPECT_NEAR(elastic_energy(nodal, y.data(), 1).energy_j, e_tet, 1e-12 * e_tet);
  const std::vector<double> f_tet = forces_at(per_tet, y);
  EXPECT_LT(relative_error(forces_at(nodal, y), f_tet), 1e-10);
  // a non-homogeneous deformation: different energies, same on two threads
  std::mt19937 rng(5);
  const std::vector<double> z = random_deformation(mesh, rng, 0.05 * first_edge_m(mesh));
  const double e_nodal = elastic_energy(nodal, z.data(), 1).energy_j;
  EXPECT_LT(e_nodal, elastic_energy(per_tet, z.data(), 1).energy_j);  // fewer volume constraints
  EXPECT_NEAR(elastic_energy(nodal, z.data(), 2).energy_j, e_nodal, 1e-13 * e_nodal);
  EXPECT_LT(relative_error(forces_at(nodal, z, 2), forces_at(nodal, z, 1)), 1e-13);
}

TEST(ElasticMakeBody, RefusesNonPositiveReferenceVolume) {
  mesh::TetMesh mesh = make_box_mesh(2, 1, 1, kBoxSize, kBoxSize, kBoxSize);
  std::swap(mesh.tets[4 * 7], mesh.tets[4 * 7 + 1]);  // tet 7 now negatively oriented
  const Material materials[] = {material(1.0, 0.45)};
  StatusOr<ElasticBody> body = make_elastic_body(mesh, materials);
  ASSERT_FALSE(body.ok());
  EXPECT_EQ(body.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(body.status().message().find("tetrahedron 7 "), std::string::npos) << body.status().message();
}

TEST(ElasticMakeBody, RefusesInvalidMaterial) {
  const mesh::TetMesh mesh = make_box_mesh(1, 1, 1, kBoxSize, kBoxSize, kBoxSize);
  const Material materials[] = {material(1.0, 0.5)};
  StatusOr<ElasticBody> body = make_elastic_body(mesh, materials);
  ASSERT_FALSE(body.ok());
  EXPECT_EQ(body.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(body.status().message().find("materials[0].poisson_ratio"), std::string::npos);
}

}  // namespace
}  // namespace cellflow::elastic::testing
