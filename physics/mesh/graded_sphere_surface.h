// Sphere surface triangulations for the TetGen sphere mesher: rings of
// vertices about the z axis whose spacing grows from the poles, where the
// contact scenes' plates and probe touch the cell, to the bulk spacing.
#pragma once

#include <array>
#include <vector>

namespace cellflow::mesh {

struct SphereSurface {
  std::vector<double> points;  // 3 per vertex, every vertex on the sphere
  std::vector<std::array<int, 3>>
      triangles;  // indices into points, outward (counter-clockwise seen from outside)
};

// A closed triangulation of the sphere of `radius` centred at the origin,
// with a vertex at both poles (0, 0, +-radius). The target edge length at arc
// distance s from the nearer pole is h(s) = min(bulk_spacing, pole_spacing +
// growth s): rings of vertices at polar arc positions s_k with
// integral ds / h = k (sqrt(3)/2)-spaced (equilateral triangles), each ring
// holding round(2 pi r_k / h(s_k)) vertices (r_k its radius), staggered by
// half a spacing from the ring before, and consecutive rings joined by the
// shorter diagonal. Deterministic.
// ring_jitter > 0 then moves each ring vertex along its meridian, on the
// sphere, by ring_jitter (u - 1/2) times the local ring distance, u =
// |azimuth| / pi in [0, 1] (half that on the first ring about each pole):
// the vertices of a ring no longer share one height, so a plate or a probe
// takes them into contact one by one instead of a whole ring at once; Lawson
// flips then take the triangles of the rings to the convex hull of the moved
// points (on a sphere, the Delaunay triangulation: the best-shaped triangles
// of those points).
// Requires 0 < pole_spacing <= bulk_spacing <= radius, growth in (0, 1] and
// ring_jitter in [0, 1]; the caller validates (make_sphere_mesh).
SphereSurface make_pole_graded_sphere_surface(double radius, double pole_spacing, double bulk_spacing,
                                              double growth, double ring_jitter);

}  // namespace cellflow::mesh
