// The row kernels of one lattice step, internal to cellflow::lb (included by
// fluid_step.cc only): the step context, the periodic gather and scatter of
// shifted runs, and the fused collide-stream rows of the AA pattern (even and
// odd steps) and of the two-array push, with the moving-wall bounce-back.
// Everything is forced inline (CELLFLOW_LB_INLINE) into the row loop of one
// SIMD level, see collide_kernel.h. Internal linkage (an unnamed namespace):
// with it GCC generates the row loops exactly as when they were in one source
// file with their caller; do not include this header anywhere else.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "physics/lb/collide_kernel.h"
#include "physics/lb/d3q19.h"
#include "physics/lb/fluid_internal.h"

namespace cellflow::lb {
namespace {

constexpr int kChunk = 128;  // x nodes per collision run: 19 run buffers stay in L1

// dst[k] = row[wrap(x0 + k + shift)], k in [0, n), |shift| <= 1, n <= nx.
template <class T>
CELLFLOW_LB_INLINE void gather_shifted(T* dst, const T* row, int x0, int n, int shift, int nx) {
  const int s = x0 + shift, e = x0 + n + shift;
  int k = 0;
  if (s < 0) dst[k++] = row[s + nx];
  const int mid = std::min(e, nx) - (s + k);
  if (mid > 0) std::memcpy(dst + k, row + s + k, static_cast<std::size_t>(mid) * sizeof(T));
  if (e > nx) dst[n - 1] = row[e - 1 - nx];
}

// row[wrap(x0 + k + shift)] = src[k], k in [0, n), |shift| <= 1, n <= nx.
template <class T>
CELLFLOW_LB_INLINE void scatter_shifted(T* row, const T* src, int x0, int n, int shift, int nx) {
  const int s = x0 + shift, e = x0 + n + shift;
  int k = 0;
  if (s < 0) row[s + nx] = src[k++];
  const int mid = std::min(e, nx) - (s + k);
  if (mid > 0) std::memcpy(row + s + k, src + k, static_cast<std::size_t>(mid) * sizeof(T));
  if (e > nx) row[e - 1 - nx] = src[n - 1];
}

template <class T>
struct StepContext {
  int nx, ny, nz;
  bool walls;
  std::size_t stride;
  T* a;  // populations (AA: the one array; two-array: source)
  T* b;  // two-array destination
  const T *fx, *fy, *fz;
  T *ux, *uy, *uz;
  T* wall_rho;  // AA with walls: rho of layer y = 0 (first nx nz) and y = ny - 1 (next nx nz)
  detail::CollisionCoeffs<T> k;
  const std::uint8_t* phase;           // per-node phase index (kPh only)
  const detail::PhaseTable<T>* table;  // coefficients per phase (kPh only)
  WallTerms<T> wall;

