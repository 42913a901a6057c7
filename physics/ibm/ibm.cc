#include "physics/ibm/ibm.h"

#include <omp.h>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

namespace cellflow::ibm {
namespace {

// Periodic index for any integer.
inline int wrap_index(int i, int n) {
  const int m = i % n;
  return m < 0 ? m + n : m;
}

// Periodic coordinate in [0, n).
[[gnu::always_inline]] inline double wrap_coordinate(double x, int n) {
  if (x >= 0.0 && x < n) return x;  // the common case, without the division
  const double w = x - n * std::floor(x / n);
  return w >= n ? 0.0 : w;  // x slightly below 0 can round up to n
}

template <Kernel K>
constexpr int kWidth = K == Kernel::kPeskin4 ? 4 : (K == Kernel::kPeskin3 ? 3 : 2);

// 1-D weights at coordinate s (nodes at j + 1/2), written with the square root
// shared by the stencil's nodes; outer weights from sum over even nodes = sum
// over odd nodes = 1/2 (peskin4), so the weights sum to 1 to rounding.
template <Kernel K>
[[gnu::always_inline]] inline int weights_1d(double s, double* w) {
  const double t = s - 0.5;  // coordinate in node index units
  if constexpr (K == Kernel::kPeskin4) {
    const double f = std::floor(t);
    const double r = t - f;  // distance to node f, in [0, 1)
    // q = sqrt(1 + 4r - 4r^2); inner phi(r) = (3 - 2r + q)/8, phi(r - 1) = (1 + 2r + q)/8
    const double q = std::sqrt(1.0 + 4.0 * r - 4.0 * r * r);
    w[1] = (3.0 - 2.0 * r + q) * 0.125;
    w[2] = (1.0 + 2.0 * r + q) * 0.125;
    w[0] = 0.5 - w[2];  // phi(r + 1) = (3 - 2r - q)/8
    w[3] = 0.5 - w[1];  // phi(r - 2) = (1 + 2r - q)/8
    return static_cast<int>(f) - 1;
  } else if constexpr (K == Kernel::kPeskin3) {
    const double f = std::floor(t + 0.5);  // nearest node
    const double d = t - f;                // in [-1/2, 1/2)
    // q = sqrt(1 - 3 d^2); phi(d) = (1 + q)/3, phi(d + 1) = (2 - 3d - q)/6, phi(d - 1) = (2 + 3d - q)/6
    const double q = std::sqrt(1.0 - 3.0 * d * d);
    w[0] = (2.0 - 3.0 * d - q) / 6.0;
    w[1] = (1.0 + q) / 3.0;
    w[2] = (2.0 + 3.0 * d - q) / 6.0;
    return static_cast<int>(f) - 1;
  } else {
    const double f = std::floor(t);
    const double r = t - f;
    // phi(r) = 1 - r, phi(r - 1) = r
    w[0] = 1.0 - r;
    w[1] = r;
    return static_cast<int>(f);
  }
}

// Index i + n or i - n for i within one period of [0, n) (no division).
[[gnu::always_inline]] inline int wrap_near(int i, int n) {
  if (i < 0) return i + n < 0 ? wrap_index(i, n) : i + n;
  if (i >= n) return i - n >= n ? wrap_index(i, n) : i - n;
  return i;
}

// The coordinates as the weights see them: x and z wrapped into the box, y
// wrapped (periodic) or clamped (walls). False if one is not finite.
[[gnu::always_inline]] inline bool prepare_coordinates(const Grid& g, double& x, double& y, double& z) {
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) return false;
  x = wrap_coordinate(x, g.nx);
  z = wrap_coordinate(z, g.nz);
  if (g.walls_y) {
    // Far outside, every weight is dropped anyway; the clamp keeps int conversion defined.
    y = std::clamp(y, -4.0, g.ny + 4.0);
  } else {
    y = wrap_coordinate(y, g.ny);
  }
  return true;
}

[[gnu::always_inline]] inline void mark_not_finite(PointStencil& st) {
  st.finite = false;
  st.x_contiguous = false;
  st.y_begin = st.y_end = 0;
}

// The node indices of the stencil with first nodes (fx, fy, fz).
template <Kernel K>
[[gnu::always_inline]] inline void stencil_indices(const Grid& g, int fx, int fy, int fz, PointStencil& st) {
  constexpr int W = kWidth<K>;
  st.finite = true;
  for (int a = 0; a < W; ++a) st.x[a] = wrap_near(fx + a, g.nx);
  st.x_contiguous = fx >= 0 && fx + W <= g.nx;
  if (g.walls_y) {
    // Rows beyond a wall are dropped (identically in interpolation and spreading).
    st.y_begin = std::clamp(-fy, 0, W);
    st.y_end = std::clamp(g.ny - fy, 0, W);
    for (int b = 0; b < W; ++b) st.y[b] = std::clamp(fy + b, 0, g.ny - 1);
  } else {
    st.y_begin = 0;
    st.y_end = W;
    for (int b = 0; b < W; ++b) st.y[b] = wrap_near(fy + b, g.ny);
  }
  for (int c = 0; c < W; ++c) st.z[c] = wrap_near(fz + c, g.nz);
}

// The separable stencil of the point (x, y, z).
template <Kernel K>
[[gnu::always_inline]] inline void make_stencil(const Grid& g, double x, double y, double z,
                                                PointStencil& st) {
  if (!prepare_coordinates(g, x, y, z)) {
    mark_not_finite(st);
    return;
  }
  const int fx = weights_1d<K>(x, st.wx);
  const int fy = weights_1d<K>(y, st.wy);
  const int fz = weights_1d<K>(z, st.wz);
  stencil_indices<K>(g, fx, fy, fz, st);
}

int thread_count(int threads) {
  return threads > 0 ? threads : omp_get_max_threads();
}

// Fewer points than this are not worth a parallel region.
constexpr std::ptrdiff_t kParallelPoints = 256;

// One copy of each loop per instruction set, picked at run time: the default
// build targets baseline x86-64 (SSE2: scalar loads, floor a libm call); with
// AVX2 an x row of 4 nodes is one vector and floor one instruction. No FMA
// (-ffp-contract=off, no "fma" target): every copy gives the same bits.
bool use_avx2() {
#if defined(__x86_64__)
  static const bool avx2 = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return avx2;
#else
  return false;
#endif
}

#if defined(__x86_64__)
#define CELLFLOW_IBM_AVX2 __attribute__((target("avx2")))
#else
#define CELLFLOW_IBM_AVX2
#endif

#if defined(__x86_64__)
// make_stencil<kPeskin4> with x, y, z in the lanes of one vector (one floor,
// one square root); the arithmetic of weights_1d lane by lane, so the same bits.
CELLFLOW_IBM_AVX2 inline void make_stencil4_avx2(const Grid& g, double x, double y, double z,
                                                 PointStencil& st) {
  if (!prepare_coordinates(g, x, y, z)) {
    mark_not_finite(st);
    return;
  }
  const __m256d half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1.0), eighth = _mm256_set1_pd(0.125);
  const __m256d t = _mm256_sub_pd(_mm256_set_pd(0.5, z, y, x), half);
  const __m256d f = _mm256_round_pd(t, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
  const __m256d r = _mm256_sub_pd(t, f);
  const __m256d four_r = _mm256_mul_pd(_mm256_set1_pd(4.0), r);
  const __m256d two_r = _mm256_mul_pd(_mm256_set1_pd(2.0), r);
  // q = sqrt(1 + 4r - 4r^2); phi(r) = (3 - 2r + q)/8, phi(r - 1) = (1 + 2r + q)/8
  const __m256d q = _mm256_sqrt_pd(_mm256_sub_pd(_mm256_add_pd(one, four_r), _mm256_mul_pd(four_r, r)));
  const __m256d w1 = _mm256_mul_pd(_mm256_add_pd(_mm256_sub_pd(_mm256_set1_pd(3.0), two_r), q), eighth);
  const __m256d w2 = _mm256_mul_pd(_mm256_add_pd(_mm256_add_pd(one, two_r), q), eighth);
  const __m256d w0 = _mm256_sub_pd(half, w2);
  const __m256d w3 = _mm256_sub_pd(half, w1);
  // Transpose (w0 w1 w2 w3) x (x y z -) into the rows wx, wy, wz.
  const __m256d t0 = _mm256_unpacklo_pd(w0, w1);  // w0x w1x w0z w1z
  const __m256d t1 = _mm256_unpackhi_pd(w0, w1);  // w0y w1y . .
  const __m256d t2 = _mm256_unpacklo_pd(w2, w3);  // w2x w3x w2z w3z
  const __m256d t3 = _mm256_unpackhi_pd(w2, w3);  // w2y w3y . .
  _mm256_storeu_pd(st.wx, _mm256_permute2f128_pd(t0, t2, 0x20));
  _mm256_storeu_pd(st.wy, _mm256_permute2f128_pd(t1, t3, 0x20));
  _mm256_storeu_pd(st.wz, _mm256_permute2f128_pd(t0, t2, 0x31));
  alignas(16) int first[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(first), _mm256_cvttpd_epi32(f));
  stencil_indices<Kernel::kPeskin4>(g, first[0] - 1, first[1] - 1, first[2] - 1, st);
}
#endif

template <Kernel K>
void build_generic(const Grid& g, const double* x, PointStencil* st, std::ptrdiff_t p0, std::ptrdiff_t p1) {
  for (std::ptrdiff_t p = p0; p < p1; ++p) make_stencil<K>(g, x[3 * p], x[3 * p + 1], x[3 * p + 2], st[p]);
}
template <Kernel K>
CELLFLOW_IBM_AVX2 void build_avx2(const Grid& g, const double* x, PointStencil* st, std::ptrdiff_t p0,
                                  std::ptrdiff_t p1) {
  for (std::ptrdiff_t p = p0; p < p1; ++p) {
#if defined(__x86_64__)
    if constexpr (K == Kernel::kPeskin4) {
      make_stencil4_avx2(g, x[3 * p], x[3 * p + 1], x[3 * p + 2], st[p]);
      continue;
    }
#endif
    make_stencil<K>(g, x[3 * p], x[3 * p + 1], x[3 * p + 2], st[p]);
  }
}

template <Kernel K>
void build_impl(const Grid& g, std::span<const double> points, StencilSet& set, int threads) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(points.size() / 3);
  set.points.resize(static_cast<std::size_t>(n));
  PointStencil* st = set.points.data();
  const auto build = use_avx2() ? build_avx2<K> : build_generic<K>;
  const int t = n >= kParallelPoints ? thread_count(threads) : 1;
#pragma omp parallel num_threads(t) if (t > 1)
  {
    const std::ptrdiff_t me = omp_get_thread_num(), nt = omp_get_num_threads();
    build(g, points.data(), st, n * me / nt, n * (me + 1) / nt);
  }
  // Counting sort of the finite points by first z plane, stable.
  set.bin_begin.assign(static_cast<std::size_t>(g.nz) + 1, 0);
  for (std::ptrdiff_t p = 0; p < n; ++p) {
    if (st[p].finite) ++set.bin_begin[static_cast<std::size_t>(st[p].z[0]) + 1];
  }
  for (int k = 0; k < g.nz; ++k) set.bin_begin[k + 1] += set.bin_begin[k];
  set.order.resize(static_cast<std::size_t>(set.bin_begin[g.nz]));
  set.bin_fill.assign(set.bin_begin.begin(), set.bin_begin.end() - 1);
  for (std::ptrdiff_t p = 0; p < n; ++p) {
    if (st[p].finite) set.order[set.bin_fill[st[p].z[0]]++] = static_cast<int>(p);
  }
}

