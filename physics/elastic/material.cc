#include "physics/elastic/material.h"

#include <cmath>
#include <string>

namespace cellflow::elastic {

namespace {

// What a scene can run. E: from a thousandth of a pascal (below the softest
// gel) to 1 GPa (stiff plastic): the forces scale with E R^2, and outside
// this range E R^2 at the cell radii of cell_params.h leaves the range in
// which the solver's tolerances and the contact penalty are calibrated.
constexpr double kMinYoungsModulusPa = 1e-3;
constexpr double kMaxYoungsModulusPa = 1e9;
// nu: the bulk modulus kappa = E / (3 (1 - 2 nu)) over the shear modulus
// mu = E / (2 (1 + nu)) stays below about 3e4 (nu <= 0.49999) and above about
// 2e-4 (nu >= -0.999); beyond, one term of eq. (5) is more than ten thousand
// times stiffer than the other and the tangent solve loses every digit of the
// softer one (nu -> 1/2 gives kappa = inf at 0.5 - 1 ulp).
constexpr double kMinPoissonRatio = -0.999;
constexpr double kMaxPoissonRatio = 0.49999;

std::string range_text(double lo, double hi) {
  return "lie in [" + number_text(lo) + ", " + number_text(hi) + "]";
}

}  // namespace

Moduli moduli_from(const Material& material) {
  const double e = material.youngs_modulus_pa;
  const double nu = material.poisson_ratio;
  const double w = material.mooney_rivlin_w;
  // mu = E / (2 (1 + nu))   (paper eq. 6)
  const double mu = e / (2.0 * (1.0 + nu));
  Moduli moduli;
  // mu1 = w mu, mu2 = (1 - w) mu   (paper eq. 8); w = 1 gives mu2 = 0 exactly
  moduli.mu1_pa = w * mu;
  moduli.mu2_pa = (1.0 - w) * mu;
  // kappa = E / (3 (1 - 2 nu))   (paper eq. 6)
  moduli.kappa_pa = e / (3.0 * (1.0 - 2.0 * nu));
  return moduli;
}

Violations check(const Material& material) {
  Violations violations;
  // Written so that NaN fails every check: comparisons with NaN are false.
  const double e = material.youngs_modulus_pa;
  if (!(e > 0.0 && std::isfinite(e))) {
    violations.add_value("youngs_modulus_pa", e, "be > 0 and finite");
  } else if (!(e >= kMinYoungsModulusPa && e <= kMaxYoungsModulusPa)) {
    violations.add_value("youngs_modulus_pa", e,
                         range_text(kMinYoungsModulusPa, kMaxYoungsModulusPa) + " Pa");
  }
  const double nu = material.poisson_ratio;
  if (!(nu > -1.0 && nu < 0.5)) {
    violations.add_value("poisson_ratio", nu, "lie in (-1, 0.5)");
  } else if (!(nu >= kMinPoissonRatio && nu <= kMaxPoissonRatio)) {
    violations.add_value(
        "poisson_ratio", nu,
        range_text(kMinPoissonRatio, kMaxPoissonRatio) + " (kappa / mu within 2e-4 ... 3e4)");
  }
  const double w = material.mooney_rivlin_w;
  if (!(w >= 0.0 && w <= 1.0)) violations.add_value("mooney_rivlin_w", w, "lie in [0, 1]");
  return violations;
}

Status validate(const Material& material, std::string_view field_prefix) {
  return check(material).status(field_prefix);
}

}  // namespace cellflow::elastic
