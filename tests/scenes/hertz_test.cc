// Hertz reference forces against the numbers of shared/validation/README.md.
#include <gtest/gtest.h>

#include <cmath>

#include "physics/scenes/quasi_static/quasi_static.h"

namespace cellflow::scenes {
namespace {

TEST(Hertz, PlatesMatchTheValidationTable) {
  // nu = 0.5: F / (E R^2) = 0.0199, 0.0562, 0.159, 0.292 at eps = 0.05, 0.1, 0.2, 0.3 (3 digits)
  const elastic::Material m{.youngs_modulus_pa = 1.0, .poisson_ratio = 0.5, .mooney_rivlin_w = 1.0};
  const double radius = 1.0;
  const double eps[] = {0.05, 0.1, 0.2, 0.3};
  const double table[] = {0.0199, 0.0562, 0.159, 0.292};
  const double half_last_digit[] = {5e-5, 5e-5, 5e-4, 5e-4};
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(hertz_plates_force_n(m, radius, 2.0 * radius * eps[i]), table[i], half_last_digit[i])
        << "eps " << eps[i];
  }
}

TEST(Hertz, PlatesFormulaWithUnits) {
  // F = (sqrt 2 / 3) E* sqrt(R) delta^1.5, the same law written with delta
  const elastic::Material m{.youngs_modulus_pa = 150.0, .poisson_ratio = 0.48, .mooney_rivlin_w = 0.5};
  const double radius = 8.6e-6, delta = 0.3 * radius;
  const double e_star = 150.0 / (1.0 - 0.48 * 0.48);
  const double expected = std::sqrt(2.0) / 3.0 * e_star * std::sqrt(radius) * std::pow(delta, 1.5);
  EXPECT_NEAR(hertz_plates_force_n(m, radius, delta), expected, 1e-12 * expected);
  EXPECT_EQ(hertz_plates_force_n(m, radius, 0.0), 0.0);
}

TEST(Hertz, ProbeBalancesTheTwoContacts) {
  const elastic::Material m{.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.3, .mooney_rivlin_w = 1.0};
  const double rc = 40e-6, rp = 26.5e-6, delta = 4e-6;
  const double force = hertz_probe_force_n(m, rc, rp, delta);
  const double e_star = 1000.0 / (1.0 - 0.09);
  const double r12 = rp * rc / (rp + rc);
  // invert each contact for its approach: d = (3 F / (4 E* sqrt(R)))^(2/3)
  const double d_top = std::pow(3.0 * force / (4.0 * e_star * std::sqrt(r12)), 2.0 / 3.0);
  const double d_bottom = std::pow(3.0 * force / (4.0 * e_star * std::sqrt(rc)), 2.0 / 3.0);
  EXPECT_NEAR(d_top + d_bottom, delta, 1e-12 * delta);
  EXPECT_GT(d_top, d_bottom);  // the smaller effective radius takes the larger approach
}

TEST(Hertz, HugeProbeIsAPlate) {
  // Rp -> infinity: both contacts are sphere-on-flat, each takes delta/2: the plates formula
  const elastic::Material m{.youngs_modulus_pa = 1000.0, .poisson_ratio = 0.4, .mooney_rivlin_w = 1.0};
  const double rc = 10e-6, delta = 1e-6;
  EXPECT_NEAR(hertz_probe_force_n(m, rc, 1e6 * rc, delta), hertz_plates_force_n(m, rc, delta),
              1e-5 * hertz_plates_force_n(m, rc, delta));
}

}  // namespace
}  // namespace cellflow::scenes