// U = sum_x u(x) phi(x - X) phi(y - Y) phi(z - Z) for one point: the x row of
// W nodes is accumulated lane by lane (one lane per a), the lanes summed last.
template <int W, bool kContiguous, class T>
[[gnu::always_inline]] inline void interpolate_point(const Grid& g, const PointStencil& st,
                                                     lb::VectorField<const T> field, double* out) {
  double acc[3][W] = {};
  const std::size_t plane = static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny);
  for (int c = 0; c < W; ++c) {
    const std::size_t zoff = plane * static_cast<std::size_t>(st.z[c]);
    for (int b = st.y_begin; b < st.y_end; ++b) {
      const double wyz = st.wz[c] * st.wy[b];
      const std::size_t row = zoff + static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(st.y[b]);
      const T* __restrict fx = field.x + row;
      const T* __restrict fy = field.y + row;
      const T* __restrict fz = field.z + row;
      for (int a = 0; a < W; ++a) {
        const std::size_t i = kContiguous ? static_cast<std::size_t>(st.x[0] + a) : st.x[a];
        const double w = wyz * st.wx[a];
        acc[0][a] += w * static_cast<double>(fx[i]);
        acc[1][a] += w * static_cast<double>(fy[i]);
        acc[2][a] += w * static_cast<double>(fz[i]);
      }
    }
  }
  for (int d = 0; d < 3; ++d) {
    double u = 0.0;
    for (int a = 0; a < W; ++a) u += acc[d][a];
    out[d] = u;
  }
}

