// Numbers read from users' text (CSV fields, metadata items, orbit files)
// without the standard library's messages ("stod") reaching them.
#pragma once

#include <optional>
#include <string>

namespace gissar::util {

// The finite number that `text` holds whole (std::stod's syntax: leading
// white space allowed, nothing after the number), or nullopt for anything
// else: empty, trailing characters, out of double's range, inf or nan.
// Never throws.
std::optional<double> ParseFiniteNumber(const std::string& text);

}  // namespace gissar::util
