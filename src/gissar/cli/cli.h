// The gissar command line: parses, calls the library, reports. Errors of
// the gissar::Error family and bad command lines print exactly one line
// "gissar: error: <what> (<where>)" on `err` and return exit status 2.
#pragma once

#include <ostream>

namespace gissar::cli {

// Returns the process exit status: 0 success (including --help and
// --version), 2 bad input/config/I-O or bad command line.
int RunCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err);

}  // namespace gissar::cli
