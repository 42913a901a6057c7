// Conservation laws of the collide-stream step: mass with moving walls and
// forcing, and momentum in a periodic box, where each step must add exactly
// the total body force (Guo forcing: sum_i c_i S_i = F).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "physics/lb/fluid.h"
#include "tests/lb/lb_test_support.h"

namespace cellflow::lb {
namespace {

using testing::make_or_die;

// Random small velocity field (|u| < 0.03) and density (|rho - 1| < 0.01).
void randomize(Fluid& fluid, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> du(-0.03, 0.03), dr(-0.01, 0.01);
  const std::size_t n = fluid.num_nodes();
  std::vector<double> rho(n), ux(n), uy(n), uz(n);
  for (std::size_t i = 0; i < n; ++i) {
    rho[i] = 1.0 + dr(rng);
    ux[i] = du(rng);
    uy[i] = du(rng);
    uz[i] = du(rng);
  }
  set_equilibrium(fluid, rho, ux, uy, uz);
}

// Random force-density field (|f| < 1e-4), returns its sum.
std::array<double, 3> fill_random_force(Fluid& fluid, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> df(-1e-4, 1e-4);
  std::array<double, 3> sum{0, 0, 0};
  const auto fill = [&](auto f) {
    using T = std::remove_reference_t<decltype(*f.x)>;
    for (std::size_t i = 0; i < fluid.num_nodes(); ++i) {
      const T fx = static_cast<T>(df(rng)), fy = static_cast<T>(df(rng)), fz = static_cast<T>(df(rng));
      f.x[i] = fx;
      f.y[i] = fy;
      f.z[i] = fz;
      sum[0] += fx;
      sum[1] += fy;
      sum[2] += fz;
    }
  };
  if (fluid.params().precision == Precision::kDouble)
    fill(fluid.force_field<double>());
  else
    fill(fluid.force_field<float>());
  return sum;
}

FluidParams box(Precision precision, Streaming streaming, bool walls) {
  FluidParams p;
  p.nx = 12;
  p.ny = 10;
  p.nz = 6;
  p.tau = 0.8;
  p.walls_y = walls;
  if (walls) {
    p.lower_wall_velocity = {-0.04, 0.0, 0.01};
    p.upper_wall_velocity = {0.03, 0.0, -0.02};
  }
  p.uniform_force = {2e-5, -1e-5, 3e-5};
  p.force_field = true;
  p.precision = precision;
  p.streaming = streaming;
  return p;
}

// Mass is conserved to round-off: the collision conserves it, Guo's source
// has zero sum, and the moving-wall terms cancel over the links of a node for
// a tangential wall velocity. Tolerance per step and node: 4 eps of the
// storage type (double 9e-16, float 4.8e-7) on deviations of order 1e-2, i.e.
// relative drift of the total below 1e-13 (double) and 1e-6 (float) after 200
// steps (measured: see output).
TEST(Conservation, MassWithMovingWallsAndForces) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
      Fluid fluid = make_or_die(box(precision, streaming, true));
      randomize(fluid, 1);
      const double m0 = total_mass(fluid);
      for (int s = 0; s < 200; ++s) {
        fill_random_force(fluid, 100 + s);
        collide_stream(fluid);
      }
      const double drift = std::abs(total_mass(fluid) - m0) / m0;
      std::printf("[ measured ] mass drift after 200 steps (%s, %s): %.2e\n",
                  precision == Precision::kDouble ? "double" : "float",
                  streaming == Streaming::kAA ? "AA" : "two-array", drift);
      EXPECT_LT(drift, precision == Precision::kDouble ? 1e-13 : 1e-6);
    }
  }
}

// Total momentum sum_x (sum_i f_i c_i) grows by exactly the total force per
// step in a periodic box (relative to the momentum added: 1e-10 double, 1e-4
// float).
TEST(Conservation, MomentumGainEqualsTotalForce) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
      Fluid fluid = make_or_die(box(precision, streaming, false));
      randomize(fluid, 2);
      const std::array<double, 3> field_sum = fill_random_force(fluid, 7);  // kept fixed
      const auto momentum = [&] {
        // sum_i f_i c_i = rho u - F/2 at every node
        std::array<double, 3> p{0, 0, 0};
        for (int k = 0; k < fluid.nz(); ++k)
          for (int j = 0; j < fluid.ny(); ++j)
            for (int i = 0; i < fluid.nx(); ++i) {
              const std::array<double, kQ> f = populations(fluid, i, j, k);
              for (int q = 0; q < kQ; ++q) {
                p[0] += kCx[q] * f[q];
                p[1] += kCy[q] * f[q];
                p[2] += kCz[q] * f[q];
              }
            }
        return p;
      };
      const std::array<double, 3> p0 = momentum();
      const int steps = 50;
      for (int s = 0; s < steps; ++s) collide_stream(fluid);
      const std::array<double, 3> p1 = momentum();
      const auto& g = fluid.params().uniform_force;
      for (int d = 0; d < 3; ++d) {
        const double added = steps * (field_sum[d] + g[d] * static_cast<double>(fluid.num_nodes()));
        EXPECT_NEAR(p1[d] - p0[d], added, (precision == Precision::kDouble ? 1e-10 : 1e-4) * std::abs(added))
            << "component " << d;
      }
    }
  }
}

}  // namespace
}  // namespace cellflow::lb
