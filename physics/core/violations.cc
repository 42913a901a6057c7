#include "physics/core/violations.h"

#include <charconv>
#include <cstdio>

namespace cellflow {
namespace {

// `text` with every "{}" replaced by "{}" + `path` (keep: an outer struct's
// path still goes in front) or by `path` (final).
std::string with_path(std::string_view text, std::string_view path, bool keep_placeholder) {
  std::string out;
  std::size_t start = 0;
  for (std::size_t at = text.find("{}"); at != std::string_view::npos; at = text.find("{}", start)) {
    out += text.substr(start, at - start);
    if (keep_placeholder) out += "{}";
    out += path;
    start = at + 2;
  }
  out += text.substr(start);
  return out;
}

}  // namespace

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
    // A whole message (no field) names its fields through its placeholders.
    if (v.field.empty()) {
      list_.push_back({"", with_path(v.problem, prefix, true)});
    } else {
      list_.push_back({std::string(prefix) + v.field, v.problem});
    }
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
      message += with_path(v.problem, prefix, false);
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