#if defined(__x86_64__)
// The 4-node x rows of peskin4 as AVX2 vectors (lane a = node x[0] + a), in
// the arithmetic of interpolate_point / spread_plane: w = (wz wy) wx, the
// lanes of the interpolation summed in the order a = 0..3 at the end.
CELLFLOW_IBM_AVX2 inline __m256d load4(const double* p) {
  return _mm256_loadu_pd(p);
}
CELLFLOW_IBM_AVX2 inline __m256d load4(const float* p) {
  return _mm256_cvtps_pd(_mm_loadu_ps(p));
}
CELLFLOW_IBM_AVX2 inline void add4(double* p, __m256d v) {
  _mm256_storeu_pd(p, _mm256_add_pd(_mm256_loadu_pd(p), v));
}
CELLFLOW_IBM_AVX2 inline void add4(float* p, __m256d v) {
  // float(w F) added in float, as static_cast<float>(w * f) in spread_plane.
  _mm_storeu_ps(p, _mm_add_ps(_mm_loadu_ps(p), _mm256_cvtpd_ps(v)));
}
CELLFLOW_IBM_AVX2 inline double lane_sum(__m256d v) {
  alignas(32) double lane[4];
  _mm256_store_pd(lane, v);
  return ((lane[0] + lane[1]) + lane[2]) + lane[3];
}

