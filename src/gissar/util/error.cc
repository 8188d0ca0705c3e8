#include "gissar/util/error.h"

namespace gissar {
namespace {

std::string Format(const std::string& what, const std::string& where) {
  return where.empty() ? what : what + " (" + where + ")";
}

}  // namespace

Error::Error(const std::string& what, const std::string& where)
    : std::runtime_error(Format(what, where)), message_(what), where_(where) {}

}  // namespace gissar
