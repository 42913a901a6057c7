// Sphere meshing with TetGen: size, geometry, orientation, quality,
// determinism, nucleus region and option validation.
#include "physics/mesh/sphere_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <limits>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "physics/mesh/tet_geometry.h"

namespace cellflow::mesh {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kCellRadius = 8e-6;  // a typical cell, SI metres

double ball_volume(double r) {
  return 4.0 / 3.0 * kPi * r * r * r;
}

// Volume enclosed by the boundary triangles (faces of exactly one tet),
// oriented outward from their tet: sum over faces of x0 . (x1 x x2) / 6.
double boundary_enclosed_volume(const TetMesh& mesh) {
  std::vector<std::pair<std::array<std::int32_t, 3>, std::array<std::int32_t, 3>>> faces;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const std::int32_t* v = &mesh.tets[4 * t];
    // Faces of a positive tet (det[x1-x4, x2-x4, x3-x4] > 0) with outward
    // orientation (right-hand rule).
    const std::array<std::array<std::int32_t, 3>, 4> oriented = {
        {{v[0], v[1], v[2]}, {v[1], v[3], v[2]}, {v[0], v[2], v[3]}, {v[0], v[3], v[1]}}};
    for (const auto& f : oriented) {
      auto key = f;
      std::sort(key.begin(), key.end());
      faces.emplace_back(key, f);
    }
  }
  std::sort(faces.begin(), faces.end());
  double volume = 0.0;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].first == faces[i].first) ++j;
    if (j - i == 1) {
      const auto& f = faces[i].second;
      const double* a = &mesh.positions_m[3 * static_cast<std::size_t>(f[0])];
      const double* b = &mesh.positions_m[3 * static_cast<std::size_t>(f[1])];
      const double* c = &mesh.positions_m[3 * static_cast<std::size_t>(f[2])];
      volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
                 a[2] * (b[0] * c[1] - b[1] * c[0])) /
                6.0;
    }
    i = j;
  }
  return volume;
}

struct EdgeLengths {
  double surface = 0.0;   // mean over edges with both ends on the surface
  double interior = 0.0;  // mean over edges with both ends inside
};
EdgeLengths mean_edge_lengths(const TetMesh& mesh) {
  std::vector<std::pair<std::int32_t, std::int32_t>> edges;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = a + 1; b < 4; ++b) {
        const std::int32_t u = mesh.tets[4 * t + a];
        const std::int32_t w = mesh.tets[4 * t + b];
        edges.emplace_back(std::min(u, w), std::max(u, w));
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  double sum[2] = {0, 0};
  int count[2] = {0, 0};
  for (const auto& [u, w] : edges) {
    const bool su = mesh.on_surface[static_cast<std::size_t>(u)] != 0;
    const bool sw = mesh.on_surface[static_cast<std::size_t>(w)] != 0;
    if (su != sw) continue;
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double d = mesh.positions_m[3 * static_cast<std::size_t>(u) + k] -
                       mesh.positions_m[3 * static_cast<std::size_t>(w) + k];
      d2 += d * d;
    }
    sum[su ? 0 : 1] += std::sqrt(d2);
    ++count[su ? 0 : 1];
  }
  return {sum[0] / count[0], sum[1] / count[1]};
}

struct SizeCase {
  int target;
  double volume_tolerance;  // relative, against 4/3 pi R^3 (inscribed polyhedron)
};

void PrintTo(const SizeCase& c, std::ostream* os) {
  *os << c.target << " vertices";
}

class SphereMeshSizeTest : public ::testing::TestWithParam<SizeCase> {};

