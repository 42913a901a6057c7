#include "physics/ibm/ibm.h"

#include <omp.h>

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
inline double wrap_coordinate(double x, int n) {
  const double w = x - n * std::floor(x / n);
  return w >= n ? 0.0 : w;  // x slightly below 0 can round up to n
}

template <Kernel K>
constexpr int kWidth = K == Kernel::kPeskin4 ? 4 : (K == Kernel::kPeskin3 ? 3 : 2);

// 1-D weights at coordinate s (nodes at j + 1/2), written with the square root
// shared by the stencil's nodes; outer weights from sum over even nodes = sum
// over odd nodes = 1/2 (peskin4), so the weights sum to 1 to rounding.
template <Kernel K>
inline int weights_1d(double s, double* w) {
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

// The 3-D stencil of one point: periodic indices in x and z; in y the rows
// [y_begin, y_end) of the stencil that lie in the fluid (all rows if periodic).
template <Kernel K>
struct PointStencil {
  static constexpr int W = kWidth<K>;
  std::size_t row_offset[W][W];  // nx (j + ny k) for y row b, z row c
  int ix[W];
  double wx[W], wy[W], wz[W];
  int y_begin = 0, y_end = 0;
};

template <Kernel K>
inline bool make_stencil(const Grid& g, double x, double y, double z, PointStencil<K>& st) {
  constexpr int W = kWidth<K>;
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) return false;
  x = wrap_coordinate(x, g.nx);
  z = wrap_coordinate(z, g.nz);
  if (g.walls_y) {
    // Far outside, every weight is dropped anyway; the clamp keeps int conversion defined.
    y = std::clamp(y, -4.0, g.ny + 4.0);
  } else {
    y = wrap_coordinate(y, g.ny);
  }
  const int fx = weights_1d<K>(x, st.wx);
  const int fy = weights_1d<K>(y, st.wy);
  const int fz = weights_1d<K>(z, st.wz);
  for (int a = 0; a < W; ++a) st.ix[a] = wrap_index(fx + a, g.nx);
  int iy[W];
  if (g.walls_y) {
    // Rows beyond a wall are dropped (identically in interpolation and spreading).
    st.y_begin = std::clamp(-fy, 0, W);
    st.y_end = std::clamp(g.ny - fy, 0, W);
    for (int b = 0; b < W; ++b) iy[b] = std::clamp(fy + b, 0, g.ny - 1);
  } else {
    st.y_begin = 0;
    st.y_end = W;
    for (int b = 0; b < W; ++b) iy[b] = wrap_index(fy + b, g.ny);
  }
  for (int c = 0; c < W; ++c) {
    const std::size_t k = static_cast<std::size_t>(wrap_index(fz + c, g.nz));
    for (int b = 0; b < W; ++b) {
      st.row_offset[c][b] = static_cast<std::size_t>(g.nx) * (static_cast<std::size_t>(iy[b]) + g.ny * k);
    }
  }
  return true;
}

int thread_count(int threads) {
  return threads > 0 ? threads : omp_get_max_threads();
}

// Fewer points than this are not worth a parallel region.
constexpr std::ptrdiff_t kParallelPoints = 256;

template <Kernel K, class T>
void interpolate_impl(const Grid& g, lb::VectorField<const T> field, std::span<const double> points,
                      std::span<double> values, int threads) {
  constexpr int W = kWidth<K>;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(points.size() / 3);
#pragma omp parallel for schedule(static) num_threads(thread_count(threads)) if (n >= kParallelPoints)
  for (std::ptrdiff_t p = 0; p < n; ++p) {
    PointStencil<K> st;
    double u[3] = {0.0, 0.0, 0.0};
    if (!make_stencil<K>(g, points[3 * p], points[3 * p + 1], points[3 * p + 2], st)) {
      u[0] = u[1] = u[2] = std::nan("");
    } else {
      // U = sum_x u(x) phi(x - X) phi(y - Y) phi(z - Z)
      for (int c = 0; c < W; ++c) {
        for (int b = st.y_begin; b < st.y_end; ++b) {
          const double wyz = st.wz[c] * st.wy[b];
          const std::size_t row = st.row_offset[c][b];
          for (int a = 0; a < W; ++a) {
            const double w = wyz * st.wx[a];
            const std::size_t at = row + st.ix[a];
            u[0] += w * field.x[at];
            u[1] += w * field.y[at];
            u[2] += w * field.z[at];
          }
        }
      }
    }
    values[3 * p] = u[0];
    values[3 * p + 1] = u[1];
    values[3 * p + 2] = u[2];
  }
}

