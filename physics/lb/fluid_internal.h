// Internal to cellflow::lb, shared by the sources of the fluid (fluid.cc,
// fluid_step.cc, fluid_moments.cc) and not part of the public API
// (physics/lb/fluid.h): FluidAccess to the storage of a Fluid, the layout of
// the direction arrays, the thread count of the lattice loops, the periodic
// wrap and the moving-wall bounce-back terms.
#pragma once

#include <omp.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "physics/lb/d3q19.h"
#include "physics/lb/fluid.h"

namespace cellflow::lb {

// Access to Fluid's storage for the lb sources (a friend of Fluid).
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
  static AlignedArray<std::uint8_t>& phases(Fluid& f) { return f.phases_; }
  static const AlignedArray<std::uint8_t>& phases(const Fluid& f) { return f.phases_; }
  static std::size_t stride(const Fluid& f) { return f.stride_; }
  static bool& aa_swapped(Fluid& f) { return f.aa_swapped_; }
  static bool aa_swapped(const Fluid& f) { return f.aa_swapped_; }
  static int& current(Fluid& f) { return f.current_; }
  static int current(const Fluid& f) { return f.current_; }
  static std::int64_t& time_step(Fluid& f) { return f.time_step_; }
};

// Internal linkage, as when all of this was one source file: every lb source
// gets its own copy, and GCC inlines and schedules the row loops exactly as
// before the split (checked on the object code).
namespace {

// Direction arrays start on 64-byte boundaries, one cache line more than
// needed apart: with strides a multiple of 4 KiB the 19 streams of a row
// alias in the low address bits (measured a few % slower, bench/lb).
inline std::size_t direction_stride(std::size_t nodes) {
  return (nodes + 15) / 16 * 16 + 16;
}

// AA pattern with walls: one density per node of the two wall layers.
inline std::size_t wall_density_size(const FluidParams& p) {
  if (p.streaming != Streaming::kAA || !p.walls_y || p.nx < 1 || p.nz < 1) return 0;
  return 2 * static_cast<std::size_t>(p.nx) * static_cast<std::size_t>(p.nz);
}

// Below this many nodes a step takes less than an OpenMP fork-join on a busy
// machine (tens of microseconds up to a time slice), so loops run serially.
constexpr std::size_t kSerialBelowNodes = 16384;

inline int thread_count(const FluidParams& p) {
  const std::size_t nodes = static_cast<std::size_t>(p.nx) * p.ny * static_cast<std::size_t>(p.nz);
  if (nodes < kSerialBelowNodes) return 1;
  return p.threads > 0 ? p.threads : omp_get_max_threads();
}

// Periodic index for a shift of at most one period.
inline int wrap(int i, int n) {
  return i < 0 ? i + n : (i >= n ? i - n : i);
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

}  // namespace
}  // namespace cellflow::lb
