// CHECK macros for internal invariants: a failed check is a bug in gissar,
// not bad input, so it prints the condition and location to stderr and
// aborts. User-facing failures throw the exceptions of error.h instead.
#pragma once

#include <sstream>
#include <string>

namespace gissar::internal {

[[noreturn]] void CheckFailed(const char* condition, const char* file, int line,
                              const std::string& message);

}  // namespace gissar::internal

#define GISSAR_CHECK(condition)                                              \
  do {                                                                       \
    if (!(condition)) {                                                      \
      ::gissar::internal::CheckFailed(#condition, __FILE__, __LINE__, "");   \
    }                                                                        \
  } while (false)

// GISSAR_CHECK_MSG(x > 0, "x=" << x): the message is a stream expression.
#define GISSAR_CHECK_MSG(condition, stream_message)                          \
  do {                                                                       \
    if (!(condition)) {                                                      \
      std::ostringstream gissar_check_stream_;                               \
      gissar_check_stream_ << stream_message;                                \
      ::gissar::internal::CheckFailed(#condition, __FILE__, __LINE__,        \
                                      gissar_check_stream_.str());           \
    }                                                                        \
  } while (false)