TEST_P(SphereMeshSizeTest, CountGeometryOrientationQuality) {
  const SizeCase c = GetParam();
  SphereMeshOptions options;
  options.radius_m = kCellRadius;
  options.target_vertex_count = c.target;
  const StatusOr<TetMesh> result = make_sphere_mesh(options);
  ASSERT_TRUE(result.ok()) << result.status().to_string();
  const TetMesh& mesh = *result;

  // Vertex count within 15 % of the target.
  EXPECT_NEAR(static_cast<double>(mesh.num_vertices()), c.target, 0.15 * c.target);
  ASSERT_EQ(mesh.tets.size(), 4 * mesh.num_tets());
  ASSERT_EQ(mesh.tet_region.size(), mesh.num_tets());
  ASSERT_EQ(mesh.on_surface.size(), mesh.num_vertices());
  for (Region r : mesh.tet_region) EXPECT_EQ(r, Region::kCytoplasm);

  // Every tet positively oriented (tet_mesh.h convention).
  double min_volume = 1e300;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    min_volume = std::min(min_volume, tet_signed_volume(mesh.positions_m.data(), &mesh.tets[4 * t]));
  }
  EXPECT_GT(min_volume, 0.0);

  // Surface vertices on the sphere within 1e-9 relative; interior ones inside.
  std::size_t surface_count = 0;
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    const double r = std::sqrt(mesh.positions_m[3 * v] * mesh.positions_m[3 * v] +
                               mesh.positions_m[3 * v + 1] * mesh.positions_m[3 * v + 1] +
                               mesh.positions_m[3 * v + 2] * mesh.positions_m[3 * v + 2]);
    if (mesh.on_surface[v]) {
      ++surface_count;
      EXPECT_NEAR(r / kCellRadius, 1.0, 1e-9) << "surface vertex " << v;
    } else {
      EXPECT_LT(r, kCellRadius * (1.0 - 1e-9)) << "interior vertex " << v;
    }
  }
  EXPECT_GT(surface_count, 0u);

  // Volume: the tets fill the surface polyhedron exactly (1e-9), and that
  // inscribed polyhedron is within the stated tolerance of the ball.
  const MeshQuality q = mesh_quality(mesh);
  EXPECT_NEAR(q.volume_m3 / boundary_enclosed_volume(mesh), 1.0, 1e-9);
  EXPECT_NEAR(q.volume_m3 / ball_volume(kCellRadius), 1.0, c.volume_tolerance);
  EXPECT_LT(q.volume_m3, ball_volume(kCellRadius));

  // Quality bounds requested from TetGen.
  EXPECT_GT(q.min_dihedral_deg, options.min_dihedral_deg);
  EXPECT_LE(q.max_radius_edge_ratio, options.max_radius_edge_ratio);
  EXPECT_EQ(q.num_surface_vertices, surface_count);

  // Uniform in size: mean interior edge within 20 % of mean surface edge.
  const EdgeLengths edges = mean_edge_lengths(mesh);
  EXPECT_NEAR(edges.interior / edges.surface, 1.0, 0.20);
}

// Volume tolerances: the inscribed geodesic polyhedron loses about 6 % of the
// ball at 200 vertices (frequency 3), under 1 % at 3000, 0.3 % at 20000.
INSTANTIATE_TEST_SUITE_P(Sizes, SphereMeshSizeTest,
                         ::testing::Values(SizeCase{200, 0.08}, SizeCase{3000, 0.02}, SizeCase{20000, 0.005}),
                         [](const ::testing::TestParamInfo<SizeCase>& param_info) {
                           return "Vertices" + std::to_string(param_info.param.target);
                         });

TEST(SphereMeshTest, CountWithinFifteenPercentAcrossRange) {
  for (int target : {250, 500, 1000, 1700, 5000}) {
    SphereMeshOptions options;
    options.radius_m = kCellRadius;
    options.target_vertex_count = target;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
    EXPECT_NEAR(static_cast<double>(mesh->num_vertices()), target, 0.15 * target) << "target " << target;
  }
}

TEST(SphereMeshTest, Deterministic) {
  SphereMeshOptions options;
  options.radius_m = kCellRadius;
  options.target_vertex_count = 3000;
  const StatusOr<TetMesh> a = make_sphere_mesh(options);
  const StatusOr<TetMesh> b = make_sphere_mesh(options);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->positions_m, b->positions_m);  // bitwise
  EXPECT_EQ(a->tets, b->tets);
  EXPECT_EQ(a->on_surface, b->on_surface);
  EXPECT_EQ(a->tet_region, b->tet_region);
}

