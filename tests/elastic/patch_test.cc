// Patch tests: homogeneous deformations of a tetrahedral box against the exact
// stresses of the compressible Mooney-Rivlin law (shared/validation/README.md,
// "Exact homogeneous states"). For a constant F the discrete forces are exact:
// interior vertices feel nothing and each boundary vertex carries P N A / 3 of
// every boundary triangle A around it, P the nominal stress dU/dF.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "tests/elastic/elastic_test_util.h"

namespace cellflow::elastic::testing {
namespace {

// The box of the patch tests: 3 x 4 x 3 cells, 10 x 8 x 12 um.
constexpr double kLengths[3] = {kBoxSize, 0.8 * kBoxSize, 1.2 * kBoxSize};

mesh::TetMesh patch_box() {
  return make_box_mesh(3, 4, 3, kLengths[0], kLengths[1], kLengths[2]);
}

// Cauchy stress of U = mu1/2 (I - 3) + mu2/2 (K - 3) + kappa/2 (J - 1)^2 in the
// textbook form for isotropic laws in the isochoric invariants of
// b* = J^-2/3 F F^T (I = tr b*, K = ((tr b*)^2 - tr b*^2) / 2), written
// independently of the library's kernel:
// sigma = 2/J [(W1 + I W2) b* - W2 b*^2] - 2/(3J) (W1 I + 2 W2 K) 1 + kappa (J - 1) 1,
// W1 = dU/dI = mu1/2, W2 = dU/dK = mu2/2.
Eigen::Matrix3d cauchy_stress(const Eigen::Matrix3d& f, const Moduli& m) {
  const double j = f.determinant();
  const Eigen::Matrix3d b = std::pow(j, -2.0 / 3.0) * f * f.transpose();
  const double inv_i = b.trace();
  const double inv_k = 0.5 * (inv_i * inv_i - (b * b).trace());
  const double w1 = 0.5 * m.mu1_pa, w2 = 0.5 * m.mu2_pa;
  const Eigen::Matrix3d identity = Eigen::Matrix3d::Identity();
  return 2.0 / j * ((w1 + inv_i * w2) * b - w2 * b * b) -
         2.0 / (3.0 * j) * (w1 * inv_i + 2.0 * w2 * inv_k) * identity + m.kappa_pa * (j - 1.0) * identity;
}

// Nominal (first Piola-Kirchhoff) stress P = J sigma F^-T = dU/dF.
Eigen::Matrix3d nominal_stress(const Eigen::Matrix3d& f, const Moduli& m) {
  return f.determinant() * cauchy_stress(f, m) * f.inverse().transpose();
}

// dU/dlambda_i for F = diag(l): the principal nominal stress, by the chain rule
// on I, K, J in the stretches (a third, independent form for the uniaxial state).
double principal_nominal_stress(const double l[3], int i, const Moduli& m) {
  const double j = l[0] * l[1] * l[2];
  const double a = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
  const double b = l[0] * l[0] * l[0] * l[0] + l[1] * l[1] * l[1] * l[1] + l[2] * l[2] * l[2] * l[2];
  const double k_numerator = 0.5 * (a * a - b);
  const double li = l[i];
  // dI/dl_i = J^-2/3 (2 l_i - 2/3 a / l_i), dK/dl_i = J^-4/3 (2 a l_i - 2 l_i^3 - 4/3 K' / l_i)
  const double d_inv_i = std::pow(j, -2.0 / 3.0) * (2.0 * li - 2.0 / 3.0 * a / li);
  const double d_inv_k =
      std::pow(j, -4.0 / 3.0) * (2.0 * a * li - 2.0 * li * li * li - 4.0 / 3.0 * k_numerator / li);
  return 0.5 * m.mu1_pa * d_inv_i + 0.5 * m.mu2_pa * d_inv_k + m.kappa_pa * (j - 1.0) * j / li;
}

// Boundary triangles of the box: tet faces lying in one of its six planes.
struct BoundaryTriangle {
  std::int32_t v[3];
  int axis;     // normal along e_axis
  double sign;  // outward: -1 on the plane x_axis = 0, +1 on x_axis = L_axis
  double area_m2;
};

std::vector<BoundaryTriangle> boundary_triangles(const mesh::TetMesh& mesh) {
  std::vector<BoundaryTriangle> triangles;
  const double* x = mesh.positions_m.data();
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    for (int skip = 0; skip < 4; ++skip) {
      BoundaryTriangle tri{};
      int n = 0;
      for (int a = 0; a < 4; ++a) {
        if (a != skip) tri.v[n++] = mesh.tets[4 * t + a];
      }
      for (int axis = 0; axis < 3; ++axis) {
        for (const double plane : {0.0, kLengths[axis]}) {
          bool on_plane = true;
          for (const std::int32_t v : tri.v) on_plane = on_plane && x[3 * v + axis] == plane;
          if (!on_plane) continue;
          const Eigen::Vector3d p0(x + 3 * tri.v[0]), p1(x + 3 * tri.v[1]), p2(x + 3 * tri.v[2]);
          tri.axis = axis;
          tri.sign = plane == 0.0 ? -1.0 : 1.0;
          tri.area_m2 = 0.5 * (p1 - p0).cross(p2 - p0).norm();
          triangles.push_back(tri);
        }
      }
    }
  }
  return triangles;
}

// Applies y = F X to the box, computes the vertex forces and checks:
//  - the reaction -f at every vertex equals sum over its boundary triangles of
//    P N A / 3 (interior vertices: zero), to 1e-10 of the largest nodal force;
//  - the total reaction on each face equals P N A_face to 1e-10.
// Returns the total reaction on the six faces (index 2 axis + (side == L)).
std::vector<Eigen::Vector3d> check_homogeneous_state(const Eigen::Matrix3d& f,
                                                     const Material& material_case) {
  const mesh::TetMesh mesh = patch_box();
  const ElasticBody body = make_body(mesh, material_case);
  const Moduli moduli = moduli_from(material_case);
  const Eigen::Matrix3d p = nominal_stress(f, moduli);
  std::vector<double> y(mesh.positions_m.size());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d x(mesh.positions_m.data() + 3 * v);
    const Eigen::Vector3d deformed = f * x;
    for (int i = 0; i < 3; ++i) y[3 * v + i] = deformed[i];
  }
  std::vector<double> forces(y.size(), 0.0);
  const ElasticEvaluation eval = add_elastic_forces(body, y.data(), forces.data(), 1);
  EXPECT_EQ(eval.first_inverted_tet, -1);

