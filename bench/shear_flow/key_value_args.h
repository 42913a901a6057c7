// The key=value command line of the single-run drivers in this folder
// (shear_flow_run, ibm_sphere_drag).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <string>

namespace cellflow::bench {

// The arguments by key; nullopt (after a message on stderr) when one is not key=value.
inline std::optional<std::map<std::string, std::string>> parse_key_value_args(int argc, char** argv) {
  std::map<std::string, std::string> args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto eq = a.find('=');
    if (eq == std::string::npos) {
      std::fprintf(stderr, "argument '%s' is not key=value\n", a.c_str());
      return std::nullopt;
    }
    args[a.substr(0, eq)] = a.substr(eq + 1);
  }
  return args;
}

// The number given for `key`, else `fallback`.
inline double number_arg(const std::map<std::string, std::string>& args, const char* key, double fallback) {
  const auto it = args.find(key);
  return it == args.end() ? fallback : std::atof(it->second.c_str());
}

}  // namespace cellflow::bench
