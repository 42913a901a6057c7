// Shape observables on sphere meshes mapped affinely onto ellipsoids of known
// semi-axes: x -> Q diag(a/R, b/R, c/R) x + t maps the ball of radius R onto
// the ellipsoid with semi-axes a, b, c, rotated by Q and moved by t.
#include "physics/observables/shape.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"

namespace cellflow::observables {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadius = 6e-6;  // metres

const mesh::TetMesh& sphere_3000() {
  static const mesh::TetMesh mesh = [] {
    mesh::SphereMeshOptions options;
    options.radius_m = kRadius;
    options.target_vertex_count = 3000;
    StatusOr<mesh::TetMesh> m = mesh::make_sphere_mesh(options);
    EXPECT_TRUE(m.ok()) << m.status().to_string();
    return std::move(m).value();
  }();
  return mesh;
}

std::vector<double> map_affine(const mesh::TetMesh& mesh, const Eigen::Matrix3d& linear,
                               const Eigen::Vector3d& shift) {
  std::vector<double> out(mesh.positions_m.size());
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d x(mesh.positions_m[3 * v], mesh.positions_m[3 * v + 1],
                            mesh.positions_m[3 * v + 2]);
    const Eigen::Vector3d y = linear * x + shift;
    for (int d = 0; d < 3; ++d) out[3 * v + d] = y(d);
  }
  return out;
}

Eigen::Matrix3d ellipsoid_map(double a, double b, double c, const Eigen::Matrix3d& rotation) {
  return rotation * Eigen::Vector3d(a / kRadius, b / kRadius, c / kRadius).asDiagonal();
}

Eigen::Matrix3d rotation(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::AngleAxisd(angle_rad, axis.normalized()).toRotationMatrix();
}

struct EllipsoidCase {
  const char* name;
  double a, b, c;  // semi-axes along the local x, y, z, in units of R
  double angle_deg;
  Eigen::Vector3d axis;
};

TEST(ShapeTest, EllipsoidSemiAxesAndTaylorDeformation) {
  const mesh::TetMesh& mesh = sphere_3000();
  const std::vector<EllipsoidCase> cases = {
      {"prolate_x", 1.5, 1.0, 1.0, 0.0, {0, 0, 1}},
      {"oblate_z", 1.2, 1.2, 0.7, 0.0, {0, 0, 1}},
      {"triaxial", 0.8, 1.0, 1.25, 0.0, {0, 0, 1}},
      {"strong", 2.0, 0.7, 0.5, 0.0, {0, 0, 1}},
      {"triaxial_rot_z_30", 1.4, 0.9, 0.8, 30.0, {0, 0, 1}},
      {"triaxial_rot_general", 0.6, 1.1, 1.7, 50.0, {1, 2, 3}},
      {"prolate_rot_general", 1.0, 1.0, 1.8, -110.0, {-2, 1, 0.5}},
  };
  for (const EllipsoidCase& c : cases) {
    SCOPED_TRACE(c.name);
    const Eigen::Matrix3d q = rotation(c.angle_deg * kPi / 180.0, c.axis);
    const std::vector<double> x = map_affine(
        mesh, ellipsoid_map(c.a * kRadius, c.b * kRadius, c.c * kRadius, q), Eigen::Vector3d::Zero());
    const Shape shape = measure_shape(mesh, x.data());
    std::array<double, 3> exact = {c.a * kRadius, c.b * kRadius, c.c * kRadius};
    std::sort(exact.begin(), exact.end());
    // D = (a3 - a1) / (a3 + a1) within 1 % of the exact ellipsoid's.
    const double exact_d = (exact[2] - exact[0]) / (exact[2] + exact[0]);
    EXPECT_NEAR(shape.taylor_deformation / exact_d, 1.0, 0.01);
    // Semi-axes within 1 %.
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(shape.semi_axes_m[i] / exact[i], 1.0, 0.01) << "a" << i + 1;
    // Volume scales exactly with det(map) = abc / R^3 (linear map of the
    // same tets), against the sphere mesh's own volume.
    const double sphere_volume = measure_shape(mesh, mesh.positions_m.data()).volume_m3;
    EXPECT_NEAR(shape.volume_m3 / (sphere_volume * c.a * c.b * c.c), 1.0, 1e-12);
  }
}

