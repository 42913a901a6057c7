#include "client/spec_arg.h"

#include <fstream>
#include <sstream>

namespace cellflow::client {

SpecText read_spec_arg(const std::string& arg, std::istream& in) {
  SpecText spec;
  const auto first = arg.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && arg[first] == '{') {
    spec.text = arg;
    spec.source = "inline spec";
    return spec;
  }
  std::ostringstream text;
  if (arg == "-") {
    spec.source = "stdin";
    text << in.rdbuf();
    if (text.str().empty()) spec.error = "no spec on stdin (--spec - reads the JSON from standard input)";
  } else {
    spec.source = arg;
    std::ifstream file(arg);
    if (!file) {
      spec.error = "cannot read " + arg;
      return spec;
    }
    text << file.rdbuf();
  }
  spec.text = text.str();
  return spec;
}

}  // namespace cellflow::client