template <class T>
CELLFLOW_IBM_AVX2 inline void interpolate_point4_avx2(const Grid& g, const PointStencil& st,
                                                      lb::VectorField<const T> field, double* out) {
  const __m256d wx = _mm256_loadu_pd(st.wx);
  __m256d acc0 = _mm256_setzero_pd(), acc1 = _mm256_setzero_pd(), acc2 = _mm256_setzero_pd();
  const std::size_t plane = static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny);
  for (int c = 0; c < 4; ++c) {
    const std::size_t zoff = plane * static_cast<std::size_t>(st.z[c]) + static_cast<std::size_t>(st.x[0]);
    for (int b = st.y_begin; b < st.y_end; ++b) {
      const __m256d w = _mm256_mul_pd(_mm256_set1_pd(st.wz[c] * st.wy[b]), wx);
      const std::size_t at = zoff + static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(st.y[b]);
      acc0 = _mm256_add_pd(acc0, _mm256_mul_pd(w, load4(field.x + at)));
      acc1 = _mm256_add_pd(acc1, _mm256_mul_pd(w, load4(field.y + at)));
      acc2 = _mm256_add_pd(acc2, _mm256_mul_pd(w, load4(field.z + at)));
    }
  }
  out[0] = lane_sum(acc0);
  out[1] = lane_sum(acc1);
  out[2] = lane_sum(acc2);
}

