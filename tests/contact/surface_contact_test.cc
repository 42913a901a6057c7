// The probe on the surface triangles (closest point of each triangle) and
// the augmented-Lagrangian offsets: the closest-point distance against brute
// force, its gradient and Hessian against finite differences; forces minus
// the energy gradient, the Hessian blocks the derivative of the forces, the
// reaction minus the sum of the vertex forces (with offsets); a probe much
// narrower than the mesh spacing sees a continuous surface (the force has no
// jumps as it slides over faces, edges and vertices, where on the vertices
// alone it drops to zero); Uzawa updates of the offsets drive the gap to zero.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <vector>

#include "physics/contact/rigid_contact.h"
#include "physics/contact/surface_triangles.h"
#include "physics/contact/triangle_distance.h"

namespace cellflow::contact {
namespace {

constexpr double kRadius = 8.6e-6;

TEST(TriangleDistance, MatchesBruteForceAndItsDerivativesInEveryRegion) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::set<ClosestFeature> seen;
  for (int trial = 0; trial < 400; ++trial) {
    double p[9], q[3];
    for (double& x : p) x = u(rng);
    for (double& x : q) x = 1.5 * u(rng);
    const TriangleDistance td = triangle_distance(q, p);
    seen.insert(td.feature);
    // brute force over a barycentric grid: never below, and close to it
    double best = 1e300;
    const int n = 200;
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        const double b1 = double(i) / n, b2 = double(j) / n, b0 = 1.0 - b1 - b2;
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
          const double x = b0 * p[a] + b1 * p[3 + a] + b2 * p[6 + a] - q[a];
          d2 += x * x;
        }
        best = std::min(best, std::sqrt(d2));
      }
    }
    ASSERT_LE(td.distance_m, best + 1e-12);
    ASSERT_GT(td.distance_m, best - 2e-2);
    if (td.distance_m < 1e-3) continue;
    // gradient: d d / d p_ia = -b_i n_a; Hessian: central differences of it
    double hessian[81];
    triangle_distance_hessian(q, p, td, hessian);
    const double h = 1e-6;
    for (int k = 0; k < 9; ++k) {
      double pp[9], pm[9];
      std::copy(p, p + 9, pp);
      std::copy(p, p + 9, pm);
      pp[k] += h;
      pm[k] -= h;
      const TriangleDistance tp = triangle_distance(q, pp), tm = triangle_distance(q, pm);
      if (tp.feature != td.feature || tm.feature != td.feature) continue;  // at a region boundary
      const double fd = (tp.distance_m - tm.distance_m) / (2 * h);
      EXPECT_NEAR(-td.barycentric[k / 3] * td.normal[k % 3], fd, 1e-7) << "trial " << trial << " k " << k;
      for (int l = 0; l < 9; ++l) {
        const double gp = -tp.barycentric[l / 3] * tp.normal[l % 3];
        const double gm = -tm.barycentric[l / 3] * tm.normal[l % 3];
        EXPECT_NEAR(hessian[9 * l + k], (gp - gm) / (2 * h), 1e-5 * (1.0 + std::abs(hessian[9 * l + k])))
            << "trial " << trial << " feature " << int(td.feature) << " " << l << "," << k;
      }
    }
  }
  EXPECT_EQ(seen.size(), 7u);  // face, three edges, three vertices
}

// A bumpy triangulated cap of a sphere of radius kRadius (grid in x-y), the
// probe pressing on it so that triangles are outside, inside the range and
// penetrating, with random augmented-Lagrangian offsets.
struct SurfaceSetup {
  Obstacles obstacles;
  std::vector<double> positions;
  std::vector<std::int32_t> triangles, vertices;
  std::vector<double> offsets;
};