TEST(SphereMeshTest, NucleusRegion) {
  SphereMeshOptions options;
  options.radius_m = kCellRadius;
  options.target_vertex_count = 3000;
  options.nucleus_radius_m = 0.5 * kCellRadius;
  const StatusOr<TetMesh> result = make_sphere_mesh(options);
  ASSERT_TRUE(result.ok()) << result.status().to_string();
  const TetMesh& mesh = *result;
  EXPECT_NEAR(static_cast<double>(mesh.num_vertices()), 3000.0, 0.15 * 3000.0);

  double nucleus_volume = 0.0;
  double total_volume = 0.0;
  std::size_t nucleus_tets = 0;
  double max_centroid_radius = 0.0;
  double min_cytoplasm_centroid_radius = 1e300;
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    const std::int32_t* tet = &mesh.tets[4 * t];
    const double v = tet_signed_volume(mesh.positions_m.data(), tet);
    ASSERT_GT(v, 0.0);
    total_volume += v;
    double c[3] = {0, 0, 0};
    for (int k = 0; k < 4; ++k) {
      for (int d = 0; d < 3; ++d) c[d] += 0.25 * mesh.positions_m[3 * static_cast<std::size_t>(tet[k]) + d];
    }
    const double r = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    if (mesh.tet_region[t] == Region::kNucleus) {
      nucleus_volume += v;
      ++nucleus_tets;
      max_centroid_radius = std::max(max_centroid_radius, r);
    } else {
      min_cytoplasm_centroid_radius = std::min(min_cytoplasm_centroid_radius, r);
    }
  }
  EXPECT_GT(nucleus_tets, 0u);
  EXPECT_LT(nucleus_tets, mesh.num_tets());
  // Nucleus volume within 3 % of 4/3 pi Rn^3; every nucleus tet inside Rn,
  // every cytoplasm tet outside the nucleus polyhedron's inner radius.
  EXPECT_NEAR(nucleus_volume / ball_volume(options.nucleus_radius_m), 1.0, 0.03);
  EXPECT_LT(max_centroid_radius, options.nucleus_radius_m);
  EXPECT_GT(min_cytoplasm_centroid_radius, 0.8 * options.nucleus_radius_m);
  EXPECT_NEAR(total_volume / ball_volume(kCellRadius), 1.0, 0.02);

  // The nucleus surface is internal: on_surface marks only the outer sphere.
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    if (!mesh.on_surface[v]) continue;
    const double r = std::sqrt(mesh.positions_m[3 * v] * mesh.positions_m[3 * v] +
                               mesh.positions_m[3 * v + 1] * mesh.positions_m[3 * v + 1] +
                               mesh.positions_m[3 * v + 2] * mesh.positions_m[3 * v + 2]);
    EXPECT_NEAR(r / kCellRadius, 1.0, 1e-9);
  }
  // The interface (vertices of both nucleus and cytoplasm tets) lies on the
  // nucleus sphere: the sliver pass must not move it.
  std::vector<int> region_mask(mesh.num_vertices(), 0);
  for (std::size_t t = 0; t < mesh.num_tets(); ++t) {
    for (int k = 0; k < 4; ++k) {
      region_mask[static_cast<std::size_t>(mesh.tets[4 * t + k])] |=
          mesh.tet_region[t] == Region::kNucleus ? 2 : 1;
    }
  }
  std::size_t interface_count = 0;
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    if (region_mask[v] != 3) continue;
    ++interface_count;
    const double r = std::sqrt(mesh.positions_m[3 * v] * mesh.positions_m[3 * v] +
                               mesh.positions_m[3 * v + 1] * mesh.positions_m[3 * v + 1] +
                               mesh.positions_m[3 * v + 2] * mesh.positions_m[3 * v + 2]);
    EXPECT_NEAR(r / options.nucleus_radius_m, 1.0, 1e-9) << "interface vertex " << v;
  }
  EXPECT_GT(interface_count, 0u);
  const MeshQuality q = mesh_quality(mesh);
  EXPECT_GT(q.min_dihedral_deg, options.min_dihedral_deg);
}

