// What a GIS scene is built from: vector layers mapped to radar classes,
// road widths, building heights, and per-class material overrides. Read from
// a JSON file (schema in docs/scene.md) or from built-in presets for
// OpenStreetMap data and for layer names.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/geo/vector_io.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::scene {

// The radar classes (ClassId values). Their default materials and
// priorities are documented in docs/scene.md.
enum : ClassId {
  kClassDefault = 0,
  kClassWater = 1,
  kClassForest = 2,
  kClassUrban = 3,
  kClassRoad = 4,
  kClassBuilding = 5,
  kClassSea = 6,  // the sea (coastline polygons or the --sea auto fallback), not inland water
};
inline constexpr int kClassCount = 7;

// "default", "water", "forest", "urban", "road", "building", "sea" (index = ClassId).
const std::array<std::string, kClassCount>& ClassNames();
// ClassId of a class name; nullopt when unknown.
std::optional<ClassId> ClassIdFromName(const std::string& name);

enum class LayerKind {
  kPolygon,   // areas of a class
  kLine,      // lines buffered into strips (roads, rivers)
  kBuilding,  // footprints extruded to a height
  // OSM `natural=coastline` ways (land on the left of the way's direction):
  // closed against the DEM extent into sea polygons. Closed coastline
  // polygons (islands) are land.
  kCoastline,
};

struct LayerSpec {
  geo::VectorLayerRequest source;
  ClassId class_id = kClassDefault;
  LayerKind kind = LayerKind::kPolygon;
  // Strip width for lines; 0 = per feature: a `width` tag, else the road
  // table by `highway` (roads) or `waterway` value, else the class default.
  double line_width_m = 0.0;
};

struct SceneConfig {
  std::string source;  // config file (or preset name) for messages
  std::vector<LayerSpec> layers;
  // Higher wins where classes overlap.
  std::array<int, kClassCount> priority = {0, 4, 2, 3, 5, 6, 1};
  // Strip width (metres) per OSM `highway` / `waterway` value.
  std::map<std::string, double> line_widths_m;
  double default_road_width_m = 5.0;
  double default_waterway_width_m = 8.0;
  double building_default_height_m = 10.0;
  double building_level_height_m = 3.0;
  // Sea (--sea auto|off, --sea-level): with `sea_auto`, coastline layers
  // give the sea; without any coastline in the extent, DEM posts at or below
  // `sea_level_m` (orthometric, the DEM's heights) connected to the DEM
  // border are sea, and a no-data post becomes sea only next to sea posts.
  bool sea_auto = true;
  double sea_level_m = 0.0;
  // Split constraint edges longer than this (metres); 0 = never.
  double densify_m = 0.0;
  // {"water": {"diffuse": 0.05, ...}, ...}: validated by the material module.
  nlohmann::json materials = nlohmann::json::object();

  nlohmann::json ToJson() const;
};

// Default strip widths by OSM highway/waterway value (documented in docs/scene.md).
std::map<std::string, double> DefaultLineWidths();

// Reads a JSON scene config. Relative layer paths are relative to the
// config's directory. Throws ConfigError naming the key and the file for an
// unknown key, a wrong type, an unknown class, a negative width/height or
// priority out of [0, 100]; InputError when the file is missing or not JSON.
SceneConfig LoadSceneConfig(const std::string& path);

// Built-in preset for an OpenStreetMap file (.osm.pbf, .osm, .osm.gz) read
// through GDAL's OSM driver: water, forest, urban and building polygons,
// roads (highway=*) and rivers/canals as strips, natural=coastline ways
// (sea).
SceneConfig OsmPreset(const std::string& osm_path);

// Preset for vector files whose layer names say their class: water, forest,
// urban, road(s), waterway(s), building(s), sea (polygons), coastline(s)
// (lines, land on the left) (case-insensitive); other layers
// are skipped with a warning appended to `warnings`. Throws InputError when
// a file has no usable layer.
SceneConfig LayerNamePreset(const std::vector<std::string>& paths,
                            std::vector<std::string>* warnings);

}  // namespace gissar::scene
