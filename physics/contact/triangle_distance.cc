#include "physics/contact/triangle_distance.h"

#include <cmath>

namespace cellflow::contact {
namespace {

// Value, gradient and Hessian of a function of the nine vertex coordinates
// (forward-mode second-order automatic differentiation): the Hessians of the
// distances to a plane, a line and a point without hand-written algebra.
struct Jet {
  double v = 0.0;
  double g[9] = {};
  double h[81] = {};
};

Jet constant(double value) {
  Jet j;
  j.v = value;
  return j;
}

Jet variable(double value, int index) {
  Jet j;
  j.v = value;
  j.g[index] = 1.0;
  return j;
}

Jet operator+(const Jet& a, const Jet& b) {
  Jet r;
  r.v = a.v + b.v;
  for (int i = 0; i < 9; ++i) r.g[i] = a.g[i] + b.g[i];
  for (int i = 0; i < 81; ++i) r.h[i] = a.h[i] + b.h[i];
  return r;
}

Jet operator-(const Jet& a, const Jet& b) {
  Jet r;
  r.v = a.v - b.v;
  for (int i = 0; i < 9; ++i) r.g[i] = a.g[i] - b.g[i];
  for (int i = 0; i < 81; ++i) r.h[i] = a.h[i] - b.h[i];
  return r;
}

Jet operator*(const Jet& a, const Jet& b) {
  Jet r;
  r.v = a.v * b.v;
  for (int i = 0; i < 9; ++i) r.g[i] = a.v * b.g[i] + b.v * a.g[i];
  for (int i = 0; i < 9; ++i) {
    for (int k = 0; k < 9; ++k)
      r.h[9 * i + k] = a.v * b.h[9 * i + k] + b.v * a.h[9 * i + k] + a.g[i] * b.g[k] + b.g[i] * a.g[k];
  }
  return r;
}

Jet scaled(const Jet& a, double s) {
  Jet r;
  r.v = s * a.v;
  for (int i = 0; i < 9; ++i) r.g[i] = s * a.g[i];
  for (int i = 0; i < 81; ++i) r.h[i] = s * a.h[i];
  return r;
}

// f(a) for a scalar function with derivatives f0, f1, f2 at a.v (chain rule).
Jet compose(const Jet& a, double f0, double f1, double f2) {
  Jet r;
  r.v = f0;
  for (int i = 0; i < 9; ++i) r.g[i] = f1 * a.g[i];
  for (int i = 0; i < 9; ++i) {
    for (int k = 0; k < 9; ++k) r.h[9 * i + k] = f1 * a.h[9 * i + k] + f2 * a.g[i] * a.g[k];
  }
  return r;
}

Jet sqrt_of(const Jet& a) {
  const double s = std::sqrt(a.v);
  return compose(a, s, 0.5 / s, -0.25 / (s * a.v));
}

Jet inverse_of(const Jet& a) {
  const double i = 1.0 / a.v;
  return compose(a, i, -i * i, 2.0 * i * i * i);
}

using Vec = std::array<Jet, 3>;

Vec sub(const Vec& a, const Vec& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}

Jet dot(const Vec& a, const Vec& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

double dot3(const double* a, const double* b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

}  // namespace

TriangleDistance triangle_distance(const double* q, const double* p) {
  const double* a = p;
  const double* b = p + 3;
  const double* c = p + 6;
  double ab[3], ac[3], ap[3], bp[3], cp[3];
  for (int k = 0; k < 3; ++k) {
    ab[k] = b[k] - a[k];
    ac[k] = c[k] - a[k];
    ap[k] = q[k] - a[k];
    bp[k] = q[k] - b[k];
    cp[k] = q[k] - c[k];
  }
  TriangleDistance out;
  auto finish = [&](double u, double v, double w, ClosestFeature feature) {
    out.barycentric = {u, v, w};
    out.feature = feature;
    double d[3];
    for (int k = 0; k < 3; ++k) d[k] = q[k] - (u * a[k] + v * b[k] + w * c[k]);
    out.distance_m = std::sqrt(dot3(d, d));
    if (out.distance_m > 0.0) {
      for (int k = 0; k < 3; ++k) out.normal[k] = d[k] / out.distance_m;
    }
    return out;
  };
  const double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return finish(1.0, 0.0, 0.0, ClosestFeature::kVertex0);
  const double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return finish(0.0, 1.0, 0.0, ClosestFeature::kVertex1);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double t = d1 / (d1 - d3);
    return finish(1.0 - t, t, 0.0, ClosestFeature::kEdge01);
  }
  const double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return finish(0.0, 0.0, 1.0, ClosestFeature::kVertex2);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double t = d2 / (d2 - d6);
    return finish(1.0 - t, 0.0, t, ClosestFeature::kEdge20);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return finish(0.0, 1.0 - t, t, ClosestFeature::kEdge12);
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return finish(1.0 - v - w, v, w, ClosestFeature::kFace);
}

void triangle_distance_hessian(const double* q, const double* p, const TriangleDistance& at,
                               double* hessian) {
  std::array<Vec, 3> vertex;
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) vertex[i][k] = variable(p[3 * i + k], 3 * i + k);
  }
  const Vec query = {constant(q[0]), constant(q[1]), constant(q[2])};
  Jet distance;
  auto to_point = [&](int i) { return sqrt_of(dot(sub(query, vertex[i]), sub(query, vertex[i]))); };
  // |w|^2 - (w.e)^2 / |e|^2: the squared distance to the line through p_i, p_j
  auto to_line = [&](int i, int j) {
    const Vec w = sub(query, vertex[i]);
    const Vec e = sub(vertex[j], vertex[i]);
    const Jet we = dot(w, e);
    return sqrt_of(dot(w, w) - we * we * inverse_of(dot(e, e)));
  };
  switch (at.feature) {
    case ClosestFeature::kVertex0:
      distance = to_point(0);
      break;
    case ClosestFeature::kVertex1:
      distance = to_point(1);
      break;
    case ClosestFeature::kVertex2:
      distance = to_point(2);
      break;
    case ClosestFeature::kEdge01:
      distance = to_line(0, 1);
      break;
    case ClosestFeature::kEdge12:
      distance = to_line(1, 2);
      break;
    case ClosestFeature::kEdge20:
      distance = to_line(2, 0);
      break;
    case ClosestFeature::kFace: {
      // |(q - p0) . N| / |N|, N = (p1 - p0) x (p2 - p0)
      const Vec normal = cross(sub(vertex[1], vertex[0]), sub(vertex[2], vertex[0]));
      const Jet height = dot(sub(query, vertex[0]), normal) * inverse_of(sqrt_of(dot(normal, normal)));
      distance = height.v < 0.0 ? scaled(height, -1.0) : height;
      break;
    }
  }
  for (int i = 0; i < 81; ++i) hessian[i] = distance.h[i];
}

}  // namespace cellflow::contact
