// How a request field is spelt at each door (docs/conventions.md): the
// field's snake_case name with its unit suffix is the Python keyword, the
// options-file key and the sidecar key; the CLI flag is derived from it.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "gissar/util/error.h"

namespace gissar::pipeline {

// The flag of a request field: kebab case of the snake_case name without
// its unit suffix (heading_deg -> --heading, slant_range_m -> --slant-range);
// the exceptions are out_prefix (--out), center_lonlat (--center) and
// look_side (--look).
std::string FlagOfField(const std::string& field);

// Reads `value` into the request field `field` (ApplyJson of every request);
// ConfigError naming `key` and `source` when the JSON type does not fit.
template <class T>
void AssignField(T& field, const nlohmann::json& value, const std::string& key, const std::string& source) {
  try {
    field = value.get<T>();
  } catch (const nlohmann::json::exception&) {
    throw ConfigError("key '" + key + "' has a value of the wrong type: " + value.dump(), source);
  }
}

}  // namespace gissar::pipeline