SurfaceSetup make_cap(bool with_offsets) {
  SurfaceSetup s;
  const int n = 9;
  const double spacing = 0.12 * kRadius;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.15 * spacing, 0.15 * spacing);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = (i - (n - 1) / 2.0) * spacing + jitter(rng);
      const double y = (j - (n - 1) / 2.0) * spacing + jitter(rng);
      const double z = std::sqrt(kRadius * kRadius - x * x - y * y) + 0.02 * jitter(rng);
      s.positions.insert(s.positions.end(), {x, y, z});
      s.vertices.push_back(i * n + j);
    }
  }
  for (int i = 0; i + 1 < n; ++i) {
    for (int j = 0; j + 1 < n; ++j) {
      const int a = i * n + j, b = (i + 1) * n + j, c = (i + 1) * n + j + 1, d = i * n + j + 1;
      s.triangles.insert(s.triangles.end(), {a, b, c, a, c, d});
    }
  }
  const double rp = 0.3 * kRadius;
  s.obstacles.penalty = {.stiffness_n_per_m = 1e-3, .range_m = 0.01 * kRadius};
  // centre so that the closest triangle penetrates by about 2 ranges
  s.obstacles.probe =
      Probe{.centre_m = {0.013 * kRadius, -0.021 * kRadius, kRadius + rp - 0.02 * kRadius}, .radius_m = rp};
  s.obstacles.probe_triangles = s.triangles;
  if (with_offsets) {
    std::uniform_real_distribution<double> offset(-0.01 * kRadius, 0.01 * kRadius);
    s.offsets.resize(s.triangles.size() / 3);
    for (double& o : s.offsets) o = offset(rng);
    s.obstacles.probe_offsets_m = s.offsets;
  }
  return s;
}

class SurfaceProbe : public ::testing::TestWithParam<bool> {};

TEST_P(SurfaceProbe, ForcesAreMinusEnergyGradient) {
  SurfaceSetup s = make_cap(GetParam());
  std::vector<double> forces(s.positions.size(), 0.0);
  const ContactEvaluation eval =
      add_contact_forces(s.obstacles, s.vertices, s.positions.data(), forces.data());
  ASSERT_GT(eval.num_active, 4);
  ASSERT_GT(eval.max_penetration_m, 0.0);
  double max_force = 0.0;
  for (double f : forces) max_force = std::max(max_force, std::abs(f));
  const double h = 1e-6 * s.obstacles.penalty.range_m;
  for (std::size_t i = 0; i < s.positions.size(); ++i) {
    std::vector<double> y = s.positions;
    y[i] += h;
    const double ep = contact_energy(s.obstacles, s.vertices, y.data()).energy_j;
    y[i] -= 2 * h;
    const double em = contact_energy(s.obstacles, s.vertices, y.data()).energy_j;
    EXPECT_NEAR(forces[i], -(ep - em) / (2 * h), 1e-6 * max_force) << "dof " << i;
  }
}

TEST_P(SurfaceProbe, HessianIsDerivativeOfForces) {
  SurfaceSetup s = make_cap(GetParam());
  const std::size_t n = s.positions.size();
  const std::size_t triangles = s.triangles.size() / 3;
  std::vector<double> blocks(81 * triangles, 0.0);
  add_probe_triangle_hessian(s.obstacles, s.positions.data(), blocks.data());
  // dense K from the triangle blocks
  std::vector<double> k(n * n, 0.0);
  for (std::size_t t = 0; t < triangles; ++t) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) {
            const std::size_t row = 3 * static_cast<std::size_t>(s.triangles[3 * t + i]) + a;
            const std::size_t col = 3 * static_cast<std::size_t>(s.triangles[3 * t + j]) + b;
            k[n * row + col] += blocks[81 * t + 9 * (3 * i + j) + 3 * a + b];
          }
        }
      }
    }
  }
  double max_entry = 0.0;
  for (double e : k) max_entry = std::max(max_entry, std::abs(e));
  ASSERT_GT(max_entry, 0.0);
  const double h = 1e-7 * s.obstacles.penalty.range_m;
  for (std::size_t col = 0; col < n; ++col) {
    std::vector<double> y = s.positions, fp(n, 0.0), fm(n, 0.0);
    y[col] += h;
    add_contact_forces(s.obstacles, s.vertices, y.data(), fp.data());
    y[col] -= 2 * h;
    add_contact_forces(s.obstacles, s.vertices, y.data(), fm.data());
    for (std::size_t row = 0; row < n; ++row) {
      EXPECT_NEAR(k[n * row + col], -(fp[row] - fm[row]) / (2 * h), 1e-5 * max_entry) << row << "," << col;
    }
  }
  // symmetric
  for (std::size_t r = 0; r < n; ++r) {
    for (std::size_t c = 0; c < r; ++c) EXPECT_NEAR(k[n * r + c], k[n * c + r], 1e-12 * max_entry);
  }
}

