// Pole-graded sphere surfaces (graded_sphere_surface.h). A geodesic sphere
// cannot be graded by moving its vertices: its topology fixes about 6 k
// vertices on the k-th ring around a pole, while a spacing that grows
// linearly with the distance from the pole needs about 2 pi / growth on every
// ring, so a mapped geodesic mesh stretches its triangles along the rings by
// the ring number times the growth. Rings built for the sizing keep every
// triangle near equilateral.
#include "physics/mesh/graded_sphere_surface.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace cellflow::mesh {
namespace {

// Vertex index range of one ring and the azimuth of its first vertex.
struct Ring {
  int first = 0;
  int count = 0;
};

void orient_outward(const std::vector<double>& p, std::array<int, 3>& tri) {
  const double* a = &p[3 * static_cast<std::size_t>(tri[0])];
  const double* b = &p[3 * static_cast<std::size_t>(tri[1])];
  const double* c = &p[3 * static_cast<std::size_t>(tri[2])];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  // The sphere is convex about the origin: outward normals point away from it.
  if (n[0] * (a[0] + b[0] + c[0]) + n[1] * (a[1] + b[1] + c[1]) + n[2] * (a[2] + b[2] + c[2]) < 0.0) {
    std::swap(tri[1], tri[2]);
  }
}

double distance2(const std::vector<double>& p, int i, int j) {
  double d2 = 0.0;
  for (int d = 0; d < 3; ++d) {
    const double e = p[3 * static_cast<std::size_t>(i) + d] - p[3 * static_cast<std::size_t>(j) + d];
    d2 += e * e;
  }
  return d2;
}

}  // namespace

SphereSurface make_pole_graded_sphere_surface(double radius, double pole_spacing, double bulk_spacing,
                                              double growth) {
  const double half_arc = M_PI * radius;  // pole to pole along a meridian
  auto spacing = [&](double s) {
    const double from_pole = std::min(s, half_arc - s);
    return std::min(bulk_spacing, pole_spacing + growth * from_pole);
  };
  // t(s) = integral_0^s ds' / h(s'), tabulated (midpoint rule) and inverted.
  constexpr int kTable = 20000;
  std::vector<double> t(kTable + 1, 0.0);
  const double ds = half_arc / kTable;
  for (int i = 0; i < kTable; ++i) t[i + 1] = t[i] + ds / spacing((i + 0.5) * ds);
  // Ring distance sqrt(3)/2 h: the height of an equilateral triangle of side h.
  const int intervals = std::max(2, static_cast<int>(std::lround(t[kTable] / (0.5 * std::sqrt(3.0)))));
  std::vector<double> ring_arc(static_cast<std::size_t>(intervals) + 1, 0.0);
  for (int k = 1; k < intervals; ++k) {
    const double wanted = t[kTable] * k / intervals;
    const auto it = std::lower_bound(t.begin(), t.end(), wanted);
    const int i = static_cast<int>(it - t.begin());  // t[i - 1] < wanted <= t[i], i >= 1
    const double fraction = (wanted - t[i - 1]) / (t[i] - t[i - 1]);
    ring_arc[k] = (i - 1 + fraction) * ds;
  }
  ring_arc[intervals] = half_arc;

  SphereSurface surface;
  std::vector<Ring> rings;
  double offset = 0.0;
  for (int k = 0; k <= intervals; ++k) {
    const double polar = ring_arc[k] / radius;
    const double ring_radius = radius * std::sin(polar);
    const double z = radius * std::cos(polar);
    Ring ring{static_cast<int>(surface.points.size() / 3), 1};
    if (k == 0 || k == intervals) {
      surface.points.insert(surface.points.end(), {0.0, 0.0, k == 0 ? radius : -radius});
    } else {
      ring.count =
          std::max(3, static_cast<int>(std::lround(2.0 * M_PI * ring_radius / spacing(ring_arc[k]))));
      // Half a spacing of this ring past the previous ring's start: staggered
      // rings give near-equilateral triangles between them.
      offset += M_PI / ring.count;
      for (int j = 0; j < ring.count; ++j) {
        const double azimuth = offset + 2.0 * M_PI * j / ring.count;
        surface.points.insert(surface.points.end(),
                              {ring_radius * std::cos(azimuth), ring_radius * std::sin(azimuth), z});
      }
    }
    rings.push_back(ring);
  }
  // Join consecutive rings: walk both by azimuth and close each triangle on
  // the shorter of the two candidate diagonals (a pole is a ring of one).
  for (std::size_t k = 0; k + 1 < rings.size(); ++k) {
    const Ring a = rings[k], b = rings[k + 1];
    auto at_a = [&](int i) { return a.first + i % a.count; };
    auto at_b = [&](int j) { return b.first + j % b.count; };
    // Start on b at the vertex nearest to a's first vertex.
    int j0 = 0;
    for (int j = 1; j < b.count; ++j) {
      if (distance2(surface.points, at_a(0), at_b(j)) < distance2(surface.points, at_a(0), at_b(j0))) j0 = j;
    }
    int i = 0, j = 0;
    const int steps_a = a.count == 1 ? 0 : a.count;
    const int steps_b = b.count == 1 ? 0 : b.count;
    while (i < steps_a || j < steps_b) {
      const int ai = at_a(i), bj = at_b(j0 + j);
      bool advance_a;
      if (i >= steps_a) {
        advance_a = false;
      } else if (j >= steps_b) {
        advance_a = true;
      } else {
        advance_a =
            distance2(surface.points, at_a(i + 1), bj) <= distance2(surface.points, ai, at_b(j0 + j + 1));
      }
      std::array<int, 3> tri =
          advance_a ? std::array<int, 3>{ai, at_a(i + 1), bj} : std::array<int, 3>{ai, at_b(j0 + j + 1), bj};
      orient_outward(surface.points, tri);
      surface.triangles.push_back(tri);
      (advance_a ? i : j) += 1;
    }
  }
  return surface;
}

}  // namespace cellflow::mesh
