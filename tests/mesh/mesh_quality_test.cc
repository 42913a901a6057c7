// mesh_quality against closed-form values of single tetrahedra.
#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_geometry.h"

namespace cellflow::mesh {
namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

TetMesh single_tet(const double (&p)[4][3]) {
  TetMesh mesh;
  for (const auto& x : p) mesh.positions_m.insert(mesh.positions_m.end(), x, x + 3);
  mesh.tets = {0, 1, 2, 3};
  if (tet_signed_volume(mesh.positions_m.data(), mesh.tets.data()) < 0) std::swap(mesh.tets[0], mesh.tets[1]);
  mesh.tet_region = {Region::kCytoplasm};
  mark_surface_vertices(mesh);
  return mesh;
}

TEST(MeshQualityTest, RegularTetrahedron) {
  const double a = 2e-6;  // edge, metres
  // Regular tet: alternate corners of a cube of side a / sqrt(2).
  const double s = a / std::sqrt(2.0);
  const TetMesh mesh = single_tet({{0, 0, 0}, {s, s, 0}, {s, 0, s}, {0, s, s}});
  const MeshQuality q = mesh_quality(mesh);
  EXPECT_EQ(q.num_vertices, 4u);
  EXPECT_EQ(q.num_tets, 1u);
  EXPECT_EQ(q.num_surface_vertices, 4u);
  // Dihedral angle acos(1/3) = 70.53 deg at every edge.
  EXPECT_NEAR(q.min_dihedral_deg, std::acos(1.0 / 3.0) * kRadToDeg, 1e-9);
  EXPECT_NEAR(q.max_dihedral_deg, std::acos(1.0 / 3.0) * kRadToDeg, 1e-9);
  // Circumradius / edge = sqrt(6) / 4.
  EXPECT_NEAR(q.max_radius_edge_ratio, std::sqrt(6.0) / 4.0, 1e-12);
  // V = a^3 / (6 sqrt 2)
  EXPECT_NEAR(q.volume_m3 / (a * a * a / (6.0 * std::sqrt(2.0))), 1.0, 1e-12);
  EXPECT_NEAR(q.min_tet_volume_m3 / q.volume_m3, 1.0, 1e-12);
  EXPECT_NEAR(q.mean_edge_length_m / a, 1.0, 1e-12);
}

TEST(MeshQualityTest, CornerTetrahedron) {
  const TetMesh mesh = single_tet({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  const MeshQuality q = mesh_quality(mesh);
  // Right angles at the three edges through the origin, acos(1/sqrt 3) =
  // 54.74 deg at the edges of the slanted face.
  EXPECT_NEAR(q.min_dihedral_deg, std::acos(1.0 / std::sqrt(3.0)) * kRadToDeg, 1e-9);
  EXPECT_NEAR(q.max_dihedral_deg, 90.0, 1e-9);
  // Circumcentre (1/2, 1/2, 1/2): R = sqrt(3)/2, shortest edge 1.
  EXPECT_NEAR(q.max_radius_edge_ratio, std::sqrt(3.0) / 2.0, 1e-12);
  EXPECT_NEAR(q.volume_m3, 1.0 / 6.0, 1e-15);
  EXPECT_NEAR(q.mean_edge_length_m, (3.0 + 3.0 * std::sqrt(2.0)) / 6.0, 1e-12);
}

TEST(MeshQualityTest, SphereMeshTotalsAgreeWithGeometry) {
  SphereMeshOptions options;
  options.radius_m = 1e-5;
  options.target_vertex_count = 1000;
  const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
  ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
  const MeshQuality q = mesh_quality(*mesh);
  EXPECT_EQ(q.num_vertices, mesh->num_vertices());
  EXPECT_EQ(q.num_tets, mesh->num_tets());
  EXPECT_GT(q.min_tet_volume_m3, 0.0);
  EXPECT_LT(q.min_tet_volume_m3, q.volume_m3 / static_cast<double>(q.num_tets));
  EXPECT_GT(q.min_dihedral_deg, options.min_dihedral_deg);
  EXPECT_LT(q.max_dihedral_deg, 180.0);
  // Mean edge of a uniform mesh of N vertices in a ball: the (V/N)^(1/3) scale
  // times a factor of order one (1.0 to 1.6 for tet meshes).
  const double scale = std::cbrt(q.volume_m3 / static_cast<double>(q.num_vertices));
  EXPECT_GT(q.mean_edge_length_m / scale, 1.0);
  EXPECT_LT(q.mean_edge_length_m / scale, 1.6);
}

}  // namespace
}  // namespace cellflow::mesh
