// Shape observables of a deformed cell: Taylor deformation from the inertia
// tensor (paper eq. 13-16), semi-axes, inclination, net strain (paper eq. 18),
// volume.
#pragma once

#include <array>
#include <cstddef>

#include "physics/mesh/tet_mesh.h"

namespace cellflow::observables {

struct Shape {
  double taylor_deformation = 0.0;      // D = (a3 - a1) / (a3 + a1)   (paper eq. 13)
  std::array<double, 3> semi_axes_m{};  // a1 <= a2 <= a3 of the equivalent ellipsoid
  std::array<double, 3> major_axis{};   // unit vector along a3
  double inclination_rad = 0.0;         // angle of the major axis in the x-y plane from +x, in (-pi/2, pi/2]
  double volume_m3 = 0.0;               // current volume, sum of signed tet volumes
  std::array<double, 3> centroid_m{};   // volume-weighted centre
};

// positions_m: 3 per vertex of `mesh`, the current configuration.
// Inertia tensor about the centroid from tet volumes and centroids as in the
// paper (eq. 15, tets as point masses), semi-axes from eq. 16 read as a_i^2
// (see shape.cc). major_axis is signed so that its first nonzero component is
// positive. A mesh with non-positive total volume gives only volume_m3.
Shape measure_shape(const mesh::TetMesh& mesh, const double* positions_m);

// Net strain (d_max - d_ref) / d_ref with d_max the largest vertex-vertex
// distance (paper eq. 18), d_ref = 2 R. Uses surface vertices only (the
// largest distance is always between two of them); all vertices when
// mesh.on_surface is empty. Exact (branch and bound, no sampling).
// reference_diameter_m <= 0 gives NaN.
double net_strain(const mesh::TetMesh& mesh, const double* positions_m, double reference_diameter_m);

}  // namespace cellflow::observables
