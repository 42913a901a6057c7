// Vertex and tetrahedron order of a generated mesh for memory locality:
// TetGen numbers the input surface points first and the Steiner points in
// insertion order, so the neighbours of a vertex are spread over the whole
// index range. Every pass over the mesh (the K product, the assembly, the
// elastic forces, the immersed-boundary stencils) then reads scattered
// memory, and a contiguous vertex range shares vertices with every other
// range: a thread of the linear solve reads p on nearly the whole mesh.
#pragma once

#include "physics/mesh/tet_mesh.h"

namespace cellflow::mesh {

// Renumbers the vertices in the reverse Cuthill-McKee order of the vertex
// graph (two vertices adjacent when they share a tet), which keeps a vertex's
// neighbours within the graph's bandwidth of it and makes a contiguous vertex
// range a slab of level sets, and sorts the tets by their smallest new vertex
// index (stable; the order within a tet and the regions follow). Positions,
// tets, regions and the surface flags move together; the geometry is
// unchanged. Not for quadratic meshes (call it before their mid-edge nodes
// are added).
void order_for_locality(TetMesh& mesh);

}  // namespace cellflow::mesh
