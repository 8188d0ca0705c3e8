#include "gissar/scene/scene_config.h"

#include <gtest/gtest.h>

#include <fstream>

#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::scene {
namespace {

std::string WriteConfig(const std::string& text) {
  const auto path = testing::MakeTempDir() / "scene.json";
  std::ofstream(path) << text;
  return path.string();
}

void ExpectConfigError(const std::string& text, const std::string& needle) {
  const std::string path = WriteConfig(text);
  try {
    LoadSceneConfig(path);
    FAIL() << "expected ConfigError for " << text;
  } catch (const ConfigError& e) {
    EXPECT_NE(e.message().find(needle), std::string::npos) << e.what();
    EXPECT_EQ(e.where(), path);
  }
}

TEST(SceneConfigTest, ReadsLayersPrioritiesAndMaterials) {
  const std::string path = WriteConfig(R"({
    "layers": [
      {"path": "osm.gpkg", "layer": "water", "class": "water"},
      {"path": "/abs/roads.shp", "class": "road", "geometry": "line", "width_m": 7},
      {"path": "b.geojson", "class": "building", "where": "height > 3"}
    ],
    "priorities": {"forest": 9},
    "line_widths_m": {"primary": 14},
    "building": {"default_height_m": 8, "level_height_m": 3.2},
    "densify_m": 25,
    "materials": {"water": {"diffuse": 0.01}}
  })");
  const SceneConfig c = LoadSceneConfig(path);
  ASSERT_EQ(c.layers.size(), 3u);
  EXPECT_EQ(c.layers[0].source.path, (std::filesystem::path(path).parent_path() / "osm.gpkg").string());
  EXPECT_EQ(c.layers[0].class_id, kClassWater);
  EXPECT_EQ(c.layers[1].kind, LayerKind::kLine);
  EXPECT_EQ(c.layers[1].line_width_m, 7.0);
  EXPECT_EQ(c.layers[1].source.path, "/abs/roads.shp");
  EXPECT_EQ(c.layers[2].kind, LayerKind::kBuilding);
  EXPECT_EQ(c.layers[2].source.where, "height > 3");
  EXPECT_EQ(c.priority[kClassForest], 9);
  EXPECT_EQ(c.line_widths_m.at("primary"), 14.0);
  EXPECT_EQ(c.line_widths_m.at("motorway"), 25.0);  // defaults kept
  EXPECT_EQ(c.building_level_height_m, 3.2);
  EXPECT_EQ(c.densify_m, 25.0);
  EXPECT_EQ(c.materials["water"]["diffuse"], 0.01);
}

TEST(SceneConfigTest, UnknownKeysAndBadValuesNameKeyAndFile) {
  ExpectConfigError(R"({"layer": []})", "unknown key 'layer'");
  ExpectConfigError(R"({"layers": [{"path": "a", "class": "water", "colour": 1}]})",
                    "unknown key 'layers[0].colour'");
  ExpectConfigError(R"({"layers": [{"path": "a", "class": "lava"}]})", "unknown class 'lava'");
  ExpectConfigError(R"({"layers": [{"path": "a", "class": "road", "width_m": -2}]})",
                    "'layers[0].width_m' must not be negative");
  ExpectConfigError(R"({"layers": [{"path": 3, "class": "road"}]})", "'layers[0].path' must be a string");
  ExpectConfigError(R"({"building": {"default_height_m": -1}})", "must not be negative");
  ExpectConfigError(R"({"priorities": {"water": 1000}})", "integer in [0, 100]");
  ExpectConfigError(R"({"materials": {"sand": {}}})", "unknown key 'materials.sand'");
}

TEST(SceneConfigTest, NotJsonIsAnInputError) {
  EXPECT_THROW(LoadSceneConfig(WriteConfig("layers = []")), InputError);
  EXPECT_THROW(LoadSceneConfig("/nonexistent/scene.json"), InputError);
}

TEST(SceneConfigTest, LayerNamePresetMapsTheBundledGeoPackage) {
  std::vector<std::string> warnings;
  const SceneConfig c =
      LayerNamePreset({testing::DataPath("andorra/andorra_osm.gpkg").string()}, &warnings);
  ASSERT_EQ(c.layers.size(), 5u);
  int lines = 0;
  for (const auto& l : c.layers) lines += l.kind == LayerKind::kLine;
  EXPECT_EQ(lines, 2);  // roads, waterways
  EXPECT_TRUE(warnings.empty());
}

}  // namespace
}  // namespace gissar::scene
