// Material moduli (paper eq. 6 and 8) and validation of the Material fields.
#include "physics/elastic/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace cellflow::elastic {
namespace {

TEST(ElasticMaterial, ModuliFollowPaperEquations) {
  const Material material{1200.0, 0.3, 0.25};
  const Moduli moduli = moduli_from(material);
  const double mu = 1200.0 / (2.0 * 1.3);
  // mu1 = w mu, mu2 = (1 - w) mu, kappa = E / (3 (1 - 2 nu)): exact to rounding (1e-14 relative)
  EXPECT_NEAR(moduli.mu1_pa, 0.25 * mu, 1e-14 * mu);
  EXPECT_NEAR(moduli.mu2_pa, 0.75 * mu, 1e-14 * mu);
  EXPECT_NEAR(moduli.kappa_pa, 1200.0 / (3.0 * 0.4), 1e-14 * 1000.0);
  // mu1 + mu2 = mu and the small-strain Young's modulus 9 kappa mu / (3 kappa + mu) = E
  const double shear = moduli.mu1_pa + moduli.mu2_pa;
  EXPECT_NEAR(9.0 * moduli.kappa_pa * shear / (3.0 * moduli.kappa_pa + shear), 1200.0, 1e-12 * 1200.0);
}

TEST(ElasticMaterial, NeoHookeanHasExactlyZeroMu2) {
  EXPECT_EQ(moduli_from(Material{1000.0, 0.48, 1.0}).mu2_pa, 0.0);
}

TEST(ElasticMaterial, ValidMaterialPasses) {
  EXPECT_TRUE(validate(Material{1000.0, 0.48, 1.0}, "cell.material.").ok());
  EXPECT_TRUE(validate(Material{1000.0, -0.99, 0.0}, "").ok());
}

struct BadMaterial {
  Material material;
  std::string field;
  std::string range;
};

class ElasticMaterialValidation : public ::testing::TestWithParam<BadMaterial> {};

TEST_P(ElasticMaterialValidation, NamesTheFieldAndItsRange) {
  const BadMaterial& bad = GetParam();
  const Status status = validate(bad.material, "compression.cell.material.");
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("compression.cell.material." + bad.field), std::string::npos)
      << status.message();
  EXPECT_NE(status.message().find(bad.range), std::string::npos) << status.message();
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

INSTANTIATE_TEST_SUITE_P(
    Bad, ElasticMaterialValidation,
    ::testing::Values(BadMaterial{{0.0, 0.3, 1.0}, "youngs_modulus_pa", "> 0 and finite"},
                      BadMaterial{{-5.0, 0.3, 1.0}, "youngs_modulus_pa", "> 0 and finite"},
                      BadMaterial{{kNaN, 0.3, 1.0}, "youngs_modulus_pa", "> 0 and finite"},
                      BadMaterial{{kInf, 0.3, 1.0}, "youngs_modulus_pa", "> 0 and finite"},
                      BadMaterial{{1000.0, 0.5, 1.0}, "poisson_ratio = 0.5", "(-1, 0.5)"},
                      BadMaterial{{1000.0, -1.0, 1.0}, "poisson_ratio = -1", "(-1, 0.5)"},
                      BadMaterial{{1000.0, kNaN, 1.0}, "poisson_ratio", "(-1, 0.5)"},
                      BadMaterial{{1000.0, 0.3, 1.2}, "mooney_rivlin_w = 1.2", "[0, 1]"},
                      BadMaterial{{1000.0, 0.3, -0.1}, "mooney_rivlin_w", "[0, 1]"},
                      BadMaterial{{1000.0, 0.3, kNaN}, "mooney_rivlin_w", "[0, 1]"}));

TEST(ElasticMaterial, ReportsEveryBadField) {
  const Status status = validate(Material{0.0, 0.5, 2.0}, "m.");
  ASSERT_FALSE(status.ok());
  for (const char* field : {"m.youngs_modulus_pa", "m.poisson_ratio", "m.mooney_rivlin_w"}) {
    EXPECT_NE(status.message().find(field), std::string::npos) << status.message();
  }
}

}  // namespace
}  // namespace cellflow::elastic
