#include "io/afm/java_properties.h"

#include <cstdint>

#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

void append_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

// Resolves escapes in one logical line's key or value.
std::string unescape(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '\\' || i + 1 == s.size()) {
      out += s[i];
      continue;
    }
    const char c = s[++i];
    switch (c) {
      case 't':
        out += '\t';
        break;
      case 'n':
        out += '\n';
        break;
      case 'r':
        out += '\r';
        break;
      case 'f':
        out += '\f';
        break;
      case 'u': {
        std::uint32_t cp = 0;
        std::size_t j = 0;
        for (; j < 4 && i + 1 + j < s.size(); ++j) {
          const char h = s[i + 1 + j];
          int d = (h >= '0' && h <= '9')   ? h - '0'
                  : (h >= 'a' && h <= 'f') ? h - 'a' + 10
                  : (h >= 'A' && h <= 'F') ? h - 'A' + 10
                                           : -1;
          if (d < 0) break;
          cp = cp * 16 + static_cast<std::uint32_t>(d);
        }
        append_utf8(out, cp);
        i += j;
        break;
      }
      default:
        out += c;  // \: \= \\ \# and "\ " stand for themselves
    }
  }
  return out;
}

// True when the line ends in an odd number of backslashes (a continuation).
bool continues(std::string_view line) {
  std::size_t n = 0;
  while (n < line.size() && line[line.size() - 1 - n] == '\\') ++n;
  return n % 2 == 1;
}

}  // namespace

Properties parse_java_properties(std::string_view text) {
  Properties props;
  const auto lines = split_lines(text);
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::string_view first = trim(lines[i]);
    if (first.empty() || first.front() == '#' || first.front() == '!') continue;
    std::string logical(first);
    while (continues(logical) && i + 1 < lines.size()) {
      logical.pop_back();
      logical += trim(lines[++i]);
    }
    // The key ends at the first unescaped '=', ':' or whitespace.
    std::size_t k = 0;
    while (k < logical.size()) {
      const char c = logical[k];
      if (c == '\\') {
        k += 2;
        continue;
      }
      if (c == '=' || c == ':' || c == ' ' || c == '\t') break;
      ++k;
    }
    k = std::min(k, logical.size());
    std::size_t v = k;
    while (v < logical.size() && (logical[v] == ' ' || logical[v] == '\t')) ++v;
    if (v < logical.size() && (logical[v] == '=' || logical[v] == ':')) ++v;
    while (v < logical.size() && (logical[v] == ' ' || logical[v] == '\t')) ++v;
    props[unescape(std::string_view(logical).substr(0, k))] = unescape(std::string_view(logical).substr(v));
  }
  return props;
}

}  // namespace cellflow::afm
