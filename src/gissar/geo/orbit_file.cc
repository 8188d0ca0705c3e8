#include "gissar/geo/orbit_file.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include <cpl_minixml.h>
#include <nlohmann/json.hpp>

#include "gissar/geo/look_side.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/number_text.h"
#include "gissar/util/utc_time.h"

namespace gissar::geo {
namespace fs = std::filesystem;

namespace {

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

std::string ReadText(const fs::path& path) {
  std::error_code error;
  if (!fs::is_regular_file(path, error)) throw InputError("no such file", path.string());
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open", path.string());
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

double Number(const std::string& text, const std::string& where) {
  size_t end = text.size();  // trailing white space allowed
  while (end > 0 && std::isspace(static_cast<unsigned char>(text[end - 1]))) --end;
  const std::optional<double> value = util::ParseFiniteNumber(text.substr(0, end));
  if (!value) throw InputError("'" + text + "' is not a finite number", where);
  return *value;
}

std::string Trim(const std::string& text) {
  size_t first = 0, last = text.size();
  while (first < last && std::isspace(static_cast<unsigned char>(text[first]))) ++first;
  while (last > first && std::isspace(static_cast<unsigned char>(text[last - 1]))) --last;
  return text.substr(first, last - first);
}

void AddVector(StateVectors& v, double utc_s, const Eigen::Vector3d& position, const Eigen::Vector3d& velocity) {
  v.utc_s.push_back(utc_s);
  v.position_m.push_back(position);
  v.velocity_mps.push_back(velocity);
}

StateVectors ReadCsv(const std::string& text, const std::string& file) {
  static const std::vector<std::string> kColumns = {"time_utc", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps"};
  StateVectors v;
  v.format = "csv";
  std::istringstream lines(text);
  std::string line;
  std::map<std::string, int> column_of;
  int row = 0;
  while (std::getline(lines, line)) {
    ++row;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream fields(trimmed);
    std::string cell;
    while (std::getline(fields, cell, ',')) cells.push_back(Trim(cell));
    const std::string where = file + " row " + std::to_string(row);
    if (column_of.empty()) {
      for (size_t i = 0; i < cells.size(); ++i) {
        if (std::find(kColumns.begin(), kColumns.end(), cells[i]) == kColumns.end()) {
          throw InputError("unknown column '" + cells[i] + "' (expected time_utc,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps)",
                           where);
        }
        if (!column_of.emplace(cells[i], int(i)).second) throw InputError("column '" + cells[i] + "' twice", where);
      }
      for (const auto& name : kColumns) {
        if (!column_of.count(name)) throw InputError("missing column '" + name + "'", where);
      }
      continue;
    }
    if (cells.size() != column_of.size()) {
      throw InputError(std::to_string(cells.size()) + " fields, expected " + std::to_string(column_of.size()), where);
    }
    auto get = [&](const char* name) { return Number(cells[column_of.at(name)], where + " " + name); };
    AddVector(v, ParseUtcSeconds(cells[column_of.at("time_utc")], where + " time_utc"),
              {get("x_m"), get("y_m"), get("z_m")}, {get("vx_mps"), get("vy_mps"), get("vz_mps")});
  }
  if (column_of.empty()) throw InputError("no header (time_utc,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps)", file);
  return v;
}

Eigen::Vector3d Triple(const nlohmann::json& value, const std::string& where) {
  if (!value.is_array() || value.size() != 3) throw InputError("must be an array of 3 numbers", where);
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i) {
    if (!value[i].is_number() || !std::isfinite(value[i].get<double>())) {
      throw InputError("must be an array of 3 finite numbers", where);
    }
    out[i] = value[i].get<double>();
  }
  return out;
}

StateVectors ReadJson(const std::string& text, const std::string& file) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("not valid JSON: ") + e.what(), file);
  }
  if (!doc.is_object()) throw InputError("must be a JSON object with \"state_vectors\"", file);
  for (const auto& [key, value] : doc.items()) {
    if (key != "state_vectors") throw InputError("unknown key '" + key + "'", file);
  }
  if (!doc.contains("state_vectors") || !doc["state_vectors"].is_array()) {
    throw InputError("\"state_vectors\" must be an array", file);
  }
  StateVectors v;
  v.format = "json";
  for (size_t i = 0; i < doc["state_vectors"].size(); ++i) {
    const nlohmann::json& item = doc["state_vectors"][i];
    const std::string where = file + " state_vectors[" + std::to_string(i) + "]";
    if (!item.is_object()) throw InputError("must be an object", where);
    for (const auto& [key, value] : item.items()) {
      if (key != "time_utc" && key != "position_m" && key != "velocity_mps") {
        throw InputError("unknown key '" + key + "'", where);
      }
    }
    if (!item.contains("time_utc") || !item["time_utc"].is_string()) {
      throw InputError("\"time_utc\" must be a UTC timestamp string", where);
    }
    if (!item.contains("position_m") || !item.contains("velocity_mps")) {
      throw InputError("needs \"position_m\" and \"velocity_mps\"", where);
    }
    AddVector(v, ParseUtcSeconds(item["time_utc"].get<std::string>(), where + ".time_utc"),
              Triple(item["position_m"], where + ".position_m"), Triple(item["velocity_mps"], where + ".velocity_mps"));
  }
  return v;
}

