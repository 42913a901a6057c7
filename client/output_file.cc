#include "client/output_file.h"

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace cellflow::client {

bool is_stdout_name(const std::string& name) {
  return name == "-";
}

std::string check_output_name(const std::string& name, const std::string& format,
                              const std::vector<std::string>& extensions) {
  if (name.empty() || is_stdout_name(name)) return "";
  std::string extension = std::filesystem::path(name).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const std::string& allowed : extensions) {
    if (extension == allowed) return "";
  }
  std::string supported;
  for (std::size_t i = 0; i < extensions.size(); ++i)
    supported += (i == 0 ? "" : i + 1 == extensions.size() ? " or " : ", ") + extensions[i];
  return "-o " + name + ": " +
         (extension.empty() ? std::string("no extension")
                            : "the extension " + extension + " is not " + format + " output") +
         "; use " + supported + " (or - for stdout)";
}

bool write_output(const std::string& name, const std::string& bytes) {
  if (name.empty() || is_stdout_name(name)) {
    return std::fwrite(bytes.data(), 1, bytes.size(), stdout) == bytes.size() && std::fflush(stdout) == 0;
  }
  std::ofstream out(name, std::ios::binary | std::ios::trunc);
  out << bytes;
  return static_cast<bool>(out);
}

}  // namespace cellflow::client
