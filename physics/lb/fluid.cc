#include "physics/lb/fluid.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <new>
#include <string>
#include <type_traits>
#include <vector>

#include "physics/lb/collide_kernel.h"

namespace cellflow::lb {

// Internal access for the kernels of this file.
struct FluidAccess {
  template <class T>
  static AlignedArray<T>& populations(Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.populations_d_;
    else
      return f.populations_f_;
  }
  template <class T>
  static const AlignedArray<T>& populations(const Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.populations_d_;
    else
      return f.populations_f_;
  }
  template <class T>
  static AlignedArray<T>& force(Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.force_d_;
    else
      return f.force_f_;
  }
  template <class T>
  static const AlignedArray<T>& force(const Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.force_d_;
    else
      return f.force_f_;
  }
  template <class T>
  static AlignedArray<T>& velocity(Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.velocity_d_;
    else
      return f.velocity_f_;
  }
  template <class T>
  static const AlignedArray<T>& velocity(const Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.velocity_d_;
    else
      return f.velocity_f_;
  }
  // AA pattern with walls: density of the two wall-adjacent layers at the
  // last even step (2 nx nz values), read by the next odd step's bounce-back.
  template <class T>
  static AlignedArray<T>& wall_density(Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.wall_density_d_;
    else
      return f.wall_density_f_;
  }
  template <class T>
  static const AlignedArray<T>& wall_density(const Fluid& f) {
    if constexpr (std::is_same_v<T, double>)
      return f.wall_density_d_;
    else
      return f.wall_density_f_;
  }
  static std::size_t stride(const Fluid& f) { return f.stride_; }
  static bool& aa_swapped(Fluid& f) { return f.aa_swapped_; }
  static bool aa_swapped(const Fluid& f) { return f.aa_swapped_; }
  static int& current(Fluid& f) { return f.current_; }
  static int current(const Fluid& f) { return f.current_; }
  static std::int64_t& time_step(Fluid& f) { return f.time_step_; }
};

namespace {

constexpr int kChunk = 128;  // x nodes per collision run: 19 run buffers stay in L1

// Direction arrays start on 64-byte boundaries, one cache line more than
// needed apart: with strides a multiple of 4 KiB the 19 streams of a row
// alias in the low address bits (measured a few % slower, bench/lb).
std::size_t direction_stride(std::size_t nodes) {
  return (nodes + 15) / 16 * 16 + 16;
}

// AA pattern with walls: one density per node of the two wall layers.
std::size_t wall_density_size(const FluidParams& p) {
  if (p.streaming != Streaming::kAA || !p.walls_y || p.nx < 1 || p.nz < 1) return 0;
  return 2 * static_cast<std::size_t>(p.nx) * static_cast<std::size_t>(p.nz);
}

// Below this many nodes a step takes less than an OpenMP fork-join on a busy
// machine (tens of microseconds up to a time slice), so loops run serially.
constexpr std::size_t kSerialBelowNodes = 16384;

int thread_count(const FluidParams& p) {
  const std::size_t nodes = static_cast<std::size_t>(p.nx) * p.ny * static_cast<std::size_t>(p.nz);
  if (nodes < kSerialBelowNodes) return 1;
  return p.threads > 0 ? p.threads : omp_get_max_threads();
}

// Periodic index for a shift of at most one period.
inline int wrap(int i, int n) {
  return i < 0 ? i + n : (i >= n ? i - n : i);
}

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

// Moving-wall bounce-back (Ladd 1994): a population leaving into the wall
// returns as f_q = f*_qbar + 2 w_q rho c_q.u_w / c_s^2, c_q pointing back into
// the fluid. wall_term[q] = 6 w_q c_q.u_w, multiplied by rho at the node.
template <class T>
struct WallTerms {
  T lower[kQ];
  T upper[kQ];
};

template <class T>
WallTerms<T> wall_terms(const FluidParams& p) {
  WallTerms<T> w{};
  for (int q = 0; q < kQ; ++q) {
    const auto dot = [q](const std::array<double, 3>& u) {
      return kCx[q] * u[0] + kCy[q] * u[1] + kCz[q] * u[2];
    };
    // 2 w_q c_q.u_w / c_s^2 = 6 w_q c_q.u_w
    w.lower[q] = static_cast<T>(6.0 * kWeight[q] * dot(p.lower_wall_velocity));
    w.upper[q] = static_cast<T>(6.0 * kWeight[q] * dot(p.upper_wall_velocity));
  }
  return w;
}

template <class T>
detail::CollisionCoeffs<T> collision_coeffs(const FluidParams& p) {
  // tau_minus = 1/2 + Lambda / (tau - 1/2)   (TRT magic parameter)
  const double tau_minus = p.collision == CollisionModel::kBgk ? p.tau : 0.5 + p.trt_magic / (p.tau - 0.5);
  const double omega_plus = 1.0 / p.tau, omega_minus = 1.0 / tau_minus;
  return {static_cast<T>(omega_plus),
          static_cast<T>(omega_minus),
          static_cast<T>(1.0 - 0.5 * omega_plus),
          static_cast<T>(1.0 - 0.5 * omega_minus),
          static_cast<T>(p.uniform_force[0]),
          static_cast<T>(p.uniform_force[1]),
          static_cast<T>(p.uniform_force[2])};
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

template <class T, bool kForce, bool kVel>
CELLFLOW_LB_INLINE void collide(const StepContext<T>& c, const T* const* in, T* const* out, int n,
                                std::size_t at, T* rho) {
  detail::collide_run<T, kForce, kVel>(in, out, n, kForce ? c.fx + at : nullptr, kForce ? c.fy + at : nullptr,
                                       kForce ? c.fz + at : nullptr, kVel ? c.ux + at : nullptr,
                                       kVel ? c.uy + at : nullptr, kVel ? c.uz + at : nullptr, rho, c.k);
}

// AA even step: purely local. Reads f_i(x) from slot i, writes f*_i(x) to slot
// ibar of the same node; streaming happens in the next (odd) step's reads.
template <class T, bool kForce, bool kVel>
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
    collide<T, kForce, kVel>(c, in, out, n, row + x0, rho);
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
template <class T, bool kForce, bool kVel>
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
  collide<T, kForce, kVel>(c, in, out, n, at, s.rho);
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

template <class T, bool kForce, bool kVel>
CELLFLOW_LB_INLINE void row_aa_odd(const StepContext<T>& c, int y, int z) {
  RowScratch<T> s;
  for (int x0 = 0; x0 < c.nx; x0 += kChunk)
    aa_odd_run<T, kForce, kVel>(c, y, z, x0, std::min(kChunk, c.nx - x0), s);
}

// Two-array push step: reads f_i(x) locally from a, writes f*_i(x) to b at
// x + c_i (or bounced back into slot ibar at x).
template <class T, bool kForce, bool kVel>
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
  collide<T, kForce, kVel>(c, in, out, n, at, s.rho);
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

template <class T, bool kForce, bool kVel>
CELLFLOW_LB_INLINE void row_two_array(const StepContext<T>& c, int y, int z) {
  RowScratch<T> s;
  for (int x0 = 0; x0 < c.nx; x0 += kChunk)
    two_array_run<T, kForce, kVel>(c, y, z, x0, std::min(kChunk, c.nx - x0), s);
}

enum class Phase { kAAEven, kAAOdd, kTwoArray };

// Rows r0 <= r < r1 (r = y + ny z) of one step.
template <class T, bool kForce, bool kVel, Phase kPhase>
CELLFLOW_LB_INLINE void process_rows(const StepContext<T>& c, std::int64_t r0, std::int64_t r1) {
  for (std::int64_t r = r0; r < r1; ++r) {
    const int y = static_cast<int>(r % c.ny), z = static_cast<int>(r / c.ny);
    if constexpr (kPhase == Phase::kAAEven)
      row_aa_even<T, kForce, kVel>(c, y, z);
    else if constexpr (kPhase == Phase::kAAOdd)
      row_aa_odd<T, kForce, kVel>(c, y, z);
    else
      row_two_array<T, kForce, kVel>(c, y, z);
  }
}

// One row loop per SIMD level. The kernel is memory-bound with AVX2/AVX-512
// but compute-bound with the baseline SSE2 (bench/lb), and the default build
// does not use -march=native, so the level is picked at run time. Built with
// -ffp-contract=off: no FMA contraction, every level gives the same bits.
template <class T, bool kForce, bool kVel, Phase kPhase>
void rows_generic(const StepContext<T>& c, std::int64_t r0, std::int64_t r1) {
  process_rows<T, kForce, kVel, kPhase>(c, r0, r1);
}
#if defined(__x86_64__)
template <class T, bool kForce, bool kVel, Phase kPhase>
__attribute__((target("avx2"))) void rows_avx2(const StepContext<T>& c, std::int64_t r0, std::int64_t r1) {
  process_rows<T, kForce, kVel, kPhase>(c, r0, r1);
}
template <class T, bool kForce, bool kVel, Phase kPhase>
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void rows_avx512(const StepContext<T>& c,
                                                                               std::int64_t r0,
                                                                               std::int64_t r1) {
  process_rows<T, kForce, kVel, kPhase>(c, r0, r1);
}
#endif

template <class T>
using RowsFn = void (*)(const StepContext<T>&, std::int64_t, std::int64_t);

template <class T, bool kForce, bool kVel, Phase kPhase>
RowsFn<T> rows_for(Simd simd) {
#if defined(__x86_64__)
  if (simd == Simd::kAvx512) return rows_avx512<T, kForce, kVel, kPhase>;
  if (simd == Simd::kAvx2) return rows_avx2<T, kForce, kVel, kPhase>;
#endif
  return rows_generic<T, kForce, kVel, kPhase>;
}

Simd resolve_simd(Simd requested) {
  return requested == Simd::kAuto ? best_simd() : requested;
}

template <class T, bool kForce, bool kVel>
void step_impl(Fluid& fluid) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  T* pops = FluidAccess::populations<T>(fluid).data();
  const bool two_array = p.streaming == Streaming::kTwoArray;
  int& current = FluidAccess::current(fluid);
  StepContext<T> c{};
  c.nx = p.nx;
  c.ny = p.ny;
  c.nz = p.nz;
  c.walls = p.walls_y;
  c.stride = stride;
  c.a = pops + (two_array ? current * kQ * stride : 0);
  c.b = two_array ? pops + (1 - current) * kQ * stride : nullptr;
  if constexpr (kForce) {
    const T* f = FluidAccess::force<T>(fluid).data();
    c.fx = f;
    c.fy = f + stride;
    c.fz = f + 2 * stride;
  }
  if constexpr (kVel) {
    T* u = FluidAccess::velocity<T>(fluid).data();
    c.ux = u;
    c.uy = u + stride;
    c.uz = u + 2 * stride;
  }
  c.wall_rho = FluidAccess::wall_density<T>(fluid).data();
  c.k = collision_coeffs<T>(p);
  c.wall = wall_terms<T>(p);
  bool& swapped = FluidAccess::aa_swapped(fluid);
  const Simd simd = resolve_simd(p.simd);
  RowsFn<T> rows_fn;
  if (two_array)
    rows_fn = rows_for<T, kForce, kVel, Phase::kTwoArray>(simd);
  else if (!swapped)
    rows_fn = rows_for<T, kForce, kVel, Phase::kAAEven>(simd);
  else
    rows_fn = rows_for<T, kForce, kVel, Phase::kAAOdd>(simd);
  // Rows are split into equal contiguous ranges, one per thread (a static
  // schedule); the result does not depend on the split.
  const std::int64_t rows = static_cast<std::int64_t>(p.ny) * p.nz;
  const int threads = thread_count(p);
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
    const std::int64_t t = omp_get_thread_num(), nt = omp_get_num_threads();
    rows_fn(c, rows * t / nt, rows * (t + 1) / nt);
  }
  if (two_array)
    current = 1 - current;
  else
    swapped = !swapped;
  ++FluidAccess::time_step(fluid);
}

template <class T>
void step_typed(Fluid& fluid) {
  const bool force = fluid.params().force_field, vel = fluid.params().velocity_field;
  if (force && vel)
    step_impl<T, true, true>(fluid);
  else if (force)
    step_impl<T, true, false>(fluid);
  else if (vel)
    step_impl<T, false, true>(fluid);
  else
    step_impl<T, false, false>(fluid);
}

// Pre-collision deviations h_q = f_q - w_q of one node at the current time.
template <class T>
void node_deviations(const Fluid& fluid, int i, int j, int k, double* h) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  const T* a = FluidAccess::populations<T>(fluid).data();
  const std::size_t at = fluid.node(i, j, k);
  if (p.streaming == Streaming::kTwoArray) {
    a += FluidAccess::current(fluid) * kQ * stride;
    for (int q = 0; q < kQ; ++q) h[q] = a[q * stride + at];
    return;
  }
  if (!FluidAccess::aa_swapped(fluid)) {
    for (int q = 0; q < kQ; ++q) h[q] = a[q * stride + at];
    return;
  }
  // Swapped AA layout: slot qbar at x holds f*_q(x) of the last collision;
  // across a wall the kernel bounces back with the density it saved.
  const WallTerms<T> wall = wall_terms<T>(p);
  for (int q = 0; q < kQ; ++q) {
    const int ys = j - kCy[q];
    if (p.walls_y && (ys < 0 || ys >= p.ny)) {
      const T* term = ys < 0 ? wall.lower : wall.upper;
      const T rho_prev =
          FluidAccess::wall_density<T>(fluid)[static_cast<std::size_t>(p.nx) * ((j == 0 ? 0 : p.nz) + k) + i];
      h[q] = a[q * stride + at] + term[q] * rho_prev;
    } else {
      const std::size_t src = fluid.node(wrap(i - kCx[q], p.nx), wrap(ys, p.ny), wrap(k - kCz[q], p.nz));
      h[q] = a[opposite(q) * stride + src];
    }
  }
}

