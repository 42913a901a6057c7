// Parser for Java .properties text (JPK headers): "key=value" or "key: value"
// lines, '#' and '!' comments, backslash escapes (\:, \=, \t, \uXXXX) and line
// continuations. Duplicate keys: the last one wins, as in java.util.Properties.
#pragma once

#include <map>
#include <string>
#include <string_view>

namespace cellflow::afm {

using Properties = std::map<std::string, std::string, std::less<>>;

Properties parse_java_properties(std::string_view text);

}  // namespace cellflow::afm
