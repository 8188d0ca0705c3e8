#include "gissar/render/ortho_renderer.h"

#include <gtest/gtest.h>

#include <cmath>

namespace gissar::render {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

void AddFacingQuad(scene::TriangleMesh& mesh, Vector3f a, Vector3f b, Vector3f c, Vector3f d,
                   const Vector3f& facing, scene::ClassId cls) {
  if ((b - a).cross(c - a).dot(facing) < 0) std::swap(b, d);
  mesh.AddQuad(a, b, c, d, cls);
}

// The G_perp view of a box: the roof's pixels span exactly the affine SAR
// projection of the roof corners (within 0.5 px), for several headings.
TEST(OrthoRendererTest, SlantRangeNormalViewMatchesAffineSarGeometry) {
  const float x0 = -20, x1 = 25, y0 = -15, y1 = 30, H = 18;
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-200, -200, 0}, {200, -200, 0}, {200, 200, 0}, {-200, 200, 0}, Vector3f::UnitZ(), 0);
  AddFacingQuad(mesh, {x0, y0, H}, {x1, y0, H}, {x1, y1, H}, {x0, y1, H}, Vector3f::UnitZ(), 5);
  AddFacingQuad(mesh, {x0, y0, 0}, {x0, y1, 0}, {x0, y1, H}, {x0, y0, H}, -Vector3f::UnitX(), 5);
  AddFacingQuad(mesh, {x1, y0, 0}, {x1, y1, 0}, {x1, y1, H}, {x1, y0, H}, Vector3f::UnitX(), 5);
  AddFacingQuad(mesh, {x0, y0, 0}, {x1, y0, 0}, {x1, y0, H}, {x0, y0, H}, -Vector3f::UnitY(), 5);
  AddFacingQuad(mesh, {x0, y1, 0}, {x1, y1, 0}, {x1, y1, H}, {x0, y1, H}, Vector3f::UnitY(), 5);
  const size_t roof_first = 2, roof_last = 3;  // triangles of the roof quad
  const EmbreeScene embree(mesh);
  for (double heading : {0.0, 90.0}) {
    sensor::SarGeometryOptions o;
    o.heading_deg = heading;
    o.depression_deg = 35.0;
    o.range_spacing_m = 0.5;
    o.azimuth_spacing_m = 0.5;
    const auto g = sensor::SarGeometry::Covering(o, Vector3d::Zero(), mesh.vertices);
    const OrthoImage view = RenderOrtho(embree, mesh, g, OrthoView::kSlantRangeNormal,
                                        [](const Vector3d&, int32_t) { return std::array<uint8_t, 3>{200, 50, 40}; });
    ASSERT_EQ(view.width, g.width());
    int cmin = 1 << 30, cmax = -1, rmin = 1 << 30, rmax = -1;
    for (int r = 0; r < view.height; ++r)
      for (int c = 0; c < view.width; ++c) {
        const int32_t t = view.triangle[size_t(r) * view.width + c];
        if (t < int32_t(roof_first) || t > int32_t(roof_last)) continue;
        cmin = std::min(cmin, c);
        cmax = std::max(cmax, c);
        rmin = std::min(rmin, r);
        rmax = std::max(rmax, r);
      }
    double pcmin = 1e9, pcmax = -1e9, prmin = 1e9, prmax = -1e9;
    for (float x : {x0, x1})
      for (float y : {y0, y1}) {
        const Eigen::Vector2d p = g.Project(Vector3d(x, y, H));
        pcmin = std::min(pcmin, p.x());
        pcmax = std::max(pcmax, p.x());
        prmin = std::min(prmin, p.y());
        prmax = std::max(prmax, p.y());
      }
    // Pixel extents (centre +- 0.5) against the continuous projected corners.
    EXPECT_NEAR(cmin - 0.5, pcmin, 0.5) << heading;
    EXPECT_NEAR(cmax + 0.5, pcmax, 0.5) << heading;
    EXPECT_NEAR(rmin - 0.5, prmin, 0.5) << heading;
    EXPECT_NEAR(rmax + 0.5, prmax, 0.5) << heading;
  }
}

TEST(OrthoRendererTest, LineOfSightViewSeesTheFrontWall) {
  // Looking along l (east, heading 0), the west wall faces the camera.
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-100, -100, 0}, {100, -100, 0}, {100, 100, 0}, {-100, 100, 0}, Vector3f::UnitZ(), 0);
  AddFacingQuad(mesh, {0, -20, 0}, {0, 20, 0}, {0, 20, 30}, {0, -20, 30}, -Vector3f::UnitX(), 5);
  const EmbreeScene embree(mesh);
  sensor::SarGeometryOptions o;
  o.depression_deg = 30.0;
  o.range_spacing_m = 1.0;
  o.azimuth_spacing_m = 1.0;
  const auto g = sensor::SarGeometry::Covering(o, Vector3d::Zero(), mesh.vertices);
  const OrthoImage view = RenderOrtho(embree, mesh, g, OrthoView::kLineOfSight,
                                      [](const Vector3d&, int32_t t) {
                                        return t >= 2 ? std::array<uint8_t, 3>{255, 0, 0}
                                                      : std::array<uint8_t, 3>{0, 255, 0};
                                      });
  int wall = 0;
  for (int32_t t : view.triangle) wall += t >= 2;
  // The wall's 40 m x 30 m face seen at 30 deg depression: area 40 * 30 * cos(30) m^2.
  EXPECT_NEAR(wall, 40 * 30 * std::cos(M_PI / 6), 40.0);
}

}  // namespace
}  // namespace gissar::render