TEST_P(SurfaceProbe, ReactionIsMinusSumOfVertexForces) {
  SurfaceSetup s = make_cap(GetParam());
  std::vector<double> forces(s.positions.size(), 0.0);
  const ContactEvaluation eval =
      add_contact_forces(s.obstacles, s.vertices, s.positions.data(), forces.data());
  double sum[3] = {0, 0, 0}, scale = 0.0;
  for (std::size_t i = 0; i < forces.size(); ++i) {
    sum[i % 3] += forces[i];
    scale += std::abs(forces[i]);
  }
  ASSERT_GT(eval.probe_reaction_n[2], 0.0);  // the cell pushes the probe up
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(eval.probe_reaction_n[a], -sum[a], 1e-12 * scale);
}

INSTANTIATE_TEST_SUITE_P(Offsets, SurfaceProbe, ::testing::Values(false, true));

// Total probe force on a flat triangulated plane (spacing h) with the probe
// (Rp = h / 5) at a fixed height inside the contact range, at x along a line.
double flat_force(bool on_triangles, double x, double y) {
  static std::vector<double> positions;
  static std::vector<std::int32_t> triangles, vertices;
  const int n = 8;
  const double h = 1.0e-6;
  if (positions.empty()) {
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        positions.insert(positions.end(), {i * h, j * h, 0.0});
        vertices.push_back(i * n + j);
      }
    }
    for (int i = 0; i + 1 < n; ++i) {
      for (int j = 0; j + 1 < n; ++j) {
        const int a = i * n + j, b = (i + 1) * n + j, c = (i + 1) * n + j + 1, d = i * n + j + 1;
        triangles.insert(triangles.end(), {a, b, c, a, c, d});
      }
    }
  }
  Obstacles o;
  o.penalty = {.stiffness_n_per_m = 1.0, .range_m = 0.01 * h};
  const double rp = 0.2 * h;
  o.probe = Probe{.centre_m = {x, y, rp + 0.5 * o.penalty.range_m}, .radius_m = rp};
  if (on_triangles) o.probe_triangles = triangles;
  return contact_energy(o, vertices, positions.data()).probe_reaction_n[2];
}

TEST(SurfaceProbe, ANarrowProbeSeesAContinuousSurface) {
  const double h = 1.0e-6;
  // the single-triangle force at the fixed height: F(r/2) = k r / 4
  const double face_force = 1.0 * 0.01 * h / 4.0;
  for (const double y : {0.0, 0.3 * h, 0.5 * h}) {  // through vertices, across faces and edges
    double largest_jump[2] = {0, 0}, largest_force = 0.0;
    for (int level = 0; level < 2; ++level) {
      const int samples = 400 << level;
      double previous = flat_force(true, 2.0 * h, 2.0 * h + y);
      for (int i = 1; i <= samples; ++i) {
        const double x = 2.0 * h + 2.0 * h * i / samples;
        const double f = flat_force(true, x, 2.0 * h + y);
        EXPECT_GE(f, face_force * (1.0 - 1e-9)) << "x " << x << " y " << y;  // never falls through
        largest_jump[level] = std::max(largest_jump[level], std::abs(f - previous));
        largest_force = std::max(largest_force, f);
        previous = f;
      }
    }
    // continuous: halving the sampling step halves the largest change
    // between neighbouring samples (a jump would stay)
    EXPECT_LT(largest_jump[1], 0.6 * largest_jump[0]) << "y " << y;
    EXPECT_LT(largest_jump[1], 0.1 * largest_force) << "y " << y;
  }
  // on the vertices alone the same probe finds no vertex between them
  EXPECT_EQ(flat_force(false, 2.5 * h, 2.3 * h), 0.0);
  EXPECT_GT(flat_force(false, 2.0 * h, 2.0 * h), 0.0);
}

