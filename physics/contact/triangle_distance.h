// Distance from a fixed point q (the probe centre) to a triangle p0 p1 p2 of
// the cell's surface, with its first and second derivatives with respect to
// the nine vertex coordinates: what a contact that acts on the closest point
// of each surface triangle needs for its force and its consistent tangent.
//
// The distance to a convex set is C1 away from the set: the closest point
// moves continuously from the face to an edge to a vertex as q slides, and
// the gradient d d / d p_i = -b_i n (b the barycentric coordinates of the
// closest point x, n = (q - x) / |q - x|) is continuous; the Hessian jumps
// between the seven regions (face, three edges, three vertices), where the
// distance is the distance to a plane, a line or a point.
#pragma once

#include <array>

namespace cellflow::contact {

enum class ClosestFeature { kFace, kEdge01, kEdge12, kEdge20, kVertex0, kVertex1, kVertex2 };

struct TriangleDistance {
  double distance_m = 0.0;
  std::array<double, 3> barycentric{};  // of the closest point x, summing to 1
  std::array<double, 3> normal{};       // (q - x) / |q - x|; zero if q lies on the triangle
  ClosestFeature feature = ClosestFeature::kFace;
};

// Closest point of the triangle to q (Ericson, Real-Time Collision Detection,
// 5.1.5, by Voronoi regions). p = 9 coordinates p0 p1 p2.
TriangleDistance triangle_distance(const double* q, const double* p);

// d^2 distance / dp dp (9x9, row-major, index 3 i + a for vertex i,
// component a) in the region of `at`; exact within the region. Requires
// at.distance_m > 0.
void triangle_distance_hessian(const double* q, const double* p, const TriangleDistance& at, double* hessian);

}  // namespace cellflow::contact
