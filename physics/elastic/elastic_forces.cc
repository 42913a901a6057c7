// Energy and vertex forces of an ElasticBody: the blocked per-tet loop over
// the stages of tet_kernel.h, the nodal-averaged volumetric pressures, the
// parallel split of the tets with private force buffers (add_elastic_forces,
// add_elastic_forces_of_range, elastic_energy) and the smallest deformed to
// reference volume ratio (min_volume_ratio).
#include <omp.h>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cstdint>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/elastic/elastic_internal.h"
#include "physics/elastic/tet_kernel.h"

namespace cellflow::elastic {

namespace {

using detail::kMinForceTetsPerThread;
using detail::kNoTet;
using detail::team_size;
using detail::volumetric_pressures;

// Energy (and, with kForces, the forces scattered into `forces`) of tets
// [begin, end). The first inverted tet of the range goes to first_inverted.
//
// The tets run in the lane blocks of ElasticBody (kTetBlockLanes tets, lane =
// tet; a range that starts or ends inside a block runs part of its lanes):
// one lane loop over the stages of tet_kernel.h that the compiler vectorises
// across tets (the inverse cube root, a long dependency chain, overlaps over
// the lanes). B, the vertex indices and the material are read from the
// blocked copies with vector loads; the positions by vertex index for the whole
// block (vector gathers where the level has them, AVX2 and AVX-512). The
// forces are scattered and the energy summed tet after tet in order; the
// callers that cover many tets (add_elastic_forces) scatter into a padded
// accumulator of 4 doubles per vertex with vector adds (ScatterForces).
// The lane loop has no FMA contraction (-ffp-contract=off, CMakeLists.txt) and
// the same operation order as one tet alone, so every SIMD level gives the
// same bits. The stress is scaled by -V0 inside stress_from_gradient (three
// products instead of nine), so the forces agree with the tangent path's
// (stress scaled afterwards) to round-off, not bit for bit.
// With tet_pressure (kNodalAverage) the tets carry no kappa term; their
// stress gets tet_pressure[t] cof(F) instead, and the volumetric energy is
// summed per vertex by volumetric_pressures.
constexpr int kLanes = kTetBlockLanes;

struct TetBlock {
  alignas(64) double y[12 * kLanes];       // y[kLanes (3 a + i) + lane] = y_i of local vertex a
  alignas(64) double forces[12 * kLanes];  // forces[kLanes (3 a + i) + lane] = f_i of local vertex a
  alignas(64) double energy[kLanes];       // V0 U of each lane
  kernel::TetStressLanes<kLanes> stress;
};

// The positions of the 4 vertices of the kLanes tets of a block into
// y_lanes (TetBlock::y layout), vertex indices in the ElasticBody::block_vertices
// layout. Always all lanes: the padding of the last block names vertex 0.
// One copy per SIMD level; only copies, so every level gives the same bits.
using GatherPositions = void (*)(const double* y, const std::int32_t* vertices, double* y_lanes);

void gather_positions_generic(const double* y, const std::int32_t* vertices, double* y_lanes) {
  for (int a = 0; a < 4; ++a) {
    for (int lane = 0; lane < kLanes; ++lane) {
      const double* ya = y + 3 * static_cast<std::int64_t>(vertices[kLanes * a + lane]);
      for (int i = 0; i < 3; ++i) y_lanes[kLanes * (3 * a + i) + lane] = ya[i];
    }
  }
}
#if defined(__x86_64__)
// 32-bit offsets 3 v (in doubles): make_elastic_body keeps 3 num_vertices below 2^31.
__attribute__((target("avx2"))) void gather_positions_avx2(const double* y, const std::int32_t* vertices,
                                                           double* y_lanes) {
  for (int a = 0; a < 4; ++a) {
    for (int c = 0; c < kLanes; c += 4) {
      const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(vertices + kLanes * a + c));
      const __m128i offset = _mm_add_epi32(v, _mm_add_epi32(v, v));
      for (int i = 0; i < 3; ++i) {
        _mm256_store_pd(y_lanes + kLanes * (3 * a + i) + c, _mm256_i32gather_pd(y + i, offset, 8));
      }
    }
  }
}
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void gather_positions_avx512(
    const double* y, const std::int32_t* vertices, double* y_lanes) {
  for (int a = 0; a < 4; ++a) {
    for (int c = 0; c < kLanes; c += 8) {
      const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(vertices + kLanes * a + c));
      const __m256i offset = _mm256_add_epi32(v, _mm256_add_epi32(v, v));
      for (int i = 0; i < 3; ++i) {
        _mm512_store_pd(y_lanes + kLanes * (3 * a + i) + c, _mm512_i32gather_pd(offset, y + i, 8));
      }
    }
  }
}
#endif

// The forces of a full block (TetBlock::forces layout) added into a padded
// accumulator of 4 doubles per vertex (acc[4 v + i], i < 3; acc[4 v + 3] is
// padding and receives zeros), tet after tet in lane order and, within a tet,
// corner after corner: the same additions in the same order as the scalar
// scatter into 3 doubles per vertex, so every copy gives the same bits. One
// copy per SIMD level: AVX2 and AVX-512 transpose four lanes of a corner
// (x, y, z rows) into four (x, y, z, 0) vectors and add each with one aligned
// 256-bit load and store, instead of three scalar read-modify-writes;
// 32-byte rows never straddle a cache line and the next tet's load at the same
// vertex is forwarded from the store whole.
using ScatterForces = void (*)(const double* f_lanes, const std::int32_t* vertices, double* acc);

void scatter_forces_generic(const double* f_lanes, const std::int32_t* vertices, double* acc) {
#pragma GCC unroll 16
  for (int lane = 0; lane < kLanes; ++lane) {
#pragma GCC unroll 4
    for (int a = 0; a < 4; ++a) {
      double* out = acc + 4 * static_cast<std::int64_t>(vertices[kLanes * a + lane]);
      out[0] += f_lanes[kLanes * (3 * a) + lane];
      out[1] += f_lanes[kLanes * (3 * a + 1) + lane];
      out[2] += f_lanes[kLanes * (3 * a + 2) + lane];
    }
  }
}
#if defined(__x86_64__)
// One body for the AVX2 and the AVX-512 copy: the AVX-512 one holds the 16
// transposed corners in its 32 vector registers instead of spilling them.
#define CELLFLOW_SCATTER_FORCES_TRANSPOSED(name, isa)                                                        \
  __attribute__((target(isa))) void name(const double* f_lanes, const std::int32_t* vertices, double* acc) { \
    const __m256d zero = _mm256_setzero_pd();                                                                \
    for (int c = 0; c < kLanes; c += 4) {                                                                    \
      __m256d corner[4][4]; /* [local vertex a][lane c + l] = (f_x, f_y, f_z, 0) */                          \
      for (int a = 0; a < 4; ++a) {                                                                          \
        const __m256d x = _mm256_load_pd(f_lanes + kLanes * (3 * a) + c);                                    \
        const __m256d y = _mm256_load_pd(f_lanes + kLanes * (3 * a + 1) + c);                                \
        const __m256d z = _mm256_load_pd(f_lanes + kLanes * (3 * a + 2) + c);                                \
        const __m256d xy_even = _mm256_unpacklo_pd(x, y);   /* x0 y0 x2 y2 */                                \
        const __m256d xy_odd = _mm256_unpackhi_pd(x, y);    /* x1 y1 x3 y3 */                                \
        const __m256d z_odd = _mm256_unpackhi_pd(z, zero);  /* z1 0 z3 0 */                                  \
        const __m256d z_even = _mm256_unpacklo_pd(z, zero); /* z0 0 z2 0 */                                  \
        corner[a][0] = _mm256_permute2f128_pd(xy_even, z_even, 0x20);                                        \
        corner[a][1] = _mm256_permute2f128_pd(xy_odd, z_odd, 0x20);                                          \
        corner[a][2] = _mm256_permute2f128_pd(xy_even, z_even, 0x31);                                        \
        corner[a][3] = _mm256_permute2f128_pd(xy_odd, z_odd, 0x31);                                          \
      }                                                                                                      \
      for (int l = 0; l < 4; ++l) {                                                                          \
        for (int a = 0; a < 4; ++a) {                                                                        \
          double* out = acc + 4 * static_cast<std::int64_t>(vertices[kLanes * a + c + l]);                   \
          _mm256_store_pd(out, _mm256_add_pd(_mm256_load_pd(out), corner[a][l]));                            \
        }                                                                                                    \
      }                                                                                                      \
    }                                                                                                        \
  }
CELLFLOW_SCATTER_FORCES_TRANSPOSED(scatter_forces_avx2, "avx2")
CELLFLOW_SCATTER_FORCES_TRANSPOSED(scatter_forces_avx512, "avx512f,avx512vl,avx512dq,avx512bw")
#undef CELLFLOW_SCATTER_FORCES_TRANSPOSED
#endif

