// Small text helpers shared by the text-format readers: line splitting that
// accepts LF, CRLF and CR endings, locale-independent number parsing (strtod
// would follow the C locale's decimal point), trimming and field splitting.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cellflow::afm {

std::vector<std::string_view> split_lines(std::string_view text);
std::vector<std::string_view> split_fields(std::string_view line, char delimiter);
std::string_view trim(std::string_view s);
std::string to_lower(std::string_view s);
bool starts_with_ci(std::string_view s, std::string_view prefix);

// The whole field as a number, or nullopt. decimal_comma accepts "1,25"
// (NT-MDT exports in a German locale).
std::optional<double> parse_number(std::string_view field, bool decimal_comma = false);

}  // namespace cellflow::afm
