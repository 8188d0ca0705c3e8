// How a request field is spelt at each door (docs/conventions.md): the
// field's snake_case name with its unit suffix is the Python keyword, the
// options-file key and the sidecar key; the CLI flag is derived from it.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/util/error.h"

namespace gissar::pipeline {

// The flag of a request field: kebab case of the snake_case name without
// its unit suffix (heading_deg -> --heading, slant_range_m -> --slant-range);
// the exceptions are out_prefix (--out), center_lonlat (--center) and
// look_side (--look).
std::string FlagOfField(const std::string& field);

// Levenshtein distance between `a` and `b` (insertions, deletions,
// substitutions): the measure of every "did you mean" (keys here, flags and
// commands in cli/command_line.cc).
size_t EditDistance(const std::string& a, const std::string& b);

// The known key closest to a mistyped `key`, "" when none is close. A key
// is close when, compared lower-case with '-' read as '_' and leading
// dashes dropped, it is a known key (Heading_Deg, range-spacing-m), the
// flag name of one (heading, range_spacing, center: the CLI spelling,
// FlagOfField), or at most 2 edits (Levenshtein) away from either and fewer
// edits than it has characters; the fewest edits wins, ties the first of
// `known`.
std::string ClosestKey(const std::string& key, const std::vector<std::string>& known);

// "unknown key 'KEY'" with "; did you mean K?" when ClosestKey finds one: the
// message of every request's ApplyJson (Python keywords, options files,
// sidecars) for a key it does not know.
std::string UnknownKeyMessage(const std::string& key, const std::vector<std::string>& known);

// The keys of a JSON object (a request's ToJson(): its fields), in order.
std::vector<std::string> KeysOf(const nlohmann::json& object);

// Parses "A,B" into two finite numbers; throws ConfigError naming `option`
// ("expected two numbers 'A,B', got 'TEXT'").
Eigen::Vector2d ParseNumberPair(const std::string& text, const std::string& option);

// "3,5,7" -> {3, 5, 7}: a comma-separated list of integers given to `flag`;
// throws ConfigError naming `flag` ("needs <expected>, got 'TEXT'", e.g.
// expected = "two integers R,A") for an item that is not an integer, an
// empty list, or when `count` > 0 items were expected and another number
// was given.
std::vector<int> ParseIntegerList(const std::string& text, const std::string& flag, const std::string& expected,
                                  size_t count = 0);

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