template <class T>
void set_equilibrium_typed(Fluid& fluid, std::span<const double> density, std::span<const double> ux,
                           std::span<const double> uy, std::span<const double> uz) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  T* a = FluidAccess::populations<T>(fluid).data();
  if (p.streaming == Streaming::kTwoArray) a += FluidAccess::current(fluid) * kQ * stride;
  const std::ptrdiff_t nodes = static_cast<std::ptrdiff_t>(fluid.num_nodes());
#pragma omp parallel for schedule(static) num_threads(thread_count(p))
  for (std::ptrdiff_t n = 0; n < nodes; ++n) {
    const double rho = density.empty() ? 1.0 : density[n];
    const double vx = ux[n], vy = uy[n], vz = uz[n];
    const double usq = vx * vx + vy * vy + vz * vz;
    for (int q = 0; q < kQ; ++q) {
      const double cu = kCx[q] * vx + kCy[q] * vy + kCz[q] * vz;
      // f_eq - w = w ((rho - 1) + rho (3 c.u + 9/2 (c.u)^2 - 3/2 u.u))
      a[q * stride + n] =
          static_cast<T>(kWeight[q] * ((rho - 1.0) + rho * (3.0 * cu + 4.5 * cu * cu - 1.5 * usq)));
    }
  }
  FluidAccess::aa_swapped(fluid) = false;
}

