#include "physics/elastic/material.h"

#include <cmath>
#include <string>

namespace cellflow::elastic {

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
  if (!(e > 0.0 && std::isfinite(e))) violations.add_value("youngs_modulus_pa", e, "be > 0 and finite");
  const double nu = material.poisson_ratio;
  if (!(nu > -1.0 && nu < 0.5)) violations.add_value("poisson_ratio", nu, "lie in (-1, 0.5)");
  const double w = material.mooney_rivlin_w;
  if (!(w >= 0.0 && w <= 1.0)) violations.add_value("mooney_rivlin_w", w, "lie in [0, 1]");
  return violations;
}

Status validate(const Material& material, std::string_view field_prefix) {
  return check(material).status(field_prefix);
}

}  // namespace cellflow::elastic
