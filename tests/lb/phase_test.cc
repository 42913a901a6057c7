// The per-node phase field of the fluid (FluidParams::phase_taus): a phase
// field of zeros gives the bits of a fluid without one; a fluid all in phase
// 1 is a fluid of that tau (Poiseuille through Guo forcing, exact with TRT);
// two layers of viscosity ratio lambda in plane Couette flow carry the same
// shear stress (shear rates in the ratio 1 / lambda); a sphere of tau =
// kMinStableTau in a sheared box stays stable; bad phase input is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "physics/lb/fluid.h"
#include "physics/lb/fluid_state.h"
#include "tests/lb/lb_test_support.h"

namespace cellflow::lb {
namespace {

using testing::make_or_die;

FluidParams sheared_box(Precision precision, Streaming streaming) {
  FluidParams p;
  p.nx = 13;
  p.ny = 11;
  p.nz = 7;
  p.tau = 0.8;
  p.lower_wall_velocity = {-0.03, 0.0, 0.0};
  p.upper_wall_velocity = {0.03, 0.0, 0.0};
  p.uniform_force = {1e-5, 0.0, -2e-6};
  p.force_field = true;
  p.velocity_field = true;
  p.precision = precision;
  p.streaming = streaming;
  return p;
}

template <class T>
void fill_force(Fluid& fluid) {
  VectorField<T> f = fluid.force_field<T>();
  for (std::size_t n = 0; n < fluid.num_nodes(); ++n) {
    f.x[n] = static_cast<T>(1e-4 * std::sin(0.37 * n));
    f.y[n] = static_cast<T>(1e-4 * std::cos(0.21 * n));
    f.z[n] = static_cast<T>(-5e-5 * std::sin(0.11 * n));
  }
}

TEST(Phases, ZeroPhasesGiveTheBitsOfAFluidWithoutAPhaseField) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    for (Streaming streaming : {Streaming::kAA, Streaming::kTwoArray}) {
      FluidParams plain = sheared_box(precision, streaming);
      FluidParams phased = plain;
      phased.phase_taus = {0.52, 1.7};
      Fluid a = make_or_die(plain), b = make_or_die(phased);
      for (int s = 0; s < 9; ++s) {
        for (Fluid* f : {&a, &b}) {
          if (precision == Precision::kDouble)
            fill_force<double>(*f);
          else
            fill_force<float>(*f);
          collide_stream(*f);
        }
      }
      const std::span<const std::byte> pa = population_bytes(a), pb = population_bytes(b);
      ASSERT_EQ(pa.size(), pb.size());
      EXPECT_EQ(std::memcmp(pa.data(), pb.data(), pa.size()), 0);
      EXPECT_GT(memory_bytes(phased), memory_bytes(plain));
    }
  }
}

// u = f / (2 rho nu_1) (H^2/4 - s^2) with nu_1 = (tau_1 - 1/2) / 3 of phase 1:
// the Guo forcing factors and the TRT tau_minus are those of the node's tau.
TEST(Phases, AFluidAllInPhaseOneIsAFluidOfItsTau) {
  for (Precision precision : {Precision::kDouble, Precision::kFloat}) {
    const int h = 16;
    const double tau1 = 0.7, nu1 = (tau1 - 0.5) / 3.0, u_max = 0.02;
    const double force = 8.0 * nu1 * u_max / (h * h);
    FluidParams p;
    p.nx = 1;
    p.ny = h;
    p.nz = 1;
    p.tau = 1.0;
    p.phase_taus = {tau1};
    p.uniform_force = {force, 0.0, 0.0};
    p.precision = precision;
    Fluid fluid = make_or_die(p);
    ASSERT_TRUE(set_phases(fluid, std::vector<std::uint8_t>(fluid.num_nodes(), 1)).ok());
    testing::run(fluid, static_cast<int>(12.0 * h * h / nu1));
    const std::vector<double> u = testing::ux_profile(fluid);
    double num = 0.0, den = 0.0;
    for (int j = 0; j < h; ++j) {
      const double s = (j + 0.5) - 0.5 * h;
      const double exact = force / (2.0 * nu1) * (0.25 * h * h - s * s);
      num += (u[j] - exact) * (u[j] - exact);
      den += exact * exact;
    }
    const double err = std::sqrt(num / den);
    std::printf("[ measured ] Poiseuille in phase 1 (tau 0.7 in a tau 1 fluid), %s: L2 rel. error %.2e\n",
                precision == Precision::kDouble ? "double" : "float", err);
    EXPECT_LT(err, precision == Precision::kDouble ? 1e-9 : 1e-3);
  }
}