  std::vector<double> expected(y.size(), 0.0);
  for (const BoundaryTriangle& tri : boundary_triangles(mesh)) {
    const Eigen::Vector3d traction = tri.sign * p.col(tri.axis) * tri.area_m2 / 3.0;
    for (const std::int32_t v : tri.v) {
      for (int i = 0; i < 3; ++i) expected[3 * v + i] += traction[i];
    }
  }
  std::vector<double> reaction(forces.size());
  for (std::size_t k = 0; k < forces.size(); ++k) reaction[k] = -forces[k];
  EXPECT_LT(relative_error(reaction, expected), 1e-10);
  const double nodal_scale = max_abs(expected);
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    if (mesh.on_surface[v]) continue;
    for (int i = 0; i < 3; ++i) EXPECT_LT(std::abs(forces[3 * v + i]), 1e-10 * nodal_scale) << "vertex " << v;
  }

  std::vector<Eigen::Vector3d> face_reaction(6, Eigen::Vector3d::Zero());
  const double* x = mesh.positions_m.data();
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    for (int axis = 0; axis < 3; ++axis) {
      for (int side = 0; side < 2; ++side) {
        if (x[3 * v + axis] != side * kLengths[axis]) continue;
        face_reaction[2 * axis + side] -= Eigen::Vector3d(forces.data() + 3 * v);
      }
    }
  }
  const double stress_scale = p.cwiseAbs().maxCoeff() * kLengths[0] * kLengths[1];
  for (int axis = 0; axis < 3; ++axis) {
    const double area = kLengths[(axis + 1) % 3] * kLengths[(axis + 2) % 3];
    for (int side = 0; side < 2; ++side) {
      const Eigen::Vector3d analytic = (side == 1 ? 1.0 : -1.0) * p.col(axis) * area;
      EXPECT_LT((face_reaction[2 * axis + side] - analytic).norm(), 1e-10 * stress_scale)
          << "face " << axis << (side ? "+" : "-");
    }
  }
  return face_reaction;
}

