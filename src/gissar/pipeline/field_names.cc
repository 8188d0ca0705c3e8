#include "gissar/pipeline/field_names.h"

namespace gissar::pipeline {

std::string FlagOfField(const std::string& field) {
  // Flags whose name is not the field's (docs/conventions.md).
  if (field == "out_prefix") return "--out";
  if (field == "center_lonlat") return "--center";
  if (field == "look_side") return "--look";
  if (field == "success_heading_deg") return "--success-heading-deg";
  std::string name = field;
  for (const char* unit : {"_deg", "_m", "_db", "_bytes", "_px", "_s"}) {
    const std::string suffix = unit;
    if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
      name.resize(name.size() - suffix.size());
      break;
    }
  }
  for (char& c : name) {
    if (c == '_') c = '-';
  }
  return "--" + name;
}

}  // namespace gissar::pipeline
