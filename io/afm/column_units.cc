#include "io/afm/column_units.h"

#include <array>
#include <utility>

#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

struct UnitEntry {
  std::string_view name;
  Dimension dimension;
  double to_si;
};

constexpr std::array<UnitEntry, 19> kUnits{{
    {"m", Dimension::kLength, 1.0},          {"mm", Dimension::kLength, 1e-3},
    {"um", Dimension::kLength, 1e-6},        {"\xC2\xB5m", Dimension::kLength, 1e-6},  // µm (micro sign)
    {"\xCE\xBCm", Dimension::kLength, 1e-6},                                           // μm (Greek mu)
    {"micron", Dimension::kLength, 1e-6},    {"nm", Dimension::kLength, 1e-9},
    {"pm", Dimension::kLength, 1e-12},       {"N", Dimension::kForce, 1.0},
    {"mN", Dimension::kForce, 1e-3},         {"uN", Dimension::kForce, 1e-6},
    {"\xC2\xB5N", Dimension::kForce, 1e-6},  {"nN", Dimension::kForce, 1e-9},
    {"pN", Dimension::kForce, 1e-12},        {"s", Dimension::kTime, 1.0},
    {"ms", Dimension::kTime, 1e-3},          {"us", Dimension::kTime, 1e-6},
    {"\xC2\xB5s", Dimension::kTime, 1e-6},   {"ns", Dimension::kTime, 1e-9},
}};

const UnitEntry* lookup(std::string_view unit) {
  for (const UnitEntry& e : kUnits) {
    if (e.name == unit) return &e;
  }
  // snake_case headers are usually all lower case: "force_nn", "force_n".
  const std::string lower = to_lower(unit);
  for (const UnitEntry& e : kUnits) {
    if (to_lower(e.name) == lower) return &e;
  }
  return nullptr;
}

}  // namespace

StatusOr<UnitSpec> parse_unit(std::string_view unit) {
  unit = trim(unit);
  const UnitEntry* e = lookup(unit);
  if (e == nullptr) return invalid_argument("unknown unit '" + std::string(unit) + "'");
  return UnitSpec{e->dimension, e->to_si};
}

HeaderName split_header_name(std::string_view header) {
  header = trim(header);
  HeaderName out;
  for (auto [open, close] : {std::pair{'(', ')'}, std::pair{'[', ']'}}) {
    const std::size_t a = header.rfind(open);
    if (a != std::string_view::npos && !header.empty() && header.back() == close) {
      out.quantity = to_lower(trim(header.substr(0, a)));
      out.unit = std::string(trim(header.substr(a + 1, header.size() - a - 2)));
      return out;
    }
  }
  const std::size_t u = header.rfind('_');
  if (u != std::string_view::npos && u + 1 < header.size() && lookup(header.substr(u + 1)) != nullptr) {
    out.quantity = to_lower(trim(header.substr(0, u)));
    out.unit = std::string(header.substr(u + 1));
    return out;
  }
  out.quantity = to_lower(header);
  return out;
}

}  // namespace cellflow::afm
