// Where the CLI writes `result` and `plot` output: "-" (or no -o where that
// means stdout) is standard output, any other name is a file whose extension
// must be the format written.
#pragma once

#include <string>
#include <vector>

namespace cellflow::client {

// True for "-": the output goes to standard output.
bool is_stdout_name(const std::string& name);

// "" when `name` may hold `format` output ("-" always may; a file's extension
// must be one of `extensions`, compared case-insensitively, each with its
// dot), else the message: "-o x.png: the extension .png is not SVG output;
// use .svg (or - for stdout)".
std::string check_output_name(const std::string& name, const std::string& format,
                              const std::vector<std::string>& extensions);

// Writes `bytes` to stdout ("" or "-") or to the file `name`; false if the
// file could not be written.
bool write_output(const std::string& name, const std::string& bytes);

}  // namespace cellflow::client