template <class T>
void compute_moments_typed(const Fluid& fluid, std::span<double> density, std::span<double> ux,
                           std::span<double> uy, std::span<double> uz) {
  const FluidParams& p = fluid.params();
  const std::size_t stride = FluidAccess::stride(fluid);
  const T* force = p.force_field ? FluidAccess::force<T>(fluid).data() : nullptr;
  const int nx = p.nx, ny = p.ny, nz = p.nz;
#pragma omp parallel for collapse(2) schedule(static) num_threads(thread_count(p))
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        double h[kQ];
        node_deviations<T>(fluid, i, j, k, h);
        const std::size_t at = fluid.node(i, j, k);
        double rho = 1.0, jx = 0.0, jy = 0.0, jz = 0.0;
        for (int q = 0; q < kQ; ++q) {
          rho += h[q];
          jx += kCx[q] * h[q];
          jy += kCy[q] * h[q];
          jz += kCz[q] * h[q];
        }
        double fx = p.uniform_force[0], fy = p.uniform_force[1], fz = p.uniform_force[2];
        if (force) {
          fx += force[at];
          fy += force[stride + at];
          fz += force[2 * stride + at];
        }
        // u = (sum_i f_i c_i + F/2) / rho   (Guo 2002, eq. 7)
        if (!density.empty()) density[at] = rho;
        if (!ux.empty()) ux[at] = (jx + 0.5 * fx) / rho;
        if (!uy.empty()) uy[at] = (jy + 0.5 * fy) / rho;
        if (!uz.empty()) uz[at] = (jz + 0.5 * fz) / rho;
      }
}

