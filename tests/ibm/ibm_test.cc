// Immersed-boundary interpolation and spreading: kernel identities, force
// conservation, exactness for linear fields, and the transpose property
// <spread(F), u> = <F, interpolate(u)> (all to round-off).
#include "physics/ibm/ibm.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "physics/lb/fluid.h"

namespace cellflow::ibm {
namespace {

constexpr Kernel kKernels[] = {Kernel::kPeskin4, Kernel::kPeskin3, Kernel::kTrilinear};

// A vector field on the lattice, structure of arrays.
struct Field {
  explicit Field(const Grid& g) : n(static_cast<std::size_t>(g.nx) * g.ny * g.nz), x(n), y(n), z(n) {}
  std::size_t n;
  std::vector<double> x, y, z;
  lb::VectorField<double> view() { return {x.data(), y.data(), z.data()}; }
  lb::VectorField<const double> cview() const { return {x.data(), y.data(), z.data()}; }
};

std::vector<double> random_points(int n, const Grid& g, double y_lo, double y_hi, double margin_xz,
                                  unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(margin_xz, g.nx - margin_xz), uy(y_lo, y_hi),
      uz(margin_xz, g.nz - margin_xz);
  std::vector<double> p(3 * n);
  for (int i = 0; i < n; ++i) {
    p[3 * i] = ux(rng);
    p[3 * i + 1] = uy(rng);
    p[3 * i + 2] = uz(rng);
  }
  return p;
}

std::vector<double> random_vectors(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  std::vector<double> v(3 * n);
  for (double& x : v) x = d(rng);
  return v;
}

TEST(Kernel, WeightsSumToOneWithZeroFirstMomentAndMatchFormula) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> pos(0.0, 50.0);
  std::vector<double> samples = {0.5, 1.0, 1.5, 2.0, 7.25, 7.75, 3.0 - 1e-12, 3.0 + 1e-12};
  for (int i = 0; i < 2000; ++i) samples.push_back(pos(rng));
  for (Kernel k : kKernels) {
    double worst_sum = 0.0, worst_moment = 0.0, worst_formula = 0.0;
    for (double s : samples) {
      const Stencil1D st = stencil_1d(k, s);
      double sum = 0.0, moment = 0.0;
      for (int m = 0; m < kernel_width(k); ++m) {
        const double r = s - (st.first + m + 0.5);  // distance to the node at first + m + 1/2
        sum += st.weight[m];
        moment += r * st.weight[m];
        worst_formula = std::max(worst_formula, std::abs(st.weight[m] - kernel_weight(k, r)));
      }
      // No node outside the stencil carries weight.
      EXPECT_EQ(kernel_weight(k, s - (st.first - 1 + 0.5)), 0.0) << kernel_name(k) << " s " << s;
      EXPECT_EQ(kernel_weight(k, s - (st.first + kernel_width(k) + 0.5)), 0.0)
          << kernel_name(k) << " s " << s;
      worst_sum = std::max(worst_sum, std::abs(sum - 1.0));
      worst_moment = std::max(worst_moment, std::abs(moment));
    }
    EXPECT_LT(worst_sum, 1e-15) << kernel_name(k);
    EXPECT_LT(worst_moment, 1e-14) << kernel_name(k);
    // The stencil's shared-sqrt form equals the textbook piecewise formula.
    EXPECT_LT(worst_formula, 1e-14) << kernel_name(k);
  }
}

TEST(Kernel, ThreeDimensionalWeightsSumToOne) {
  // Interpolating the constant field 1 returns the sum of the 3-D weights.
  const Grid g{10, 12, 9, true};
  Field one(g);
  std::fill(one.x.begin(), one.x.end(), 1.0);
  const std::vector<double> pts = random_points(500, g, 2.0, g.ny - 2.0, 0.0, 2);
  std::vector<double> u(pts.size());
  for (Kernel k : kKernels) {
    interpolate<double>(k, g, one.cview(), pts, u);
    for (std::size_t p = 0; p < pts.size() / 3; ++p) ASSERT_NEAR(u[3 * p], 1.0, 1e-15) << kernel_name(k);
  }
}

TEST(Spread, TotalForceEqualsSumOfPointForces) {
  // Walls in y (points at least 2 spacings from them) and fully periodic
  // (points anywhere, also outside the box: they wrap). 1000 points on 32 y
  // layers exercise the parallel slab path.
  for (bool walls : {true, false}) {
    const Grid g{16, 32, 12, walls};
    const int n = 1000;
    const std::vector<double> pts =
        walls ? random_points(n, g, 2.0, g.ny - 2.0, -20.0, 3) : random_points(n, g, -40.0, 70.0, -20.0, 3);
    const std::vector<double> f = random_vectors(n, 4);
    double total[3] = {0, 0, 0}, magnitude = 0.0;
    for (int p = 0; p < n; ++p) {
      for (int d = 0; d < 3; ++d) {
        total[d] += f[3 * p + d];
        magnitude += std::abs(f[3 * p + d]);
      }
    }
    for (Kernel k : kKernels) {
      Field field(g);
      spread<double>(k, g, pts, f, field.view());
      double sum[3] = {0, 0, 0};
      for (std::size_t i = 0; i < field.n; ++i) {
        sum[0] += field.x[i];
        sum[1] += field.y[i];
        sum[2] += field.z[i];
      }
      for (int d = 0; d < 3; ++d) {
        EXPECT_NEAR(sum[d], total[d], 1e-14 * magnitude)
            << kernel_name(k) << " walls " << walls << " comp " << d;
      }
    }
  }
}

TEST(Interpolate, LinearFieldIsExactAwayFromWalls) {
  const Grid g{14, 16, 12, true};
  Field field(g);
  // u = a + B x at node positions (i + 1/2, j + 1/2, k + 1/2)
  const double a[3] = {0.3, -0.2, 0.1};
  const double b[3][3] = {{0.01, 0.02, -0.03}, {-0.015, 0.005, 0.025}, {0.02, -0.01, 0.004}};
  for (int k = 0; k < g.nz; ++k)
    for (int j = 0; j < g.ny; ++j)
      for (int i = 0; i < g.nx; ++i) {
        const double x[3] = {i + 0.5, j + 0.5, k + 0.5};
        const std::size_t at = i + static_cast<std::size_t>(g.nx) * (j + static_cast<std::size_t>(g.ny) * k);
        double* comp[3] = {&field.x[at], &field.y[at], &field.z[at]};
        for (int d = 0; d < 3; ++d) *comp[d] = a[d] + b[d][0] * x[0] + b[d][1] * x[1] + b[d][2] * x[2];
      }
  // Stencils must not reach a wall nor wrap across the periodic seam of the
  // (non-periodic) linear field: 2.5 spacings of margin.
  const std::vector<double> pts = random_points(400, g, 2.5, g.ny - 2.5, 2.5, 5);
  std::vector<double> u(pts.size());
  for (Kernel k : kKernels) {
    interpolate<double>(k, g, field.cview(), pts, u);
    double worst = 0.0;
    for (std::size_t p = 0; p < pts.size() / 3; ++p) {
      for (int d = 0; d < 3; ++d) {
        const double exact =
            a[d] + b[d][0] * pts[3 * p] + b[d][1] * pts[3 * p + 1] + b[d][2] * pts[3 * p + 2];
        worst = std::max(worst, std::abs(u[3 * p + d] - exact));
      }
    }
    EXPECT_LT(worst, 1e-14) << kernel_name(k);
  }
}

// <spread(F), u> = <F, interpolate(u)>: same weights in both, including
// points near and beyond the walls (dropped weights) and across the
// periodic seams.
TEST(Transpose, SpreadIsAdjointOfInterpolate) {
  for (bool walls : {true, false}) {
    const Grid g{12, 20, 10, walls};
    const int n = 600;
    const std::vector<double> pts = random_points(n, g, -1.0, g.ny + 1.0, -5.0, 6);
    const std::vector<double> f = random_vectors(n, 7);
    Field u(g);
    {
      std::mt19937 rng(8);
      std::uniform_real_distribution<double> d(-1.0, 1.0);
      for (std::size_t i = 0; i < u.n; ++i) {
        u.x[i] = d(rng);
        u.y[i] = d(rng);
        u.z[i] = d(rng);
      }
    }
    for (Kernel k : kKernels) {
      Field s(g);
      spread<double>(k, g, pts, f, s.view());
      double lattice_side = 0.0, scale = 0.0;
      for (std::size_t i = 0; i < u.n; ++i) {
        lattice_side += s.x[i] * u.x[i] + s.y[i] * u.y[i] + s.z[i] * u.z[i];
        scale += std::abs(s.x[i] * u.x[i]) + std::abs(s.y[i] * u.y[i]) + std::abs(s.z[i] * u.z[i]);
      }
      std::vector<double> ui(pts.size());
      interpolate<double>(k, g, u.cview(), pts, ui);
      double point_side = 0.0;
      for (std::size_t i = 0; i < pts.size(); ++i) point_side += f[i] * ui[i];
      EXPECT_NEAR(lattice_side, point_side, 1e-14 * scale) << kernel_name(k) << " walls " << walls;
    }
  }
}

// Near a wall the dropped weights are the same in both directions: the force
// a unit point force deposits equals the constant-1 field interpolated there,
// and is below 1 within a half-width of the wall.
TEST(Walls, DroppedWeightsConsistent) {
  const Grid g{8, 16, 8, true};
  Field one(g);
  std::fill(one.x.begin(), one.x.end(), 1.0);
  for (Kernel k : kKernels) {
    for (double y : {0.1, 0.5, 0.9, 1.3, 15.2, 15.9}) {
      const std::vector<double> pt = {3.3, y, 4.1};
      const std::vector<double> unit = {1.0, 0.0, 0.0};
      Field s(g);
      spread<double>(k, g, pt, unit, s.view());
      double deposited = 0.0;
      for (double v : s.x) deposited += v;
      std::vector<double> u(3);
      interpolate<double>(k, g, one.cview(), pt, u);
      EXPECT_NEAR(deposited, u[0], 1e-15) << kernel_name(k) << " y " << y;
      EXPECT_LE(deposited, 1.0 + 1e-15);
      // Within a half-width (minus half a spacing) of a wall some weight is always lost.
      if (std::min(y, g.ny - y) < 0.5 * kernel_width(k) - 0.5) {
        EXPECT_LT(deposited, 1.0 - 1e-3) << kernel_name(k) << " y " << y;
      }
    }
  }
}

TEST(Spread, ThreadCountDoesNotChangeResult) {
  const Grid g{16, 40, 12, true};
  const int n = 2000;
  const std::vector<double> pts = random_points(n, g, 0.0, g.ny, 0.0, 9);
  const std::vector<double> f = random_vectors(n, 10);
  Field one(g), two(g);
  spread<double>(Kernel::kPeskin4, g, pts, f, one.view(), 1);
  spread<double>(Kernel::kPeskin4, g, pts, f, two.view(), 2);
  EXPECT_EQ(one.x, two.x);
  EXPECT_EQ(one.y, two.y);
  EXPECT_EQ(one.z, two.z);
}

// The separable stencils, the z-plane ownership of the threads and the AVX2
// rows against a plain 64-node loop over kernel_weight, on lattices where
// stencils wrap in x and z (points anywhere, nz = 3 below the stencil width),
// with walls and periodic in y: spreading and interpolation agree to
// round-off (1e-13 on values of order 1), every thread count gives the same
// bits, and a StencilSet built once serves both passes.
void reference_stencil(Kernel k, const Grid& g, const double* p, std::vector<std::size_t>& nodes,
                       std::vector<double>& weights) {
  nodes.clear();
  weights.clear();
  const int h = kernel_width(k);
  const int fx = static_cast<int>(std::floor(p[0])), fy = static_cast<int>(std::floor(p[1])),
            fz = static_cast<int>(std::floor(p[2]));
  auto wrap = [](int i, int n) { return ((i % n) + n) % n; };
  for (int k3 = fz - h; k3 <= fz + h; ++k3) {
    for (int j = fy - h; j <= fy + h; ++j) {
      if (g.walls_y && (j < 0 || j >= g.ny)) continue;
      for (int i = fx - h; i <= fx + h; ++i) {
        const double w = kernel_weight(k, i + 0.5 - p[0]) * kernel_weight(k, j + 0.5 - p[1]) *
                         kernel_weight(k, k3 + 0.5 - p[2]);
        if (w == 0.0) continue;
        const std::size_t node =
            static_cast<std::size_t>(wrap(i, g.nx)) +
            static_cast<std::size_t>(g.nx) *
                (static_cast<std::size_t>(wrap(j, g.ny)) +
                 static_cast<std::size_t>(g.ny) * static_cast<std::size_t>(wrap(k3, g.nz)));
        nodes.push_back(node);
        weights.push_back(w);
      }
    }
  }
}

TEST(Stencils, SpreadAndInterpolateMatchAPlainLoopOnEveryThreadCount) {
  const Grid grids[] = {{13, 20, 9, true}, {10, 12, 7, false}, {8, 16, 3, true}};
  for (const Grid& g : grids) {
    for (Kernel k : kKernels) {
      const int n = 700;  // above the parallel threshold
      // x and z anywhere (stencils across the periodic boundary); y within the walls.
      const std::vector<double> pts = random_points(n, g, 0.0, g.ny, 0.0, 21);
      const std::vector<double> f = random_vectors(n, 22);
      Field ref(g), field(g);
      for (std::size_t i = 0; i < ref.n; ++i) {
        field.x[i] = std::sin(0.1 * i);
        field.y[i] = std::cos(0.3 * i);
        field.z[i] = std::sin(0.7 * i + 1.0);
      }
      std::vector<double> u_ref(3 * n, 0.0);
      std::vector<std::size_t> nodes;
      std::vector<double> w;
      for (int p = 0; p < n; ++p) {
        reference_stencil(k, g, &pts[3 * p], nodes, w);
        for (std::size_t m = 0; m < nodes.size(); ++m) {
          ref.x[nodes[m]] += w[m] * f[3 * p];
          ref.y[nodes[m]] += w[m] * f[3 * p + 1];
          ref.z[nodes[m]] += w[m] * f[3 * p + 2];
          u_ref[3 * p] += w[m] * field.x[nodes[m]];
          u_ref[3 * p + 1] += w[m] * field.y[nodes[m]];
          u_ref[3 * p + 2] += w[m] * field.z[nodes[m]];
        }
      }
      StencilSet set;
      build_stencils(k, g, pts, set, 2);
      Field first(g);
      std::vector<double> u_first;
      for (int threads : {1, 2, 3}) {
        const std::string what = std::string(kernel_name(k)) + " nz " + std::to_string(g.nz) + " walls " +
                                 std::to_string(g.walls_y) + " threads " + std::to_string(threads);
        Field out(g);
        spread<double>(set, f, out.view(), threads);
        std::vector<double> u(3 * n, 0.0);
        interpolate<double>(set, field.cview(), u, threads);
        for (std::size_t i = 0; i < ref.n; ++i) {
          ASSERT_NEAR(out.x[i], ref.x[i], 1e-13) << what << " node " << i;
          ASSERT_NEAR(out.y[i], ref.y[i], 1e-13) << what << " node " << i;
          ASSERT_NEAR(out.z[i], ref.z[i], 1e-13) << what << " node " << i;
        }
        for (int i = 0; i < 3 * n; ++i) ASSERT_NEAR(u[i], u_ref[i], 1e-13) << what << " value " << i;
        if (threads == 1) {
          first = out;
          u_first = u;
        } else {
          EXPECT_EQ(out.x, first.x) << what;
          EXPECT_EQ(out.y, first.y) << what;
          EXPECT_EQ(out.z, first.z) << what;
          EXPECT_EQ(u, u_first) << what;
        }
      }
    }
  }
}

// A point that is not finite gets a NaN velocity and spreads nothing; the
// others are unaffected.
TEST(Stencils, NonFinitePointIsSkipped) {
  const Grid g{16, 16, 16, true};
  std::vector<double> pts = {8.2, 8.4, 8.6, std::nan(""), 8.0, 8.0, 4.0, 5.0, 6.0};
  const std::vector<double> f = {1.0, 2.0, 3.0, 5.0, 5.0, 5.0, -1.0, 0.5, 0.25};
  StencilSet set;
  build_stencils(Kernel::kPeskin4, g, pts, set, 1);
  Field out(g), one(g);
  spread<double>(set, f, out.view(), 1);
  double sum[3] = {0, 0, 0};
  for (std::size_t i = 0; i < out.n; ++i) {
    sum[0] += out.x[i];
    sum[1] += out.y[i];
    sum[2] += out.z[i];
  }
  EXPECT_NEAR(sum[0], 0.0, 1e-13);
  EXPECT_NEAR(sum[1], 2.5, 1e-13);
  EXPECT_NEAR(sum[2], 3.25, 1e-13);
  for (std::size_t i = 0; i < one.n; ++i) one.x[i] = one.y[i] = one.z[i] = 1.0;
  std::vector<double> u(9, 0.0);
  interpolate<double>(set, one.cview(), u, 1);
  EXPECT_NEAR(u[0], 1.0, 1e-13);
  EXPECT_TRUE(std::isnan(u[3]) && std::isnan(u[4]) && std::isnan(u[5]));
  EXPECT_NEAR(u[8], 1.0, 1e-13);
}

// Through the fluid API and float storage: total force to float round-off
// (1e-6 relative: float epsilon 6e-8 per addition, ~64 additions per node),
// velocity of a uniform flow to float round-off.
TEST(FluidCoupling, SpreadAndInterpolateOnFluid) {
  for (lb::Precision precision : {lb::Precision::kDouble, lb::Precision::kFloat}) {
    lb::FluidParams p;
    p.nx = 12;
    p.ny = 16;
    p.nz = 10;
    p.force_field = true;
    p.velocity_field = true;
    p.precision = precision;
    StatusOr<lb::Fluid> made = lb::make_fluid(p);
    ASSERT_TRUE(made.ok());
    lb::Fluid fluid = std::move(made).value();
    const std::size_t nodes = fluid.num_nodes();
    std::vector<double> ux(nodes, 0.01), uy(nodes, -0.02), uz(nodes, 0.005);
    lb::set_equilibrium(fluid, {}, ux, uy, uz);
    lb::update_velocity_field(fluid);
    const Grid g = grid_of(fluid);
    const int n = 300;
    const std::vector<double> pts = random_points(n, g, 2.0, g.ny - 2.0, 0.0, 11);
    std::vector<double> v(pts.size());
    const double tol = precision == lb::Precision::kDouble ? 1e-15 : 1e-8;
    for (Kernel k : kKernels) {
      ASSERT_TRUE(interpolate_velocity(k, fluid, pts, v).ok());
      for (int i = 0; i < n; ++i) {
        ASSERT_NEAR(v[3 * i], 0.01, tol);
        ASSERT_NEAR(v[3 * i + 1], -0.02, tol);
        ASSERT_NEAR(v[3 * i + 2], 0.005, tol);
      }
    }
    const std::vector<double> f = random_vectors(n, 12);
    double total = 0.0, magnitude = 0.0;
    for (int i = 0; i < n; ++i) {
      total += f[3 * i];
      magnitude += std::abs(f[3 * i]);
    }
    lb::zero_force_field(fluid);
    ASSERT_TRUE(spread_forces(Kernel::kPeskin4, pts, f, fluid).ok());
    double sum = 0.0;
    if (precision == lb::Precision::kDouble) {
      const lb::VectorField<const double> ff = std::as_const(fluid).force_field<double>();
      for (std::size_t i = 0; i < nodes; ++i) sum += ff.x[i];
    } else {
      const lb::VectorField<const float> ff = std::as_const(fluid).force_field<float>();
      for (std::size_t i = 0; i < nodes; ++i) sum += ff.x[i];
    }
    EXPECT_NEAR(sum, total, (precision == lb::Precision::kDouble ? 1e-14 : 1e-6) * magnitude);
  }
}

// End to end with the lattice: in steady plane Couette flow the lattice
// velocity is exactly linear, u = v (y / h - 1/2) with the walls at y = 0 and
// y = h and node j at y = j + 1/2, so every kernel must return that value at
// any point at least a half-width from the walls. Checks that lb and ibm
// agree on where the nodes and walls are.
TEST(FluidCoupling, InterpolatesSteadyCouetteProfile) {
  const int h = 16;
  const double v = 0.05;
  lb::FluidParams p;
  p.nx = 8;
  p.ny = h;
  p.nz = 4;
  p.tau = 1.0;
  p.lower_wall_velocity = {-0.5 * v, 0.0, 0.0};
  p.upper_wall_velocity = {0.5 * v, 0.0, 0.0};
  p.velocity_field = true;
  StatusOr<lb::Fluid> made = lb::make_fluid(p);
  ASSERT_TRUE(made.ok());
  lb::Fluid fluid = std::move(made).value();
  for (int s = 0; s < 6200; ++s) lb::collide_stream(fluid);  // 4 h^2 / nu: transient below 1e-60
  const std::vector<double> pts = random_points(200, grid_of(fluid), 2.0, h - 2.0, -10.0, 14);
  std::vector<double> u(pts.size());
  for (Kernel k : kKernels) {
    ASSERT_TRUE(interpolate_velocity(k, fluid, pts, u).ok());
    double worst = 0.0;
    for (std::size_t i = 0; i < pts.size() / 3; ++i) {
      worst = std::max({worst, std::abs(u[3 * i] - v * (pts[3 * i + 1] / h - 0.5)), std::abs(u[3 * i + 1]),
                        std::abs(u[3 * i + 2])});
    }
    EXPECT_LT(worst, 1e-12 * v) << kernel_name(k);
  }
}

TEST(FluidCoupling, MissingFieldsAreRefused) {
  lb::FluidParams p;
  p.nx = p.ny = p.nz = 4;
  StatusOr<lb::Fluid> made = lb::make_fluid(p);
  ASSERT_TRUE(made.ok());
  lb::Fluid fluid = std::move(made).value();
  std::vector<double> pts = {1.0, 1.0, 1.0}, out(3);
  EXPECT_EQ(interpolate_velocity(Kernel::kPeskin4, fluid, pts, out).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(spread_forces(Kernel::kPeskin4, pts, out, fluid).code(), StatusCode::kFailedPrecondition);
}

TEST(Kernel, ParseNames) {
  EXPECT_EQ(parse_kernel("peskin4").value(), Kernel::kPeskin4);
  EXPECT_EQ(parse_kernel("").value(), Kernel::kPeskin4);  // unset: the default
  EXPECT_EQ(parse_kernel("peskin3").value(), Kernel::kPeskin3);
  EXPECT_EQ(parse_kernel("trilinear").value(), Kernel::kTrilinear);
  const StatusOr<Kernel> bad = parse_kernel("gauss", "shear_flow.numerics.ibm_kernel");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("shear_flow.numerics.ibm_kernel"), std::string::npos);
  for (Kernel k : kKernels) EXPECT_EQ(parse_kernel(kernel_name(k)).value(), k);
}

}  // namespace
}  // namespace cellflow::ibm