template <class T>
CELLFLOW_IBM_AVX2 inline void spread_plane4_avx2(const Grid& g, const PointStencil& st, int c,
                                                 const double* f, lb::VectorField<T> field) {
  const __m256d wx = _mm256_loadu_pd(st.wx);
  const __m256d f0 = _mm256_set1_pd(f[0]), f1 = _mm256_set1_pd(f[1]), f2 = _mm256_set1_pd(f[2]);
  const std::size_t zoff =
      static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny) * static_cast<std::size_t>(st.z[c]) +
      static_cast<std::size_t>(st.x[0]);
  for (int b = st.y_begin; b < st.y_end; ++b) {
    const __m256d w = _mm256_mul_pd(_mm256_set1_pd(st.wz[c] * st.wy[b]), wx);
    const std::size_t at = zoff + static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(st.y[b]);
    add4(field.x + at, _mm256_mul_pd(w, f0));
    add4(field.y + at, _mm256_mul_pd(w, f1));
    add4(field.z + at, _mm256_mul_pd(w, f2));
  }
}
#endif

template <Kernel K, class T, bool kAvx2>
[[gnu::always_inline]] inline void interpolate_body(const StencilSet& set, lb::VectorField<const T> field,
                                                    double* values, std::ptrdiff_t p0, std::ptrdiff_t p1) {
  constexpr int W = kWidth<K>;
  const Grid& g = set.grid;
  const PointStencil* st = set.points.data();
  for (std::ptrdiff_t p = p0; p < p1; ++p) {
    double* out = &values[3 * p];
    if (!st[p].finite) {
      out[0] = out[1] = out[2] = std::nan("");
    } else if (st[p].x_contiguous) {
#if defined(__x86_64__)
      if constexpr (kAvx2 && W == 4) {
        interpolate_point4_avx2<T>(g, st[p], field, out);
        continue;
      }
#endif
      interpolate_point<W, true, T>(g, st[p], field, out);
    } else {
      interpolate_point<W, false, T>(g, st[p], field, out);
    }
  }
}
template <Kernel K, class T>
void interpolate_generic(const StencilSet& set, lb::VectorField<const T> field, double* values,
                         std::ptrdiff_t p0, std::ptrdiff_t p1) {
  interpolate_body<K, T, false>(set, field, values, p0, p1);
}
template <Kernel K, class T>
CELLFLOW_IBM_AVX2 void interpolate_avx2(const StencilSet& set, lb::VectorField<const T> field, double* values,
                                        std::ptrdiff_t p0, std::ptrdiff_t p1) {
  interpolate_body<K, T, true>(set, field, values, p0, p1);
}

template <Kernel K, class T>
void interpolate_impl(const StencilSet& set, lb::VectorField<const T> field, std::span<double> values,
                      int threads) {
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(set.points.size());
  const auto run = use_avx2() ? interpolate_avx2<K, T> : interpolate_generic<K, T>;
  const int t = n >= kParallelPoints ? thread_count(threads) : 1;
#pragma omp parallel num_threads(t) if (t > 1)
  {
    const std::ptrdiff_t me = omp_get_thread_num(), nt = omp_get_num_threads();
    run(set, field, values.data(), n * me / nt, n * (me + 1) / nt);
  }
}

// f(x) += F phi(x - X) phi(y - Y) phi(z - Z) on plane z[c] of the point's stencil.
template <int W, bool kContiguous, class T>
[[gnu::always_inline]] inline void spread_plane(const Grid& g, const PointStencil& st, int c, const double* f,
                                                lb::VectorField<T> field) {
  const std::size_t zoff =
      static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(g.ny) * static_cast<std::size_t>(st.z[c]);
  const double f0 = f[0], f1 = f[1], f2 = f[2];
  for (int b = st.y_begin; b < st.y_end; ++b) {
    const double wyz = st.wz[c] * st.wy[b];
    const std::size_t row = zoff + static_cast<std::size_t>(g.nx) * static_cast<std::size_t>(st.y[b]);
    T* __restrict fx = field.x + row;
    T* __restrict fy = field.y + row;
    T* __restrict fz = field.z + row;
    for (int a = 0; a < W; ++a) {
      const std::size_t i = kContiguous ? static_cast<std::size_t>(st.x[0] + a) : st.x[a];
      const double w = wyz * st.wx[a];
      fx[i] += static_cast<T>(w * f0);
      fy[i] += static_cast<T>(w * f1);
      fz[i] += static_cast<T>(w * f2);
    }
  }
}

