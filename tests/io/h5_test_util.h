// Test support for HDF5 results and their XDMF sidecars, shared by the io
// tests and the service tests: run a tool, read a file, check that every
// dataset an XDMF file names exists in the HDF5 file.
#pragma once

#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

namespace cellflow::testing {

// Runs a command, returns its output (stdout and stderr) and exit code.
inline std::string run_command(const std::string& command, int* exit_code) {
  std::string output;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    *exit_code = -1;
    return output;
  }
  char buffer[4096];
  std::size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) output.append(buffer, n);
  const int status = ::pclose(pipe);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return output;
}

// The whole file as text.
inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

#ifdef CELLFLOW_XMLLINT
// The text of an XML file that xmllint must accept (a failure otherwise).
inline std::string read_valid_xml(const std::filesystem::path& path) {
  int code = 0;
  const std::string lint = run_command(std::string(CELLFLOW_XMLLINT) + " --noout " + path.string(), &code);
  EXPECT_EQ(code, 0) << lint;
  return read_text(path);
}
#endif

// The number of matches of `item` in `xml`, whose first group is a dataset
// path that must exist in the HDF5 file `h5_path` (a failure per missing one).
inline int count_existing_items(const std::filesystem::path& h5_path, const std::string& xml,
                                const std::regex& item) {
  hid_t file = H5Fopen(h5_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  EXPECT_GE(file, 0) << h5_path;
  if (file < 0) return -1;
  int items = 0;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), item); it != std::sregex_iterator(); ++it) {
    const std::string dataset = (*it)[1];
    ++items;
    EXPECT_GT(H5Oexists_by_name(file, dataset.c_str(), H5P_DEFAULT), 0) << dataset;
  }
  H5Fclose(file);
  return items;
}

}  // namespace cellflow::testing
