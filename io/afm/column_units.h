// Column headers of text exports: "force_n", "force (nN)", "height [um]",
// "Extend Z-Sense(nm)". Splits a header into a quantity name and a unit and
// gives the factor to SI. An unknown unit is an error, never a guess: a
// silently wrong factor of 1000 would pass every later check.
#pragma once

#include <string>
#include <string_view>

#include "physics/core/status.h"

namespace cellflow::afm {

enum class Dimension { kLength, kForce, kTime, kNone };

struct UnitSpec {
  Dimension dimension = Dimension::kNone;
  double to_si = 1.0;  // value_si = value * to_si
};

// "nm" -> length 1e-9; "nN" -> force 1e-9; "s" -> time 1. Case matters
// ("mN" vs "MN" would differ); "um", "µm" and "micron" are all micrometres.
StatusOr<UnitSpec> parse_unit(std::string_view unit);

struct HeaderName {
  std::string quantity;  // lower case, trimmed, e.g. "force", "extend z-sense"
  std::string unit;      // as written, e.g. "nN"; empty when none is given
};

// Splits "force (nN)", "force [nN]" and "force_nN" (last underscore field, if it
// parses as a unit) into quantity and unit.
HeaderName split_header_name(std::string_view header);

}  // namespace cellflow::afm
