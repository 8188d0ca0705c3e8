#include "gissar/material/material.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gissar/util/error.h"

namespace gissar::material {
namespace {

TEST(MaterialTest, DefaultIsUnitLambertian) {
  const MaterialTable table;
  EXPECT_EQ(table.Get(0).diffuse, 1.0);
  EXPECT_EQ(table.Get(7).name, "default");
  EXPECT_NEAR(table.Get(0).Backscatter(0.5), 0.5, 1e-15);
}

TEST(MaterialTest, SpecularHighlightIsAConeAroundNormalIncidence) {
  const Material m{"m", 0.0, 1.0, 0.5, 0.0};
  EXPECT_NEAR(m.Backscatter(1.0), 1.0, 1e-12);  // facing the radar
  const double c = std::cos(20.0 * M_PI / 180);
  EXPECT_NEAR(m.Backscatter(c), std::pow(std::cos(40.0 * M_PI / 180), 2.0), 1e-12);
  EXPECT_EQ(m.Backscatter(std::cos(50.0 * M_PI / 180)), 0.0);  // beyond 45 deg
  EXPECT_EQ(m.Backscatter(-0.3), 0.0);
  // Rougher: wider cone.
  const Material rough{"r", 0.0, 1.0, 1.0, 0.0};
  EXPECT_GT(rough.Backscatter(c), m.Backscatter(c));
}

TEST(MaterialTest, SetGrowsTheTable) {
  MaterialTable table;
  table.Set(3, Material{"water", 0.05});
  EXPECT_EQ(table.size(), 4u);
  EXPECT_EQ(table.Get(3).diffuse, 0.05);
  EXPECT_EQ(table.Get(2).name, "default");
}

TEST(MaterialTest, RejectsOutOfRangeCoefficients) {
  MaterialTable table;
  EXPECT_THROW(table.Set(1, Material{"bad", -0.1}), ConfigError);
  EXPECT_THROW(table.Set(1, Material{"bad", 1.5}), ConfigError);
  EXPECT_THROW(table.Set(1, Material{"bad", 0.5, 0.5, 0.0}), ConfigError);
}

TEST(MaterialTest, SceneDefaultsFollowTheThesis) {
  const MaterialTable t = SceneMaterials(nullptr, "test");
  EXPECT_LT(t.Get(scene::kClassWater).diffuse, 0.1);
  EXPECT_GT(t.Get(scene::kClassWater).mirror, 0.5);
  EXPECT_GT(t.Get(scene::kClassForest).diffuse, t.Get(scene::kClassDefault).diffuse);
  EXPECT_GT(t.Get(scene::kClassRoad).specular, t.Get(scene::kClassRoad).diffuse);
  EXPECT_GT(t.Get(scene::kClassBuilding).mirror, 0.5);
}

TEST(MaterialTest, OverridesAreValidatedNamingKeyAndSource) {
  const MaterialTable t = SceneMaterials(nlohmann::json::parse(R"({"water": {"diffuse": 0.01}})"), "s.json");
  EXPECT_EQ(t.Get(scene::kClassWater).diffuse, 0.01);
  EXPECT_EQ(t.Get(scene::kClassWater).mirror, DefaultMaterial(scene::kClassWater).mirror);
  auto expect_error = [](const char* text, const std::string& needle) {
    try {
      SceneMaterials(nlohmann::json::parse(text), "s.json");
      FAIL() << text;
    } catch (const ConfigError& e) {
      EXPECT_NE(e.message().find(needle), std::string::npos) << e.what();
      EXPECT_EQ(e.where(), "s.json");
    }
  };
  expect_error(R"({"lava": {}})", "materials.lava");
  expect_error(R"({"water": {"shininess": 3}})", "materials.water.shininess");
  expect_error(R"({"water": {"diffuse": "dark"}})", "must be a number");
  expect_error(R"({"road": {"diffuse": -0.2}})", "diffuse must be in [0, 1]");
}

}  // namespace
}  // namespace gissar::material
