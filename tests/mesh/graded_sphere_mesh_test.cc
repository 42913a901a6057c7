// Pole-graded sphere meshes: closed surface on the sphere, volume, quality,
// refinement at both poles (and only there), determinism and validation.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "physics/mesh/graded_sphere_surface.h"
#include "physics/mesh/sphere_mesh.h"

namespace cellflow::mesh {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadius = 8e-6;  // the small-probe cell of validation/fe

// Surface edges (both ends on the surface and on a boundary face) with the
// arc distance of their midpoint from the nearer pole.
struct SurfaceEdge {
  double length_m = 0.0;
  double pole_arc_m = 0.0;
};

std::vector<SurfaceEdge> boundary_edges(const TetMesh& mesh, double radius) {
  std::map<std::array<std::int32_t, 3>, int> face_count;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const std::int32_t* v = &mesh.tets[4 * t];
    for (int skip = 0; skip < 4; ++skip) {
      std::array<std::int32_t, 3> f{};
      int n = 0;
      for (int k = 0; k < 4; ++k) {
        if (k != skip) f[n++] = v[k];
      }
      std::sort(f.begin(), f.end());
      ++face_count[f];
    }
  }
  std::map<std::pair<std::int32_t, std::int32_t>, int> edge_faces;
  for (const auto& [f, count] : face_count) {
    if (count != 1) continue;
    for (int k = 0; k < 3; ++k)
      ++edge_faces[{std::min(f[k], f[(k + 1) % 3]), std::max(f[k], f[(k + 1) % 3])}];
  }
  std::vector<SurfaceEdge> edges;
  for (const auto& [e, faces] : edge_faces) {
    EXPECT_EQ(faces, 2) << "boundary edge " << e.first << "-" << e.second << " not shared by two faces";
    const double* a = &mesh.positions_m[3 * static_cast<std::size_t>(e.first)];
    const double* b = &mesh.positions_m[3 * static_cast<std::size_t>(e.second)];
    const double z = 0.5 * (a[2] + b[2]);
    const double length = std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                    (a[2] - b[2]) * (a[2] - b[2]));
    const double polar = std::acos(std::clamp(std::abs(z) / radius, 0.0, 1.0));
    edges.push_back({length, radius * polar});
  }
  return edges;
}

SphereMeshOptions graded_options(double pole_spacing_m, int vertices = 3000) {
  SphereMeshOptions o;
  o.radius_m = kRadius;
  o.target_vertex_count = vertices;
  o.pole_grading.pole_spacing_m = pole_spacing_m;
  return o;
}