// kStride: doubles per vertex of `forces`, 3 (the caller's array) or 4 (a
// padded accumulator, see ScatterForces; full blocks then go through kScatter).
template <bool kMooneyRivlin, bool kForces, int kStride, GatherPositions kGather, ScatterForces kScatter>
inline __attribute__((always_inline)) double evaluate_range_body(const ElasticBody& body, const double* y,
                                                                 double* forces, std::int64_t begin,
                                                                 std::int64_t end,
                                                                 std::int64_t& first_inverted,
                                                                 const double* tet_pressure) {
  const double* block_b = body.block_b_matrix.data();
  const std::int32_t* block_vertices = body.block_vertices.data();
  const double* volume = body.ref_volume_m3.data();
  const double* mu1 = body.mu1_pa.data();
  const double* mu2 = body.mu2_pa.data();
  const double* kappa = body.kappa_pa.data();
  // mu2 (neo-Hookean: 0), kappa and the pressure as products with 1 or 0
  // (exact) rather than selects, which would stop the lane loop vectorising.
  const double mu2_scale = kMooneyRivlin ? 1.0 : 0.0;
  const double kappa_scale = tet_pressure == nullptr ? 1.0 : 0.0;
  const double pressure_scale = tet_pressure == nullptr ? 0.0 : 1.0;
  const double* pressure = tet_pressure == nullptr ? kappa : tet_pressure;
  TetBlock blk;
  double energy = 0.0;
  for (std::int64_t block = begin / kLanes; block * kLanes < end; ++block) {
    const std::int64_t first = block * kLanes;
    const int lane_begin = static_cast<int>(std::max<std::int64_t>(0, begin - first));
    const int lane_end = static_cast<int>(std::min<std::int64_t>(kLanes, end - first));
    const double* b = block_b + 9 * kLanes * block;
    const std::int32_t* v0 = block_vertices + 4 * kLanes * block;
    kGather(y, v0, blk.y);
    const double* volume_b = volume + first;
    const double* mu1_b = mu1 + first;
    const double* mu2_b = mu2 + first;
    const double* kappa_b = kappa + first;
    const double* pressure_b = pressure + first;
    // The stages over lanes [lo, hi); a full block runs them with constant
    // bounds, which the compiler vectorises without a remainder loop.
    const auto run_lanes = [&](int lo, int hi) __attribute__((always_inline)) {
#pragma omp simd
      for (int lane = lo; lane < hi; ++lane) {
        kernel::TetStressLanes<kLanes>& s = blk.stress;
        const double* yl = blk.y + lane;
        const double det_f = kernel::deformation_gradient<kLanes>(
            b + lane, yl, yl + 3 * kLanes, yl + 6 * kLanes, yl + 9 * kLanes, s.f + lane, s.cof + lane);
        s.det_f[lane] = det_f;
        // J^-1/3; an inverted lane (J <= 0) gets a harmless J = 1 and is skipped below.
        const double j_m13 = kernel::inverse_cube_root(kernel::one_if_not_positive(det_f));
        // The stress comes scaled by -V0 for the forces (the energy only ignores it).
        kernel::stress_from_gradient<kMooneyRivlin, kLanes, false>(
            mu1_b[lane], mu2_scale * mu2_b[lane], kappa_scale * kappa_b[lane], j_m13, s, lane,
            pressure_scale * pressure_b[lane], -volume_b[lane]);
        blk.energy[lane] = volume_b[lane] * s.energy_density[lane];
        if constexpr (kForces) {
          kernel::forces_from_scaled_stress<kLanes>(b + lane, s.stress + lane, blk.forces + lane);
        }
      }
    };
    if (lane_begin == 0 && lane_end == kLanes) {
      run_lanes(0, kLanes);
    } else {
      run_lanes(lane_begin, lane_end);
    }
    // Energy in tet order, forces scattered tet after tet (the same sums in
    // the same order on every level). A full block without an inverted tet
    // runs unrolled with constant offsets.
    const auto scatter_lanes = [&](int lo, int hi) __attribute__((always_inline)) {
      for (int lane = lo; lane < hi; ++lane) {
        const std::int64_t t = first + lane;
        if (blk.stress.det_f[lane] <= 0.0) {
          first_inverted = std::min(first_inverted, t);
          continue;
        }
        energy += blk.energy[lane];
        if constexpr (kForces) {
          for (int a = 0; a < 4; ++a) {
            double* out = forces + kStride * static_cast<std::int64_t>(v0[kLanes * a + lane]);
            out[0] += blk.forces[kLanes * (3 * a) + lane];
            out[1] += blk.forces[kLanes * (3 * a + 1) + lane];
            out[2] += blk.forces[kLanes * (3 * a + 2) + lane];
          }
        }
      }
    };
    bool any_inverted = false;
    for (int lane = 0; lane < kLanes; ++lane) any_inverted |= blk.stress.det_f[lane] <= 0.0;
    if (lane_begin == 0 && lane_end == kLanes && !any_inverted) {
#pragma GCC unroll 16
      for (int lane = 0; lane < kLanes; ++lane) energy += blk.energy[lane];
      if constexpr (kForces && kStride == 4) {
        kScatter(blk.forces, v0, forces);
      } else if constexpr (kForces) {
#pragma GCC unroll 16
        for (int lane = 0; lane < kLanes; ++lane) {
#pragma GCC unroll 4
          for (int a = 0; a < 4; ++a) {
            double* out = forces + 3 * static_cast<std::int64_t>(v0[kLanes * a + lane]);
            out[0] += blk.forces[kLanes * (3 * a) + lane];
            out[1] += blk.forces[kLanes * (3 * a + 1) + lane];
            out[2] += blk.forces[kLanes * (3 * a + 2) + lane];
          }
        }
      }
    } else {
      scatter_lanes(lane_begin, lane_end);
    }
  }
  return energy;
}

// One copy of the tet loop per SIMD level, the best the CPU has chosen at run
// time (resolve_tet_simd): the default build has no -march, so the generic
// copy is SSE2 and runs on any x86-64.
template <bool kMooneyRivlin, bool kForces, int kStride>
double evaluate_range_generic(const ElasticBody& body, const double* y, double* forces, std::int64_t begin,
                              std::int64_t end, std::int64_t& first_inverted, const double* tet_pressure) {
  return evaluate_range_body<kMooneyRivlin, kForces, kStride, gather_positions_generic,
                             scatter_forces_generic>(body, y, forces, begin, end, first_inverted,
                                                     tet_pressure);
}
#if defined(__x86_64__)
template <bool kMooneyRivlin, bool kForces, int kStride>
__attribute__((target("avx2"))) double evaluate_range_avx2(const ElasticBody& body, const double* y,
                                                           double* forces, std::int64_t begin,
                                                           std::int64_t end, std::int64_t& first_inverted,
                                                           const double* tet_pressure) {
  return evaluate_range_body<kMooneyRivlin, kForces, kStride, gather_positions_avx2, scatter_forces_avx2>(
      body, y, forces, begin, end, first_inverted, tet_pressure);
}
// The AVX-512 copy scatters with the 256-bit transposes too: a vertex row is 4 doubles.
template <bool kMooneyRivlin, bool kForces, int kStride>
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) double evaluate_range_avx512(
    const ElasticBody& body, const double* y, double* forces, std::int64_t begin, std::int64_t end,
    std::int64_t& first_inverted, const double* tet_pressure) {
  return evaluate_range_body<kMooneyRivlin, kForces, kStride, gather_positions_avx512, scatter_forces_avx512>(
      body, y, forces, begin, end, first_inverted, tet_pressure);
}
#endif

// kAuto is the best level; a level the CPU lacks runs the generic copy
// rather than faulting on an illegal instruction.
TetSimd resolve_tet_simd(TetSimd requested) {
  if (requested == TetSimd::kAuto) return best_tet_simd();
  return tet_simd_supported(requested) ? requested : TetSimd::kGeneric;
}

// kStride 4: `forces` is a padded accumulator (PaddedForces), 3: the caller's
// array (energy only passes 3 and no forces).
template <bool kMooneyRivlin, bool kForces, int kStride = 3>
double evaluate_range(const ElasticBody& body, const double* y, double* forces, std::int64_t begin,
                      std::int64_t end, std::int64_t& first_inverted, const double* tet_pressure,
                      TetSimd simd = TetSimd::kAuto) {
  const std::size_t num_blocks = (body.num_tets() + kLanes - 1) / kLanes;
  if (body.block_b_matrix.size() != 9 * kLanes * num_blocks ||
      body.block_vertices.size() != 4 * kLanes * num_blocks) {
    ElasticBody blocked = body;  // assembled by hand without build_lane_blocks
    build_lane_blocks(blocked);
    return evaluate_range<kMooneyRivlin, kForces, kStride>(blocked, y, forces, begin, end, first_inverted,
                                                           tet_pressure, simd);
  }
  switch (resolve_tet_simd(simd)) {
#if defined(__x86_64__)
    case TetSimd::kAvx512:
      return evaluate_range_avx512<kMooneyRivlin, kForces, kStride>(body, y, forces, begin, end,
                                                                    first_inverted, tet_pressure);
    case TetSimd::kAvx2:
      return evaluate_range_avx2<kMooneyRivlin, kForces, kStride>(body, y, forces, begin, end, first_inverted,
                                                                  tet_pressure);
#endif
    default:
      return evaluate_range_generic<kMooneyRivlin, kForces, kStride>(body, y, forces, begin, end,
                                                                     first_inverted, tet_pressure);
  }
}

// The padded force accumulator of the calling thread: 4 doubles per vertex,
// 32-byte aligned (ScatterForces). Kept per thread and reused, so a flow step
// allocates nothing once it has run; the OpenMP team's threads persist.
class PaddedForces {
 public:
  explicit PaddedForces(std::size_t num_vertices) : num_vertices_(num_vertices) {
    thread_local std::vector<double> storage;
    if (storage.size() < 4 * num_vertices + 4) storage.resize(4 * num_vertices + 4);
    const std::uintptr_t address = reinterpret_cast<std::uintptr_t>(storage.data());
    data_ = storage.data() + (32 - address % 32) % 32 / sizeof(double);
  }
  double* data() const { return data_; }
  // acc = the caller's forces (3 per vertex) and zero padding: the tet sums
  // then continue from them in the same order as a direct scatter.
  void load(const double* forces) const {
    for (std::size_t v = 0; v < num_vertices_; ++v) {
      for (int i = 0; i < 3; ++i) data_[4 * v + i] = forces[3 * v + i];
      data_[4 * v + 3] = 0.0;
    }
  }
  void clear() const { std::fill(data_, data_ + 4 * num_vertices_, 0.0); }
  void store(double* forces) const {
    for (std::size_t v = 0; v < num_vertices_; ++v) {
      for (int i = 0; i < 3; ++i) forces[3 * v + i] = data_[4 * v + i];
    }
  }

