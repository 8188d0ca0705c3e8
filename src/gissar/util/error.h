// The exception family for expected, user-facing failures: bad input data,
// bad options or configuration, and I/O failures. Each carries a message
// (what went wrong) and a context (where: a file, an option, a row). The CLI
// prints them as one line "gissar: error: <what> (<where>)" and exits 2.
// Internal invariants use the CHECK macros of check.h instead.
#pragma once

#include <stdexcept>
#include <string>

namespace gissar {

class Error : public std::runtime_error {
 public:
  // `what`: the problem in words; `where`: the file, option or item it
  // concerns (may be empty).
  Error(const std::string& what, const std::string& where);

  const std::string& message() const { return message_; }
  const std::string& where() const { return where_; }

 private:
  std::string message_;
  std::string where_;
};

// Bad input data: a file that is missing, unreadable as the expected format,
// or whose contents are invalid (no-data cells, NaN, wrong shape).
class InputError : public Error {
 public:
  using Error::Error;
};

// Bad options or configuration: values out of range, unknown keys,
// inconsistent combinations.
class ConfigError : public Error {
 public:
  using Error::Error;
};

// A read or write that failed at the operating-system or driver level.
class IoError : public Error {
 public:
  using Error::Error;
};

}  // namespace gissar
