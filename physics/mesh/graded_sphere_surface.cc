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
#include <map>
#include <utility>

namespace cellflow::mesh {
namespace {

// Vertex index range of one ring and the azimuth of its first vertex.
struct Ring {
  int first = 0;
  int count = 0;
};

// ((b - a) x (c - a)) . (q - a): positive when q lies on the side of the
// plane of (a, b, c) that its counter-clockwise normal points to.
double side_of_plane(const std::vector<double>& p, int a, int b, int c, const double* q) {
  const double* pa = &p[3 * static_cast<std::size_t>(a)];
  const double* pb = &p[3 * static_cast<std::size_t>(b)];
  const double* pc = &p[3 * static_cast<std::size_t>(c)];
  const double u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
  const double w[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
  const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  return n[0] * (q[0] - pa[0]) + n[1] * (q[1] - pa[1]) + n[2] * (q[2] - pa[2]);
}

void orient_outward(const std::vector<double>& p, std::array<int, 3>& tri) {
  // The sphere is convex about the origin: outward normals point away from it.
  constexpr double kOrigin[3] = {0.0, 0.0, 0.0};
  if (side_of_plane(p, tri[0], tri[1], tri[2], kOrigin) > 0.0) std::swap(tri[1], tri[2]);
}

double distance2(const std::vector<double>& p, int i, int j) {
  double d2 = 0.0;
  for (int d = 0; d < 3; ++d) {
    const double e = p[3 * static_cast<std::size_t>(i) + d] - p[3 * static_cast<std::size_t>(j) + d];
    d2 += e * e;
  }
  return d2;
}

// Lawson flips until every edge is convex: the triangles of two neighbouring
// faces (a, b, c) and (b, a, d) fold outwards at their edge a-b when d lies
// outside the plane of (a, b, c); the flip to c-d makes it convex. For points
// on a sphere the convex hull is the spherical Delaunay triangulation, so the
// moved ring vertices get the best-shaped triangles their positions allow.
// A flip that would duplicate an edge is skipped; the tolerance keeps the
// cocircular quads of unmoved rings as they are.
void flip_to_convex_hull(SphereSurface& surface, double radius) {
  const double tolerance = 1e-12 * radius * radius * radius;
  auto key = [](int a, int b) { return std::make_pair(std::min(a, b), std::max(a, b)); };
  for (bool flipped = true; flipped;) {
    flipped = false;
    std::map<std::pair<int, int>, std::vector<std::size_t>> faces_of_edge;
    for (std::size_t t = 0; t < surface.triangles.size(); ++t) {
      const auto& tri = surface.triangles[t];
      for (int e = 0; e < 3; ++e) faces_of_edge[key(tri[e], tri[(e + 1) % 3])].push_back(t);
    }
    std::vector<char> touched(surface.triangles.size(), 0);
    for (const auto& [edge, faces] : faces_of_edge) {
      if (faces.size() != 2 || touched[faces[0]] || touched[faces[1]]) continue;
      auto& t1 = surface.triangles[faces[0]];
      auto& t2 = surface.triangles[faces[1]];
      // Rotate t1 to (a, b, c) with a-b the edge; t2 is then (b, a, d).
      int r = 0;
      while (key(t1[r], t1[(r + 1) % 3]) != edge) ++r;
      const int a = t1[r], b = t1[(r + 1) % 3], c = t1[(r + 2) % 3];
      int d = t2[0];
      for (int v : t2) {
        if (v != a && v != b) d = v;
      }
      if (faces_of_edge.count(key(c, d)) != 0) continue;
      if (side_of_plane(surface.points, a, b, c, &surface.points[3 * static_cast<std::size_t>(d)]) <=
          tolerance) {
        continue;
      }
      t1 = {a, d, c};
      t2 = {d, b, c};
      touched[faces[0]] = touched[faces[1]] = 1;
      faces_of_edge[key(c, d)];  // no second flip of this pass makes c-d again (std::map: no iterator moves)
      flipped = true;
    }
  }
}

}  // namespace

SphereSurface make_pole_graded_sphere_surface(double radius, double pole_spacing, double bulk_spacing,
                                              double growth, double ring_jitter) {
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
  if (ring_jitter > 0.0) {
    // The polar offset is a triangle wave of the azimuth, one period per
    // turn: the heights of a ring spread evenly over ring_jitter ring
    // distances, neighbours along a ring differ by only 2 / count of it, and
    // no seam (a random offset per vertex, or a spiral's seam, left edges
    // of half the spacing and tets of radius-edge ratio 3.6-4 at the
    // surface). The first ring about each pole moves half as far: a full
    // move puts it within half a ring distance of the pole vertex.
    for (int k = 1; k < intervals; ++k) {
      const double ring_distance = 0.5 * (ring_arc[k + 1] - ring_arc[k - 1]);
      const int from_pole = std::min(k, intervals - k);
      const double amplitude = ring_jitter * std::min(1.0, 0.5 * from_pole);
      const Ring ring = rings[static_cast<std::size_t>(k)];
      for (int j = 0; j < ring.count; ++j) {
        double* x = &surface.points[3 * static_cast<std::size_t>(ring.first + j)];
        const double azimuth = std::atan2(x[1], x[0]);  // (-pi, pi]
        const double wave = std::abs(azimuth) / M_PI;   // [0, 1], 0 and 1 once per turn
        const double polar = (ring_arc[k] + amplitude * (wave - 0.5) * ring_distance) / radius;
        x[0] = radius * std::sin(polar) * std::cos(azimuth);
        x[1] = radius * std::sin(polar) * std::sin(azimuth);
        x[2] = radius * std::cos(polar);
      }
    }
    flip_to_convex_hull(surface, radius);
  }
  return surface;
}

}  // namespace cellflow::mesh