 private:
  std::size_t num_vertices_;
  double* data_;
};

// Deformed volume v = det[y1 - y4, y2 - y4, y3 - y4] / 6 of a tetrahedron.
double deformed_volume(const double* y, const std::int32_t* v) {
  const double* y3 = y + 3 * static_cast<std::int64_t>(v[3]);
  double d[9];
  for (int k = 0; k < 3; ++k) {
    const double* yk = y + 3 * static_cast<std::int64_t>(v[k]);
    for (int i = 0; i < 3; ++i) d[3 * i + k] = yk[i] - y3[i];
  }
  return (d[0] * (d[4] * d[8] - d[5] * d[7]) + d[1] * (d[5] * d[6] - d[3] * d[8]) +
          d[2] * (d[3] * d[7] - d[4] * d[6])) /
         6.0;
}

}  // namespace

namespace detail {

// kNodalAverage: the vertex pressures p_a = (kappa V)_a / V_a (Jbar_a - 1),
// Jbar_a = v_a / V_a with v_a = sum_{t at a} v_t / 4, and per tet the mean of
// its four vertices' pressures (tet_pressure, one per tet). Returns the
// volumetric energy sum_a (kappa V)_a / 2 (Jbar_a - 1)^2. Its gradient is
// sum_a p_a dv_a/dy = sum_t tet_pressure_t V0_t dJ_t/dy, so the tet stress
// takes tet_pressure_t cof(F) (dJ/dF = cof F).
double volumetric_pressures(const ElasticBody& body, const double* y, int team,
                            std::vector<double>& tet_pressure) {
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  const std::int64_t num_vertices = static_cast<std::int64_t>(body.num_vertices);
  const std::int32_t* tets = body.tets.data();
  std::vector<double> tet_volume(static_cast<std::size_t>(num_tets));
  std::vector<double> vertex_pressure(static_cast<std::size_t>(num_vertices), 0.0);
  tet_pressure.resize(static_cast<std::size_t>(num_tets));
  double energy = 0.0;
#pragma omp parallel num_threads(team) reduction(+ : energy)
  {
#pragma omp for schedule(static)
    for (std::int64_t t = 0; t < num_tets; ++t) tet_volume[t] = deformed_volume(y, tets + 4 * t);
#pragma omp for schedule(static)
    for (std::int64_t a = 0; a < num_vertices; ++a) {
      const double volume = body.vertex_volume_m3[a];
      if (volume <= 0.0) continue;  // a vertex of no tet
      double deformed = 0.0;
      for (std::int64_t k = body.vertex_tet_offsets[a]; k < body.vertex_tet_offsets[a + 1]; ++k)
        deformed += tet_volume[body.vertex_tets[k]];
      // Jbar_a - 1 = v_a / V_a - 1
      const double excess = 0.25 * deformed / volume - 1.0;
      vertex_pressure[a] = body.vertex_bulk_volume_j[a] / volume * excess;
      energy += 0.5 * body.vertex_bulk_volume_j[a] * excess * excess;
    }
#pragma omp for schedule(static)
    for (std::int64_t t = 0; t < num_tets; ++t) {
      const std::int32_t* v = tets + 4 * t;
      tet_pressure[t] = 0.25 * (vertex_pressure[v[0]] + vertex_pressure[v[1]] + vertex_pressure[v[2]] +
                                vertex_pressure[v[3]]);
    }
  }
  return energy;
}

}  // namespace detail