TEST(GradedSphereMeshTest, RefinedAtBothPolesOnTheSphereWithQuality) {
  const double bulk = sphere_mesh_spacing_m(kRadius, 3000);
  ASSERT_GT(bulk, 0.5e-6);  // ~0.7 um: the case the grading is for
  const double pole = 0.1e-6;
  const StatusOr<TetMesh> made = make_sphere_mesh(graded_options(pole));
  ASSERT_TRUE(made.ok()) << made.status().to_string();
  const TetMesh& mesh = *made;
  const MeshQuality q = mesh_quality(mesh);
  // The uniform mesh's quality bounds hold on the graded one.
  EXPECT_GE(q.min_dihedral_deg, 10.0);
  EXPECT_LE(q.max_radius_edge_ratio, 2.0);
  EXPECT_GT(q.min_tet_volume_m3, 0.0);
  // Volume of the inscribed polyhedron: within 1 % of the ball (the bulk
  // triangles are those of the uniform mesh).
  const double ball = 4.0 / 3.0 * kPi * kRadius * kRadius * kRadius;
  EXPECT_NEAR(q.volume_m3 / ball, 1.0, 0.01);
  EXPECT_LT(q.volume_m3, ball);
  // Every surface vertex on the sphere, both poles vertices.
  int poles = 0;
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    if (!mesh.on_surface[v]) continue;
    const double* p = &mesh.positions_m[3 * v];
    EXPECT_NEAR(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), kRadius, 1e-12 * kRadius);
    if (std::abs(std::abs(p[2]) - kRadius) < 1e-12 * kRadius) ++poles;
  }
  EXPECT_EQ(poles, 2);
  // Refinement where asked: edges near either pole at the pole spacing,
  // growing with the arc distance; the bulk at the uniform spacing.
  const std::vector<SurfaceEdge> edges = boundary_edges(mesh, kRadius);
  double near_max = 0.0, near_sum = 0.0, bulk_sum = 0.0;
  int near_count = 0, bulk_count = 0;
  for (const SurfaceEdge& e : edges) {
    if (e.pole_arc_m < 2.0 * pole) {
      near_max = std::max(near_max, e.length_m);
      near_sum += e.length_m;
      ++near_count;
    }
    // h(s) = pole + 0.15 s reaches the bulk spacing at s = 6.7 (bulk - pole)
    if (e.pole_arc_m > 6.7 * bulk + 2.0 * bulk) {
      bulk_sum += e.length_m;
      ++bulk_count;
    }
    // No edge much longer than the sizing asks (1.5: ring triangles).
    EXPECT_LT(e.length_m, 1.5 * std::min(bulk, pole + 0.15 * e.pole_arc_m) + 0.5 * pole)
        << "edge at arc " << e.pole_arc_m;
  }
  ASSERT_GT(near_count, 10);
  // h <= 1.5 pole within two pole spacings; a ring triangle's diagonal is
  // up to 1.2 h
  EXPECT_LT(near_max, 1.8 * pole);
  EXPECT_NEAR(near_sum / near_count, pole, 0.35 * pole);
  ASSERT_GT(bulk_count, 100);
  EXPECT_NEAR(bulk_sum / bulk_count, bulk, 0.15 * bulk);
  // The volume is graded too (TetGen's -m sizing): edges of tets within
  // 0.5 um of a pole (3-D distance, the contact's stress field) are short,
  // those far from both poles have the bulk length.
  double close_sum = 0.0, far_sum = 0.0;
  int close_count = 0, far_count = 0;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        const double* a = &mesh.positions_m[3 * static_cast<std::size_t>(mesh.tets[4 * t + i])];
        const double* b = &mesh.positions_m[3 * static_cast<std::size_t>(mesh.tets[4 * t + j])];
        const double m[3] = {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])};
        const double to_pole =
            std::sqrt(m[0] * m[0] + m[1] * m[1] + (std::abs(m[2]) - kRadius) * (std::abs(m[2]) - kRadius));
        const double length = std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                        (a[2] - b[2]) * (a[2] - b[2]));
        if (to_pole < 0.5e-6) {
          close_sum += length;
          ++close_count;
        } else if (to_pole > 7.0 * bulk) {
          far_sum += length;
          ++far_count;
        }
      }
    }
  }
  ASSERT_GT(close_count, 100);
  ASSERT_GT(far_count, 1000);
  EXPECT_LT(close_sum / close_count, 0.3 * bulk);
  EXPECT_NEAR(far_sum / far_count, bulk, 0.25 * bulk);
  // The grading adds vertices, bounded: the bulk of 3000 plus two caps.
  EXPECT_GT(mesh.num_vertices(), 3000u);
  EXPECT_LT(mesh.num_vertices(), 9000u);
}

TEST(GradedSphereMeshTest, DeterministicAndUniformWhenPoleIsCoarse) {
  const StatusOr<TetMesh> a = make_sphere_mesh(graded_options(0.2e-6, 500));
  const StatusOr<TetMesh> b = make_sphere_mesh(graded_options(0.2e-6, 500));
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->positions_m, b->positions_m);
  EXPECT_EQ(a->tets, b->tets);
  // A pole spacing at or above the bulk spacing is the uniform mesh.
  const StatusOr<TetMesh> coarse = make_sphere_mesh(graded_options(3e-6, 500));
  const StatusOr<TetMesh> uniform = make_sphere_mesh(graded_options(0.0, 500));
  ASSERT_TRUE(coarse.ok() && uniform.ok());
  EXPECT_EQ(coarse->positions_m, uniform->positions_m);
}