std::string format_double(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

Simd best_simd() {
#if defined(__x86_64__)
  static const Simd best = [] {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
        __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw")) {
      return Simd::kAvx512;
    }
    if (__builtin_cpu_supports("avx2")) return Simd::kAvx2;
    return Simd::kGeneric;
  }();
  return best;
#else
  return Simd::kGeneric;
#endif
}

bool simd_supported(Simd simd) {
  switch (simd) {
    case Simd::kAuto:
    case Simd::kGeneric:
      return true;
    case Simd::kAvx2:
      return best_simd() == Simd::kAvx2 || best_simd() == Simd::kAvx512;
    case Simd::kAvx512:
      return best_simd() == Simd::kAvx512;
  }
  return false;
}

const char* simd_name(Simd simd) {
  switch (simd) {
    case Simd::kAuto:
      return "auto";
    case Simd::kGeneric:
      return "generic";
    case Simd::kAvx2:
      return "avx2";
    case Simd::kAvx512:
      return "avx512";
  }
  return "?";
}

Status validate(const FluidParams& p) {
  if (p.nx < 1 || p.ny < 1 || p.nz < 1) {
    return invalid_argument("lb: lattice size " + std::to_string(p.nx) + " x " + std::to_string(p.ny) +
                            " x " + std::to_string(p.nz) + " must be at least 1 node per direction");
  }
  if (!(p.tau > 0.5) || !std::isfinite(p.tau)) {
    return invalid_argument("lb: tau = " + format_double(p.tau) + " must lie in (0.5, inf)");
  }
  if (p.collision == CollisionModel::kTrt && (!(p.trt_magic > 0.0) || !std::isfinite(p.trt_magic))) {
    return invalid_argument("lb: trt_magic = " + format_double(p.trt_magic) + " must lie in (0, inf)");
  }
  if (p.walls_y && (p.lower_wall_velocity[1] != 0.0 || p.upper_wall_velocity[1] != 0.0)) {
    return invalid_argument("lb: wall velocities must be tangential (y component 0)");
  }
  for (int d = 0; d < 3; ++d) {
    if (!std::isfinite(p.lower_wall_velocity[d]) || !std::isfinite(p.upper_wall_velocity[d]) ||
        !std::isfinite(p.uniform_force[d])) {
      return invalid_argument("lb: wall velocities and uniform_force must be finite");
    }
  }
  if (p.threads < 0) return invalid_argument("lb: threads = " + std::to_string(p.threads) + " must be >= 0");
  if (!simd_supported(p.simd)) {
    return invalid_argument("lb: simd = " + std::string(simd_name(p.simd)) +
                            " is not supported by this CPU (best: " + std::string(simd_name(best_simd())) +
                            ")");
  }
  return Status::ok_status();
}