namespace {

// Tets are split into one contiguous range per thread. Every thread scatters
// into its own padded accumulator (PaddedForces), thread 0's starting from
// forces_n, the others' from zero; the others are added to thread 0's
// afterwards: no two threads write the same memory, and every thread streams
// its tets in order (faster than colouring here, see bench/elastic). The sums
// are those of a direct scatter into forces_n (thread 0) and into zeroed
// private buffers (the others).
template <bool kMooneyRivlin, bool kForces>
ElasticEvaluation evaluate(const ElasticBody& body, const double* y, double* forces, int threads) {
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  const std::int64_t num_vertices = static_cast<std::int64_t>(body.num_vertices);
  const int team = team_size(threads, num_tets, kMinForceTetsPerThread);
  ElasticEvaluation result;
  std::int64_t first_inverted = kNoTet;
  std::vector<double> pressure;
  double volumetric_energy = 0.0;
  if (body.volumetric == VolumetricTerm::kNodalAverage) {
    volumetric_energy = volumetric_pressures(body, y, team, pressure);
  }
  const double* tet_pressure = pressure.empty() ? nullptr : pressure.data();
  if (team == 1) {
    if constexpr (kForces) {
      const PaddedForces acc(body.num_vertices);
      acc.load(forces);
      result.energy_j = evaluate_range<kMooneyRivlin, kForces, 4>(body, y, acc.data(), 0, num_tets,
                                                                  first_inverted, tet_pressure);
      acc.store(forces);
    } else {
      result.energy_j =
          evaluate_range<kMooneyRivlin, kForces>(body, y, nullptr, 0, num_tets, first_inverted, tet_pressure);
    }
  } else {
    // The team's accumulators, for the reduction: the calling thread's list,
    // kept (no allocation per call) and read through a plain pointer, since
    // inside the region the name would mean each thread's own list.
    thread_local std::vector<const double*> accumulator_list;
    accumulator_list.assign(static_cast<std::size_t>(team), nullptr);
    const double** accumulators = accumulator_list.data();
    double energy = 0.0;
#pragma omp parallel num_threads(team) reduction(+ : energy) reduction(min : first_inverted)
    {
      const int rank = omp_get_thread_num();
      const int size = omp_get_num_threads();
      const std::int64_t begin = num_tets * rank / size;
      const std::int64_t end = num_tets * (rank + 1) / size;
      if constexpr (kForces) {
        const PaddedForces acc(body.num_vertices);
        if (rank == 0) {
          acc.load(forces);
        } else {
          acc.clear();
        }
        accumulators[rank] = acc.data();
        energy = evaluate_range<kMooneyRivlin, kForces, 4>(body, y, acc.data(), begin, end, first_inverted,
                                                           tet_pressure);
#pragma omp barrier
#pragma omp for schedule(static)
        for (std::int64_t v = 0; v < num_vertices; ++v) {
          for (int i = 0; i < 3; ++i) {
            double sum = 0.0;
            for (int r = 1; r < size; ++r) sum += accumulators[r][4 * v + i];
            forces[3 * v + i] = accumulators[0][4 * v + i] + sum;
          }
        }
      } else {
        energy = evaluate_range<kMooneyRivlin, kForces>(body, y, nullptr, begin, end, first_inverted,
                                                        tet_pressure);
      }
    }
    result.energy_j = energy;
  }
  result.energy_j += volumetric_energy;
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

// add_elastic_forces_of_range over [begin, end): through a padded accumulator
// when the range is long enough to pay for copying the forces in and out
// (same bits either way).
template <bool kMooneyRivlin>
double forces_of_range(const ElasticBody& body, const double* y, double* forces, std::int64_t begin,
                       std::int64_t end, std::int64_t& first_inverted, const double* tet_pressure,
                       TetSimd simd) {
  if (2 * (end - begin) < static_cast<std::int64_t>(body.num_vertices)) {
    return evaluate_range<kMooneyRivlin, true>(body, y, forces, begin, end, first_inverted, tet_pressure,
                                               simd);
  }
  const PaddedForces acc(body.num_vertices);
  acc.load(forces);
  const double energy = evaluate_range<kMooneyRivlin, true, 4>(body, y, acc.data(), begin, end,
                                                               first_inverted, tet_pressure, simd);
  acc.store(forces);
  return energy;
}

// ---------------------------------------------------------------------------
// The single-precision force loop (ForcePrecision::kFloat, the flow scenes'
// option), over the same lane blocks of kLanes tets, run in chunks of one
// register (4 lanes SSE2, 8 AVX2, 16 AVX-512; 8 AVX2 lanes instead of the
// double loop's 4), reading the float copies of B, V0 and the moduli in
// ElasticBody. Mooney-Rivlin: the stages of tet_kernel.h instantiated for
// float (float_tet_lane); neo-Hookean: float_neo_hookean_lane, the same
// forces with a quarter fewer products. The positions come as 4 floats per vertex
// (x, y, z, 0), relative to the centre c of their bounding box: F = D B
// needs only differences of positions, and |y - c| <= the body's half size
// keeps D to float round-off of the edge (about 1e-7 of the cell's size);
// the box offset of a flow cell would otherwise cost its digits. The forces
// are summed per vertex in a padded float accumulator (4 floats per vertex)
// and added to the caller's double forces at the end; the energy is summed
// over lanes in double. Gather and scatter are 128-bit loads and adds (one
// tet corner each) and 4x4 transposes, done on 4 lanes at a time by the
// generic copy and on 8 / 16 at once by the AVX2 / AVX-512 ones; they only
// move values and the adds keep one order, so with no FMA contraction every
// level gives the same bits here too.

struct FloatTetBlock {
  // y[n % 2][kLanes (3 a + i) + lane] = y_i - c_i of local vertex a in block
  // n: the loop gathers block n + 1 while block n runs (below).
  alignas(64) float y[2][12 * kLanes];
  alignas(64) float forces[12 * kLanes];  // forces[kLanes (3 a + i) + lane] = f_i of local vertex a
  alignas(64) float energy[kLanes];       // V0 U of each lane
  alignas(64) float det_f[kLanes];        // J of each lane
};

// The stages of one tet in a lane of the float loop: B (b), positions (y),
// forces stride kLanes, the tensors in a TetStressLanes<1> local to the call
// (registers once inlined and unrolled, not the block's memory). A local
// declared in the omp simd loop itself would become an "omp simd array",
// which GCC 12 does not vectorise; inside the inlined call it is plain.
template <bool kMooneyRivlin>
inline __attribute__((always_inline)) void float_tet_lane(const float* b, const float* y, float mu1,
                                                          float mu2, float kappa, float pressure,
                                                          float volume, float* det_f_out, float* energy_out,
                                                          float* forces) {
  kernel::TetStressLanes<1, float> s;
  float bl[9];
  for (int k = 0; k < 9; ++k) bl[k] = b[kLanes * k];
  const float det_f = kernel::deformation_gradient<1, kLanes>(bl, y, y + 3 * kLanes, y + 6 * kLanes,
                                                              y + 9 * kLanes, s.f, s.cof);
  s.det_f[0] = det_f;
  *det_f_out = det_f;
  // J^-1/3; an inverted lane (J <= 0) gets a harmless J = 1 and is skipped by the caller.
  const float j_m13 = kernel::inverse_cube_root(kernel::one_if_not_positive(det_f));
  // The stress comes scaled by -V0 for the forces.
  kernel::stress_from_gradient<kMooneyRivlin, 1, false, float>(mu1, mu2, kappa, j_m13, s, 0, pressure,
                                                               -volume);
  *energy_out = volume * s.energy_density[0];
  float fl[12];
  kernel::forces_from_scaled_stress<1>(bl, s.stress, fl);
  for (int k = 0; k < 12; ++k) forces[kLanes * k] = fl[k];
}

// The neo-Hookean lane (w = 1, the flow scenes' default) with a quarter
// fewer products than the stages of tet_kernel.h: with F = D B, M = B B^T
// and cof(D B) = cof(D) cof(B), cof(B) B^T = det(B) 1 (nh: the rows of
// ElasticBody::float_block_neo_hookean),
//   f^a_i = -V0 P_il B_al = s_F (D M)_ia + s_cof det(B) cof(D)_ia   (paper eq. 9-10, a = 1..3),
//   T_C = F:F = D:(D M), J = det(D) det(B)   (paper eq. 2-3),
// so neither F nor cof(F) is formed (100 products a tet instead of 135).
template <bool kNodal>
inline __attribute__((always_inline)) void float_neo_hookean_lane(const float* nh, const float* y, float mu1,
                                                                  float kappa, float pressure, float volume,
                                                                  float* det_f_out, float* energy_out,
                                                                  float* forces) {
  // D_ik = y_i^k - y_i^4   (paper eq. 11)
  float d[9];
  for (int i = 0; i < 3; ++i) {
    const float y4 = y[kLanes * (9 + i)];
    for (int k = 0; k < 3; ++k) d[3 * i + k] = y[kLanes * (3 * k + i)] - y4;
  }
  const float m00 = nh[0], m11 = nh[kLanes], m22 = nh[kLanes * 2];
  const float m01 = nh[kLanes * 3], m02 = nh[kLanes * 4], m12 = nh[kLanes * 5];
  const float det_b = nh[kLanes * 6];
  // G = D M = F B^T
  float g[9];
  for (int i = 0; i < 3; ++i) {
    const float d0 = d[3 * i], d1 = d[3 * i + 1], d2 = d[3 * i + 2];
    g[3 * i] = d0 * m00 + d1 * m01 + d2 * m02;
    g[3 * i + 1] = d0 * m01 + d1 * m11 + d2 * m12;
    g[3 * i + 2] = d0 * m02 + d1 * m12 + d2 * m22;
  }
  // T_C = tr C = F:F = D:G   (paper eq. 3-4)
  float trace_c = 0.0f;
  for (int k = 0; k < 9; ++k) trace_c += d[k] * g[k];
  // cof(D)
  float cd[9];
  cd[0] = d[4] * d[8] - d[5] * d[7];
  cd[1] = d[5] * d[6] - d[3] * d[8];
  cd[2] = d[3] * d[7] - d[4] * d[6];
  cd[3] = d[2] * d[7] - d[1] * d[8];
  cd[4] = d[0] * d[8] - d[2] * d[6];
  cd[5] = d[1] * d[6] - d[0] * d[7];
  cd[6] = d[1] * d[5] - d[2] * d[4];
  cd[7] = d[2] * d[3] - d[0] * d[5];
  cd[8] = d[0] * d[4] - d[1] * d[3];
  // J = det F = det(D) det(B)   (paper eq. 3), signed
  const float det_f = (d[0] * cd[0] + d[1] * cd[1] + d[2] * cd[2]) * det_b;
  *det_f_out = det_f;
  // J^-1/3; an inverted lane (J <= 0) gets a harmless J = 1 and is skipped
  // by the caller (std::max here would become a branch and stop the loop
  // vectorising: measured 3.6 x slower).
  const float j_m13 = kernel::inverse_cube_root(kernel::one_if_not_positive(det_f));
  const float j_m23 = j_m13 * j_m13;
  const float inv_det = j_m23 * j_m13;
  const float jm1 = det_f - 1.0f;
  // I = T_C J^-2/3; U = mu1/2 (I - 3) + kappa/2 (J - 1)^2   (paper eq. 3, 5)
  const float inv_i = trace_c * j_m23;
  const float twice_energy = kNodal ? mu1 * (inv_i - 3.0f) : mu1 * (inv_i - 3.0f) + kappa * jm1 * jm1;
  *energy_out = volume * (0.5f * twice_energy);
  // dU/dF = c_F F + c_cof cof(F): c_F = mu1 J^-2/3, c_cof = -mu1/3 T_C J^-5/3 + kappa (J - 1) + p
  const float scaled_f = -volume * (mu1 * j_m23);
  const float volumetric = kNodal ? pressure : kappa * jm1;
  const float scaled_cof = -volume * (-(1.0f / 3.0f) * mu1 * inv_i * inv_det + volumetric) * det_b;
  for (int i = 0; i < 3; ++i) {
    const float f0 = scaled_f * g[3 * i] + scaled_cof * cd[3 * i];
    const float f1 = scaled_f * g[3 * i + 1] + scaled_cof * cd[3 * i + 1];
    const float f2 = scaled_f * g[3 * i + 2] + scaled_cof * cd[3 * i + 2];
    forces[kLanes * i] = f0;
    forces[kLanes * (3 + i)] = f1;
    forces[kLanes * (6 + i)] = f2;
    forces[kLanes * (9 + i)] = -(f0 + f1 + f2);
  }
}

// The positions of the 4 vertices of the kLanes tets of a block from y4
// (4 floats per vertex, 16-byte aligned) into the rows of FloatTetBlock::y.
// Only copies, so every level gives the same bits. Generic (SSE2): per
// corner and 4 lanes, four 128-bit loads and a 4x4 transpose (7 shuffles).
// AVX2 / AVX-512: the same transpose on 8 / 16 lanes at once (below). The
// shuffles share one port with the 512-bit arithmetic on Intel (perf
// annotate, bench/elastic: gather and scatter were 40 % of the loop); vector
// gathers (vgatherdps, 3 per corner) measured slower still on the AVX-512
// VM: flow cell 114 against 136 M tets/s with these transposes.
using GatherFloatPositions = void (*)(const float* y4, const std::int32_t* vertices, float* y_lanes);

inline __attribute__((always_inline)) void gather_float_positions_generic(const float* y4,
                                                                          const std::int32_t* vertices,
                                                                          float* y_lanes) {
#if defined(__x86_64__)
  for (int a = 0; a < 4; ++a) {
    for (int c = 0; c < kLanes; c += 4) {
      const std::int32_t* v = vertices + kLanes * a + c;
      const __m128 p0 = _mm_load_ps(y4 + 4 * static_cast<std::int64_t>(v[0]));
      const __m128 p1 = _mm_load_ps(y4 + 4 * static_cast<std::int64_t>(v[1]));
      const __m128 p2 = _mm_load_ps(y4 + 4 * static_cast<std::int64_t>(v[2]));
      const __m128 p3 = _mm_load_ps(y4 + 4 * static_cast<std::int64_t>(v[3]));
      const __m128 xy01 = _mm_unpacklo_ps(p0, p1);  // x0 x1 y0 y1
      const __m128 xy23 = _mm_unpacklo_ps(p2, p3);  // x2 x3 y2 y3
      const __m128 zw01 = _mm_unpackhi_ps(p0, p1);  // z0 z1 0 0
      const __m128 zw23 = _mm_unpackhi_ps(p2, p3);  // z2 z3 0 0
      _mm_store_ps(y_lanes + kLanes * (3 * a) + c, _mm_movelh_ps(xy01, xy23));
      _mm_store_ps(y_lanes + kLanes * (3 * a + 1) + c, _mm_movehl_ps(xy23, xy01));
      _mm_store_ps(y_lanes + kLanes * (3 * a + 2) + c, _mm_movelh_ps(zw01, zw23));
    }
  }
#else
  for (int a = 0; a < 4; ++a) {
    for (int lane = 0; lane < kLanes; ++lane) {
      const float* ya = y4 + 4 * static_cast<std::int64_t>(vertices[kLanes * a + lane]);
      for (int i = 0; i < 3; ++i) y_lanes[kLanes * (3 * a + i) + lane] = ya[i];
    }
  }
#endif
}
#if defined(__x86_64__)
// _mm512_unpack{lo,hi}_ps with every lane kept: the same instruction, but
// GCC 12's plain intrinsics pass an undefined register and warn
// (-Wmaybe-uninitialized) wherever they are inlined.
__attribute__((target("avx512f"))) inline __m512 unpacklo_ps512(__m512 a, __m512 b) {
  return _mm512_maskz_unpacklo_ps(0xffff, a, b);
}
__attribute__((target("avx512f"))) inline __m512 unpackhi_ps512(__m512 a, __m512 b) {
  return _mm512_maskz_unpackhi_ps(0xffff, a, b);
}
#endif
#if defined(__x86_64__)
// One body for AVX2 (V = __m256, 8 lanes) and AVX-512 (__m512, 16 lanes):
// per corner and register of lanes, the vertices of lanes c + 4 j + k
// (j = 0 .. kWidth / 4 - 1) loaded into the 128-bit parts of p[k] (a load
// and kWidth / 4 - 1 inserts), then the 4x4 transpose of the generic copy on
// all parts at once: 7 shuffles per kWidth lanes instead of per 4.
#define CELLFLOW_GATHER_FLOAT_POSITIONS(name, isa, V, kWidth, widen, insert, store, unpacklo, unpackhi, \
                                        shuffle)                                                        \
  __attribute__((target(isa))) inline void name(const float* y4, const std::int32_t* vertices,          \
                                                float* y_lanes) {                                       \
    for (int a = 0; a < 4; ++a) {                                                                       \
      for (int c = 0; c < kLanes; c += kWidth) {                                                        \
        const std::int32_t* v = vertices + kLanes * a + c;                                              \
        V p[4];                                                                                         \
        for (int k = 0; k < 4; ++k) {                                                                   \
          p[k] = widen(_mm_load_ps(y4 + 4 * static_cast<std::int64_t>(v[k])));                          \
          for (int j = 1; j < kWidth / 4; ++j) {                                                        \
            p[k] = insert(p[k], _mm_load_ps(y4 + 4 * static_cast<std::int64_t>(v[4 * j + k])), j);      \
          }                                                                                             \
        }                                                                                               \
        const V xy01 = unpacklo(p[0], p[1]); /* x0 x1 y0 y1 in every part */                            \
        const V xy23 = unpacklo(p[2], p[3]);                                                            \
        const V zw01 = unpackhi(p[0], p[1]); /* z0 z1 0 0 */                                            \
        const V zw23 = unpackhi(p[2], p[3]);                                                            \
        store(y_lanes + kLanes * (3 * a) + c, shuffle(xy01, xy23, 0x44));                               \
        store(y_lanes + kLanes * (3 * a + 1) + c, shuffle(xy01, xy23, 0xee));                           \
        store(y_lanes + kLanes * (3 * a + 2) + c, shuffle(zw01, zw23, 0x44));                           \
      }                                                                                                 \
    }                                                                                                   \
  }
CELLFLOW_GATHER_FLOAT_POSITIONS(gather_float_positions_avx2, "avx2", __m256, 8, _mm256_zextps128_ps256,
                                _mm256_insertf128_ps, _mm256_store_ps, _mm256_unpacklo_ps, _mm256_unpackhi_ps,
                                _mm256_shuffle_ps)
CELLFLOW_GATHER_FLOAT_POSITIONS(gather_float_positions_avx512, "avx512f,avx512vl,avx512dq,avx512bw", __m512,
                                16, _mm512_zextps128_ps512, _mm512_insertf32x4, _mm512_store_ps,
                                unpacklo_ps512, unpackhi_ps512, _mm512_shuffle_ps)
#undef CELLFLOW_GATHER_FLOAT_POSITIONS
#endif

// The forces of a full block (FloatTetBlock::forces layout) added into the
// float accumulator (acc[4 v + i], acc[4 v + 3] padding that receives zeros)
// as one 128-bit add of (f_x, f_y, f_z, 0) per tet corner, corner after
// corner and within a corner lane after lane: the same additions in the same
// order on every level, so every level gives the same bits. The levels
// differ in how the (x, y, z) rows become corners: generic, per 4 lanes a
// 4x4 transpose (8 shuffles); AVX2 / AVX-512, the same unpacks on 8 / 16
// lanes at once (8 shuffles per 8 / 16 lanes), then one corner at a time
// from a staging row (GCC keeps it in registers and extracts the 128-bit
// parts; forcing the stores and loads measured 10 % slower).
using ScatterFloatForces = void (*)(const float* f_lanes, const std::int32_t* vertices, float* acc);

inline __attribute__((always_inline)) void scatter_float_forces_generic(const float* f_lanes,
                                                                        const std::int32_t* vertices,
                                                                        float* acc) {
#if defined(__x86_64__)
  const __m128 zero = _mm_setzero_ps();
  for (int a = 0; a < 4; ++a) {
    for (int c = 0; c < kLanes; c += 4) {
      const __m128 x = _mm_load_ps(f_lanes + kLanes * (3 * a) + c);
      const __m128 y = _mm_load_ps(f_lanes + kLanes * (3 * a + 1) + c);
      const __m128 z = _mm_load_ps(f_lanes + kLanes * (3 * a + 2) + c);
      const __m128 xy01 = _mm_unpacklo_ps(x, y);    // x0 y0 x1 y1
      const __m128 xy23 = _mm_unpackhi_ps(x, y);    // x2 y2 x3 y3
      const __m128 z01 = _mm_unpacklo_ps(z, zero);  // z0 0 z1 0
      const __m128 z23 = _mm_unpackhi_ps(z, zero);  // z2 0 z3 0
      const __m128 corner[4] = {_mm_movelh_ps(xy01, z01), _mm_movehl_ps(z01, xy01), _mm_movelh_ps(xy23, z23),
                                _mm_movehl_ps(z23, xy23)};
      const std::int32_t* v = vertices + kLanes * a + c;
      for (int l = 0; l < 4; ++l) {
        float* out = acc + 4 * static_cast<std::int64_t>(v[l]);
        _mm_store_ps(out, _mm_add_ps(_mm_load_ps(out), corner[l]));
      }
    }
  }
#else
  for (int a = 0; a < 4; ++a) {
    for (int lane = 0; lane < kLanes; ++lane) {
      float* out = acc + 4 * static_cast<std::int64_t>(vertices[kLanes * a + lane]);
      for (int i = 0; i < 3; ++i) out[i] += f_lanes[kLanes * (3 * a + i) + lane];
    }
  }
#endif
}
#if defined(__x86_64__)
// One body for AVX2 (V = __m256, 8 lanes) and AVX-512 (__m512, 16 lanes):
// the in-lane unpacks leave in 128-bit part j of corners[k] the corner of
// lane c + 4 j + k, stored at staging[4 (kWidth k / 4 + j)].
#define CELLFLOW_SCATTER_FLOAT_FORCES(name, isa, V, kWidth, load, store, unpacklo, unpackhi, shuffle, zero) \
  __attribute__((target(isa))) inline void name(const float* f_lanes, const std::int32_t* vertices,         \
                                                float* acc) {                                               \
    alignas(64) float staging[4 * kWidth];                                                                  \
    const V z0 = zero();                                                                                    \
    for (int a = 0; a < 4; ++a) {                                                                           \
      for (int c = 0; c < kLanes; c += kWidth) {                                                            \
        const V x = load(f_lanes + kLanes * (3 * a) + c);                                                   \
        const V y = load(f_lanes + kLanes * (3 * a + 1) + c);                                               \
        const V z = load(f_lanes + kLanes * (3 * a + 2) + c);                                               \
        const V xy01 = unpacklo(x, y);                                                                      \
        const V xy23 = unpackhi(x, y);                                                                      \
        const V z01 = unpacklo(z, z0);                                                                      \
        const V z23 = unpackhi(z, z0);                                                                      \
        store(staging, shuffle(xy01, z01, 0x44));                                                           \
        store(staging + kWidth, shuffle(xy01, z01, 0xee));                                                  \
        store(staging + 2 * kWidth, shuffle(xy23, z23, 0x44));                                              \
        store(staging + 3 * kWidth, shuffle(xy23, z23, 0xee));                                              \
        const std::int32_t* v = vertices + kLanes * a + c;                                                  \
        for (int l = 0; l < kWidth; ++l) {                                                                  \
          float* out = acc + 4 * static_cast<std::int64_t>(v[l]);                                           \
          const float* corner = staging + kWidth * (l % 4) + 4 * (l / 4);                                   \
          _mm_store_ps(out, _mm_add_ps(_mm_load_ps(out), _mm_load_ps(corner)));                             \
        }                                                                                                   \
      }                                                                                                     \
    }                                                                                                       \
  }
CELLFLOW_SCATTER_FLOAT_FORCES(scatter_float_forces_avx2, "avx2", __m256, 8, _mm256_load_ps, _mm256_store_ps,
                              _mm256_unpacklo_ps, _mm256_unpackhi_ps, _mm256_shuffle_ps, _mm256_setzero_ps)
CELLFLOW_SCATTER_FLOAT_FORCES(scatter_float_forces_avx512, "avx512f,avx512vl,avx512dq,avx512bw", __m512, 16,
                              _mm512_load_ps, _mm512_store_ps, unpacklo_ps512, unpackhi_ps512,
                              _mm512_shuffle_ps, _mm512_setzero_ps)
#undef CELLFLOW_SCATTER_FLOAT_FORCES
#endif

// sum_l e[l] over the kLanes lanes of a block in double, as a fixed tree
// (lanes l and l + 8, then l + 4, l + 2, l + 1; written out: as a loop over
// the widths GCC kept the partial sums in memory). Plain code, so every
// level makes the same additions in the same order.
inline __attribute__((always_inline)) double lane_tree_sum(const float* e) {
  static_assert(kLanes == 16);
  double s8[8], s4[4];
  for (int l = 0; l < 8; ++l) s8[l] = static_cast<double>(e[l]) + static_cast<double>(e[l + 8]);
  for (int l = 0; l < 4; ++l) s4[l] = s8[l] + s8[l + 4];
  return (s4[0] + s4[2]) + (s4[1] + s4[3]);
}

// Energy and forces (into the float accumulator acc) of tets [begin, end) in
// float; as evaluate_range_body otherwise. tet_pressure (kNodalAverage) in
// float too.
template <bool kMooneyRivlin, bool kNodal, int kChunk, GatherFloatPositions kGather,
          ScatterFloatForces kScatter>
inline __attribute__((always_inline)) double evaluate_float_range_body(const ElasticBody& body,
                                                                       const float* y4, float* acc,
                                                                       std::int64_t begin, std::int64_t end,
                                                                       std::int64_t& first_inverted,
                                                                       const float* tet_pressure) {
  const float* block_b = body.float_block_b_matrix.data();
  const std::int32_t* block_vertices = body.block_vertices.data();
  const float* volume = body.float_ref_volume_m3.data();
  const float* mu1 = body.float_mu1_pa.data();
  const float* mu2 = body.float_mu2_pa.data();
  const float* kappa = body.float_kappa_pa.data();
  // kNodal (tet_pressure given): no kappa term, the pressure instead; one
  // copy each, so that neither costs a product in the lane loop.
  const float* pressure = kNodal ? tet_pressure : kappa;
  FloatTetBlock blk;
  double energy = 0.0;
  // The positions of the next block are gathered before the lane loop of
  // this one, so that the gather's loads (L2 latency for a flow cell's 3000
  // vertices) overlap the arithmetic instead of stalling the next block.
  const std::int64_t first_block = begin / kLanes;
  const std::int64_t end_block = (end + kLanes - 1) / kLanes;
  if (first_block < end_block) kGather(y4, block_vertices + 4 * kLanes * first_block, blk.y[0]);
  for (std::int64_t block = first_block; block < end_block; ++block) {
    const std::int64_t first = block * kLanes;
    const int lane_begin = static_cast<int>(std::max<std::int64_t>(0, begin - first));
    const int lane_end = static_cast<int>(std::min<std::int64_t>(kLanes, end - first));
    const float* b = block_b + 9 * kLanes * block;
    const float* nh = body.float_block_neo_hookean.data() + kFloatNeoHookeanRows * kLanes * block;
    const std::int32_t* v0 = block_vertices + 4 * kLanes * block;
    const float* y_block = blk.y[(block - first_block) % 2];
    if (block + 1 < end_block) kGather(y4, v0 + 4 * kLanes, blk.y[(block - first_block + 1) % 2]);
    const float* volume_b = volume + first;
    const float* mu1_b = mu1 + first;
    const float* mu2_b = mu2 + first;
    const float* kappa_b = kappa + first;
    const float* pressure_b = pressure + first;
    const auto run_lanes = [&](int lo, int hi) __attribute__((always_inline)) {
#pragma omp simd
      for (int lane = lo; lane < hi; ++lane) {
        const float kappa_l = kNodal ? 0.0f : kappa_b[lane];
        const float pressure_l = kNodal ? pressure_b[lane] : 0.0f;
        if constexpr (kMooneyRivlin) {
          float_tet_lane<kMooneyRivlin>(b + lane, y_block + lane, mu1_b[lane], mu2_b[lane], kappa_l,
                                        pressure_l, volume_b[lane], blk.det_f + lane, blk.energy + lane,
                                        blk.forces + lane);
        } else {
          float_neo_hookean_lane<kNodal>(nh + lane, y_block + lane, mu1_b[lane], kappa_l, pressure_l,
                                         volume_b[lane], blk.det_f + lane, blk.energy + lane,
                                         blk.forces + lane);
        }
      }
    };
    // Chunks of kChunk lanes (one register a value: kChunk = the level's
    // float width), one after the other, so that the values of one chunk fit
    // the register file.
    if (lane_begin == 0 && lane_end == kLanes) {
#pragma GCC unroll 1
      for (int c = 0; c < kLanes; c += kChunk) run_lanes(c, c + kChunk);
    } else {
      run_lanes(lane_begin, lane_end);
    }
    // Inverted lanes counted by a vector loop and a full block's energies
    // summed as a tree (a compare and a branch per lane, then a chain of 16
    // dependent double adds, took 9 % of the loop).
    int inverted_lanes = 0;
#pragma omp simd reduction(+ : inverted_lanes)
    for (int lane = 0; lane < kLanes; ++lane) inverted_lanes += blk.det_f[lane] <= 0.0f ? 1 : 0;
    if (lane_begin == 0 && lane_end == kLanes && inverted_lanes == 0) {
      energy += lane_tree_sum(blk.energy);
      kScatter(blk.forces, v0, acc);
    } else {
      for (int lane = lane_begin; lane < lane_end; ++lane) {
        if (blk.det_f[lane] <= 0.0f) {
          first_inverted = std::min(first_inverted, first + lane);
          continue;
        }
        energy += static_cast<double>(blk.energy[lane]);
        for (int a = 0; a < 4; ++a) {
          float* out = acc + 4 * static_cast<std::int64_t>(v0[kLanes * a + lane]);
          for (int i = 0; i < 3; ++i) out[i] += blk.forces[kLanes * (3 * a + i) + lane];
        }
      }
    }
  }
  return energy;
}

template <bool kMooneyRivlin, bool kNodal>
double evaluate_float_range_generic(const ElasticBody& body, const float* y4, float* acc, std::int64_t begin,
                                    std::int64_t end, std::int64_t& first_inverted,
                                    const float* tet_pressure) {
  return evaluate_float_range_body<kMooneyRivlin, kNodal, 4, gather_float_positions_generic,
                                   scatter_float_forces_generic>(body, y4, acc, begin, end, first_inverted,
                                                                 tet_pressure);
}
#if defined(__x86_64__)
template <bool kMooneyRivlin, bool kNodal>
__attribute__((target("avx2"))) double evaluate_float_range_avx2(const ElasticBody& body, const float* y4,
                                                                 float* acc, std::int64_t begin,
                                                                 std::int64_t end,
                                                                 std::int64_t& first_inverted,
                                                                 const float* tet_pressure) {
  return evaluate_float_range_body<kMooneyRivlin, kNodal, 8, gather_float_positions_avx2,
                                   scatter_float_forces_avx2>(body, y4, acc, begin, end, first_inverted,
                                                              tet_pressure);
}
template <bool kMooneyRivlin, bool kNodal>
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) double evaluate_float_range_avx512(
    const ElasticBody& body, const float* y4, float* acc, std::int64_t begin, std::int64_t end,
    std::int64_t& first_inverted, const float* tet_pressure) {
  return evaluate_float_range_body<kMooneyRivlin, kNodal, 16, gather_float_positions_avx512,
                                   scatter_float_forces_avx512>(body, y4, acc, begin, end, first_inverted,
                                                                tet_pressure);
}
#endif

