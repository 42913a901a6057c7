// Bounded reading of a whole input file. Refuses anything that is not a
// regular file before opening it: a FIFO would block the reader forever, a
// device could stream without end, a directory is a user mistake.
#pragma once

#include <cstdint>
#include <string>

#include "physics/core/status.h"

namespace cellflow::afm {

// The file's bytes, or an error naming the path and the reason.
StatusOr<std::string> read_regular_file(const std::string& path, std::uint64_t max_bytes);

}  // namespace cellflow::afm
