// Immersed-boundary coupling between Lagrangian points (cell vertices) and the
// lattice Boltzmann fluid (Peskin 2002): velocity interpolation
//   U(X) = sum_x u(x) delta(x - X)
// and force spreading
//   f(x) += sum_p F_p delta(x - X_p),
// with delta(x) = phi(x) phi(y) phi(z) in lattice units (node volume 1). Both
// use the same weights, so spreading is the exact transpose of interpolation:
//   <spread(F), u>_lattice = <F, interpolate(u)>_points.
//
// Geometry (that of physics/lb/fluid.h): lattice units, node (i, j, k) at
// (i + 1/2, j + 1/2, k + 1/2); x and z periodic (positions wrap); y periodic
// or bounded by walls at y = 0 and y = ny. Walls: the weights of stencil
// nodes beyond a wall are dropped, identically in interpolation and spreading
// (so the transpose property holds everywhere). For a point closer than the
// kernel half-width to a wall (2 spacings for peskin4) the weights then sum to
// less than 1: part of its force goes into the wall, and its interpolated
// velocity is pulled towards zero. Keep the cell that far from the walls (the
// shear scene's walls are 5 radii away).
//
// Kernels (1-D phi, r in lattice spacings), each with sum_j phi(r - j) = 1 and
// sum_j (r - j) phi(r - j) = 0, so constants and linear fields interpolate
// exactly and total force is conserved away from walls:
//   peskin4:   (3 - 2|r| + sqrt(1 + 4|r| - 4 r^2)) / 8       |r| <= 1
//              (5 - 2|r| - sqrt(-7 + 12|r| - 4 r^2)) / 8     1 <= |r| <= 2
//   peskin3:   (1 + sqrt(1 - 3 r^2)) / 3                      |r| <= 1/2
//              (5 - 3|r| - sqrt(-2 + 6|r| - 3 r^2)) / 6       1/2 <= |r| <= 3/2
//   trilinear: 1 - |r|                                         |r| <= 1
#pragma once

#include <span>
#include <string_view>
#include <vector>

#include "physics/core/status.h"
#include "physics/lb/fluid.h"

namespace cellflow::ibm {

enum class Kernel { kPeskin4, kPeskin3, kTrilinear };

// "peskin4" (the default), "peskin3", "trilinear" (ShearFlowNumerics.ibm_kernel).
// The message of a bad name names `field`.
StatusOr<Kernel> parse_kernel(std::string_view name, std::string_view field = "numerics.ibm_kernel");
std::string_view kernel_name(Kernel kernel);

// phi(r), the 1-D kernel at distance r (lattice spacings).
double kernel_weight(Kernel kernel, double r);
// Nodes per direction in a stencil: 4, 3, 2.
int kernel_width(Kernel kernel);

// 1-D stencil of a point at coordinate s (nodes at j + 1/2): the first node
// index (before any periodic wrap) and the kernel_width weights.
struct Stencil1D {
  int first = 0;
  double weight[4] = {0, 0, 0, 0};
};
Stencil1D stencil_1d(Kernel kernel, double s);

// The lattice as the coupling sees it.
struct Grid {
  int nx = 0, ny = 0, nz = 0;
  bool walls_y = true;
};
Grid grid_of(const lb::Fluid& fluid);

// Points and per-point vectors are interleaved x0 y0 z0 x1 ... in lattice
// units. `threads` <= 0: the OpenMP default.

// The 3-D stencil of one point, separable: delta(x - X) = wx[a] wy[b] wz[c]
// on nodes (x[a], y[b], z[c]) (3 x 4 weights, not 64). Indices are wrapped
// into the lattice; in y only rows [y_begin, y_end) lie in the fluid.
struct PointStencil {
  double wx[4] = {0, 0, 0, 0}, wy[4] = {0, 0, 0, 0}, wz[4] = {0, 0, 0, 0};
  int x[4] = {0, 0, 0, 0}, y[4] = {0, 0, 0, 0}, z[4] = {0, 0, 0, 0};
  int y_begin = 0, y_end = 0;
  bool finite = false;        // false: a coordinate is NaN or infinite (NaN velocity, no force)
  bool x_contiguous = false;  // x[a] = x[0] + a (no periodic wrap inside the stencil)
};

// The stencils of a set of points, computed once (build_stencils) and used by
// both spreading and interpolation at the same positions (the flow step
// spreads at X(t) and interpolates u(t) at the same X(t)). Also holds the
// points' order by z plane that makes spreading race-free without atomics.
// Rebuilding for the same number of points allocates nothing.
struct StencilSet {
  Kernel kernel = Kernel::kPeskin4;
  Grid grid;
  std::vector<PointStencil> points;
  // Finite points by wrapped first z plane (stable): those of plane k are
  // order[bin_begin[k] .. bin_begin[k + 1]).
  std::vector<int> order;
  std::vector<int> bin_begin;
  std::vector<int> bin_fill;     // scratch of the counting sort
  std::vector<double> work;      // scratch: spreading work per z plane
  std::vector<int> plane_split;  // scratch: z planes of each thread
};

void build_stencils(Kernel kernel, const Grid& grid, std::span<const double> points, StencilSet& stencils,
                    int threads = 0);

// values[p] = sum_x w_p(x) field(x) with the stencils of `stencils`.
template <class T>
void interpolate(const StencilSet& stencils, lb::VectorField<const T> field, std::span<double> values,
                 int threads = 0);

// field(x) += sum_p w_p(x) forces[p]. Race-free in parallel without atomics:
// each thread owns a range of z planes and adds, for every point whose
// stencil reaches them, the part of the stencil in its planes. At every node
// the additions come in a fixed order (points by first z plane, then by
// index), so the result does not depend on the thread count.
template <class T>
void spread(StencilSet& stencils, std::span<const double> forces, lb::VectorField<T> field, int threads = 0);

// One-shot forms (build_stencils into a temporary set, then the above).

// values[p] = sum_x w_p(x) field(x).
template <class T>
void interpolate(Kernel kernel, const Grid& grid, lb::VectorField<const T> field,
                 std::span<const double> points, std::span<double> values, int threads = 0);

// field(x) += sum_p w_p(x) forces[p]; as spread above.
template <class T>
void spread(Kernel kernel, const Grid& grid, std::span<const double> points, std::span<const double> forces,
            lb::VectorField<T> field, int threads = 0);

// On a fluid: the velocity field written by lb::collide_stream (or
// lb::update_velocity_field) interpolated at the points; the point forces
// added into the fluid's force field. The fluid must have been made with
// velocity_field / force_field (else kFailedPrecondition).
Status interpolate_velocity(Kernel kernel, const lb::Fluid& fluid, std::span<const double> points,
                            std::span<double> velocities);
Status spread_forces(Kernel kernel, std::span<const double> points, std::span<const double> forces,
                     lb::Fluid& fluid);

}  // namespace cellflow::ibm