// The additions into planes [z0, z1) (0 <= z0 < z1 <= nz): for the bins u of
// first planes z0 - W + 1 .. z1 - 1 in increasing order (wrapped), the
// stencil planes u + c that fall into the range. At a node of plane k the
// points come in the order of u = k - W + 1 .. k, whatever z0 and z1 are.
template <Kernel K, class T, bool kAvx2>
[[gnu::always_inline]] inline void spread_body(const StencilSet& set, const double* forces,
                                               lb::VectorField<T> field, int z0, int z1) {
  constexpr int W = kWidth<K>;
  const Grid& g = set.grid;
  for (int u = z0 - W + 1; u < z1; ++u) {
    const int bin = wrap_index(u, g.nz);
    const int c_lo = std::max(0, z0 - u), c_hi = std::min(W, z1 - u);
    for (int i = set.bin_begin[bin]; i < set.bin_begin[bin + 1]; ++i) {
      const int p = set.order[i];
      const PointStencil& st = set.points[p];
      for (int c = c_lo; c < c_hi; ++c) {
        if (st.x_contiguous) {
#if defined(__x86_64__)
          if constexpr (kAvx2 && W == 4) {
            spread_plane4_avx2<T>(g, st, c, &forces[3 * static_cast<std::size_t>(p)], field);
            continue;
          }
#endif
          spread_plane<W, true, T>(g, st, c, &forces[3 * static_cast<std::size_t>(p)], field);
        } else {
          spread_plane<W, false, T>(g, st, c, &forces[3 * static_cast<std::size_t>(p)], field);
        }
      }
    }
  }
}

template <Kernel K, class T>
void spread_generic(const StencilSet& set, const double* forces, lb::VectorField<T> field, int z0, int z1) {
  spread_body<K, T, false>(set, forces, field, z0, z1);
}
template <Kernel K, class T>
CELLFLOW_IBM_AVX2 void spread_avx2(const StencilSet& set, const double* forces, lb::VectorField<T> field,
                                   int z0, int z1) {
  spread_body<K, T, true>(set, forces, field, z0, z1);
}

template <Kernel K, class T>
void spread_impl(StencilSet& set, std::span<const double> forces, lb::VectorField<T> field, int threads) {
  constexpr int W = kWidth<K>;
  const int nz = set.grid.nz;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(set.order.size());
  const auto run = use_avx2() ? spread_avx2<K, T> : spread_generic<K, T>;
  const int t = n >= kParallelPoints ? std::min(thread_count(threads), nz) : 1;
  if (t <= 1) {
    run(set, forces.data(), field, 0, nz);
    return;
  }
  // Balance the threads' plane ranges by the point-planes they add.
  set.work.assign(static_cast<std::size_t>(nz), 0.0);
  double total = 0.0;
  for (int k = 0; k < nz; ++k) {
    const int points_here = set.bin_begin[k + 1] - set.bin_begin[k];
    for (int c = 0; c < W; ++c) set.work[wrap_index(k + c, nz)] += points_here;
    total += W * points_here;
  }
  set.plane_split.assign(static_cast<std::size_t>(t) + 1, nz);
  set.plane_split[0] = 0;
  double done = 0.0;
  int next = 1;
  for (int k = 0; k < nz && next < t; ++k) {
    done += set.work[k];
    while (next < t && done >= total * next / t) set.plane_split[next++] = k + 1;
  }
  const int* split = set.plane_split.data();
  const StencilSet& cset = set;
#pragma omp parallel num_threads(t)
  {
    // The runtime may give fewer threads than asked: the ranges are disjoint,
    // so any thread may take any of them.
    const int nt = omp_get_num_threads();
    for (int range = omp_get_thread_num(); range < t; range += nt) {
      if (split[range] < split[range + 1]) run(cset, forces.data(), field, split[range], split[range + 1]);
    }
  }
}

}  // namespace