std::size_t memory_bytes(const FluidParams& p) {
  const std::size_t nodes = static_cast<std::size_t>(std::max(p.nx, 0)) * std::max(p.ny, 0) *
                            static_cast<std::size_t>(std::max(p.nz, 0));
  const std::size_t stride = direction_stride(nodes);
  const std::size_t value = p.precision == Precision::kFloat ? sizeof(float) : sizeof(double);
  std::size_t arrays = kQ * (p.streaming == Streaming::kTwoArray ? 2 : 1);
  if (p.force_field) arrays += 3;
  if (p.velocity_field) arrays += 3;
  return arrays * stride * value + wall_density_size(p) * value;
}

Fluid::Fluid(const FluidParams& params)
    : params_(params),
      num_nodes_(static_cast<std::size_t>(params.nx) * params.ny * static_cast<std::size_t>(params.nz)),
      stride_(direction_stride(num_nodes_)) {}

StatusOr<Fluid> make_fluid(const FluidParams& params) {
  if (Status s = validate(params); !s.ok()) return s;
  Fluid fluid(params);
  const std::size_t pops = kQ * fluid.stride_ * (params.streaming == Streaming::kTwoArray ? 2 : 1);
  const std::size_t field = 3 * fluid.stride_;
  try {
    // All zero = deviations of the rest state rho = 1, u = 0 (and zero fields).
    if (params.precision == Precision::kDouble) {
      fluid.populations_d_ = AlignedArray<double>(pops);
      fluid.wall_density_d_ = AlignedArray<double>(wall_density_size(params));
      if (params.force_field) fluid.force_d_ = AlignedArray<double>(field);
      if (params.velocity_field) fluid.velocity_d_ = AlignedArray<double>(field);
    } else {
      fluid.populations_f_ = AlignedArray<float>(pops);
      fluid.wall_density_f_ = AlignedArray<float>(wall_density_size(params));
      if (params.force_field) fluid.force_f_ = AlignedArray<float>(field);
      if (params.velocity_field) fluid.velocity_f_ = AlignedArray<float>(field);
    }
  } catch (const std::bad_alloc&) {
    return Status(StatusCode::kResourceExhausted,
                  "lb: cannot allocate " + std::to_string(memory_bytes(params)) + " bytes for the lattice");
  }
  return fluid;
}

