#include "gissar/pipeline/field_names.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

namespace gissar::pipeline {

std::vector<int> ParseIntegerList(const std::string& text, const std::string& flag, const std::string& expected,
                                  size_t count) {
  std::vector<int> values;
  std::istringstream in(text);
  std::string item;
  bool ok = true;
  while (ok && std::getline(in, item, ',')) {
    try {
      size_t used = 0;
      const int k = std::stoi(item, &used);
      ok = used == item.size();
      values.push_back(k);
    } catch (const std::exception&) {
      ok = false;
    }
  }
  if (!ok || values.empty() || (count > 0 && values.size() != count)) {
    throw ConfigError("needs " + expected + ", got '" + text + "'", flag);
  }
  return values;
}

Eigen::Vector2d ParseNumberPair(const std::string& text, const std::string& option) {
  std::istringstream in(text);
  double a = 0, b = 0;
  char comma = 0;
  std::string rest;
  if (!(in >> a >> comma >> b) || comma != ',' || (in >> rest) || !std::isfinite(a) ||
      !std::isfinite(b)) {
    throw ConfigError("expected two numbers 'A,B', got '" + text + "'", option);
  }
  return {a, b};
}

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

namespace {

// Lower case, leading dashes dropped, '-' read as '_' ("--Range-Spacing" ->
// "range_spacing").
std::string Normalised(const std::string& key) {
  std::string out = key.substr(std::min(key.find_first_not_of('-'), key.size()));
  for (char& c : out) {
    c = c == '-' ? '_' : static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}

}  // namespace

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

std::string ClosestKey(const std::string& key, const std::vector<std::string>& known) {
  const std::string word = Normalised(key);
  if (word.empty()) return "";
  for (const std::string& k : known) {
    if (word == Normalised(k) || word == Normalised(FlagOfField(k))) return k;
  }
  std::string best;
  size_t best_distance = std::min<size_t>(3, word.size());  // at most 2 edits, fewer than its characters
  for (const std::string& k : known) {
    const size_t d = std::min(EditDistance(word, Normalised(k)), EditDistance(word, Normalised(FlagOfField(k))));
    if (d < best_distance) best_distance = d, best = k;
  }
  return best;
}

std::string UnknownKeyMessage(const std::string& key, const std::vector<std::string>& known) {
  const std::string closest = ClosestKey(key, known);
  return "unknown key '" + key + "'" + (closest.empty() ? "" : "; did you mean " + closest + "?");
}

std::vector<std::string> KeysOf(const nlohmann::json& object) {
  std::vector<std::string> keys;
  for (const auto& [key, value] : object.items()) keys.push_back(key);
  return keys;
}

}  // namespace gissar::pipeline
