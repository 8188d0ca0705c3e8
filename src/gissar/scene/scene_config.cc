#include "gissar/scene/scene_config.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>

#include "gissar/util/error.h"

namespace gissar::scene {
namespace fs = std::filesystem;
using nlohmann::json;

const std::array<std::string, kClassCount>& ClassNames() {
  static const std::array<std::string, kClassCount> names = {"default", "water", "forest",
                                                             "urban",   "road",  "building", "sea"};
  return names;
}

std::optional<ClassId> ClassIdFromName(const std::string& name) {
  const auto& names = ClassNames();
  for (int i = 0; i < kClassCount; ++i) {
    if (names[i] == name) return static_cast<ClassId>(i);
  }
  return std::nullopt;
}

std::map<std::string, double> DefaultLineWidths() {
  return {{"motorway", 25.0},   {"motorway_link", 8.0}, {"trunk", 20.0},      {"trunk_link", 8.0},
          {"primary", 12.0},    {"primary_link", 7.0},  {"secondary", 10.0},  {"secondary_link", 6.0},
          {"tertiary", 8.0},    {"tertiary_link", 6.0}, {"unclassified", 6.0}, {"residential", 6.0},
          {"living_street", 5.0}, {"service", 4.0},     {"pedestrian", 5.0},  {"track", 3.0},
          {"footway", 2.0},     {"cycleway", 2.0},      {"path", 1.5},        {"steps", 2.0},
          {"river", 15.0},      {"canal", 10.0},        {"stream", 3.0},      {"drain", 2.0},
          {"ditch", 1.5}};
}

json SceneConfig::ToJson() const {
  json layers_json = json::array();
  for (const LayerSpec& l : layers) {
    layers_json.push_back({{"path", l.source.path},
                           {"layer", l.source.layer},
                           {"where", l.source.where},
                           {"class", ClassNames()[l.class_id]},
                           {"geometry", l.kind == LayerKind::kLine        ? "line"
                                        : l.kind == LayerKind::kBuilding  ? "building"
                                        : l.kind == LayerKind::kCoastline ? "coastline"
                                                                          : "polygon"},
                           {"width_m", l.line_width_m}});
  }
  json priorities = json::object();
  for (int i = 0; i < kClassCount; ++i) priorities[ClassNames()[i]] = priority[i];
  return {{"source", source},
          {"layers", layers_json},
          {"priorities", priorities},
          {"line_widths_m", line_widths_m},
          {"default_road_width_m", default_road_width_m},
          {"default_waterway_width_m", default_waterway_width_m},
          {"building", {{"default_height_m", building_default_height_m},
                        {"level_height_m", building_level_height_m}}},
          {"densify_m", densify_m},
          {"sea", sea_auto ? "auto" : "off"},
          {"sea_level_m", sea_level_m},
          {"materials", materials}};
}

namespace {

// Checks that `object` only has keys in `allowed`; names the first other.
void OnlyKeys(const json& object, const std::set<std::string>& allowed, const std::string& context,
              const std::string& file) {
  if (!object.is_object()) throw ConfigError(context + " must be an object", file);
  for (const auto& [key, value] : object.items()) {
    if (!allowed.count(key)) {
      throw ConfigError("unknown key '" + (context.empty() ? "" : context + ".") + key + "'", file);
    }
  }
}

double NonNegative(const json& value, const std::string& key, const std::string& file) {
  if (!value.is_number()) throw ConfigError("'" + key + "' must be a number", file);
  const double v = value.get<double>();
  if (!(v >= 0.0) || !std::isfinite(v)) throw ConfigError("'" + key + "' must not be negative", file);
  return v;
}

std::string Text(const json& value, const std::string& key, const std::string& file) {
  if (!value.is_string()) throw ConfigError("'" + key + "' must be a string", file);
  return value.get<std::string>();
}

ClassId ParseClass(const json& value, const std::string& key, const std::string& file) {
  const std::string name = Text(value, key, file);
  const auto id = ClassIdFromName(name);
  if (!id) {
    throw ConfigError("unknown class '" + name +
                          "' at '" + key + "' (classes: default, water, forest, urban, road, building, sea)",
                      file);
  }
  return *id;
}

LayerSpec Layer(ClassId cls, LayerKind kind, const std::string& path, const std::string& layer,
                const std::string& where) {
  LayerSpec spec;
  spec.source = geo::VectorLayerRequest{path, layer, where};
  spec.class_id = cls;
  spec.kind = kind;
  return spec;
}

}  // namespace

SceneConfig LoadSceneConfig(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("scene config does not exist or cannot be read", path);
  json root;
  try {
    in >> root;
  } catch (const json::exception& e) {
    throw InputError(std::string("scene config is not valid JSON: ") + e.what(), path);
  }
  SceneConfig config;
  config.source = path;
  config.line_widths_m = DefaultLineWidths();
  OnlyKeys(root, {"layers", "priorities", "line_widths_m", "default_road_width_m",
                  "default_waterway_width_m", "building", "densify_m", "materials"},
           "", path);
  const fs::path base = fs::path(path).parent_path();
  if (root.contains("layers")) {
    if (!root["layers"].is_array()) throw ConfigError("'layers' must be an array", path);
    int index = 0;
    for (const json& l : root["layers"]) {
      const std::string ctx = "layers[" + std::to_string(index++) + "]";
      OnlyKeys(l, {"path", "layer", "where", "class", "geometry", "width_m"}, ctx, path);
      if (!l.contains("path")) throw ConfigError("'" + ctx + ".path' is required", path);
      if (!l.contains("class")) throw ConfigError("'" + ctx + ".class' is required", path);
      LayerSpec spec;
      fs::path file = Text(l["path"], ctx + ".path", path);
      if (file.is_relative()) file = base / file;
      spec.source.path = file.string();
      if (l.contains("layer")) spec.source.layer = Text(l["layer"], ctx + ".layer", path);
      if (l.contains("where")) spec.source.where = Text(l["where"], ctx + ".where", path);
      spec.class_id = ParseClass(l["class"], ctx + ".class", path);
      const std::string geometry =
          l.contains("geometry") ? Text(l["geometry"], ctx + ".geometry", path) : "polygon";
      if (geometry == "polygon") {
        spec.kind = spec.class_id == kClassBuilding ? LayerKind::kBuilding : LayerKind::kPolygon;
      } else if (geometry == "line") {
        spec.kind = LayerKind::kLine;
      } else if (geometry == "building") {
        spec.kind = LayerKind::kBuilding;
      } else if (geometry == "coastline") {
        spec.kind = LayerKind::kCoastline;
        if (spec.class_id != kClassSea) {
          throw ConfigError("'" + ctx + ".geometry' coastline needs class sea", path);
        }
      } else {
        throw ConfigError("'" + ctx + ".geometry' must be polygon, line, building or coastline", path);
      }
      if (l.contains("width_m")) spec.line_width_m = NonNegative(l["width_m"], ctx + ".width_m", path);
      config.layers.push_back(spec);
    }
  }
  if (root.contains("priorities")) {
    OnlyKeys(root["priorities"], {"default", "water", "forest", "urban", "road", "building", "sea"},
             "priorities", path);
    for (const auto& [name, value] : root["priorities"].items()) {
      const double p = NonNegative(value, "priorities." + name, path);
      if (p > 100 || p != std::floor(p)) {
        throw ConfigError("'priorities." + name + "' must be an integer in [0, 100]", path);
      }
      config.priority[*ClassIdFromName(name)] = static_cast<int>(p);
    }
  }
  if (root.contains("line_widths_m")) {
    if (!root["line_widths_m"].is_object()) throw ConfigError("'line_widths_m' must be an object", path);
    for (const auto& [name, value] : root["line_widths_m"].items()) {
      config.line_widths_m[name] = NonNegative(value, "line_widths_m." + name, path);
    }
  }
  if (root.contains("default_road_width_m")) {
    config.default_road_width_m = NonNegative(root["default_road_width_m"], "default_road_width_m", path);
  }
  if (root.contains("default_waterway_width_m")) {
    config.default_waterway_width_m =
        NonNegative(root["default_waterway_width_m"], "default_waterway_width_m", path);
  }
  if (root.contains("building")) {
    const json& b = root["building"];
    OnlyKeys(b, {"default_height_m", "level_height_m"}, "building", path);
    if (b.contains("default_height_m")) {
      config.building_default_height_m = NonNegative(b["default_height_m"], "building.default_height_m", path);
    }
    if (b.contains("level_height_m")) {
      config.building_level_height_m = NonNegative(b["level_height_m"], "building.level_height_m", path);
    }
  }
  if (root.contains("densify_m")) config.densify_m = NonNegative(root["densify_m"], "densify_m", path);
  if (root.contains("materials")) {
    const json& m = root["materials"];
    OnlyKeys(m, {"default", "water", "forest", "urban", "road", "building", "sea"}, "materials", path);
    config.materials = m;
  }
  return config;
}

SceneConfig OsmPreset(const std::string& osm_path) {
  SceneConfig c;
  c.source = "built-in OpenStreetMap preset";
  c.line_widths_m = DefaultLineWidths();
  const std::string& p = osm_path;
  c.layers = {
      Layer(kClassWater, LayerKind::kPolygon, p, "multipolygons",
            "natural = 'water' OR landuse IN ('reservoir', 'basin')"),
      Layer(kClassForest, LayerKind::kPolygon, p, "multipolygons",
            "landuse = 'forest' OR natural = 'wood'"),
      Layer(kClassUrban, LayerKind::kPolygon, p, "multipolygons",
            "landuse IN ('residential', 'commercial', 'industrial', 'retail')"),
      Layer(kClassBuilding, LayerKind::kBuilding, p, "multipolygons", "building IS NOT NULL"),
      Layer(kClassRoad, LayerKind::kLine, p, "lines", "highway IS NOT NULL"),
      Layer(kClassWater, LayerKind::kLine, p, "lines", "waterway IN ('river', 'canal')"),
      // GDAL's default osmconf.ini keeps `natural` of lines in other_tags;
      // closed coastline ways (islands) are multipolygons.
      Layer(kClassSea, LayerKind::kCoastline, p, "lines",
            "other_tags LIKE '%\"natural\"=>\"coastline\"%'"),
      Layer(kClassSea, LayerKind::kCoastline, p, "multipolygons", "natural = 'coastline'"),
  };
  return c;
}

SceneConfig LayerNamePreset(const std::vector<std::string>& paths, std::vector<std::string>* warnings) {
  SceneConfig c;
  c.source = "layer-name preset";
  c.line_widths_m = DefaultLineWidths();
  for (const std::string& path : paths) {
    int used = 0;
    for (const std::string& name : geo::ListVectorLayers(path)) {
      std::string lower = name;
      std::transform(lower.begin(), lower.end(), lower.begin(), ::tolower);
      if (lower == "water") {
        c.layers.push_back(Layer(kClassWater, LayerKind::kPolygon, path, name, ""));
      } else if (lower == "forest" || lower == "wood" || lower == "woods") {
        c.layers.push_back(Layer(kClassForest, LayerKind::kPolygon, path, name, ""));
      } else if (lower == "urban") {
        c.layers.push_back(Layer(kClassUrban, LayerKind::kPolygon, path, name, ""));
      } else if (lower == "road" || lower == "roads") {
        c.layers.push_back(Layer(kClassRoad, LayerKind::kLine, path, name, ""));
      } else if (lower == "waterway" || lower == "waterways") {
        c.layers.push_back(Layer(kClassWater, LayerKind::kLine, path, name, ""));
      } else if (lower == "building" || lower == "buildings") {
        c.layers.push_back(Layer(kClassBuilding, LayerKind::kBuilding, path, name, ""));
      } else if (lower == "sea") {
        c.layers.push_back(Layer(kClassSea, LayerKind::kPolygon, path, name, ""));
      } else if (lower == "coastline" || lower == "coastlines") {
        c.layers.push_back(Layer(kClassSea, LayerKind::kCoastline, path, name, ""));
      } else {
        if (warnings) warnings->push_back("layer '" + name + "' of " + path + " has no class name: skipped");
        continue;
      }
      ++used;
    }
    if (used == 0) {
      throw InputError("no layer named after a class (water, forest, urban, roads, waterways, "
                       "buildings, sea, coastline); give a --config",
                       path);
    }
  }
  return c;
}

}  // namespace gissar::scene