template <bool kMooneyRivlin, bool kNodal>
double evaluate_float_range_level(const ElasticBody& body, const float* y4, float* acc, std::int64_t begin,
                                  std::int64_t end, std::int64_t& first_inverted, const float* tet_pressure,
                                  TetSimd simd) {
  switch (resolve_tet_simd(simd)) {
#if defined(__x86_64__)
    case TetSimd::kAvx512:
      return evaluate_float_range_avx512<kMooneyRivlin, kNodal>(body, y4, acc, begin, end, first_inverted,
                                                                tet_pressure);
    case TetSimd::kAvx2:
      return evaluate_float_range_avx2<kMooneyRivlin, kNodal>(body, y4, acc, begin, end, first_inverted,
                                                              tet_pressure);
#endif
    default:
      return evaluate_float_range_generic<kMooneyRivlin, kNodal>(body, y4, acc, begin, end, first_inverted,
                                                                 tet_pressure);
  }
}

template <bool kMooneyRivlin>
double evaluate_float_range(const ElasticBody& body, const float* y4, float* acc, std::int64_t begin,
                            std::int64_t end, std::int64_t& first_inverted, const float* tet_pressure,
                            TetSimd simd) {
  if (tet_pressure != nullptr) {
    return evaluate_float_range_level<kMooneyRivlin, true>(body, y4, acc, begin, end, first_inverted,
                                                           tet_pressure, simd);
  }
  return evaluate_float_range_level<kMooneyRivlin, false>(body, y4, acc, begin, end, first_inverted, nullptr,
                                                          simd);
}

