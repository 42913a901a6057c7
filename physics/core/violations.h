// How a validate function reports what is wrong with its input: a list of
// violations, each a field path relative to the struct checked
// ("material.poisson_ratio") with what is wrong and the allowed range. The
// caller that knows where the struct sits in the job spec adds that path
// ("compression.cell.") when it turns the list into a Status. And the one
// number formatter for messages.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "physics/core/status.h"

namespace cellflow {

// A number as a message shows it. significant_digits = 0: the shortest text
// that reads back as the same double (a refused field quotes exactly what was
// sent: 0.5, 1e-300, 3000); > 0: printf's %.Ng, for derived quantities whose
// last digits carry no meaning (a Mach number, a stiffness ratio).
std::string number_text(double value, int significant_digits = 0);

struct Violation {
  std::string field;    // relative path, e.g. "material.poisson_ratio"; empty: the struct itself
  std::string problem;  // e.g. "= 0.5 must lie in (-1, 0.5)"
};

class Violations {
 public:
  // `problem` follows the field name after a space.
  void add(std::string_view field, std::string_view problem);
  // "<field> = <value> must <allowed>", e.g. allowed = "lie in (-1, 0.5)".
  void add_value(std::string_view field, double value, std::string_view allowed);
  // The violations of a nested struct, their fields under `prefix` ("cell.").
  void add_all(const Violations& nested, std::string_view prefix);
  // A violation that comes as a whole message already (from a function that
  // reports a Status), kept as it is. Each "{}" in it stands for the path of
  // the struct checked and is replaced by it (a message that names two
  // fields: "set only one of {}shear_rate_per_s and {}capillary_number").
  void add_message(std::string_view message);

  bool empty() const { return list_.empty(); }
  const std::vector<Violation>& list() const { return list_; }

  // OK when empty; else INVALID_ARGUMENT with every violation, each field
  // under `prefix`, joined by "; ".
  Status status(std::string_view prefix) const;

 private:
  std::vector<Violation> list_;
};

}  // namespace cellflow
