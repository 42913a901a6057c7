#include "physics/elastic/material.h"

#include <charconv>
#include <cmath>
#include <string>

namespace cellflow::elastic {

namespace {

// Shortest decimal that reads back as the same double ("0.5", "1.2", "nan").
std::string format_number(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

void add_violation(std::string& message, std::string_view prefix, std::string_view field, double value,
                   std::string_view allowed) {
  if (!message.empty()) message += "; ";
  message += prefix;
  message += field;
  message += " = ";
  message += format_number(value);
  message += " must ";
  message += allowed;
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

Status validate(const Material& material, std::string_view field_prefix) {
  std::string message;
  // Written so that NaN fails every check: comparisons with NaN are false.
  const double e = material.youngs_modulus_pa;
  if (!(e > 0.0 && std::isfinite(e))) {
    add_violation(message, field_prefix, "youngs_modulus_pa", e, "be > 0 and finite");
  }
  const double nu = material.poisson_ratio;
  if (!(nu > -1.0 && nu < 0.5)) {
    add_violation(message, field_prefix, "poisson_ratio", nu, "lie in (-1, 0.5)");
  }
  const double w = material.mooney_rivlin_w;
  if (!(w >= 0.0 && w <= 1.0)) {
    add_violation(message, field_prefix, "mooney_rivlin_w", w, "lie in [0, 1]");
  }
  if (message.empty()) return Status::ok_status();
  return invalid_argument(std::move(message));
}

}  // namespace cellflow::elastic