// 4 floats per vertex of the calling thread, 32-byte aligned, kept and
// reused (no allocation per call once sized): the float positions and the
// float force accumulators.
float* float_vertex_buffer(std::vector<float>& storage, std::size_t num_vertices) {
  if (storage.size() < 4 * num_vertices + 8) storage.resize(4 * num_vertices + 8);
  const std::uintptr_t address = reinterpret_cast<std::uintptr_t>(storage.data());
  return storage.data() + (32 - address % 32) % 32 / sizeof(float);
}

#if defined(__x86_64__)
// AVX-512 steps of the vertex loops below, 4 vertices (12 doubles, 16
// floats) at a time; each returns how many vertices it did (a multiple of
// 4), the SSE2 loops do the rest. The same exact operations element by
// element (min / max, differences, conversions, one add), so the same bits.
// The maskz forms with every lane kept are the plain instructions; GCC 12's
// plain intrinsics pass an undefined register and warn (-Wmaybe-uninitialized).
#define CELLFLOW_AVX512 __attribute__((target("avx512f,avx512vl,avx512dq,avx512bw")))
CELLFLOW_AVX512 std::size_t bounds_avx512(const double* y, std::size_t num_vertices, double* lo, double* hi) {
  const std::size_t n4 = num_vertices / 4 * 4;
  if (n4 == 0) return 0;
  // lanes (x y z x y z x y | z x y z)
  __m512d lo8 = _mm512_loadu_pd(y), hi8 = lo8;
  __m256d lo4 = _mm256_loadu_pd(y + 8), hi4 = lo4;
  for (std::size_t v = 4; v < n4; v += 4) {
    const __m512d a = _mm512_loadu_pd(y + 3 * v);
    const __m256d b = _mm256_loadu_pd(y + 3 * v + 8);
    lo8 = _mm512_maskz_min_pd(0xff, lo8, a);
    hi8 = _mm512_maskz_max_pd(0xff, hi8, a);
    lo4 = _mm256_min_pd(lo4, b);
    hi4 = _mm256_max_pd(hi4, b);
  }
  alignas(64) double l[12], h[12];
  _mm512_store_pd(l, lo8);
  _mm256_store_pd(l + 8, lo4);
  _mm512_store_pd(h, hi8);
  _mm256_store_pd(h + 8, hi4);
  for (int k = 0; k < 12; ++k) {
    lo[k % 3] = std::min(lo[k % 3], l[k]);
    hi[k % 3] = std::max(hi[k % 3], h[k]);
  }
  return n4;
}
CELLFLOW_AVX512 std::size_t convert_positions_avx512(const double* y, std::size_t num_vertices,
                                                     const double* c, float* y4) {
  const __m512d c8 = _mm512_setr_pd(c[0], c[1], c[2], c[0], c[1], c[2], c[0], c[1]);
  const __m256d c4 = _mm256_setr_pd(c[2], c[0], c[1], c[2]);
  // (x0 y0 z0 x1 y1 z1 x2 y2 | z2 x3 y3 z3 0 0 0 0) -> (x y z 0) x 4; element 12 is a zero
  const __m512i spread = _mm512_setr_epi32(0, 1, 2, 12, 3, 4, 5, 12, 6, 7, 8, 12, 9, 10, 11, 12);
  const std::size_t n4 = num_vertices / 4 * 4;
  for (std::size_t v = 0; v < n4; v += 4) {
    const __m256 first = _mm512_maskz_cvtpd_ps(0xff, _mm512_sub_pd(_mm512_loadu_pd(y + 3 * v), c8));
    const __m128 last = _mm256_cvtpd_ps(_mm256_sub_pd(_mm256_loadu_pd(y + 3 * v + 8), c4));
    const __m512 packed =
        _mm512_maskz_insertf32x8(0xffff, _mm512_maskz_insertf32x8(0xffff, _mm512_setzero_ps(), first, 0),
                                 _mm256_zextps128_ps256(last), 1);
    _mm512_storeu_ps(y4 + 4 * v, _mm512_maskz_permutexvar_ps(0xffff, spread, packed));
  }
  return n4;
}
CELLFLOW_AVX512 std::size_t add_float_forces_avx512(const float* acc, std::size_t num_vertices,
                                                    double* forces) {
  // (x y z 0) x 4 -> (x0 y0 z0 x1 y1 z1 x2 y2 | z2 x3 y3 z3)
  const __m512i pick = _mm512_setr_epi32(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, 0, 0, 0, 0);
  const std::size_t n4 = num_vertices / 4 * 4;
  for (std::size_t v = 0; v < n4; v += 4) {
    const __m512 a = _mm512_maskz_permutexvar_ps(0xffff, pick, _mm512_loadu_ps(acc + 4 * v));
    double* f = forces + 3 * v;
    _mm512_storeu_pd(f, _mm512_add_pd(_mm512_loadu_pd(f),
                                      _mm512_maskz_cvtps_pd(0xff, _mm512_maskz_extractf32x8_ps(0xff, a, 0))));
    _mm256_storeu_pd(f + 8, _mm256_add_pd(_mm256_loadu_pd(f + 8),
                                          _mm256_cvtps_pd(_mm512_maskz_extractf32x4_ps(0xf, a, 2))));
  }
  return n4;
}
#undef CELLFLOW_AVX512
#endif

