#include "nmbake/common.hpp"

#include <cstdio>
#include <cstdlib>

namespace nmbake {

void check_failed(const char* expression, const char* file, int line, const char* message) {
  std::fprintf(stderr, "nmbake: internal check failed at %s:%d: %s (%s)\n", file, line, message, expression);
  std::fflush(stderr);
  std::abort();
}

}  // namespace nmbake