TEST(AugmentedLagrangian, UzawaUpdatesDriveTheGapToZero) {
  // One vertex on a linear spring (stiffness ke) whose rest position lies a
  // below the lower plate: the exact contact force is ke a at gap 0. The
  // plain penalty leaves it inside the plate; the updates remove the gap.
  const double ke = 0.3, a = 1e-6;
  Obstacles o;
  o.penalty = {.stiffness_n_per_m = 2.0, .range_m = 1e-7};
  o.lower_plate_z_m = 0.0;
  const std::int32_t vertex = 0;
  ContactOffsets offsets = hard_contact_offsets(o.penalty, 1, 0);
  attach_offsets(offsets, o);
  ASSERT_EQ(o.lower_plate_offsets_m.size(), 1u);
  auto equilibrium = [&] {
    // ke (z + a) = contact force at z: bisection
    double lo = -10 * a, hi = a;
    for (int i = 0; i < 200; ++i) {
      const double mid = 0.5 * (lo + hi);
      double y[3] = {0, 0, mid}, f[3] = {0, 0, 0};
      add_contact_forces(o, std::span(&vertex, 1), y, f);
      (f[2] - ke * (mid + a) > 0.0 ? lo : hi) = mid;  // net upward force: the equilibrium lies higher
    }
    return 0.5 * (lo + hi);
  };
  double z = equilibrium();
  EXPECT_LT(z, -0.01 * a);  // hard contact without updates: penetrates
  double y[3] = {0, 0, z};
  double error = gap_error(o, std::span(&vertex, 1), y);
  EXPECT_NEAR(error, -z, 1e-20);
  for (int update = 0; update < 8; ++update) {
    EXPECT_NEAR(update_offsets(o, std::span(&vertex, 1), y, offsets), error, 1e-20);
    z = equilibrium();
    y[2] = z;
    const double next = gap_error(o, std::span(&vertex, 1), y);
    EXPECT_LT(next, 0.2 * error + 1e-15);  // linear convergence, rate ke / (ke + 2k)
    error = next;
  }
  EXPECT_LT(std::abs(z), 1e-8 * a);  // from about 0.1 a, at 0.07 per update
  double f[3] = {0, 0, 0};
  add_contact_forces(o, std::span(&vertex, 1), y, f);
  EXPECT_NEAR(f[2], ke * a, 1e-8 * ke * a);
}

TEST(SurfaceTriangles, ClosedAndOutwardOnATetrahedralCube) {
  // a cube of 8 vertices split into 6 tets around a diagonal (Kuhn)
  std::vector<double> p;
  for (int i = 0; i < 8; ++i) p.insert(p.end(), {double(i & 1), double((i >> 1) & 1), double((i >> 2) & 1)});
  const std::vector<std::int32_t> tets = {0, 1, 3, 7, 0, 1, 5, 7, 0, 2, 3, 7,
                                          0, 2, 6, 7, 0, 4, 5, 7, 0, 4, 6, 7};
  const std::vector<std::int32_t> tri = boundary_triangles(tets, p.data());
  ASSERT_EQ(tri.size(), 3u * 12u);  // 6 faces x 2
  double volume6 = 0.0;             // divergence theorem: sum of (p0 . (p1 x p2)) = 6 V for outward faces
  for (std::size_t t = 0; t < tri.size(); t += 3) {
    const double* a = &p[3 * tri[t]];
    const double* b = &p[3 * tri[t + 1]];
    const double* c = &p[3 * tri[t + 2]];
    volume6 += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
               a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  EXPECT_NEAR(volume6, 6.0, 1e-12);
}

}  // namespace
}  // namespace cellflow::contact
