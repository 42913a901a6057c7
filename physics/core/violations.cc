#include "physics/core/violations.h"

#include <charconv>
#include <cstdio>

namespace cellflow {

std::string number_text(double value, int significant_digits) {
  char buffer[48];
  if (significant_digits > 0) {
    std::snprintf(buffer, sizeof buffer, "%.*g", significant_digits, value);
    return buffer;
  }
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

void Violations::add(std::string_view field, std::string_view problem) {
  list_.push_back({std::string(field), std::string(problem)});
}

void Violations::add_value(std::string_view field, double value, std::string_view allowed) {
  add(field, "= " + number_text(value) + " must " + std::string(allowed));
}

void Violations::add_all(const Violations& nested, std::string_view prefix) {
  for (const Violation& v : nested.list_) {
    // A whole message (no field) stays as it is: it names its own fields.
    list_.push_back({v.field.empty() ? v.field : std::string(prefix) + v.field, v.problem});
  }
}

void Violations::add_message(std::string_view message) {
  list_.push_back({"", std::string(message)});
}

Status Violations::status(std::string_view prefix) const {
  if (list_.empty()) return {};
  std::string message;
  for (const Violation& v : list_) {
    if (!message.empty()) message += "; ";
    if (v.field.empty()) {
      message += v.problem;
    } else {
      message += prefix;
      message += v.field;
      message += ' ';
      message += v.problem;
    }
  }
  return invalid_argument(message);
}

}  // namespace cellflow