TEST(SphereMeshTest, RejectsInvalidOptionsNamingTheField) {
  struct Case {
    SphereMeshOptions options;
    std::string field;
  };
  auto with = [](double r, int n, double rn) {
    SphereMeshOptions o;
    o.radius_m = r;
    o.target_vertex_count = n;
    o.nucleus_radius_m = rn;
    return o;
  };
  const std::vector<Case> cases = {
      {with(0.0, 3000, 0.0), "radius_m"},
      {with(-1e-6, 3000, 0.0), "radius_m"},
      {with(kCellRadius, 199, 0.0), "target_vertex_count"},
      {with(kCellRadius, 20001, 0.0), "target_vertex_count"},
      {with(kCellRadius, 3000, kCellRadius), "nucleus_radius_m"},
      {with(kCellRadius, 3000, -1e-6), "nucleus_radius_m"},
      {with(kCellRadius, 3000, 2 * kCellRadius), "nucleus_radius_m"},
      // A shell thinner than half a mesh spacing.
      {with(kCellRadius, 3000, 0.99 * kCellRadius), "nucleus_radius_m"},
  };
  for (const Case& c : cases) {
    const StatusOr<TetMesh> mesh = make_sphere_mesh(c.options);
    ASSERT_FALSE(mesh.ok()) << c.field;
    EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(mesh.status().message().find(c.field), std::string::npos) << mesh.status().message();
    // The message states the allowed range.
    EXPECT_TRUE(mesh.status().message().find('(') != std::string::npos ||
                mesh.status().message().find('[') != std::string::npos)
        << mesh.status().message();
  }
}

// Hostile doubles and ints (issue 13): every one an kInvalidArgument naming
// the field and the range, never an assertion or a crash in TetGen (radius
// 1e300 used to abort in TetGen's locate(), 1e-100 to segfault in it).
TEST(SphereMeshTest, HostileRadiiAreRejectedWithTheRange) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double r : {0.0, -0.0, 5e-324, 2.2e-308, 1e-300, 1e-100, 1e-20, 9.99e-8, 1.0001e-2, 1.0, 1e20, 1e300,
                   std::numeric_limits<double>::max(), inf, -inf, nan, -nan, -1e-6, -8e-6}) {
    SphereMeshOptions options;
    options.radius_m = r;
    options.target_vertex_count = 300;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_FALSE(mesh.ok()) << r;
    EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument) << r;
    EXPECT_NE(mesh.status().message().find("radius_m"), std::string::npos) << mesh.status().message();
    EXPECT_NE(mesh.status().message().find("[1e-07, 0.01]"), std::string::npos) << mesh.status().message();
  }
}

TEST(SphereMeshTest, RangeEndsMesh) {
  for (double r : {kMinSphereRadiusM, kMaxSphereRadiusM}) {
    SphereMeshOptions options;
    options.radius_m = r;
    options.target_vertex_count = kMinSphereVertexCount;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_TRUE(mesh.ok()) << r << ": " << mesh.status().to_string();
    double max_r = 0.0;
    for (std::size_t v = 0; v < mesh->num_vertices(); ++v) {
      const double* x = &mesh->positions_m[3 * v];
      max_r = std::max(max_r, std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]));
    }
    EXPECT_NEAR(max_r / r, 1.0, 1e-12);
    for (std::size_t t = 0; t < mesh->num_tets(); ++t) {
      EXPECT_GT(tet_signed_volume(mesh->positions_m.data(), &mesh->tets[4 * t]), 0.0);
    }
  }
}

