// `cellflow submit --spec ARG`: ARG is a file name, "-" (the spec on stdin)
// or, when it starts with "{" (after blanks), the JSON text itself.
#pragma once

#include <istream>
#include <string>

namespace cellflow::client {

struct SpecText {
  std::string text;    // the JSON
  std::string source;  // for messages: the file name, "stdin" or "inline spec"
  std::string error;   // "" when read
};

// The spec text `arg` names; `in` is read for "-".
SpecText read_spec_arg(const std::string& arg, std::istream& in);

}  // namespace cellflow::client