void Fluid::set_wall_velocities(const std::array<double, 3>& lower, const std::array<double, 3>& upper) {
  params_.lower_wall_velocity = lower;
  params_.upper_wall_velocity = upper;
}

template <class T>
VectorField<T> Fluid::force_field() {
  AlignedArray<T>& f = FluidAccess::force<T>(*this);
  if (f.empty()) return {};
  return {f.data(), f.data() + stride_, f.data() + 2 * stride_};
}

template <class T>
VectorField<const T> Fluid::force_field() const {
  const AlignedArray<T>& f = FluidAccess::force<T>(*this);
  if (f.empty()) return {};
  return {f.data(), f.data() + stride_, f.data() + 2 * stride_};
}

template <class T>
VectorField<const T> Fluid::velocity_field() const {
  const AlignedArray<T>& u = FluidAccess::velocity<T>(*this);
  if (u.empty()) return {};
  return {u.data(), u.data() + stride_, u.data() + 2 * stride_};
}

template VectorField<double> Fluid::force_field<double>();
template VectorField<float> Fluid::force_field<float>();
template VectorField<const double> Fluid::force_field<double>() const;
template VectorField<const float> Fluid::force_field<float>() const;
template VectorField<const double> Fluid::velocity_field<double>() const;
template VectorField<const float> Fluid::velocity_field<float>() const;

