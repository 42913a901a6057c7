// Small geometric helpers on TetMesh shared by the mesher, the importer, the
// quality report and the observables: signed tetrahedron volume in the
// orientation convention of tet_mesh.h and boundary detection.
#pragma once

#include <cstdint>

#include "physics/mesh/tet_mesh.h"

namespace cellflow::mesh {

// 6 V = det[x1 - x4, x2 - x4, x3 - x4], positive for the reference orientation
// of tet_mesh.h (paper eq. 11-12, vertex 4 the local origin).
inline double tet_signed_volume6(const double* positions_m, const std::int32_t* tet) {
  const double* x1 = positions_m + 3 * tet[0];
  const double* x2 = positions_m + 3 * tet[1];
  const double* x3 = positions_m + 3 * tet[2];
  const double* x4 = positions_m + 3 * tet[3];
  const double a[3] = {x1[0] - x4[0], x1[1] - x4[1], x1[2] - x4[2]};
  const double b[3] = {x2[0] - x4[0], x2[1] - x4[1], x2[2] - x4[2]};
  const double c[3] = {x3[0] - x4[0], x3[1] - x4[1], x3[2] - x4[2]};
  // det[a, b, c] = a . (b x c)
  return a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
         a[2] * (b[0] * c[1] - b[1] * c[0]);
}

// V = det[x1 - x4, x2 - x4, x3 - x4] / 6
inline double tet_signed_volume(const double* positions_m, const std::int32_t* tet) {
  return tet_signed_volume6(positions_m, tet) / 6.0;
}

// Smallest and largest of the six dihedral angles of a tetrahedron, degrees.
struct DihedralRange {
  double min_deg = 0.0;
  double max_deg = 0.0;
};
DihedralRange tet_dihedral_range(const double* positions_m, const std::int32_t* tet);

// Circumradius over shortest edge (sqrt(6)/4 = 0.612 for the regular tet).
double tet_radius_edge_ratio(const double* positions_m, const std::int32_t* tet);

// Sets mesh.on_surface: 1 for every vertex of a triangle that belongs to
// exactly one tetrahedron (the outer boundary; internal region interfaces such
// as the nucleus surface are shared by two tets and stay 0).
void mark_surface_vertices(TetMesh& mesh);

}  // namespace cellflow::mesh
