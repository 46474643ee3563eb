#include "cli/process_env.hpp"

#include <unistd.h>

#include <cstdlib>

namespace tetfsi::app {

void cap_openmp_threads(char** argv) {
  if (std::getenv("OMP_THREAD_LIMIT") != nullptr)
    return;  // the user's choice, or already re-executed
  if (std::getenv("OPENBLAS_NUM_THREADS") == nullptr) setenv("OPENBLAS_NUM_THREADS", "1", 1);
  if (setenv("OMP_THREAD_LIMIT", "1", 1) != 0) return;
  execv("/proc/self/exe", argv);  // returns only on failure: carry on as we are
}

}  // namespace tetfsi::app
