// Quadratic (10-node) tetrahedra from a linear mesh: one node at the middle
// of every edge, the corner tets kept. Node order of a tet10 is VTK's
// (VTK_QUADRATIC_TETRA): corners 0-3 (those of the linear tet), then the
// mid-edge nodes of the edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
// Gmsh's tet10 (type 11) has the last two swapped: (2,3), (1,3).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "physics/mesh/tet_mesh.h"

namespace cellflow::mesh {

// Corner pairs of the mid-edge nodes 4..9 of a tet10 (VTK order).
inline constexpr int kQuadraticTetEdges[6][2] = {{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}};

// Where the mid-edge nodes of boundary edges go.
struct MidEdgeProjection {
  // Unset: the edge's midpoint (straight edges, e.g. a mesh file). Set: the
  // midpoint moved radially about this centre to the mean distance of the
  // edge's two ends from it, so that the quadratic surface follows a sphere
  // through its vertices (the generated cell).
  std::optional<std::array<double, 3>> sphere_centre_m;
};

// Appends a node per edge of mesh.tets to positions_m and on_surface (1 for
// edges of boundary faces, faces of exactly one tet) and fills
// mesh.quadratic_tets. The linear tets, their vertices and their order are
// unchanged. A mesh that already has quadratic_tets is left as it is.
void add_mid_edge_nodes(TetMesh& mesh, const MidEdgeProjection& projection = {});

// Each boundary triangle (3 corner vertices of a quadratic mesh, e.g.
// contact::boundary_triangles of mesh.tets) split at its mid-edge nodes into
// four triangles of the same orientation: (a, ab, ca), (ab, b, bc),
// (ca, bc, c), (ab, bc, ca). The six-node triangle as flat sub-triangles.
// Empty if an edge of a triangle is not an edge of mesh.quadratic_tets.
std::vector<std::int32_t> split_at_mid_edge_nodes(const TetMesh& mesh,
                                                  std::span<const std::int32_t> triangles);

}  // namespace cellflow::mesh
