#include "gissar/util/number_text.h"

#include <cmath>
#include <stdexcept>

namespace gissar::util {

std::optional<double> ParseFiniteNumber(const std::string& text) {
  size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  } catch (const std::out_of_range&) {
    return std::nullopt;
  }
  if (used == 0 || used != text.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

}  // namespace gissar::util
