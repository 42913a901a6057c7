#include "physics/core/passive_threads.h"

#include <unistd.h>

#include <cstdlib>

namespace cellflow {

void ensure_passive_openmp_wait(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  if (::setenv("OMP_WAIT_POLICY", "passive", 1) != 0) return;
  // execv only returns on failure; then the program goes on as it was
  // (spinning threads, but working).
  ::execv("/proc/self/exe", argv);
}

}  // namespace cellflow
