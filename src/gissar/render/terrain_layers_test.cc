#include "gissar/render/terrain_layers.h"

#include <gtest/gtest.h>

#include <cmath>

namespace gissar::render {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A plane tilted by `tilt_deg` towards the radar (heading 0, right look: the
// radar is to the west; z = x tan(tilt) faces it), 10 m posts, seen at
// depression 40 deg (incidence 50) with 5 m pixels. By hand: local
// incidence 50 - tilt, and a slant-range cell of 5 m cuts 5 / sin(50 - tilt)
// metres of the surface in the plane of incidence, times 5 m along track.
void ExpectPlane(double tilt_deg) {
  const int n = 81;
  const double cell = 10.0, slope = std::tan(tilt_deg * kDeg);
  std::vector<Eigen::Vector3f> posts;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const double x = -400.0 + c * cell, y = -400.0 + r * cell;
      posts.emplace_back(float(x), float(y), float(x * slope));
    }
  }
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, n, n);
  sensor::SarGeometryOptions o;
  o.heading_deg = 0.0;
  o.depression_deg = 40.0;
  o.range_spacing_m = o.azimuth_spacing_m = 5.0;
  const auto g = sensor::SarGeometry::Covering(o, Eigen::Vector3d::Zero(), mesh.vertices);
  const TerrainLayers layers = ComputeTerrainLayers(mesh, g);
  ASSERT_EQ(layers.projected_area_m2.size(), size_t(g.width()) * g.height());
  const double theta_l = 50.0 - tilt_deg;
  const double want_area = 25.0 / std::sin(theta_l * kDeg);
  // Interior pixels: the image of the central 300 x 300 m.
  int checked = 0;
  for (double x = -150; x <= 150; x += 7.3) {
    for (double y = -150; y <= 150; y += 7.3) {
      const Eigen::Vector2d q = g.Project(Eigen::Vector3d(x, y, x * slope));
      const size_t at = size_t(std::lround(q.y())) * g.width() + size_t(std::lround(q.x()));
      EXPECT_NEAR(layers.projected_area_m2[at], want_area, 1e-4 * want_area) << tilt_deg << " " << x << " " << y;
      EXPECT_NEAR(layers.local_incidence_deg[at], theta_l, 1e-3) << tilt_deg;
      ++checked;
    }
  }
  EXPECT_GT(checked, 1500);
  // Every square metre of the plane lands in some pixel (it is all lit and
  // inside the image): the total is the plane's area.
  double total = 0.0;
  for (float a : layers.projected_area_m2) total += a;
  const double plane = 800.0 * 800.0 / std::cos(tilt_deg * kDeg);
  EXPECT_NEAR(total, plane, 1e-5 * plane);
}

TEST(TerrainLayersTest, FlatGround) { ExpectPlane(0.0); }
TEST(TerrainLayersTest, PlaneFacingTheRadar) { ExpectPlane(15.0); }
TEST(TerrainLayersTest, PlaneTurnedAway) { ExpectPlane(-15.0); }

// A slope turned away steeper than the incidence (here 60 deg > 50) faces
// away: no area, no incidence (NaN), while the pixels exist.
TEST(TerrainLayersTest, BackSlopeHasNoArea) {
  const int n = 21;
  std::vector<Eigen::Vector3f> posts;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) posts.emplace_back(float(c * 10.0), float(r * 10.0), float(-c * 10.0 * std::tan(60 * kDeg)));
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, n, n);
  sensor::SarGeometryOptions o;
  o.heading_deg = 0.0;
  o.depression_deg = 40.0;
  o.range_spacing_m = o.azimuth_spacing_m = 5.0;
  const auto g = sensor::SarGeometry::Covering(o, Eigen::Vector3d(100, 100, -100 * std::tan(60 * kDeg)), mesh.vertices);
  const TerrainLayers layers = ComputeTerrainLayers(mesh, g);
  for (size_t i = 0; i < layers.projected_area_m2.size(); ++i) {
    EXPECT_EQ(layers.projected_area_m2[i], 0.0f);
    EXPECT_TRUE(std::isnan(layers.local_incidence_deg[i]));
  }
}

}  // namespace
}  // namespace gissar::render