// y4 = (y - c, 0) in float, c the centre of the bounding box of y. SSE2
// (every x86-64) and AVX-512 steps: min / max, the differences and the
// conversions are exact IEEE operations, so any grouping gives the same
// bits; as scalar loops they were 4 % (flow cell) to 9 % (196k-tet box) of
// a force call.
void float_positions(const double* y, std::size_t num_vertices, float* y4) {
  double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
  if (num_vertices > 0) {
    for (int i = 0; i < 3; ++i) lo[i] = hi[i] = y[i];
  }
  std::size_t v = 1;
#if defined(__x86_64__)
  const bool avx512 = best_tet_simd() == TetSimd::kAvx512;
  if (avx512) v = std::max<std::size_t>(v, bounds_avx512(y, num_vertices, lo, hi));
  // Two vertices (x y | z x | y z) a step, three pairs of running bounds.
  __m128d lo_xy = _mm_set_pd(lo[1], lo[0]), lo_zx = _mm_set_pd(lo[0], lo[2]),
          lo_yz = _mm_set_pd(lo[2], lo[1]);
  __m128d hi_xy = _mm_set_pd(hi[1], hi[0]), hi_zx = _mm_set_pd(hi[0], hi[2]),
          hi_yz = _mm_set_pd(hi[2], hi[1]);
  for (; v + 2 <= num_vertices; v += 2) {
    const double* p = y + 3 * v;
    const __m128d xy = _mm_loadu_pd(p), zx = _mm_loadu_pd(p + 2), yz = _mm_loadu_pd(p + 4);
    lo_xy = _mm_min_pd(lo_xy, xy);
    lo_zx = _mm_min_pd(lo_zx, zx);
    lo_yz = _mm_min_pd(lo_yz, yz);
    hi_xy = _mm_max_pd(hi_xy, xy);
    hi_zx = _mm_max_pd(hi_zx, zx);
    hi_yz = _mm_max_pd(hi_yz, yz);
  }
  alignas(16) double l[6], h[6];
  _mm_store_pd(l, lo_xy);
  _mm_store_pd(l + 2, lo_zx);
  _mm_store_pd(l + 4, lo_yz);
  _mm_store_pd(h, hi_xy);
  _mm_store_pd(h + 2, hi_zx);
  _mm_store_pd(h + 4, hi_yz);
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::min(l[i], l[i + 3]);
    hi[i] = std::max(h[i], h[i + 3]);
  }
#endif
  for (; v < num_vertices; ++v) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], y[3 * v + i]);
      hi[i] = std::max(hi[i], y[3 * v + i]);
    }
  }
  // + 0.0 turns a -0 centre into +0: c then does not depend on which signed
  // zero the bounds kept (min and max of +-0 depend on the order).
  const double c[3] = {0.5 * (lo[0] + hi[0]) + 0.0, 0.5 * (lo[1] + hi[1]) + 0.0, 0.5 * (lo[2] + hi[2]) + 0.0};
  std::size_t u = 0;
#if defined(__x86_64__)
  if (avx512) u = convert_positions_avx512(y, num_vertices, c, y4);
  // (x - c_x, y - c_y) and (z - c_z, 0 - 0) converted, packed to (x, y, z, 0).
  const __m128d c_xy = _mm_set_pd(c[1], c[0]), c_z = _mm_set_sd(c[2]);
  for (; u < num_vertices; ++u) {
    const double* p = y + 3 * u;
    const __m128 xy = _mm_cvtpd_ps(_mm_sub_pd(_mm_loadu_pd(p), c_xy));
    const __m128 z = _mm_cvtpd_ps(_mm_sub_pd(_mm_load_sd(p + 2), c_z));
    _mm_store_ps(y4 + 4 * u, _mm_movelh_ps(xy, z));
  }
#endif
  for (; u < num_vertices; ++u) {
    for (int i = 0; i < 3; ++i) y4[4 * u + i] = static_cast<float>(y[3 * u + i] - c[i]);
    y4[4 * u + 3] = 0.0f;
  }
}

// forces (3 doubles per vertex) += acc (4 floats per vertex), one double
// add per component (exact conversions: the same bits as scalar code).
void add_float_forces(const float* acc, std::size_t num_vertices, double* forces) {
  std::size_t v = 0;
#if defined(__x86_64__)
  if (best_tet_simd() == TetSimd::kAvx512) v = add_float_forces_avx512(acc, num_vertices, forces);
  for (; v < num_vertices; ++v) {
    const __m128 a = _mm_load_ps(acc + 4 * v);
    double* f = forces + 3 * v;
    _mm_storeu_pd(f, _mm_add_pd(_mm_loadu_pd(f), _mm_cvtps_pd(a)));
    f[2] += static_cast<double>(acc[4 * v + 2]);
  }
#endif
  for (; v < num_vertices; ++v) {
    for (int i = 0; i < 3; ++i) forces[3 * v + i] += static_cast<double>(acc[4 * v + i]);
  }
}