StatusOr<Kernel> parse_kernel(std::string_view name, std::string_view field) {
  if (name.empty() || name == "peskin4") return Kernel::kPeskin4;
  if (name == "peskin3") return Kernel::kPeskin3;
  if (name == "trilinear") return Kernel::kTrilinear;
  return invalid_argument(std::string(field) + " = \"" + std::string(name) +
                          "\" must be one of \"peskin4\", \"peskin3\", \"trilinear\"");
}

std::string_view kernel_name(Kernel kernel) {
  switch (kernel) {
    case Kernel::kPeskin4:
      return "peskin4";
    case Kernel::kPeskin3:
      return "peskin3";
    case Kernel::kTrilinear:
      return "trilinear";
  }
  return "peskin4";
}

double kernel_weight(Kernel kernel, double r) {
  const double a = std::abs(r);
  switch (kernel) {
    case Kernel::kPeskin4:
      // (3 - 2|r| + sqrt(1 + 4|r| - 4r^2))/8, (5 - 2|r| - sqrt(-7 + 12|r| - 4r^2))/8   (Peskin 2002,
      // eq. 6.27)
      if (a <= 1.0) return (3.0 - 2.0 * a + std::sqrt(1.0 + 4.0 * a - 4.0 * a * a)) / 8.0;
      if (a <= 2.0) return (5.0 - 2.0 * a - std::sqrt(std::max(0.0, -7.0 + 12.0 * a - 4.0 * a * a))) / 8.0;
      return 0.0;
    case Kernel::kPeskin3:
      // (1 + sqrt(1 - 3r^2))/3, (5 - 3|r| - sqrt(-2 + 6|r| - 3r^2))/6   (Roma, Peskin & Berger 1999)
      if (a <= 0.5) return (1.0 + std::sqrt(1.0 - 3.0 * a * a)) / 3.0;
      if (a <= 1.5) return (5.0 - 3.0 * a - std::sqrt(std::max(0.0, -2.0 + 6.0 * a - 3.0 * a * a))) / 6.0;
      return 0.0;
    case Kernel::kTrilinear:
      return a <= 1.0 ? 1.0 - a : 0.0;
  }
  return 0.0;
}

int kernel_width(Kernel kernel) {
  switch (kernel) {
    case Kernel::kPeskin4:
      return 4;
    case Kernel::kPeskin3:
      return 3;
    case Kernel::kTrilinear:
      return 2;
  }
  return 4;
}

Stencil1D stencil_1d(Kernel kernel, double s) {
  Stencil1D st;
  switch (kernel) {
    case Kernel::kPeskin4:
      st.first = weights_1d<Kernel::kPeskin4>(s, st.weight);
      break;
    case Kernel::kPeskin3:
      st.first = weights_1d<Kernel::kPeskin3>(s, st.weight);
      break;
    case Kernel::kTrilinear:
      st.first = weights_1d<Kernel::kTrilinear>(s, st.weight);
      break;
  }
  return st;
}

Grid grid_of(const lb::Fluid& fluid) {
  return {fluid.nx(), fluid.ny(), fluid.nz(), fluid.params().walls_y};
}

void build_stencils(Kernel kernel, const Grid& grid, std::span<const double> points, StencilSet& stencils,
                    int threads) {
  stencils.kernel = kernel;
  stencils.grid = grid;
  switch (kernel) {
    case Kernel::kPeskin4:
      build_impl<Kernel::kPeskin4>(grid, points, stencils, threads);
      break;
    case Kernel::kPeskin3:
      build_impl<Kernel::kPeskin3>(grid, points, stencils, threads);
      break;
    case Kernel::kTrilinear:
      build_impl<Kernel::kTrilinear>(grid, points, stencils, threads);
      break;
  }
}

template <class T>
void interpolate(const StencilSet& stencils, lb::VectorField<const T> field, std::span<double> values,
                 int threads) {
  switch (stencils.kernel) {
    case Kernel::kPeskin4:
      interpolate_impl<Kernel::kPeskin4, T>(stencils, field, values, threads);
      break;
    case Kernel::kPeskin3:
      interpolate_impl<Kernel::kPeskin3, T>(stencils, field, values, threads);
      break;
    case Kernel::kTrilinear:
      interpolate_impl<Kernel::kTrilinear, T>(stencils, field, values, threads);
      break;
  }
}