// Two layers, phase 0 (tau 1) below y = H/2 and phase 1 above, between walls
// moving at -+u: the shear stress eta du/dy is the same in both layers, so
// du/dy = 2u / (H/2 (1 + lambda)) above and lambda times that below; with
// TRT at Lambda = 3/16 the piecewise-linear profile is exact (measured 3e-13).
TEST(Phases, TwoLayerCouetteCarriesOneShearStress) {
  for (double lambda : {0.05, 4.0}) {
    const int h = 16;
    const double u = 0.01;
    FluidParams p;
    p.nx = 1;
    p.ny = h;
    p.nz = 1;
    p.tau = 1.0;
    p.phase_taus = {tau_for_viscosity_ratio(p.tau, lambda)};
    p.lower_wall_velocity = {-u, 0.0, 0.0};
    p.upper_wall_velocity = {u, 0.0, 0.0};
    Fluid fluid = make_or_die(p);
    std::vector<std::uint8_t> phases(fluid.num_nodes(), 0);
    for (int j = h / 2; j < h; ++j) phases[fluid.node(0, j, 0)] = 1;
    ASSERT_TRUE(set_phases(fluid, phases).ok());
    const double nu_min = std::min(lambda, 1.0) * (p.tau - 0.5) / 3.0;
    testing::run(fluid, static_cast<int>(3.0 * h * h / nu_min));
    const std::vector<double> prof = testing::ux_profile(fluid);
    const double g_upper_exact = 2.0 * u / (0.5 * h * (1.0 + lambda));
    const double g_lower_exact = lambda * g_upper_exact;
    // Slopes away from the interface and the walls.
    const double g_lower = (prof[h / 2 - 3] - prof[2]) / (h / 2 - 5);
    const double g_upper = (prof[h - 3] - prof[h / 2 + 2]) / (h / 2 - 5);
    std::printf("[ measured ] two-layer Couette lambda %.2f: shear rate / exact - 1: lower %.2e upper %.2e\n",
                lambda, g_lower / g_lower_exact - 1.0, g_upper / g_upper_exact - 1.0);
    EXPECT_NEAR(g_lower / g_lower_exact, 1.0, 1e-6) << "lambda " << lambda;  // TRT 3/16: exact
    EXPECT_NEAR(g_upper / g_upper_exact, 1.0, 1e-6) << "lambda " << lambda;
  }
}

// A sphere of radius 5 at tau_in = kMinStableTau (lambda = 0.01 in a tau 1
// fluid) in plane Couette flow at wall Mach 0.06, float storage as the flow
// scene: after 3000 steps (2 viscous times of the 16-node box, 60 of the
// inner fluid's sphere) the fields stay finite and the velocity bounded by
// the walls'.
TEST(Phases, ASphereAtTheMinimumStableTauStaysStable) {
  FluidParams p;
  p.nx = 16;
  p.ny = 16;
  p.nz = 16;
  p.tau = 1.0;
  p.phase_taus = {kMinStableTau};
  const double u = 0.035;
  p.lower_wall_velocity = {-u, 0.0, 0.0};
  p.upper_wall_velocity = {u, 0.0, 0.0};
  p.precision = Precision::kFloat;
  Fluid fluid = make_or_die(p);
  std::vector<std::uint8_t> phases(fluid.num_nodes(), 0);
  for (int k = 0; k < p.nz; ++k)
    for (int j = 0; j < p.ny; ++j)
      for (int i = 0; i < p.nx; ++i) {
        const double x = i + 0.5 - 8.0, y = j + 0.5 - 8.0, z = k + 0.5 - 8.0;
        if (x * x + y * y + z * z < 25.0) phases[fluid.node(i, j, k)] = 1;
      }
  ASSERT_TRUE(set_phases(fluid, phases).ok());
  testing::run(fluid, 3000);
  const testing::Velocity v = testing::velocity(fluid);
  double u_max = 0.0;
  bool finite = true;
  for (std::size_t n = 0; n < fluid.num_nodes(); ++n) {
    finite = finite && std::isfinite(v.ux[n]) && std::isfinite(v.uy[n]) && std::isfinite(v.uz[n]);
    u_max = std::max(u_max, std::sqrt(v.ux[n] * v.ux[n] + v.uy[n] * v.uy[n] + v.uz[n] * v.uz[n]));
  }
  std::printf("[ measured ] sphere at tau_in %.3f in Couette flow: max |u| / u_wall %.3f\n", kMinStableTau,
              u_max / u);
  EXPECT_TRUE(finite);
  EXPECT_LT(u_max, 1.05 * u);
}

TEST(Phases, BadPhaseInputIsRefused) {
  FluidParams p;
  p.nx = p.ny = p.nz = 4;
  p.phase_taus = {0.5};
  StatusOr<Fluid> bad_tau = make_fluid(p);
  ASSERT_FALSE(bad_tau.ok());
  EXPECT_NE(bad_tau.status().message().find("phase_taus[0]"), std::string::npos);
  p.phase_taus.assign(256, 0.7);
  EXPECT_FALSE(make_fluid(p).ok());
  p.phase_taus = {0.7};
  Fluid fluid = make_or_die(p);
  EXPECT_FALSE(set_phases(fluid, std::vector<std::uint8_t>(fluid.num_nodes(), 2)).ok());
  EXPECT_FALSE(set_phases(fluid, std::vector<std::uint8_t>(3, 1)).ok());
  FluidParams none;
  none.nx = none.ny = none.nz = 4;
  Fluid plain = make_or_die(none);
  EXPECT_TRUE(plain.phases().empty());
  EXPECT_FALSE(set_phases(plain, std::vector<std::uint8_t>(plain.num_nodes(), 0)).ok());
}

}  // namespace
}  // namespace cellflow::lb
