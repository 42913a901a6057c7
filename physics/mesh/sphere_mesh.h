// Spherical tetrahedral meshes from a real mesher (TetGen), Gmsh .msh v4 ASCII
// import, and a mesh-quality report.
#pragma once

#include <string>

#include "physics/core/status.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::mesh {

struct SphereMeshOptions {
  double radius_m = 0.0;          // R > 0
  int target_vertex_count = 3000; // about; 200 ... 20000
  double nucleus_radius_m = 0.0;  // > 0: concentric nucleus region (tets marked Region::kNucleus)
  double max_radius_edge_ratio = 1.5;  // TetGen quality bound (-q)
  double min_dihedral_deg = 10.0;      // TetGen quality bound (-q/..)
};

// Deterministic: the same options give the same mesh.
StatusOr<TetMesh> make_sphere_mesh(const SphereMeshOptions& options);

// Gmsh MSH 4.1 ASCII: $Nodes and $Elements (4-node tetrahedra, type 4). A
// physical group named "nucleus" (or physical tag 2) marks nucleus tets.
// Coordinates are taken in metres times `length_scale_m` (1 = file in metres).
// Missing/unreadable file -> kNotFound/kInvalidArgument; inverted or degenerate
// tetrahedra -> kFailedPrecondition naming the element.
StatusOr<TetMesh> read_gmsh_msh(const std::string& path, double length_scale_m = 1.0);
Status write_gmsh_msh(const TetMesh& mesh, const std::string& path);

struct MeshQuality {
  std::size_t num_vertices = 0, num_tets = 0, num_surface_vertices = 0;
  double min_dihedral_deg = 0.0;
  double max_dihedral_deg = 0.0;
  double max_radius_edge_ratio = 0.0;  // circumradius / shortest edge, worst tet
  double volume_m3 = 0.0;
  double min_tet_volume_m3 = 0.0;
  double mean_edge_length_m = 0.0;
};
MeshQuality mesh_quality(const TetMesh& mesh);

}  // namespace cellflow::mesh