// Adds the force of point p into the field.
template <Kernel K, class T>
inline void spread_point(const Grid& g, const double* x, const double* f, lb::VectorField<T> field) {
  constexpr int W = kWidth<K>;
  PointStencil<K> st;
  if (!make_stencil<K>(g, x[0], x[1], x[2], st)) return;
  // f(x) += F phi(x - X) phi(y - Y) phi(z - Z)
  for (int c = 0; c < W; ++c) {
    for (int b = st.y_begin; b < st.y_end; ++b) {
      const double wyz = st.wz[c] * st.wy[b];
      const std::size_t row = st.row_offset[c][b];
      for (int a = 0; a < W; ++a) {
        const double w = wyz * st.wx[a];
        const std::size_t at = row + st.ix[a];
        field.x[at] += static_cast<T>(w * f[0]);
        field.y[at] += static_cast<T>(w * f[1]);
        field.z[at] += static_cast<T>(w * f[2]);
      }
    }
  }
}

// Slabs of this many y layers: a stencil (at most 4 nodes) of a point in slab
// s touches only rows [4s - 2, 4s + 5], disjoint from those of slab s + 2.
constexpr int kSlab = 4;

template <Kernel K, class T>
void spread_impl(const Grid& g, std::span<const double> points, std::span<const double> forces,
                 lb::VectorField<T> field, int threads) {
  const int n = static_cast<int>(points.size() / 3);
  const int slabs = std::max(1, g.ny / kSlab);  // the last slab takes the remainder
  // The path depends on the problem only, never on the thread count, so the
  // order of additions at every node is fixed.
  if (slabs < 3 || n < kParallelPoints) {
    for (int p = 0; p < n; ++p) spread_point<K, T>(g, &points[3 * p], &forces[3 * p], field);
    return;
  }
  // Bin the points by slab, keeping their order within a slab (counting sort).
  std::vector<int> slab_of(n), begin(slabs + 1, 0), order(n);
  for (int p = 0; p < n; ++p) {
    double y = points[3 * p + 1];
    if (!std::isfinite(y)) y = 0.0;  // skipped by spread_point anyway
    y = g.walls_y ? std::clamp(y, 0.0, static_cast<double>(g.ny)) : wrap_coordinate(y, g.ny);
    slab_of[p] = std::clamp(static_cast<int>(y) / kSlab, 0, slabs - 1);
    ++begin[slab_of[p] + 1];
  }
  for (int s = 0; s < slabs; ++s) begin[s + 1] += begin[s];
  {
    std::vector<int> fill(begin.begin(), begin.end() - 1);
    for (int p = 0; p < n; ++p) order[fill[slab_of[p]]++] = p;
  }
  // Phases: even slabs, odd slabs; with periodic y the last slab touches slab
  // 0 across the wrap and gets a phase of its own.
  const int last_separate = g.walls_y ? slabs : slabs - 1;
  std::vector<int> phase_slabs;
  for (int phase = 0; phase < 3; ++phase) {
    phase_slabs.clear();
    if (phase < 2) {
      for (int s = phase; s < last_separate; s += 2) phase_slabs.push_back(s);
    } else if (last_separate < slabs) {
      phase_slabs.push_back(slabs - 1);
    }
    const int count = static_cast<int>(phase_slabs.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(thread_count(threads))
    for (int i = 0; i < count; ++i) {
      const int s = phase_slabs[i];
      for (int k = begin[s]; k < begin[s + 1]; ++k) {
        const int p = order[k];
        spread_point<K, T>(g, &points[3 * p], &forces[3 * p], field);
      }
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

template <class T>
void interpolate(Kernel kernel, const Grid& grid, lb::VectorField<const T> field,
                 std::span<const double> points, std::span<double> values, int threads) {
  switch (kernel) {
    case Kernel::kPeskin4:
      interpolate_impl<Kernel::kPeskin4, T>(grid, field, points, values, threads);
      break;
    case Kernel::kPeskin3:
      interpolate_impl<Kernel::kPeskin3, T>(grid, field, points, values, threads);
      break;
    case Kernel::kTrilinear:
      interpolate_impl<Kernel::kTrilinear, T>(grid, field, points, values, threads);
      break;
  }
}

template <class T>
void spread(Kernel kernel, const Grid& grid, std::span<const double> points, std::span<const double> forces,
            lb::VectorField<T> field, int threads) {
  switch (kernel) {
    case Kernel::kPeskin4:
      spread_impl<Kernel::kPeskin4, T>(grid, points, forces, field, threads);
      break;
    case Kernel::kPeskin3:
      spread_impl<Kernel::kPeskin3, T>(grid, points, forces, field, threads);
      break;
    case Kernel::kTrilinear:
      spread_impl<Kernel::kTrilinear, T>(grid, points, forces, field, threads);
      break;
  }
}

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