TEST(ShapeTest, MajorAxisFollowsTheLongestSemiAxis) {
  const mesh::TetMesh& mesh = sphere_3000();
  const Eigen::Matrix3d q = rotation(50.0 * kPi / 180.0, {1, 2, 3});
  // Longest semi-axis along local z.
  const std::vector<double> x = map_affine(
      mesh, ellipsoid_map(0.6 * kRadius, 1.1 * kRadius, 1.7 * kRadius, q), Eigen::Vector3d::Zero());
  const Shape shape = measure_shape(mesh, x.data());
  const Eigen::Vector3d expected = q.col(2);
  const Eigen::Vector3d axis(shape.major_axis[0], shape.major_axis[1], shape.major_axis[2]);
  EXPECT_NEAR(axis.norm(), 1.0, 1e-12);
  // |cos| of the angle between measured and exact major axis: within 0.5 deg.
  EXPECT_GT(std::abs(axis.dot(expected)), std::cos(0.5 * kPi / 180.0));
}

TEST(ShapeTest, InclinationOfEllipsoidRotatedAboutZ) {
  const mesh::TetMesh& mesh = sphere_3000();
  // Major axis along x before rotation; the inclination is the rotation
  // angle folded into (-90, 90] deg.
  const std::vector<std::pair<double, double>> angles = {
      {0.0, 0.0}, {20.0, 20.0}, {45.0, 45.0}, {-35.0, -35.0}, {80.0, 80.0}, {120.0, -60.0}, {-150.0, 30.0}};
  for (const auto& [rotate_deg, expected_deg] : angles) {
    const Eigen::Matrix3d q = rotation(rotate_deg * kPi / 180.0, {0, 0, 1});
    const std::vector<double> x =
        map_affine(mesh, ellipsoid_map(1.4 * kRadius, 0.9 * kRadius, 0.8 * kRadius, q),
                   Eigen::Vector3d(1e-6, -2e-6, 0.5e-6));
    const Shape shape = measure_shape(mesh, x.data());
    EXPECT_NEAR(shape.inclination_rad * 180.0 / kPi, expected_deg, 0.5) << "rotated by " << rotate_deg;
    EXPECT_GT(shape.inclination_rad, -kPi / 2.0);
    EXPECT_LE(shape.inclination_rad, kPi / 2.0);
  }
}

TEST(ShapeTest, InvariantUnderTranslationAndRotation) {
  const mesh::TetMesh& mesh = sphere_3000();
  const Eigen::Matrix3d stretch =
      ellipsoid_map(1.3 * kRadius, 0.9 * kRadius, 0.75 * kRadius, Eigen::Matrix3d::Identity());
  const std::vector<double> base = map_affine(mesh, stretch, Eigen::Vector3d::Zero());
  const Shape reference = measure_shape(mesh, base.data());
  const Eigen::Matrix3d q = rotation(73.0 * kPi / 180.0, {0.3, -1, 2});
  const Eigen::Vector3d shift(40e-6, -25e-6, 13e-6);
  const std::vector<double> moved = map_affine(mesh, q * stretch, shift);
  const Shape shape = measure_shape(mesh, moved.data());
  EXPECT_NEAR(shape.taylor_deformation, reference.taylor_deformation, 1e-9);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(shape.semi_axes_m[i] / reference.semi_axes_m[i], 1.0, 1e-9);
  EXPECT_NEAR(shape.volume_m3 / reference.volume_m3, 1.0, 1e-9);
  // The centroid moves with the body: q c0 + t.
  const Eigen::Vector3d c0(reference.centroid_m[0], reference.centroid_m[1], reference.centroid_m[2]);
  const Eigen::Vector3d expected = q * c0 + shift;
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(shape.centroid_m[d], expected(d), 1e-9 * kRadius);
}