// A body without its float copies (assembled by hand) gets a blocked copy.
bool has_float_blocks(const ElasticBody& body) {
  const std::size_t num_blocks = (body.num_tets() + kLanes - 1) / kLanes;
  return body.float_block_b_matrix.size() == 9 * kLanes * num_blocks &&
         body.float_block_neo_hookean.size() == kFloatNeoHookeanRows * kLanes * num_blocks &&
         body.block_vertices.size() == 4 * kLanes * num_blocks &&
         body.float_ref_volume_m3.size() == kLanes * num_blocks &&
         body.float_mu1_pa.size() == kLanes * num_blocks && body.float_mu2_pa.size() == kLanes * num_blocks &&
         body.float_kappa_pa.size() == kLanes * num_blocks;
}

// kFloat forces of tets [begin, end) split over `team` threads as evaluate
// does: each thread sums into its own float accumulator (from zero), and
// forces_n += the accumulators (in double, thread after thread).
template <bool kMooneyRivlin>
ElasticEvaluation evaluate_float(const ElasticBody& body, const double* y, double* forces, std::int64_t begin,
                                 std::int64_t end, int team, TetSimd simd) {
  if (!has_float_blocks(body)) {
    ElasticBody blocked = body;
    build_lane_blocks(blocked);
    return evaluate_float<kMooneyRivlin>(blocked, y, forces, begin, end, team, simd);
  }
  const std::size_t num_vertices = body.num_vertices;
  ElasticEvaluation result;
  std::int64_t first_inverted = kNoTet;
  std::vector<double> pressure;
  thread_local std::vector<float> float_pressure;
  const float* tet_pressure = nullptr;
  if (body.volumetric == VolumetricTerm::kNodalAverage) {
    result.energy_j = volumetric_pressures(body, y, team, pressure);
    float_pressure.assign(pressure.begin(), pressure.end());
    float_pressure.resize(kLanes * ((body.num_tets() + kLanes - 1) / kLanes), 0.0f);
    tet_pressure = float_pressure.data();
  }
  thread_local std::vector<float> position_storage;
  float* y4 = float_vertex_buffer(position_storage, num_vertices);
  float_positions(y, num_vertices, y4);
  if (team == 1) {
    thread_local std::vector<float> acc_storage;
    float* acc = float_vertex_buffer(acc_storage, num_vertices);
    std::fill(acc, acc + 4 * num_vertices, 0.0f);
    result.energy_j +=
        evaluate_float_range<kMooneyRivlin>(body, y4, acc, begin, end, first_inverted, tet_pressure, simd);
    add_float_forces(acc, num_vertices, forces);
  } else {
    thread_local std::vector<const float*> accumulator_list;
    accumulator_list.assign(static_cast<std::size_t>(team), nullptr);
    const float** accumulators = accumulator_list.data();
    const std::int64_t count = end - begin;
    const std::int64_t nv = static_cast<std::int64_t>(num_vertices);
    double energy = 0.0;
#pragma omp parallel num_threads(team) reduction(+ : energy) reduction(min : first_inverted)
    {
      const int rank = omp_get_thread_num();
      const int size = omp_get_num_threads();
      const std::int64_t lo = begin + count * rank / size;
      const std::int64_t hi = begin + count * (rank + 1) / size;
      thread_local std::vector<float> acc_storage;
      float* acc = float_vertex_buffer(acc_storage, num_vertices);
      std::fill(acc, acc + 4 * num_vertices, 0.0f);
      accumulators[rank] = acc;
      energy = evaluate_float_range<kMooneyRivlin>(body, y4, acc, lo, hi, first_inverted, tet_pressure, simd);
#pragma omp barrier
#pragma omp for schedule(static)
      for (std::int64_t v = 0; v < nv; ++v) {
        for (int i = 0; i < 3; ++i) {
          double sum = forces[3 * v + i];
          for (int r = 0; r < size; ++r) sum += static_cast<double>(accumulators[r][4 * v + i]);
          forces[3 * v + i] = sum;
        }
      }
    }
    result.energy_j += energy;
  }
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

}  // namespace

ElasticEvaluation add_elastic_forces(const ElasticBody& body, const double* positions_m, double* forces_n,
                                     int threads) {
  if (body.quadratic()) {
    return detail::quadratic_forces(body, positions_m, forces_n, 0,
                                    static_cast<std::int64_t>(body.num_tets()));
  }
  if (body.neo_hookean) return evaluate<false, true>(body, positions_m, forces_n, threads);
  return evaluate<true, true>(body, positions_m, forces_n, threads);
}

ElasticEvaluation add_elastic_forces(const ElasticBody& body, const double* positions_m, double* forces_n,
                                     int threads, ForcePrecision precision) {
  if (precision == ForcePrecision::kDouble || body.quadratic())
    return add_elastic_forces(body, positions_m, forces_n, threads);
  const std::int64_t num_tets = static_cast<std::int64_t>(body.num_tets());
  const int team = team_size(threads, num_tets, kMinForceTetsPerThread);
  if (body.neo_hookean) {
    return evaluate_float<false>(body, positions_m, forces_n, 0, num_tets, team, TetSimd::kAuto);
  }
  return evaluate_float<true>(body, positions_m, forces_n, 0, num_tets, team, TetSimd::kAuto);
}

ElasticEvaluation add_elastic_forces_of_range(const ElasticBody& body, const double* positions_m,
                                              double* forces_n, std::int64_t begin_tet, std::int64_t end_tet,
                                              TetSimd simd, ForcePrecision precision) {
  if (precision == ForcePrecision::kDouble || body.quadratic()) {
    return add_elastic_forces_of_range(body, positions_m, forces_n, begin_tet, end_tet, simd);
  }
  // kNodalAverage: as the double range, the whole volumetric energy and the range's isochoric part.
  if (body.neo_hookean)
    return evaluate_float<false>(body, positions_m, forces_n, begin_tet, end_tet, 1, simd);
  return evaluate_float<true>(body, positions_m, forces_n, begin_tet, end_tet, 1, simd);
}

ElasticEvaluation add_elastic_forces_of_range(const ElasticBody& body, const double* positions_m,
                                              double* forces_n, std::int64_t begin_tet, std::int64_t end_tet,
                                              TetSimd simd) {
  if (body.quadratic()) return detail::quadratic_forces(body, positions_m, forces_n, begin_tet, end_tet);
  std::int64_t first_inverted = kNoTet;
  ElasticEvaluation result;
  // kNodalAverage: the pressures need every tet; the energy is then the
  // range's isochoric part plus the whole volumetric energy.
  std::vector<double> pressure;
  if (body.volumetric == VolumetricTerm::kNodalAverage) {
    result.energy_j = volumetric_pressures(body, positions_m, 1, pressure);
  }
  const double* tet_pressure = pressure.empty() ? nullptr : pressure.data();
  if (body.neo_hookean) {
    result.energy_j += forces_of_range<false>(body, positions_m, forces_n, begin_tet, end_tet, first_inverted,
                                              tet_pressure, simd);
  } else {
    result.energy_j += forces_of_range<true>(body, positions_m, forces_n, begin_tet, end_tet, first_inverted,
                                             tet_pressure, simd);
  }
  result.first_inverted_tet = first_inverted == kNoTet ? -1 : first_inverted;
  return result;
}

ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m, int threads) {
  if (body.quadratic()) {
    return detail::quadratic_forces(body, positions_m, nullptr, 0,
                                    static_cast<std::int64_t>(body.num_tets()));
  }
  if (body.neo_hookean) return evaluate<false, false>(body, positions_m, nullptr, threads);
  return evaluate<true, false>(body, positions_m, nullptr, threads);
}

ElasticEvaluation elastic_energy(const ElasticBody& body, const double* positions_m) {
  return elastic_energy(body, positions_m, 0);
}

TetSimd best_tet_simd() {
#if defined(__x86_64__)
  static const TetSimd best = [] {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
        __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw")) {
      return TetSimd::kAvx512;
    }
    if (__builtin_cpu_supports("avx2")) return TetSimd::kAvx2;
    return TetSimd::kGeneric;
  }();
  return best;
#else
  return TetSimd::kGeneric;
#endif
}

bool tet_simd_supported(TetSimd simd) {
  switch (simd) {
    case TetSimd::kAuto:
    case TetSimd::kGeneric:
      return true;
    case TetSimd::kAvx2:
      return best_tet_simd() == TetSimd::kAvx2 || best_tet_simd() == TetSimd::kAvx512;
    case TetSimd::kAvx512:
      return best_tet_simd() == TetSimd::kAvx512;
  }
  return false;
}

const char* tet_simd_name(TetSimd simd) {
  switch (simd) {
    case TetSimd::kAuto:
      return "auto";
    case TetSimd::kGeneric:
      return "generic";
    case TetSimd::kAvx2:
      return "avx2";
    case TetSimd::kAvx512:
      return "avx512";
  }
  return "?";
}

VolumeRatioMinimum min_volume_ratio(const ElasticBody& body, const double* positions_m) {
  if (body.quadratic()) return detail::quadratic_min_volume_ratio(body, positions_m);
  VolumeRatioMinimum minimum;
  for (std::size_t t = 0; t < body.num_tets(); ++t) {
    const double ratio = deformed_volume(positions_m, body.tets.data() + 4 * t) / body.ref_volume_m3[t];
    if (ratio < minimum.volume_ratio) minimum = {ratio, static_cast<std::int64_t>(t)};
  }
  return minimum;
}

}  // namespace cellflow::elastic