struct PatchCase {
  double w;
  double nu;
  double amount;  // shear gamma or stretch lambda
};

std::string patch_case_name(const ::testing::TestParamInfo<PatchCase>& info) {
  char name[48];
  std::snprintf(name, sizeof(name), "w%03ld_nu%03ld_amount%03ld", std::lround(info.param.w * 100),
                std::lround(info.param.nu * 100), std::lround(info.param.amount * 100));
  return name;
}

class ElasticSimpleShear : public ::testing::TestWithParam<PatchCase> {};

// y = X + gamma X_2 e_1 (J = 1): sigma_12 = mu gamma, sigma_11 - sigma_22 = mu
// gamma^2, sigma_22 - sigma_33 = -mu2 gamma^2; the top face (X_2 = L_2) carries
// mu gamma A along x.
TEST_P(ElasticSimpleShear, ExactStressAndFaceForces) {
  const PatchCase c = GetParam();
  const Material m = material(c.w, c.nu);
  const Moduli moduli = moduli_from(m);
  const double mu = moduli.mu1_pa + moduli.mu2_pa;
  const double gamma = c.amount;
  Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
  f(0, 1) = gamma;
  const Eigen::Matrix3d sigma = cauchy_stress(f, moduli);
  EXPECT_NEAR(sigma(0, 1), mu * gamma, 1e-12 * mu);
  EXPECT_NEAR(sigma(0, 0) - sigma(1, 1), mu * gamma * gamma, 1e-12 * mu);
  EXPECT_NEAR(sigma(1, 1) - sigma(2, 2), -moduli.mu2_pa * gamma * gamma, 1e-12 * mu);
  EXPECT_NEAR(sigma(0, 2), 0.0, 1e-12 * mu);
  EXPECT_NEAR(sigma(1, 2), 0.0, 1e-12 * mu);

  const std::vector<Eigen::Vector3d> reaction = check_homogeneous_state(f, m);
  const double top_area = kLengths[0] * kLengths[2];
  const Eigen::Vector3d top = reaction[2 * 1 + 1];
  EXPECT_NEAR(top.x(), mu * gamma * top_area, 1e-10 * mu * gamma * top_area);
  // Normal force on the top face: P_22 = sigma_22 (F^-T e_2 = e_2 in simple shear).
  EXPECT_NEAR(top.y(), sigma(1, 1) * top_area, 1e-10 * mu * top_area);
  EXPECT_NEAR(top.z(), 0.0, 1e-10 * mu * top_area);
}

INSTANTIATE_TEST_SUITE_P(Cases, ElasticSimpleShear,
                         ::testing::Values(PatchCase{1.0, 0.45, 0.3}, PatchCase{0.5, 0.45, 0.3},
                                           PatchCase{0.25, 0.45, 0.3}, PatchCase{1.0, 0.3, 1.0},
                                           PatchCase{0.5, 0.3, 1.0}, PatchCase{0.25, 0.48, 1.0}),
                         patch_case_name);

// Lateral stretch t of a uniaxial stretch lambda: P_22(lambda, t, t) = 0, by
// Newton on the analytic stress (derivative by central differences in t).
double lateral_stretch(double lambda, const Moduli& m) {
  double t = 1.0 / std::sqrt(lambda);
  for (int iteration = 0; iteration < 50; ++iteration) {
    const auto lateral = [&](double s) {
      const double l[3] = {lambda, s, s};
      return principal_nominal_stress(l, 1, m);
    };
    const double residual = lateral(t);
    const double h = 1e-7 * t;
    const double slope = (lateral(t + h) - lateral(t - h)) / (2.0 * h);
    const double step = residual / slope;
    t -= step;
    if (std::abs(step) < 1e-15 * t) break;
  }
  return t;
}