struct XmlDeleter {
  void operator()(CPLXMLNode* node) const { CPLDestroyXMLNode(node); }
};

StateVectors ReadEof(const std::string& text, const std::string& file) {
  std::unique_ptr<CPLXMLNode, XmlDeleter> root(CPLParseXMLString(text.c_str()));
  if (!root) throw InputError("not valid XML", file);
  CPLStripXMLNamespace(root.get(), nullptr, TRUE);
  const CPLXMLNode* list = CPLGetXMLNode(root.get(), "=Earth_Explorer_File.Data_Block.List_of_OSVs");
  if (list == nullptr) throw InputError("no Earth_Explorer_File/Data_Block/List_of_OSVs", file);
  StateVectors v;
  v.format = "eof";
  int index = 0;
  for (const CPLXMLNode* osv = list->psChild; osv != nullptr; osv = osv->psNext) {
    if (osv->eType != CXT_Element || std::string(osv->pszValue) != "OSV") continue;
    const std::string where = file + " OSV " + std::to_string(++index);
    auto value = [&](const char* name) {
      const char* found = CPLGetXMLValue(osv, name, nullptr);
      if (found == nullptr) throw InputError(std::string("no <") + name + ">", where);
      return std::string(found);
    };
    auto number = [&](const char* name) { return Number(Trim(value(name)), where + " " + name); };
    AddVector(v, ParseUtcSeconds(value("UTC"), where + " UTC"), {number("X"), number("Y"), number("Z")},
              {number("VX"), number("VY"), number("VZ")});
  }
  return v;
}

void CheckSampling(const StateVectors& v, const std::string& file) {
  if (static_cast<int>(v.utc_s.size()) < kMinStateVectors) {
    throw InputError(std::to_string(v.utc_s.size()) + " state vectors, at least " +
                         std::to_string(kMinStateVectors) + " needed",
                     file);
  }
  std::vector<double> spacing;
  for (size_t i = 1; i < v.utc_s.size(); ++i) {
    if (!(v.utc_s[i] > v.utc_s[i - 1])) {
      throw InputError("state vector times are not strictly increasing (vector " + std::to_string(i + 1) + " at " +
                           FormatUtc(v.utc_s[i]) + " after " + FormatUtc(v.utc_s[i - 1]) + ")",
                       file);
    }
    spacing.push_back(v.utc_s[i] - v.utc_s[i - 1]);
  }
  std::vector<double> sorted = spacing;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (size_t i = 0; i < spacing.size(); ++i) {
    if (spacing[i] > kMaxStateVectorGapRatio * median) {
      char text[160];
      std::snprintf(text, sizeof text, "gap of %.3f s between state vectors %zu and %zu (median spacing %.3f s)",
                    spacing[i], i + 1, i + 2, median);
      throw InputError(text, file);
    }
  }
}

}  // namespace

StateVectors ReadStateVectors(const fs::path& path) {
  const std::string file = path.string();
  const std::string text = ReadText(path);
  const std::string extension = Lower(path.extension().string());
  const std::string head = Trim(text.substr(0, std::min<size_t>(text.size(), 64)));
  StateVectors v;
  if (extension == ".eof" || extension == ".xml" || (extension != ".csv" && extension != ".json" && !head.empty() &&
                                                    head[0] == '<')) {
    v = ReadEof(text, file);
  } else if (extension == ".json" || (extension != ".csv" && !head.empty() && head[0] == '{')) {
    v = ReadJson(text, file);
  } else {
    v = ReadCsv(text, file);
  }
  CheckSampling(v, file);
  return v;
}

