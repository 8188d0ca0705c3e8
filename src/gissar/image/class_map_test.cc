#include "gissar/image/class_map.h"

#include <gtest/gtest.h>

namespace gissar::image {
namespace {

TEST(ClassMapTest, PaintsEachClassWithItsColour) {
  // West half water, east half forest, 100 m x 50 m.
  scene::TriangleMesh mesh;
  mesh.AddQuad({0, 0, 0}, {50, 0, 0}, {50, 50, 0}, {0, 50, 0}, scene::kClassWater);
  mesh.AddQuad({50, 0, 0}, {100, 0, 0}, {100, 50, 0}, {50, 50, 0}, scene::kClassForest);
  std::vector<std::string> names(scene::ClassNames().begin(), scene::ClassNames().end());
  const RgbImage image = RenderClassMap(mesh, names, 601);
  EXPECT_EQ(image.width, 601);
  EXPECT_EQ(image.height, 301);
  auto pixel = [&](int x, int y) {
    const uint8_t* p = &image.rgb[(size_t(y) * image.width + x) * 3];
    return std::array<int, 3>{p[0], p[1], p[2]};
  };
  // Flat ground: shade = 0.75 + 0.25 * sun.z.
  const float shade = 0.75f + 0.25f * (1.5f / std::sqrt(1 + 1 + 2.25f));
  // Below the legend (top-left, 150 x 142 px).
  const auto water = pixel(200, 250), forest = pixel(500, 250);
  EXPECT_NEAR(water[2], ClassColours()[scene::kClassWater][2] * shade, 1.0);
  EXPECT_NEAR(forest[1], ClassColours()[scene::kClassForest][1] * shade, 1.0);
  EXPECT_LT(forest[2], 60);
}

}  // namespace
}  // namespace gissar::image
