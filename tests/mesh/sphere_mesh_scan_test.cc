// Long: sphere meshing across the whole allowed range of vertex counts, with
// and without a nucleus. Every mesh within 15 % of its vertex target, all
// tets positive, every dihedral angle above the requested bound.
#include <gtest/gtest.h>

#include <cmath>

#include "physics/mesh/sphere_mesh.h"

namespace cellflow::mesh {
namespace {

TEST(SphereMeshScanTest, CountAndQualityAcrossRange) {
  for (double nucleus_fraction : {0.0, 0.3, 0.5, 0.7}) {
    for (int target = 200; target <= 20000; target = static_cast<int>(target * 1.37) + 1) {
      SCOPED_TRACE(::testing::Message() << "target " << target << ", nucleus " << nucleus_fraction << " R");
      SphereMeshOptions options;
      options.radius_m = 7e-6;
      options.target_vertex_count = target;
      options.nucleus_radius_m = nucleus_fraction * options.radius_m;
      const StatusOr<TetMesh> mesh = make_sphere_mesh(options);
      ASSERT_TRUE(mesh.ok()) << mesh.status().to_string();
      EXPECT_NEAR(static_cast<double>(mesh->num_vertices()), target, 0.15 * target);
      const MeshQuality q = mesh_quality(*mesh);
      EXPECT_GT(q.min_tet_volume_m3, 0.0);
      EXPECT_GT(q.min_dihedral_deg, options.min_dihedral_deg);
    }
  }
}

}  // namespace
}  // namespace cellflow::mesh
