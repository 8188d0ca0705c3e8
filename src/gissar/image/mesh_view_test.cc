#include "gissar/image/mesh_view.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gissar/util/error.h"

namespace gissar::image {
namespace {

std::array<int, 3> Pixel(const RgbImage& image, int x, int y) {
  const uint8_t* p = &image.rgb[(size_t(y) * image.width + x) * 3];
  return {p[0], p[1], p[2]};
}

// Seen straight from above (elevation 90), north up, flat ground facing the
// sun at 45 degrees elevation: shade 0.35 + 0.65 sin 45.
TEST(MeshViewTest, FlatGroundFromAboveHasItsShadedClassColour) {
  scene::TriangleMesh mesh;
  mesh.AddQuad({-100, -100, 0}, {100, -100, 0}, {100, 100, 0}, {-100, 100, 0}, scene::kClassWater);
  MeshViewOptions o;
  o.view_elevation_deg = 90.0;
  o.width = 200;
  o.height = 100;
  const RgbImage image = RenderMeshView(mesh, ClassColourList(), o);
  ASSERT_EQ(image.width, 200);
  ASSERT_EQ(image.height, 100);
  const double shade = 0.35 + 0.65 * std::sqrt(0.5);
  const auto water = ClassColours()[scene::kClassWater];
  const auto centre = Pixel(image, 100, 50);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(centre[c], water[c] * shade, 1.0) << c;
  // The square fills 95 % of the height (95 px) in the middle of the
  // 200 px wide picture: sky at the left and right edges.
  const auto sky = Pixel(image, 2, 50);
  EXPECT_GT(sky[2], 235);
  EXPECT_GT(sky[0], 195);
}

TEST(MeshViewTest, NearerSurfaceHidesTheFartherOne) {
  // A small forest plateau 20 m above water; from above, its centre is forest
  // whatever the triangle order.
  for (bool plateau_first : {false, true}) {
    scene::TriangleMesh mesh;
    auto add_plateau = [&] { mesh.AddQuad({-20, -20, 20}, {20, -20, 20}, {20, 20, 20}, {-20, 20, 20}, scene::kClassForest); };
    if (plateau_first) add_plateau();
    mesh.AddQuad({-100, -100, 0}, {100, -100, 0}, {100, 100, 0}, {-100, 100, 0}, scene::kClassWater);
    if (!plateau_first) add_plateau();
    MeshViewOptions o;
    o.view_elevation_deg = 90.0;
    o.vertical_exaggeration = 1.0;
    const RgbImage image = RenderMeshView(mesh, ClassColourList(), o);
    const auto centre = Pixel(image, o.width / 2, o.height / 2);
    const auto forest = ClassColours()[scene::kClassForest];
    const double shade = 0.35 + 0.65 * std::sqrt(0.5);
    EXPECT_NEAR(centre[1], forest[1] * shade, 1.0) << plateau_first;
    EXPECT_NEAR(centre[2], forest[2] * shade, 1.0) << plateau_first;
  }
}

TEST(MeshViewTest, ObliqueViewPutsTheNearSideLow) {
  // Looking from the south (azimuth 180) at 30 degrees: the southern (near)
  // half of the ground is in the lower half of the picture.
  scene::TriangleMesh mesh;
  mesh.AddQuad({-100, -100, 0}, {100, -100, 0}, {100, 0, 0}, {-100, 0, 0}, scene::kClassWater);
  mesh.AddQuad({-100, 0, 0}, {100, 0, 0}, {100, 100, 0}, {-100, 100, 0}, scene::kClassForest);
  MeshViewOptions o;
  o.view_azimuth_deg = 180.0;
  o.view_elevation_deg = 30.0;
  const RgbImage image = RenderMeshView(mesh, ClassColourList(), o);
  const auto below = Pixel(image, o.width / 2, o.height / 2 + 40);
  const auto above = Pixel(image, o.width / 2, o.height / 2 - 40);
  EXPECT_GT(below[2], below[1]);  // water: blue
  EXPECT_GT(above[1], above[2]);  // forest: green
}

TEST(MeshViewTest, RejectsBadOptions) {
  scene::TriangleMesh mesh;
  mesh.AddQuad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, scene::kClassDefault);
  MeshViewOptions o;
  o.view_elevation_deg = 0.0;
  EXPECT_THROW(RenderMeshView(mesh, ClassColourList(), o), ConfigError);
  o = MeshViewOptions();
  o.width = 3;
  EXPECT_THROW(RenderMeshView(mesh, ClassColourList(), o), ConfigError);
}

}  // namespace
}  // namespace gissar::image