  std::size_t row(int y, int z) const {
    return static_cast<std::size_t>(nx) * (static_cast<std::size_t>(y) + static_cast<std::size_t>(ny) * z);
  }
  bool in_wall(int y) const { return walls && (y < 0 || y >= ny); }
  bool wall_row(int y) const { return walls && (y == 0 || y == ny - 1); }
  T* wall_rho_row(int y, int z) const {
    return wall_rho + static_cast<std::size_t>(nx) * (static_cast<std::size_t>(y == 0 ? 0 : nz) + z);
  }
  const T* wall_term(int y) const { return y < 0 ? wall.lower : wall.upper; }
};

template <class T, bool kForce, bool kVel, bool kPh>
CELLFLOW_LB_INLINE void collide(const StepContext<T>& c, const T* const* in, T* const* out, int n,
                                std::size_t at, T* rho) {
  detail::collide_run<T, kForce, kVel, kPh>(
      in, out, n, kForce ? c.fx + at : nullptr, kForce ? c.fy + at : nullptr, kForce ? c.fz + at : nullptr,
      kVel ? c.ux + at : nullptr, kVel ? c.uy + at : nullptr, kVel ? c.uz + at : nullptr, rho, c.k,
      kPh ? c.phase + at : nullptr, c.table);
}

// AA even step: purely local. Reads f_i(x) from slot i, writes f*_i(x) to slot
// ibar of the same node; streaming happens in the next (odd) step's reads.
template <class T, bool kForce, bool kVel, bool kPh>
CELLFLOW_LB_INLINE void row_aa_even(const StepContext<T>& c, int y, int z) {
  alignas(64) T rho[kChunk];
  const std::size_t row = c.row(y, z);
  for (int x0 = 0; x0 < c.nx; x0 += kChunk) {
    const int n = std::min(kChunk, c.nx - x0);
    const T* in[kQ];
    T* out[kQ];
    for (int q = 0; q < kQ; ++q) {
      T* p = c.a + q * c.stride + row + x0;
      in[q] = p;
      out[opposite(q)] = p;
    }
    collide<T, kForce, kVel, kPh>(c, in, out, n, row + x0, rho);
    // The next odd step bounces the wall populations back with this density;
    // the 19 values at a node belong to 19 different nodes by then.
    if (c.wall_row(y)) std::memcpy(c.wall_rho_row(y, z) + x0, rho, static_cast<std::size_t>(n) * sizeof(T));
  }
}

// Per-row scratch of the streaming steps: run buffers for links with an x
// component or across a wall, and the densities of the run.
template <class T>
struct RowScratch {
  alignas(64) T buf[kQ][kChunk];
  alignas(64) T rho[kChunk];
  alignas(64) T rho_prev[kChunk];
};

// AA odd step: f_i(x) = f*_i(x - c_i) is read from slot ibar at x - c_i (or,
// across a wall, bounced back from slot i at x), and f*_i(x) is written to slot
// i at x + c_i (or, into a wall, bounced back into slot ibar at x). Each node
// reads and writes the same 19 locations, so the update is in place and
// race-free. Links with an x component go through the run buffers (a gather
// and a scatter with the periodic wrap): measured faster than shifted direct
// access, whose vectors straddle cache lines, and with one set-up per run.
template <class T, bool kForce, bool kVel, bool kPh>
CELLFLOW_LB_INLINE void aa_odd_run(const StepContext<T>& c, int y, int z, int x0, int n, RowScratch<T>& s) {
  const std::size_t at = c.row(y, z) + x0;
  // rho(x, t) of the previous (even) collision, saved by it.
  if (c.wall_row(y))
    std::memcpy(s.rho_prev, c.wall_rho_row(y, z) + x0, static_cast<std::size_t>(n) * sizeof(T));
  const T* in[kQ];
  T* out[kQ];
  in[0] = out[0] = c.a + at;
  for (int q = 1; q < kQ; ++q) {
    const int ys = y - kCy[q];
    if (c.in_wall(ys)) {
      const T* src = c.a + q * c.stride + at;
      const T tq = c.wall_term(ys)[q];
      for (int x = 0; x < n; ++x) s.buf[q][x] = src[x] + tq * s.rho_prev[x];
      in[q] = s.buf[q];
    } else {
      const T* src_row = c.a + opposite(q) * c.stride + c.row(wrap(ys, c.ny), wrap(z - kCz[q], c.nz));
      if (kCx[q] == 0) {
        in[q] = src_row + x0;
      } else {
        gather_shifted(s.buf[q], src_row, x0, n, -kCx[q], c.nx);
        in[q] = s.buf[q];
      }
    }
    const int yd = y + kCy[q];
    if (c.in_wall(yd)) {
      out[q] = s.buf[q];
    } else if (kCx[q] == 0) {
      out[q] = c.a + q * c.stride + c.row(wrap(yd, c.ny), wrap(z + kCz[q], c.nz)) + x0;
    } else {
      out[q] = s.buf[q];
    }
  }
  collide<T, kForce, kVel, kPh>(c, in, out, n, at, s.rho);
  for (int q = 1; q < kQ; ++q) {
    const int yd = y + kCy[q];
    if (c.in_wall(yd)) {
      const int qb = opposite(q);
      T* dst = c.a + qb * c.stride + at;
      const T tq = c.wall_term(yd)[qb];
      for (int x = 0; x < n; ++x) dst[x] = s.buf[q][x] + tq * s.rho[x];
    } else if (kCx[q] != 0) {
      scatter_shifted(c.a + q * c.stride + c.row(wrap(yd, c.ny), wrap(z + kCz[q], c.nz)), s.buf[q], x0, n,
                      kCx[q], c.nx);
    }
  }
}

template <class T, bool kForce, bool kVel, bool kPh>
CELLFLOW_LB_INLINE void row_aa_odd(const StepContext<T>& c, int y, int z) {
  RowScratch<T> s;
  for (int x0 = 0; x0 < c.nx; x0 += kChunk)
    aa_odd_run<T, kForce, kVel, kPh>(c, y, z, x0, std::min(kChunk, c.nx - x0), s);
}

// Two-array push step: reads f_i(x) locally from a, writes f*_i(x) to b at
// x + c_i (or bounced back into slot ibar at x).
template <class T, bool kForce, bool kVel, bool kPh>
CELLFLOW_LB_INLINE void two_array_run(const StepContext<T>& c, int y, int z, int x0, int n,
                                      RowScratch<T>& s) {
  const std::size_t at = c.row(y, z) + x0;
  const T* in[kQ];
  T* out[kQ];
  for (int q = 0; q < kQ; ++q) {
    in[q] = c.a + q * c.stride + at;
    const int yd = y + kCy[q];
    if (c.in_wall(yd)) {
      out[q] = s.buf[q];
    } else if (kCx[q] == 0) {
      out[q] = c.b + q * c.stride + c.row(wrap(yd, c.ny), wrap(z + kCz[q], c.nz)) + x0;
    } else {
      out[q] = s.buf[q];
    }
  }
  collide<T, kForce, kVel, kPh>(c, in, out, n, at, s.rho);
  for (int q = 1; q < kQ; ++q) {
    const int yd = y + kCy[q];
    if (c.in_wall(yd)) {
      const int qb = opposite(q);
      T* dst = c.b + qb * c.stride + at;
      const T tq = c.wall_term(yd)[qb];
      for (int x = 0; x < n; ++x) dst[x] = s.buf[q][x] + tq * s.rho[x];
    } else if (kCx[q] != 0) {
      scatter_shifted(c.b + q * c.stride + c.row(wrap(yd, c.ny), wrap(z + kCz[q], c.nz)), s.buf[q], x0, n,
                      kCx[q], c.nx);
    }
  }
}

template <class T, bool kForce, bool kVel, bool kPh>
CELLFLOW_LB_INLINE void row_two_array(const StepContext<T>& c, int y, int z) {
  RowScratch<T> s;
  for (int x0 = 0; x0 < c.nx; x0 += kChunk)
    two_array_run<T, kForce, kVel, kPh>(c, y, z, x0, std::min(kChunk, c.nx - x0), s);
}

enum class Phase { kAAEven, kAAOdd, kTwoArray };

// Rows r0 <= r < r1 (r = y + ny z) of one step.
template <class T, bool kForce, bool kVel, bool kPh, Phase kPhase>
CELLFLOW_LB_INLINE void process_rows(const StepContext<T>& c, std::int64_t r0, std::int64_t r1) {
  for (std::int64_t r = r0; r < r1; ++r) {
    const int y = static_cast<int>(r % c.ny), z = static_cast<int>(r / c.ny);
    if constexpr (kPhase == Phase::kAAEven)
      row_aa_even<T, kForce, kVel, kPh>(c, y, z);
    else if constexpr (kPhase == Phase::kAAOdd)
      row_aa_odd<T, kForce, kVel, kPh>(c, y, z);
    else
      row_two_array<T, kForce, kVel, kPh>(c, y, z);
  }
}

}  // namespace
}  // namespace cellflow::lb
