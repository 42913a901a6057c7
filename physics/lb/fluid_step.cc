// One lattice step (collide_stream) and its SIMD dispatch: the relaxation
// coefficients of a step, one row loop per SIMD level (generic, AVX2,
// AVX-512) built from the inlined kernels of stream_kernel.h, the choice of
// the level at run time (best_simd, simd_supported, simd_name) and the
// parallel split of the rows.
#include <omp.h>

#include <cstdint>

#include "physics/lb/fluid.h"
#include "physics/lb/fluid_internal.h"
#include "physics/lb/stream_kernel.h"

namespace cellflow::lb {

namespace {

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

// The coefficients of every phase: entry 0 the fluid's tau, p >= 1
// phase_taus[p - 1]; unused entries repeat entry 0.
template <class T>
void fill_phase_table(const FluidParams& p, detail::PhaseTable<T>& table) {
  for (int ph = 0; ph < 256; ++ph) {
    FluidParams q = p;
    if (ph >= 1 && ph <= static_cast<int>(p.phase_taus.size())) q.tau = p.phase_taus[ph - 1];
    q.phase_taus.clear();
    const detail::CollisionCoeffs<T> k = collision_coeffs<T>(q);
    table.omega_plus[ph] = k.omega_plus;
    table.omega_minus[ph] = k.omega_minus;
    table.force_plus[ph] = k.force_plus;
    table.force_minus[ph] = k.force_minus;
  }
}

// One row loop per SIMD level. Even with AVX-512 the arithmetic, not the
// memory, limits one core on an idle machine (bench_lb's in-cache rows reach
// about 0.6 of the in-place update bandwidth), the baseline SSE2 far more so,
// and the default build does not use -march=native, so the level is picked
// at run time. Built with
// -ffp-contract=off: no FMA contraction, every level gives the same bits.
template <class T, bool kForce, bool kVel, bool kPh, Phase kPhase>
void rows_generic(const StepContext<T>& c, std::int64_t r0, std::int64_t r1) {
  process_rows<T, kForce, kVel, kPh, kPhase>(c, r0, r1);
}
#if defined(__x86_64__)
template <class T, bool kForce, bool kVel, bool kPh, Phase kPhase>
__attribute__((target("avx2"))) void rows_avx2(const StepContext<T>& c, std::int64_t r0, std::int64_t r1) {
  process_rows<T, kForce, kVel, kPh, kPhase>(c, r0, r1);
}
template <class T, bool kForce, bool kVel, bool kPh, Phase kPhase>
__attribute__((target("avx512f,avx512vl,avx512dq,avx512bw"))) void rows_avx512(const StepContext<T>& c,
                                                                               std::int64_t r0,
                                                                               std::int64_t r1) {
  process_rows<T, kForce, kVel, kPh, kPhase>(c, r0, r1);
}
#endif

template <class T>
using RowsFn = void (*)(const StepContext<T>&, std::int64_t, std::int64_t);

template <class T, bool kForce, bool kVel, bool kPh, Phase kPhase>
RowsFn<T> rows_for(Simd simd) {
#if defined(__x86_64__)
  if (simd == Simd::kAvx512) return rows_avx512<T, kForce, kVel, kPh, kPhase>;
  if (simd == Simd::kAvx2) return rows_avx2<T, kForce, kVel, kPh, kPhase>;
#endif
  return rows_generic<T, kForce, kVel, kPh, kPhase>;
}

Simd resolve_simd(Simd requested) {
  return requested == Simd::kAuto ? best_simd() : requested;
}

template <class T, bool kForce, bool kVel, bool kPh>
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
  detail::PhaseTable<T> table;
  if constexpr (kPh) {
    fill_phase_table<T>(p, table);
    c.phase = FluidAccess::phases(fluid).data();
    c.table = &table;
  }
  c.wall = wall_terms<T>(p);
  bool& swapped = FluidAccess::aa_swapped(fluid);
  const Simd simd = resolve_simd(p.simd);
  RowsFn<T> rows_fn;
  if (two_array)
    rows_fn = rows_for<T, kForce, kVel, kPh, Phase::kTwoArray>(simd);
  else if (!swapped)
    rows_fn = rows_for<T, kForce, kVel, kPh, Phase::kAAEven>(simd);
  else
    rows_fn = rows_for<T, kForce, kVel, kPh, Phase::kAAOdd>(simd);
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

template <class T, bool kPh>
void step_with_phases(Fluid& fluid) {
  const bool force = fluid.params().force_field, vel = fluid.params().velocity_field;
  if (force && vel)
    step_impl<T, true, true, kPh>(fluid);
  else if (force)
    step_impl<T, true, false, kPh>(fluid);
  else if (vel)
    step_impl<T, false, true, kPh>(fluid);
  else
    step_impl<T, false, false, kPh>(fluid);
}

// Without a phase field the kernels are those of one tau (no phase read).
template <class T>
void step_typed(Fluid& fluid) {
  if (fluid.params().phase_taus.empty())
    step_with_phases<T, false>(fluid);
  else
    step_with_phases<T, true>(fluid);
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

void collide_stream(Fluid& fluid) {
  if (fluid.params().precision == Precision::kDouble)
    step_typed<double>(fluid);
  else
    step_typed<float>(fluid);
}

}  // namespace cellflow::lb