template <class T>
void spread(StencilSet& stencils, std::span<const double> forces, lb::VectorField<T> field, int threads) {
  switch (stencils.kernel) {
    case Kernel::kPeskin4:
      spread_impl<Kernel::kPeskin4, T>(stencils, forces, field, threads);
      break;
    case Kernel::kPeskin3:
      spread_impl<Kernel::kPeskin3, T>(stencils, forces, field, threads);
      break;
    case Kernel::kTrilinear:
      spread_impl<Kernel::kTrilinear, T>(stencils, forces, field, threads);
      break;
  }
}

template <class T>
void interpolate(Kernel kernel, const Grid& grid, lb::VectorField<const T> field,
                 std::span<const double> points, std::span<double> values, int threads) {
  StencilSet stencils;
  build_stencils(kernel, grid, points, stencils, threads);
  interpolate<T>(stencils, field, values, threads);
}

template <class T>
void spread(Kernel kernel, const Grid& grid, std::span<const double> points, std::span<const double> forces,
            lb::VectorField<T> field, int threads) {
  StencilSet stencils;
  build_stencils(kernel, grid, points, stencils, threads);
  spread<T>(stencils, forces, field, threads);
}

template void interpolate<double>(const StencilSet&, lb::VectorField<const double>, std::span<double>, int);
template void interpolate<float>(const StencilSet&, lb::VectorField<const float>, std::span<double>, int);
template void spread<double>(StencilSet&, std::span<const double>, lb::VectorField<double>, int);
template void spread<float>(StencilSet&, std::span<const double>, lb::VectorField<float>, int);
template void interpolate<double>(Kernel, const Grid&, lb::VectorField<const double>, std::span<const double>,
                                  std::span<double>, int);
template void interpolate<float>(Kernel, const Grid&, lb::VectorField<const float>, std::span<const double>,
                                 std::span<double>, int);
template void spread<double>(Kernel, const Grid&, std::span<const double>, std::span<const double>,
                             lb::VectorField<double>, int);
template void spread<float>(Kernel, const Grid&, std::span<const double>, std::span<const double>,
                            lb::VectorField<float>, int);

Status interpolate_velocity(Kernel kernel, const lb::Fluid& fluid, std::span<const double> points,
                            std::span<double> velocities) {
  if (!fluid.params().velocity_field) {
    return Status(StatusCode::kFailedPrecondition,
                  "ibm: the fluid has no velocity field (FluidParams.velocity_field)");
  }
  if (velocities.size() != points.size() || points.size() % 3 != 0) {
    return invalid_argument("ibm: points and velocities must both hold 3 values per point");
  }
  const Grid grid = grid_of(fluid);
  const int threads = fluid.params().threads;
  if (fluid.params().precision == lb::Precision::kDouble) {
    interpolate<double>(kernel, grid, fluid.velocity_field<double>(), points, velocities, threads);
  } else {
    interpolate<float>(kernel, grid, fluid.velocity_field<float>(), points, velocities, threads);
  }
  return Status::ok_status();
}

Status spread_forces(Kernel kernel, std::span<const double> points, std::span<const double> forces,
                     lb::Fluid& fluid) {
  if (!fluid.params().force_field) {
    return Status(StatusCode::kFailedPrecondition,
                  "ibm: the fluid has no force field (FluidParams.force_field)");
  }
  if (forces.size() != points.size() || points.size() % 3 != 0) {
    return invalid_argument("ibm: points and forces must both hold 3 values per point");
  }
  const Grid grid = grid_of(fluid);
  const int threads = fluid.params().threads;
  if (fluid.params().precision == lb::Precision::kDouble) {
    spread<double>(kernel, grid, points, forces, fluid.force_field<double>(), threads);
  } else {
    spread<float>(kernel, grid, points, forces, fluid.force_field<float>(), threads);
  }
  return Status::ok_status();
}

}  // namespace cellflow::ibm
