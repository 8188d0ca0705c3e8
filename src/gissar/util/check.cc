#include "gissar/util/check.h"

#include <cstdio>
#include <cstdlib>

namespace gissar::internal {

void CheckFailed(const char* condition, const char* file, int line,
                 const std::string& message) {
  std::fprintf(stderr, "gissar: internal error: check failed: %s at %s:%d%s%s\n", condition,
               file, line, message.empty() ? "" : ": ", message.c_str());
  std::fflush(stderr);
  std::abort();
}

}  // namespace gissar::internal
