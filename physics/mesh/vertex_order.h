// Vertex and tetrahedron order of a generated mesh for memory locality:
// TetGen numbers the input surface points first and the Steiner points in
// insertion order, so the neighbours of a vertex are spread over the whole
// index range. Every pass over the mesh (the K product, the assembly, the
// elastic forces, the immersed-boundary stencils) then reads scattered
// memory, and a contiguous vertex range shares vertices with every other
// range: a thread of the linear solve reads p on nearly the whole mesh.
#pragma once

#include <cstdint>
#include <vector>

#include "physics/mesh/tet_mesh.h"

namespace cellflow::mesh {

// The reverse Cuthill-McKee order of the vertex graph (two vertices adjacent
// when they share a tet): new_index[old] for every vertex. It keeps a vertex's
// neighbours within the graph's bandwidth of it, and a contiguous range of it
// is a slab of level sets whose boundary with the next range is one level.
std::vector<std::int32_t> locality_vertex_order(const TetMesh& mesh);

// Renumbers the vertices by locality_vertex_order and sorts the tets by their
// smallest new vertex index (stable: the order within a tet and the regions
// follow). Positions, tets, regions and the surface flags move together; the
// geometry is unchanged. Not for quadratic meshes (call it before their
// mid-edge nodes are added).
void order_for_locality(TetMesh& mesh);

}  // namespace cellflow::mesh