void collide_stream(Fluid& fluid) {
  if (fluid.params().precision == Precision::kDouble)
    step_typed<double>(fluid);
  else
    step_typed<float>(fluid);
}

void set_equilibrium(Fluid& fluid, std::span<const double> density, std::span<const double> ux,
                     std::span<const double> uy, std::span<const double> uz) {
  if (fluid.params().precision == Precision::kDouble)
    set_equilibrium_typed<double>(fluid, density, ux, uy, uz);
  else
    set_equilibrium_typed<float>(fluid, density, ux, uy, uz);
}

void zero_force_field(Fluid& fluid) {
  if (!fluid.params().force_field) return;
  const auto zero = [&](auto& arr) {
    using T = std::remove_reference_t<decltype(arr[0])>;
    T* d = arr.data();
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(arr.size());
#pragma omp parallel for schedule(static) num_threads(thread_count(fluid.params()))
    for (std::ptrdiff_t i = 0; i < n; ++i) d[i] = T(0);
  };
  if (fluid.params().precision == Precision::kDouble)
    zero(FluidAccess::force<double>(fluid));
  else
    zero(FluidAccess::force<float>(fluid));
}

void compute_moments(const Fluid& fluid, std::span<double> density, std::span<double> ux,
                     std::span<double> uy, std::span<double> uz) {
  if (fluid.params().precision == Precision::kDouble)
    compute_moments_typed<double>(fluid, density, ux, uy, uz);
  else
    compute_moments_typed<float>(fluid, density, ux, uy, uz);
}

void update_velocity_field(Fluid& fluid) {
  if (!fluid.params().velocity_field) return;
  const std::size_t n = fluid.num_nodes();
  std::vector<double> ux(n), uy(n), uz(n);
  compute_moments(fluid, {}, ux, uy, uz);
  const auto store = [&](auto& arr) {
    const std::size_t stride = FluidAccess::stride(fluid);
    for (std::size_t i = 0; i < n; ++i) {
      arr[i] = ux[i];
      arr[stride + i] = uy[i];
      arr[2 * stride + i] = uz[i];
    }
  };
  if (fluid.params().precision == Precision::kDouble)
    store(FluidAccess::velocity<double>(fluid));
  else
    store(FluidAccess::velocity<float>(fluid));
}

double total_mass(const Fluid& fluid) {
  // N + sum of the density deviations, so the rest mass does not swamp them.
  const FluidParams& p = fluid.params();
  double deviation = 0.0;
#pragma omp parallel for collapse(2) schedule(static) reduction(+ : deviation) num_threads(thread_count(p))
  for (int k = 0; k < p.nz; ++k)
    for (int j = 0; j < p.ny; ++j)
      for (int i = 0; i < p.nx; ++i) {
        double h[kQ];
        if (p.precision == Precision::kDouble)
          node_deviations<double>(fluid, i, j, k, h);
        else
          node_deviations<float>(fluid, i, j, k, h);
        for (int q = 0; q < kQ; ++q) deviation += h[q];
      }
  return static_cast<double>(fluid.num_nodes()) + deviation;
}

std::array<double, kQ> populations(const Fluid& fluid, int i, int j, int k) {
  std::array<double, kQ> f{};
  if (fluid.params().precision == Precision::kDouble)
    node_deviations<double>(fluid, i, j, k, f.data());
  else
    node_deviations<float>(fluid, i, j, k, f.data());
  for (int q = 0; q < kQ; ++q) f[q] += kWeight[q];
  return f;
}

}  // namespace cellflow::lb