class ElasticUniaxialStretch : public ::testing::TestWithParam<PatchCase> {};

// y = diag(lambda, t, t) X with traction-free lateral faces: the end face
// carries P_11 A, the lateral faces nothing.
TEST_P(ElasticUniaxialStretch, ExactNominalStressAndFaceForces) {
  const PatchCase c = GetParam();
  const Material m = material(c.w, c.nu);
  const Moduli moduli = moduli_from(m);
  const double mu = moduli.mu1_pa + moduli.mu2_pa;
  const double lambda = c.amount;
  const double t = lateral_stretch(lambda, moduli);
  const double stretches[3] = {lambda, t, t};
  ASSERT_LT(std::abs(principal_nominal_stress(stretches, 1, moduli)), 1e-12 * mu);
  const double p11 = principal_nominal_stress(stretches, 0, moduli);
  const Eigen::Matrix3d f = Eigen::Vector3d(lambda, t, t).asDiagonal();
  // Two independent forms of the analytic stress agree.
  const Eigen::Matrix3d p = nominal_stress(f, moduli);
  EXPECT_NEAR(p(0, 0), p11, 1e-12 * mu);
  EXPECT_NEAR(p(1, 1), 0.0, 1e-12 * mu);
  EXPECT_NEAR(p(2, 2), 0.0, 1e-12 * mu);

  const std::vector<Eigen::Vector3d> reaction = check_homogeneous_state(f, m);
  const double end_area = kLengths[1] * kLengths[2];
  const double scale = std::abs(p11) * end_area;
  EXPECT_NEAR(reaction[1].x(), p11 * end_area, 1e-10 * scale);
  EXPECT_NEAR(reaction[1].y(), 0.0, 1e-10 * scale);
  EXPECT_NEAR(reaction[1].z(), 0.0, 1e-10 * scale);
  for (int face = 2; face < 6; ++face)
    EXPECT_LT(reaction[face].norm(), 1e-10 * scale) << "lateral face " << face;
}

INSTANTIATE_TEST_SUITE_P(Cases, ElasticUniaxialStretch,
                         ::testing::Values(PatchCase{1.0, 0.45, 1.3}, PatchCase{0.5, 0.45, 1.3},
                                           PatchCase{0.25, 0.45, 1.3}, PatchCase{1.0, 0.3, 0.7},
                                           PatchCase{0.5, 0.48, 0.7}, PatchCase{0.25, 0.3, 2.0}),
                         patch_case_name);

// Near incompressibility the compressible solution approaches the published
// incompressible P = (mu1 + mu2 / lambda)(lambda - lambda^-2); the difference is
// of order mu / kappa = 3 (1 - 2 nu) / (2 (1 + nu)) = 2e-4 for nu = 0.4999, so
// the tolerance is 10 mu / kappa relative.
TEST(ElasticUniaxialStretch, IncompressibleLimit) {
  for (const double w : {1.0, 0.5, 0.25}) {
    const Moduli moduli = moduli_from(material(w, 0.4999));
    const double mu = moduli.mu1_pa + moduli.mu2_pa;
    for (const double lambda : {0.8, 1.2, 1.5}) {
      const double t = lateral_stretch(lambda, moduli);
      const double stretches[3] = {lambda, t, t};
      const double p11 = principal_nominal_stress(stretches, 0, moduli);
      const double incompressible =
          (moduli.mu1_pa + moduli.mu2_pa / lambda) * (lambda - 1.0 / (lambda * lambda));
      EXPECT_NEAR(p11, incompressible, 10.0 * mu / moduli.kappa_pa * std::abs(incompressible))
          << "w " << w << " lambda " << lambda;
    }
  }
}

}  // namespace
}  // namespace cellflow::elastic::testing
