// Material of one region of the cell: the Mooney-Rivlin law of paper eq. 5
// with mu1 = w mu, mu2 = (1 - w) mu (paper eq. 8) and mu, kappa from E and nu
// (paper eq. 6).
#pragma once

#include <string_view>

#include "physics/core/status.h"
#include "physics/core/violations.h"

namespace cellflow::elastic {

struct Material {
  double youngs_modulus_pa = 0.0;  // E > 0
  double poisson_ratio = 0.48;     // nu in (-1, 0.5)
  double mooney_rivlin_w = 1.0;    // w in [0, 1]; 1 = neo-Hookean (paper eq. 7)
};

struct Moduli {
  double mu1_pa = 0.0;    // w mu
  double mu2_pa = 0.0;    // (1 - w) mu
  double kappa_pa = 0.0;  // bulk modulus
};

// mu = E / (2 (1 + nu)), kappa = E / (3 (1 - 2 nu))   (paper eq. 6)
Moduli moduli_from(const Material& material);

// Every field out of range, with field names relative to the material
// ("poisson_ratio") and the allowed range.
Violations check(const Material& material);

// check(material) as a Status; the message names `field_prefix` + field and the allowed
// range, e.g. "compression.cell.material.poisson_ratio = 0.5 must lie in (-1, 0.5)".
Status validate(const Material& material, std::string_view field_prefix);

}  // namespace cellflow::elastic