RadarGridSpec ReadRadarGrid(const fs::path& path) {
  const std::string file = path.string();
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(ReadText(path));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string("not valid JSON: ") + e.what(), file);
  }
  if (!doc.is_object()) throw InputError("a radar grid must be a JSON object", file);
  static const std::set<std::string> kKeys = {"starting_range_m",        "range_spacing_m", "sensing_start_utc",
                                              "azimuth_time_interval_s", "width",           "length",
                                              "look_side",               "wavelength_m"};
  for (const auto& [key, value] : doc.items()) {
    if (!kKeys.count(key)) throw InputError("unknown key '" + key + "'", file);
  }
  for (const auto& key : kKeys) {
    if (!doc.contains(key)) throw InputError("missing key '" + key + "'", file);
  }
  auto positive = [&](const char* key) {
    const nlohmann::json& value = doc[key];
    if (!value.is_number() || !(value.get<double>() > 0.0) || !std::isfinite(value.get<double>())) {
      throw InputError(std::string("'") + key + "' must be a positive number", file);
    }
    return value.get<double>();
  };
  auto count = [&](const char* key) {
    const nlohmann::json& value = doc[key];
    if (!value.is_number_integer() || value.get<int64_t>() < 1 || value.get<int64_t>() > (int64_t{1} << 20)) {
      throw InputError(std::string("'") + key + "' must be an integer in [1, 1048576]", file);
    }
    return static_cast<int>(value.get<int64_t>());
  };
  RadarGridSpec grid;
  grid.starting_range_m = positive("starting_range_m");
  grid.range_spacing_m = positive("range_spacing_m");
  grid.azimuth_time_interval_s = positive("azimuth_time_interval_s");
  grid.wavelength_m = positive("wavelength_m");
  grid.width = count("width");
  grid.length = count("length");
  if (!doc["sensing_start_utc"].is_string()) throw InputError("'sensing_start_utc' must be a string", file);
  grid.sensing_start_utc = doc["sensing_start_utc"].get<std::string>();
  ParseUtcSeconds(grid.sensing_start_utc, file + " sensing_start_utc");
  const nlohmann::json& look = doc["look_side"];
  const std::optional<LookSide> side = look.is_string() ? kLookSides.Find(look.get<std::string>()) : std::nullopt;
  if (!side) {
    // Only a scalar is quoted: dumping a hostile file's deeply nested array
    // recurses once per level and overflows the stack.
    throw InputError("'look_side' must be " + kLookSides.Alternatives() + ", got " +
                         (look.is_primitive() ? look.dump() : std::string("a JSON ") + look.type_name()),
                     file);
  }
  grid.look_left = *side == LookSide::kLeft;
  return grid;
}

RslcProduct ProductFromOrbit(const StateVectors& vectors, const std::string& orbit_source, const RadarGridSpec& grid,
                             const std::string& grid_source) {
  const double start_utc_s = ParseUtcSeconds(grid.sensing_start_utc, grid_source + " sensing_start_utc");
  const double epoch_utc_s = std::floor(start_utc_s / 86400.0) * 86400.0;
  RslcProduct p;
  p.path = grid_source;
  p.mission = "";
  p.product_version = "";
  p.epoch_utc = FormatUtc(epoch_utc_s).substr(0, 19);
  p.epoch_utc[10] = ' ';
  p.frequency = "";
  p.polarization = "";
  p.zero_doppler_time_s.resize(grid.length);
  for (int i = 0; i < grid.length; ++i) {
    p.zero_doppler_time_s[i] = (start_utc_s - epoch_utc_s) + i * grid.azimuth_time_interval_s;
  }
  p.slant_range_m.resize(grid.width);
  for (int j = 0; j < grid.width; ++j) p.slant_range_m[j] = grid.starting_range_m + j * grid.range_spacing_m;
  p.wavelength_m = grid.wavelength_m;
  p.center_frequency_hz = kSpeedOfLightMps / grid.wavelength_m;
  p.look_left = grid.look_left;
  p.orbit.type = "state vectors (" + vectors.format + ")";
  for (size_t i = 0; i < vectors.utc_s.size(); ++i) p.orbit.time_s.push_back(vectors.utc_s[i] - epoch_utc_s);
  p.orbit.position_m = vectors.position_m;
  p.orbit.velocity_mps = vectors.velocity_mps;
  const double first = start_utc_s;
  const double last = start_utc_s + (grid.length - 1) * grid.azimuth_time_interval_s;
  if (first < vectors.utc_s.front() || last > vectors.utc_s.back()) {
    throw InputError("the orbit (" + FormatUtc(vectors.utc_s.front()) + " to " + FormatUtc(vectors.utc_s.back()) +
                         ") does not cover the image's lines (" + FormatUtc(first) + " to " + FormatUtc(last) +
                         " from " + grid_source + ")",
                     orbit_source);
  }
  return p;
}

void WriteStateVectorsCsv(const fs::path& path, const StateVectors& vectors) {
  AtomicOutputs outputs;
  const fs::path temporary = outputs.Add(path);
  {
    std::ofstream out(temporary);
    if (!out) throw IoError("cannot write", path.string());
    out << "time_utc,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n";
    char line[256];
    for (size_t i = 0; i < vectors.utc_s.size(); ++i) {
      const Eigen::Vector3d& p = vectors.position_m[i];
      const Eigen::Vector3d& v = vectors.velocity_mps[i];
      std::snprintf(line, sizeof line, "%s,%.6f,%.6f,%.6f,%.9f,%.9f,%.9f\n", FormatUtc(vectors.utc_s[i]).c_str(),
                    p.x(), p.y(), p.z(), v.x(), v.y(), v.z());
      out << line;
    }
    out.close();  // a full disk shows when the buffer is flushed
    if (!out) throw WriteError("write failed", temporary, errno);
  }
  outputs.Commit();
}

}  // namespace gissar::geo
