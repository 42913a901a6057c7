// Shape observables from the tetrahedral mesh: volume, centroid, inertia
// tensor, equivalent ellipsoid, Taylor deformation, inclination, net strain.
#include "physics/observables/shape.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

#include "physics/mesh/tet_geometry.h"

namespace cellflow::observables {

Shape measure_shape(const mesh::TetMesh& mesh, const double* positions_m) {
  Shape shape;
  const std::size_t num_tets = mesh.num_tets();
  if (num_tets == 0) return shape;

  // Pass 1: current volume and volume-weighted centroid, from signed tet
  // volumes so an (unphysical) inverted tet counts negatively.
  std::vector<double> tet_volume(num_tets);
  std::vector<double> tet_centroid(3 * num_tets);
  double volume = 0.0;
  double moment[3] = {0.0, 0.0, 0.0};
  for (std::size_t t = 0; t < num_tets; ++t) {
    const std::int32_t* tet = &mesh.tets[4 * t];
    // V_l = det[x1 - x4, x2 - x4, x3 - x4] / 6
    const double v = mesh::tet_signed_volume(positions_m, tet);
    tet_volume[t] = v;
    volume += v;
    for (int d = 0; d < 3; ++d) {
      // r^l = (x1 + x2 + x3 + x4) / 4
      const double c = 0.25 * (positions_m[3 * tet[0] + d] + positions_m[3 * tet[1] + d] +
                               positions_m[3 * tet[2] + d] + positions_m[3 * tet[3] + d]);
      tet_centroid[3 * t + d] = c;
      moment[d] += v * c;
    }
  }
  shape.volume_m3 = volume;
  if (!(volume > 0.0)) return shape;
  for (int d = 0; d < 3; ++d) shape.centroid_m[d] = moment[d] / volume;

  // Pass 2: inertia tensor about the centroid, tets as point masses at their
  // centroids with unit density.
  // Theta_ij = sum_l V_l (r^l . r^l delta_ij - r^l_i r^l_j)   (paper eq. 15)
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  for (std::size_t t = 0; t < num_tets; ++t) {
    const Eigen::Vector3d r(tet_centroid[3 * t] - shape.centroid_m[0],
                            tet_centroid[3 * t + 1] - shape.centroid_m[1],
                            tet_centroid[3 * t + 2] - shape.centroid_m[2]);
    inertia += tet_volume[t] * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
  }

  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(inertia);
  // Eigen sorts ascending: theta1 > theta2 > theta3 are entries 2, 1, 0.
  const double theta1 = solver.eigenvalues()(2);
  const double theta2 = solver.eigenvalues()(1);
  const double theta3 = solver.eigenvalues()(0);

  // Paper eq. 16 as printed gives a_i^2, not a_i: for a solid ellipsoid of
  // mass M, Theta_11 = M (a2^2 + a3^2) / 5 etc., so
  // a_1^2 = 5 / (2 M) (-theta1 + theta2 + theta3)   (paper eq. 16, squared)
  // a_2^2 = 5 / (2 M) ( theta1 - theta2 + theta3)
  // a_3^2 = 5 / (2 M) ( theta1 + theta2 - theta3)
  // with M = V (unit density). Taking eq. 16 literally as a_i would put a_i^2
  // into D and roughly double it for small deformations.
  const double prefactor = 5.0 / (2.0 * volume);
  const double a1_sq = prefactor * (-theta1 + theta2 + theta3);
  const double a2_sq = prefactor * (theta1 - theta2 + theta3);
  const double a3_sq = prefactor * (theta1 + theta2 - theta3);
  shape.semi_axes_m = {std::sqrt(std::max(0.0, a1_sq)), std::sqrt(std::max(0.0, a2_sq)),
                       std::sqrt(std::max(0.0, a3_sq))};

  // D = (a3 - a1) / (a3 + a1)   (paper eq. 13)
  const double a1 = shape.semi_axes_m[0];
  const double a3 = shape.semi_axes_m[2];
  shape.taylor_deformation = (a3 + a1) > 0.0 ? (a3 - a1) / (a3 + a1) : 0.0;

  // The major axis has the smallest moment of inertia. Its sign is fixed so
  // that the first nonzero of (x, y, z) is positive (deterministic output).
  Eigen::Vector3d axis = solver.eigenvectors().col(0).normalized();
  const double tiny = 1e-12;
  if (axis.x() < -tiny ||
      (std::abs(axis.x()) <= tiny && (axis.y() < -tiny || (std::abs(axis.y()) <= tiny && axis.z() < 0.0)))) {
    axis = -axis;
  }
  shape.major_axis = {axis.x(), axis.y(), axis.z()};

  // Inclination of the x-y projection from +x, folded into (-pi/2, pi/2]
  // (an axis, not a direction). Zero when the axis is along z.
  if (std::hypot(axis.x(), axis.y()) > tiny) {
    constexpr double kPi = 3.14159265358979323846;
    double angle = std::atan2(axis.y(), axis.x());
    if (angle > kPi / 2.0) angle -= kPi;
    if (angle <= -kPi / 2.0) angle += kPi;
    shape.inclination_rad = angle;
  }
  return shape;
}

double net_strain(const mesh::TetMesh& mesh, const double* positions_m, double reference_diameter_m) {
  if (!(reference_diameter_m > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t num_vertices = mesh.num_vertices();
  const bool have_surface = mesh.on_surface.size() == num_vertices;

  // Candidates (surface vertices) as offsets from their mean.
  std::vector<double> points;
  points.reserve(3 * num_vertices);
  double mean[3] = {0.0, 0.0, 0.0};
  for (std::size_t v = 0; v < num_vertices; ++v) {
    if (have_surface && mesh.on_surface[v] == 0) continue;
    for (int d = 0; d < 3; ++d) {
      points.push_back(positions_m[3 * v + d]);
      mean[d] += positions_m[3 * v + d];
    }
  }
  const std::size_t n = points.size() / 3;
  if (n < 2) return -1.0;
  for (double& m : mean) m /= static_cast<double>(n);

  // Exact diameter by branch and bound: |p - q| <= |p - c| + |q - c|, so with
  // the points sorted by distance from c (descending), the inner loop stops as
  // soon as that bound cannot beat the best pair found. The start value, the
  // largest distance from the point farthest from c, is a lower bound that for
  // an elongated cell is already (close to) the answer, so only the points near
  // the two tips take part in the pair search.
  std::vector<double> radius(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double dx = points[3 * i] - mean[0];
    const double dy = points[3 * i + 1] - mean[1];
    const double dz = points[3 * i + 2] - mean[2];
    radius[i] = std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return radius[a] > radius[b]; });
  std::vector<double> sorted(3 * n);
  std::vector<double> sorted_radius(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int d = 0; d < 3; ++d) sorted[3 * i + d] = points[3 * order[i] + d];
    sorted_radius[i] = radius[order[i]];
  }
  auto distance_sq = [&](std::size_t i, std::size_t j) {
    const double dx = sorted[3 * i] - sorted[3 * j];
    const double dy = sorted[3 * i + 1] - sorted[3 * j + 1];
    const double dz = sorted[3 * i + 2] - sorted[3 * j + 2];
    return dx * dx + dy * dy + dz * dz;
  };
  // Lower bound: the farthest point from point 0 (the farthest from c).
  double best_sq = 0.0;
  for (std::size_t j = 1; j < n; ++j) best_sq = std::max(best_sq, distance_sq(0, j));
  double best = std::sqrt(best_sq);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    if (2.0 * sorted_radius[i] <= best) break;  // no later pair can beat it
    for (std::size_t j = i + 1; j < n; ++j) {
      if (sorted_radius[i] + sorted_radius[j] <= best) break;
      const double d_sq = distance_sq(i, j);
      if (d_sq > best_sq) {
        best_sq = d_sq;
        best = std::sqrt(d_sq);
      }
    }
  }
  // Delta epsilon = (d_max - d_ref) / d_ref   (paper eq. 18)
  return (best - reference_diameter_m) / reference_diameter_m;
}

}  // namespace cellflow::observables