// Meshing runs on a sphere normalised by a power of two: radii 2^k apart give
// meshes that are exact power-of-two images of each other.
TEST(SphereMeshTest, MeshIsUnitIndependentUnderPowerOfTwoScaling) {
  SphereMeshOptions a;
  a.radius_m = 5e-6;
  a.target_vertex_count = 400;
  a.nucleus_radius_m = 2.5e-6;
  SphereMeshOptions b = a;
  b.radius_m = a.radius_m * 1024.0;
  b.nucleus_radius_m = a.nucleus_radius_m * 1024.0;
  const StatusOr<TetMesh> ma = make_sphere_mesh(a);
  const StatusOr<TetMesh> mb = make_sphere_mesh(b);
  ASSERT_TRUE(ma.ok() && mb.ok());
  ASSERT_EQ(ma->positions_m.size(), mb->positions_m.size());
  for (std::size_t i = 0; i < ma->positions_m.size(); ++i) {
    ASSERT_EQ(ma->positions_m[i] * 1024.0, mb->positions_m[i]) << i;
  }
  EXPECT_EQ(ma->tets, mb->tets);
  EXPECT_EQ(ma->tet_region, mb->tet_region);
}

TEST(SphereMeshTest, HostileVertexCountsAreRejectedWithTheRange) {
  for (int n : {INT_MIN, -1, 0, 1, kMinSphereVertexCount - 1, kMaxSphereVertexCount + 1, INT_MAX}) {
    SphereMeshOptions options;
    options.radius_m = kCellRadius;
    options.target_vertex_count = n;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_FALSE(mesh.ok()) << n;
    EXPECT_EQ(mesh.status().code(), StatusCode::kInvalidArgument) << n;
    EXPECT_NE(mesh.status().message().find("target_vertex_count"), std::string::npos)
        << mesh.status().message();
    EXPECT_NE(mesh.status().message().find("[200, 20000]"), std::string::npos) << mesh.status().message();
  }
}

TEST(SphereMeshTest, HostileNucleusAndQualityBoundsAreRejected) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double rn : {5e-324, 1e-300, -5e-324, 1e300, inf, -inf, nan}) {
    SphereMeshOptions options;
    options.radius_m = kCellRadius;
    options.target_vertex_count = 300;
    options.nucleus_radius_m = rn;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_FALSE(mesh.ok()) << rn;
    EXPECT_NE(mesh.status().message().find("nucleus_radius_m"), std::string::npos) << mesh.status().message();
  }
  for (double v : {0.0, -0.0, -1.0, 5e-324, 1.0999, 10.0001, 1e300, inf, -inf, nan}) {
    SphereMeshOptions options;
    options.radius_m = kCellRadius;
    options.target_vertex_count = 300;
    options.max_radius_edge_ratio = v;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_FALSE(mesh.ok()) << v;
    EXPECT_NE(mesh.status().message().find("max_radius_edge_ratio"), std::string::npos);
  }
  for (double v : {-5e-324, -1.0, 18.0001, 1e300, inf, -inf, nan}) {
    SphereMeshOptions options;
    options.radius_m = kCellRadius;
    options.target_vertex_count = 300;
    options.min_dihedral_deg = v;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    ASSERT_FALSE(mesh.ok()) << v;
    EXPECT_NE(mesh.status().message().find("min_dihedral_deg"), std::string::npos);
  }
  // In range, if odd: -0 is "no nucleus", a denormal dihedral bound is 0 in effect.
  for (auto [rn, dihedral] : {std::pair{-0.0, 10.0}, std::pair{0.0, 5e-324}, std::pair{0.0, 1e-5}}) {
    SphereMeshOptions options;
    options.radius_m = kCellRadius;
    options.target_vertex_count = 300;
    options.nucleus_radius_m = rn;
    options.min_dihedral_deg = dihedral;
    const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
    EXPECT_TRUE(mesh.ok()) << rn << " " << dihedral << ": " << mesh.status().to_string();
  }
}

}  // namespace
}  // namespace cellflow::mesh
