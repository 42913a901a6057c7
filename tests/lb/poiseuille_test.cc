// Body-force driven Poiseuille flow between no-slip walls at y = 0 and y = H
// (shared/validation/README.md): u = f / (2 eta) (H^2/4 - s^2), s = y - H/2.
// Tests the Guo forcing (uniform force and force field, with the half-force
// velocity shift) and the wall position of half-way bounce-back.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "physics/lb/fluid.h"
#include "tests/lb/lb_test_support.h"

namespace cellflow::lb {
namespace {

using testing::make_or_die;

struct PoiseuilleCase {
  double tau = 1.0;
  CollisionModel collision = CollisionModel::kTrt;
  Precision precision = Precision::kDouble;
  Streaming streaming = Streaming::kAA;
  bool use_force_field = false;  // drive through the per-node field instead of uniform_force
  int h = 32;                    // nodes across the channel
};

// Relative L2 error of the steady profile, sqrt(sum (u - u_a)^2 / sum u_a^2).
double poiseuille_l2_error(const PoiseuilleCase& c) {
  const int h = c.h;
  const double nu = (c.tau - 0.5) / 3.0;
  const double u_max = 0.02;                        // Mach 0.035
  const double force = 8.0 * nu * u_max / (h * h);  // f = 8 eta u_max / H^2, rho = 1
  FluidParams p;
  p.nx = 1;  // the flow is 1-D; x and z wrap onto the same node
  p.ny = h;
  p.nz = 1;
  p.tau = c.tau;
  p.collision = c.collision;
  p.precision = c.precision;
  p.streaming = c.streaming;
  p.force_field = c.use_force_field;
  if (!c.use_force_field) p.uniform_force = {force, 0.0, 0.0};
  Fluid fluid = make_or_die(p);
  // Slowest mode decays as exp(-pi^2 nu t / H^2): 12 H^2/nu leaves e^-118.
  const int steps = static_cast<int>(12.0 * h * h / nu);
  for (int s = 0; s < steps; ++s) {
    if (c.use_force_field) {
      // What a coupled run does each step: zero, then fill the field.
      zero_force_field(fluid);
      if (c.precision == Precision::kDouble) {
        VectorField<double> f = fluid.force_field<double>();
        for (std::size_t n = 0; n < fluid.num_nodes(); ++n) f.x[n] = force;
      } else {
        VectorField<float> f = fluid.force_field<float>();
        for (std::size_t n = 0; n < fluid.num_nodes(); ++n) f.x[n] = static_cast<float>(force);
      }
    }
    collide_stream(fluid);
  }
  const std::vector<double> u = testing::ux_profile(fluid);
  EXPECT_LT(testing::max_deviation_from_profile(fluid, u), 1e-6 * u_max);
  double num = 0.0, den = 0.0;
  for (int j = 0; j < h; ++j) {
    const double s = (j + 0.5) - 0.5 * h;
    // u = f / (2 rho nu) (H^2/4 - s^2)
    const double exact = force / (2.0 * nu) * (0.25 * h * h - s * s);
    num += (u[j] - exact) * (u[j] - exact);
    den += exact * exact;
  }
  return std::sqrt(num / den);
}

// Default settings (TRT, Lambda = 3/16, tau = 1): below 1e-3 as required; with
// the walls exactly half-way the parabola is in fact reproduced to round-off.
TEST(Poiseuille, DefaultSettingsL2BelowOnePermille) {
  const double err = poiseuille_l2_error({});
  std::printf("[ measured ] Poiseuille H = 32, TRT 3/16, tau 1, double: L2 rel. error %.2e\n", err);
  EXPECT_LT(err, 1e-3);
  EXPECT_LT(err, 1e-10);
}

// TRT with Lambda = 3/16 makes the result independent of tau (exact parabola).
TEST(Poiseuille, TrtExactForAnyTau) {
  for (double tau : {0.6, 2.0}) {
    PoiseuilleCase c;
    c.tau = tau;
    c.h = 16;
    SCOPED_TRACE(::testing::Message() << "tau " << tau);
    EXPECT_LT(poiseuille_l2_error(c), 1e-10);
  }
}

// Through the force field instead of the uniform force, and with the
// two-array scheme: same exact parabola.
TEST(Poiseuille, ForceFieldAndTwoArraySchemeExact) {
  PoiseuilleCase field;
  field.use_force_field = true;
  EXPECT_LT(poiseuille_l2_error(field), 1e-10);
  PoiseuilleCase two;
  two.streaming = Streaming::kTwoArray;
  EXPECT_LT(poiseuille_l2_error(two), 1e-10);
}

// BGK at tau = 1: the bounce-back wall sits at a tau-dependent distance from
// half-way (second order in dx), still well below 1e-3 at 32 cells.
TEST(Poiseuille, BgkBelowOnePermille) {
  PoiseuilleCase c;
  c.collision = CollisionModel::kBgk;
  const double err = poiseuille_l2_error(c);
  std::printf("[ measured ] Poiseuille H = 32, BGK, tau 1: L2 rel. error %.2e\n", err);
  EXPECT_LT(err, 1e-3);
}

// Float storage: the same bound of 1e-3. Here the error is float round-off
// (measured 3.7e-5): the stored populations are rounded each step and the
// bias accumulates over the viscous time H^2/nu ~ 6e3 steps.
TEST(Poiseuille, FloatStorage) {
  PoiseuilleCase c;
  c.precision = Precision::kFloat;
  const double err = poiseuille_l2_error(c);
  std::printf("[ measured ] Poiseuille H = 32, TRT 3/16, tau 1, float: L2 rel. error %.2e\n", err);
  EXPECT_LT(err, 1e-3);
  c.use_force_field = true;
  EXPECT_LT(poiseuille_l2_error(c), 1e-3);
}

}  // namespace
}  // namespace cellflow::lb