TEST(ShapeTest, SphereIsUndeformed) {
  const mesh::TetMesh& mesh = sphere_3000();
  const Shape shape = measure_shape(mesh, mesh.positions_m.data());
  EXPECT_LT(shape.taylor_deformation, 0.01);
  EXPECT_GE(shape.taylor_deformation, 0.0);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(shape.semi_axes_m[i] / kRadius, 1.0, 0.01);
  EXPECT_NEAR(shape.volume_m3 / (4.0 / 3.0 * kPi * kRadius * kRadius * kRadius), 1.0, 0.02);
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(shape.centroid_m[d] / kRadius, 0.0, 1e-2);
}

// O(n^2) over all vertex pairs, the definition of paper eq. 18.
double brute_force_strain(const mesh::TetMesh& mesh, const double* x, double reference) {
  double best = 0.0;
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    if (!mesh.on_surface[i]) continue;
    for (std::size_t j = i + 1; j < mesh.num_vertices(); ++j) {
      if (!mesh.on_surface[j]) continue;
      const double dx = x[3 * i] - x[3 * j];
      const double dy = x[3 * i + 1] - x[3 * j + 1];
      const double dz = x[3 * i + 2] - x[3 * j + 2];
      best = std::max(best, std::sqrt(dx * dx + dy * dy + dz * dz));
    }
  }
  return (best - reference) / reference;
}

TEST(NetStrainTest, SphereHasZeroStrain) {
  const mesh::TetMesh& mesh = sphere_3000();
  // Surface vertices lie on the sphere and the geodesic surface holds
  // antipodal pairs, so d_max = 2R up to rounding.
  EXPECT_NEAR(net_strain(mesh, mesh.positions_m.data(), 2.0 * kRadius), 0.0, 1e-9);
}

TEST(NetStrainTest, StretchedEllipsoid) {
  const mesh::TetMesh& mesh = sphere_3000();
  // Volume-preserving stretch to a3 = 1.5 R, rotated and moved: strain 0.5
  // within 1 % (the tips of the inscribed polyhedron fall slightly short).
  const double lateral = 1.0 / std::sqrt(1.5);
  const Eigen::Matrix3d q = rotation(37.0 * kPi / 180.0, {1, 1, 0});
  const std::vector<double> x =
      map_affine(mesh, ellipsoid_map(lateral * kRadius, 1.5 * kRadius, lateral * kRadius, q),
                 Eigen::Vector3d(9e-6, 0, -4e-6));
  const double strain = net_strain(mesh, x.data(), 2.0 * kRadius);
  EXPECT_NEAR(strain / 0.5, 1.0, 0.01);
  EXPECT_LE(strain, 0.5 + 1e-12);  // inscribed: never beyond the true ellipsoid
  EXPECT_NEAR(strain, brute_force_strain(mesh, x.data(), 2.0 * kRadius), 1e-12);
}

TEST(NetStrainTest, ExactAgainstBruteForceOnIrregularShapes) {
  const mesh::TetMesh& mesh = sphere_3000();
  // Nonlinear maps: a bent and twisted cell, and a nearly spherical one
  // where pruning helps least.
  for (double amplitude : {0.0, 0.02, 0.3}) {
    std::vector<double> x(mesh.positions_m);
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      const double px = x[3 * v] / kRadius;
      const double py = x[3 * v + 1] / kRadius;
      const double pz = x[3 * v + 2] / kRadius;
      x[3 * v] += amplitude * kRadius * (py * py - 0.5 * pz);
      x[3 * v + 1] += amplitude * kRadius * std::sin(2.0 * px + pz);
      x[3 * v + 2] += amplitude * kRadius * px * py;
    }
    const double fast = net_strain(mesh, x.data(), 2.0 * kRadius);
    EXPECT_NEAR(fast, brute_force_strain(mesh, x.data(), 2.0 * kRadius), 1e-12) << "amplitude " << amplitude;
  }
}

TEST(NetStrainTest, NonPositiveReferenceIsNaN) {
  const mesh::TetMesh& mesh = sphere_3000();
  EXPECT_TRUE(std::isnan(net_strain(mesh, mesh.positions_m.data(), 0.0)));
}

}  // namespace
}  // namespace cellflow::observables