class GradedSurfaceTest : public ::testing::TestWithParam<double> {};

TEST_P(GradedSurfaceTest, SurfaceIsClosedOutwardAndOnTheSphere) {
  const SphereSurface s = make_pole_graded_sphere_surface(1.0, 0.01, 0.1, 0.25, GetParam());
  const std::size_t n = s.points.size() / 3;
  // Euler: V - E + F = 2 with E = 3 F / 2 for a closed triangulation.
  EXPECT_EQ(2 * n, s.triangles.size() + 4);
  std::map<std::pair<int, int>, int> edge_faces;
  double volume = 0.0;
  for (const auto& t : s.triangles) {
    const double* a = &s.points[3 * static_cast<std::size_t>(t[0])];
    const double* b = &s.points[3 * static_cast<std::size_t>(t[1])];
    const double* c = &s.points[3 * static_cast<std::size_t>(t[2])];
    const double v6 = a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
                      a[2] * (b[0] * c[1] - b[1] * c[0]);
    EXPECT_GT(v6, 0.0);  // outward
    volume += v6 / 6.0;
    for (int e = 0; e < 3; ++e)
      ++edge_faces[{std::min(t[e], t[(e + 1) % 3]), std::max(t[e], t[(e + 1) % 3])}];
  }
  for (const auto& [edge, faces] : edge_faces) EXPECT_EQ(faces, 2) << edge.first << "-" << edge.second;
  EXPECT_NEAR(volume / (4.0 / 3.0 * kPi), 1.0, 0.01);
  for (std::size_t v = 0; v < n; ++v) {
    const double* p = &s.points[3 * v];
    EXPECT_NEAR(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), 1.0, 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(RingJitter, GradedSurfaceTest, ::testing::Values(0.0, 0.5, 1.0));

// The moved rings: the same vertices on the same meridians, each moved along
// it by at most half the jitter times the ring distance (sqrt(3)/2 h), nearly
// every vertex at its own height (rings are taken into contact one vertex at
// a time), and every edge convex (the flips reached the convex hull, the
// sphere's Delaunay triangulation).
TEST(GradedSphereMeshTest, JitteredRingsKeepMeridiansSpreadHeightsAndAreConvex) {
  const double pole = 0.01, bulk = 0.1, growth = 0.25, jitter = 1.0;
  const SphereSurface rings = make_pole_graded_sphere_surface(1.0, pole, bulk, growth, 0.0);
  const SphereSurface moved = make_pole_graded_sphere_surface(1.0, pole, bulk, growth, jitter);
  ASSERT_EQ(rings.points.size(), moved.points.size());
  const std::size_t n = rings.points.size() / 3;
  std::vector<double> ring_heights, moved_heights;
  for (std::size_t v = 0; v < n; ++v) {
    const double* a = &rings.points[3 * v];
    const double* b = &moved.points[3 * v];
    const double polar_a = std::acos(std::clamp(a[2], -1.0, 1.0));
    const double polar_b = std::acos(std::clamp(b[2], -1.0, 1.0));
    const double from_pole = std::min(polar_a, kPi - polar_a);
    const double ring_distance = 0.5 * std::sqrt(3.0) * std::min(bulk, pole + growth * from_pole);
    EXPECT_LE(std::abs(polar_b - polar_a), 0.5 * jitter * ring_distance * 1.1 + 1e-12) << "vertex " << v;
    if (std::hypot(a[0], a[1]) > 1e-9) {
      EXPECT_NEAR(std::atan2(b[1], b[0]), std::atan2(a[1], a[0]), 1e-9) << "vertex " << v;
    }
    ring_heights.push_back(std::round(a[2] * 1e9));
    moved_heights.push_back(std::round(b[2] * 1e9));
  }
  auto distinct = [](std::vector<double> z) {
    std::sort(z.begin(), z.end());
    return static_cast<std::size_t>(std::unique(z.begin(), z.end()) - z.begin());
  };
  EXPECT_LT(distinct(ring_heights), n / 10);  // rings: a few hundred heights
  // Moved: a vertex shares its height only with its mirror image -azimuth on
  // the same ring (the wave is |azimuth|), which the rings' stagger makes rare.
  EXPECT_GE(distinct(moved_heights), n - n / 100);
  // Convex at every edge: the vertex across it lies inside the plane of the face.
  std::map<std::pair<int, int>, std::vector<std::array<int, 3>>> faces;
  for (const auto& t : moved.triangles) {
    for (int e = 0; e < 3; ++e)
      faces[{std::min(t[e], t[(e + 1) % 3]), std::max(t[e], t[(e + 1) % 3])}].push_back(t);
  }
  for (const auto& [edge, two] : faces) {
    ASSERT_EQ(two.size(), 2u);
    const auto& t = two[0];
    int d = two[1][0];
    for (int v : two[1]) {
      if (v != edge.first && v != edge.second) d = v;
    }
    const double* a = &moved.points[3 * static_cast<std::size_t>(t[0])];
    const double* b = &moved.points[3 * static_cast<std::size_t>(t[1])];
    const double* c = &moved.points[3 * static_cast<std::size_t>(t[2])];
    const double* q = &moved.points[3 * static_cast<std::size_t>(d)];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    EXPECT_LE(nrm[0] * (q[0] - a[0]) + nrm[1] * (q[1] - a[1]) + nrm[2] * (q[2] - a[2]), 1e-12)
        << "edge " << edge.first << "-" << edge.second;
  }
}

// The tetrahedral mesh of a jittered surface keeps the uniform mesh's
// quality bounds.
TEST(GradedSphereMeshTest, JitteredRingsKeepQuality) {
  for (double jitter : {0.5, 1.0}) {
    SphereMeshOptions o = graded_options(0.1e-6);
    o.pole_grading.ring_jitter = jitter;
    const StatusOr<TetMesh> made = make_sphere_mesh(o);
    ASSERT_TRUE(made.ok()) << made.status().to_string();
    const MeshQuality q = mesh_quality(*made);
    EXPECT_GE(q.min_dihedral_deg, 10.0) << jitter;
    EXPECT_LE(q.max_radius_edge_ratio, 2.0) << jitter;
    EXPECT_GT(q.min_tet_volume_m3, 0.0) << jitter;
    EXPECT_NEAR(q.volume_m3 / (4.0 / 3.0 * kPi * kRadius * kRadius * kRadius), 1.0, 0.01) << jitter;
  }
}

TEST(GradedSphereMeshTest, RejectsOutOfRangeGrading) {
  for (double spacing : {-1e-7, 1e-12, std::nan(""), 1e-3}) {
    const StatusOr<TetMesh> m = make_sphere_mesh(graded_options(spacing, 500));
    ASSERT_FALSE(m.ok()) << spacing;
    EXPECT_NE(m.status().message().find("pole_grading.pole_spacing_m"), std::string::npos);
  }
  for (double growth : {0.0, 0.05, 2.0, std::nan("")}) {
    SphereMeshOptions o = graded_options(0.1e-6, 500);
    o.pole_grading.growth = growth;
    const StatusOr<TetMesh> m = make_sphere_mesh(o);
    ASSERT_FALSE(m.ok()) << growth;
    EXPECT_NE(m.status().message().find("pole_grading.growth"), std::string::npos);
  }
  for (double jitter : {-0.1, 1.5, std::nan("")}) {
    SphereMeshOptions o = graded_options(0.1e-6, 500);
    o.pole_grading.ring_jitter = jitter;
    const StatusOr<TetMesh> m = make_sphere_mesh(o);
    ASSERT_FALSE(m.ok()) << jitter;
    EXPECT_NE(m.status().message().find("pole_grading.ring_jitter"), std::string::npos);
  }
}

}  // namespace
}  // namespace cellflow::mesh
