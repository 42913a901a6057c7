// The boundary triangles of a tetrahedral mesh: faces that belong to exactly
// one tetrahedron, oriented with the normal (p1 - p0) x (p2 - p0) pointing
// out of the body (away from the tetrahedron's fourth vertex).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace cellflow::contact {

// 3 vertex indices per boundary triangle. `tets` holds 4 indices per tet,
// positions_m 3 coordinates per vertex (for the orientation).
std::vector<std::int32_t> boundary_triangles(std::span<const std::int32_t> tets, const double* positions_m);

}  // namespace cellflow::contact
