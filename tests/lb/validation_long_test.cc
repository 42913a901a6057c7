// Heavier variants of the lattice Boltzmann validation (label long): one more
// resolution for the start-up Couette convergence, the shear-wave viscosity
// at the largest allowed tau, and Poiseuille at 64 cells with BGK, whose
// wall-position error must fall as 1/H^2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "physics/lb/fluid.h"
#include "tests/lb/lb_test_support.h"

namespace cellflow::lb {
namespace {

using testing::make_or_die;

double couette_startup(double y, double t, double h, double nu, double v) {
  const double pi = std::numbers::pi;
  double sum = 0.0;
  for (int k = 1; k <= 20000; ++k) {
    const double decay = std::exp(-4.0 * pi * pi * nu * k * k * t / (h * h));
    if (decay < 1e-18) break;
    sum += decay * std::sin(2.0 * pi * k * y / h) / (pi * k);
  }
  return v * (y / h - 0.5 + sum);
}

double couette_error(int h, double fraction) {
  const double tau = 1.0, v = 0.05, nu = (tau - 0.5) / 3.0;
  FluidParams p;
  p.nx = 1;
  p.ny = h;
  p.nz = 1;
  p.tau = tau;
  p.lower_wall_velocity = {-0.5 * v, 0.0, 0.0};
  p.upper_wall_velocity = {0.5 * v, 0.0, 0.0};
  Fluid fluid = make_or_die(p);
  const int steps = static_cast<int>(std::lround(fraction * h * h / nu));
  testing::run(fluid, steps);
  const std::vector<double> u = testing::ux_profile(fluid);
  double err = 0.0;
  for (int j = 0; j < h; ++j)
    err = std::max(err, std::abs(u[j] - couette_startup(j + 0.5, steps, h, nu, v)) / v);
  return err;
}

// Second order continues to h = 64 (error ratio 32 -> 64 at least 3.5).
TEST(CouetteStartupLong, SecondOrderUpTo64Cells) {
  for (double fraction : {0.01, 0.05}) {
    const double e32 = couette_error(32, fraction), e64 = couette_error(64, fraction);
    std::printf("[ measured ] Couette start-up t = %.2f h^2/nu: error h=32 %.2e, h=64 %.2e\n", fraction, e32,
                e64);
    EXPECT_LT(e64, 2.5e-4);
    EXPECT_GT(e32 / e64, 3.5);
  }
}

double shear_wave_viscosity(double tau, int n) {
  FluidParams p;
  p.nx = 1;
  p.ny = n;
  p.nz = 1;
  p.tau = tau;
  p.walls_y = false;
  Fluid fluid = make_or_die(p);
  const double k = 2.0 * std::numbers::pi / n;
  std::vector<double> ux(fluid.num_nodes()), zero(fluid.num_nodes(), 0.0);
  for (int j = 0; j < n; ++j) ux[j] = 0.02 * std::sin(k * (j + 0.5));
  set_equilibrium(fluid, {}, ux, zero, zero);
  const auto amplitude = [&] {
    const std::vector<double> u = testing::ux_profile(fluid);
    double a = 0.0;
    for (int j = 0; j < n; ++j) a += u[j] * std::sin(k * (j + 0.5));
    return 2.0 * a / n;
  };
  const double nu = (tau - 0.5) / 3.0;
  const int t1 = static_cast<int>(20 * tau);
  const int t2 = t1 + static_cast<int>(std::lround(2.0 / (nu * k * k)));
  testing::run(fluid, t1);
  const double a1 = amplitude();
  testing::run(fluid, t2 - t1);
  return std::log(a1 / amplitude()) / (k * k * (t2 - t1));
}

// tau = 3 (the largest numerics.relaxation_time allowed) needs 128 cells per
// wavelength for 1 %.
TEST(ShearWaveLong, ViscosityAtLargestTau) {
  const double expected = (3.0 - 0.5) / 3.0;
  const double nu = shear_wave_viscosity(3.0, 128);
  std::printf("[ measured ] shear wave tau 3, 128 cells: nu / nu_expected - 1 = %.2e\n", nu / expected - 1.0);
  EXPECT_NEAR(nu / expected, 1.0, 0.01);
}

double poiseuille_bgk_error(int h) {
  const double tau = 1.0, nu = (tau - 0.5) / 3.0, u_max = 0.02;
  const double force = 8.0 * nu * u_max / (h * h);
  FluidParams p;
  p.nx = 1;
  p.ny = h;
  p.nz = 1;
  p.tau = tau;
  p.collision = CollisionModel::kBgk;
  p.uniform_force = {force, 0.0, 0.0};
  Fluid fluid = make_or_die(p);
  testing::run(fluid, static_cast<int>(12.0 * h * h / nu));
  const std::vector<double> u = testing::ux_profile(fluid);
  double num = 0.0, den = 0.0;
  for (int j = 0; j < h; ++j) {
    const double s = (j + 0.5) - 0.5 * h;
    const double exact = force / (2.0 * nu) * (0.25 * h * h - s * s);
    num += (u[j] - exact) * (u[j] - exact);
    den += exact * exact;
  }
  return std::sqrt(num / den);
}

TEST(PoiseuilleLong, BgkWallErrorIsSecondOrder) {
  const double e32 = poiseuille_bgk_error(32), e64 = poiseuille_bgk_error(64);
  std::printf("[ measured ] Poiseuille BGK tau 1: L2 error H=32 %.2e, H=64 %.2e\n", e32, e64);
  EXPECT_LT(e64, 2.5e-4);
  EXPECT_GT(e32 / e64, 3.5);
}

}  // namespace
}  // namespace cellflow::lb
