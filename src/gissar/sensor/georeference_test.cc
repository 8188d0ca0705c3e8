#include "gissar/sensor/georeference.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <vector>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/warp.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::sensor {
namespace {

namespace fs = std::filesystem;

// A flat WGS84 ground (ellipsoidal height 0) seen from 10 km at 40 degrees
// depression, 240 x 240 pixels of 5 m; a dark 80 m square centred at ENU
// (150, -100) on it. The image is made pixel by pixel by intersecting each
// pixel's locus with the ellipsoid (Newton on the geodetic height), which is
// independent of the georeferencing code under test.
struct FlatScene {
  geo::LocalFrame frame{1.5, 42.5, 0.0};
  SarGeometry geometry;
  static constexpr double kSquareX = 150.0, kSquareY = -100.0, kHalf = 40.0;

  explicit FlatScene(ProjectionMode mode) : geometry(Options(mode), Eigen::Vector3d::Zero(), 119.5, 119.5, 240, 240) {}

  static SarGeometryOptions Options(ProjectionMode mode) {
    SarGeometryOptions o;
    o.heading_deg = 30.0;
    o.depression_deg = 40.0;
    o.slant_range_m = 10000.0;
    o.range_spacing_m = 5.0;
    o.azimuth_spacing_m = 5.0;
    o.mode = mode;
    return o;
  }

  // ENU z of the ellipsoid at (x, y).
  double Surface(double x, double y) const {
    double z = 0.0;
    for (int i = 0; i < 4; ++i) z -= frame.GeodeticFromEnu(Eigen::Vector3d(x, y, z)).z();
    return z;
  }

  // Ground point of pixel (col, row): the point at the pixel's range and
  // azimuth on the ellipsoid, by Newton on the height along the locus.
  Eigen::Vector3d Ground(double col, double row) const {
    const double along = (row - 119.5) * 5.0;
    const double range = 10000.0 + (col - 119.5) * 5.0;
    const Eigen::Vector3d& l = geometry.look_direction();
    const Eigen::Vector3d h = geometry.flight_direction();
    Eigen::Vector3d n = geometry.range_plane_normal();
    if (n.z() < 0) n = -n;
    Eigen::Vector3d r_h(l.x(), l.y(), 0.0);
    r_h.normalize();
    const bool affine = geometry.mode() == ProjectionMode::kAffine;
    auto point = [&](double s) -> Eigen::Vector3d {
      if (affine) return (range - 10000.0) * l + along * h + s * n;
      return geometry.SensorPosition(along) +
             range * (std::cos(s) * r_h - std::sin(s) * Eigen::Vector3d::UnitZ());
    };
    double s = affine ? 0.0 : 40.0 * M_PI / 180.0;
    const double eps = affine ? 1e-3 : 1e-7;
    for (int i = 0; i < 30; ++i) {
      const double f = frame.GeodeticFromEnu(point(s)).z();
      const double df = (frame.GeodeticFromEnu(point(s + eps)).z() - f) / eps;
      s -= f / df;
    }
    return point(s);
  }

  geo::FloatRaster Image() const {
    geo::FloatRaster raster;
    raster.width = raster.height = 240;
    raster.bands.emplace_back(240 * 240);
    raster.band_names = {"total"};
    for (int r = 0; r < 240; ++r) {
      for (int c = 0; c < 240; ++c) {
        const Eigen::Vector3d g = Ground(c, r);
        const bool dark = std::abs(g.x() - kSquareX) < kHalf && std::abs(g.y() - kSquareY) < kHalf;
        raster.bands[0][r * 240 + c] = dark ? 0.0f : 1.0f;
      }
    }
    return raster;
  }
};

// Centroid (map x, y) of the dark pixels (0 <= v < 0.5) of a warped raster.
Eigen::Vector2d DarkCentroid(const fs::path& path, int* count) {
  const geo::FloatRaster map = geo::ReadFloatRaster(path);
  const std::vector<double> gt = geo::ReadGeoTransform(path);
  double sx = 0, sy = 0;
  int n = 0;
  for (int r = 0; r < map.height; ++r) {
    for (int c = 0; c < map.width; ++c) {
      const float v = map.bands[0][size_t(r) * map.width + c];
      if (v >= 0.0f && v < 0.5f) {
        sx += gt[0] + (c + 0.5) * gt[1] + (r + 0.5) * gt[2];
        sy += gt[3] + (c + 0.5) * gt[4] + (r + 0.5) * gt[5];
        ++n;
      }
    }
  }
  *count = n;
  return {sx / n, sy / n};
}

class FlatGroundWarp : public ::testing::TestWithParam<ProjectionMode> {};

TEST_P(FlatGroundWarp, FeatureLandsWithinOnePixelWithGcpsAndRpcs) {
  const FlatScene scene(GetParam());
  GeoreferenceReport report;
  geo::FloatRaster image = scene.Image();
  image.georeference = SlantRangeGeoreference(
      scene.geometry, scene.frame, [&](double x, double y) { return scene.Surface(x, y); }, -60.0, 1.0,
      12, &report);
  EXPECT_EQ(report.gcp_count, 144);
  // The affine model is affine in ENU: a cubic in lon/lat/h fits it to
  // rounding (measured 3e-10 px); exact mode's range is a square root,
  // still smooth (measured 0.027 px over a 1.2 km swath at 10 km).
  EXPECT_LT(report.rpc_max_error_px, GetParam() == ProjectionMode::kAffine ? 1e-6 : 0.05);
  const fs::path dir = testing::MakeTempDir();
  const fs::path slant = dir / "slant.tif";
  geo::WriteFloatGeoTiff(slant, image);

  // Truth: the square's centre on the ellipsoid, in UTM 31N.
  const Eigen::Vector3d centre = scene.frame.GeodeticFromEnu(
      Eigen::Vector3d(FlatScene::kSquareX, FlatScene::kSquareY, scene.Surface(FlatScene::kSquareX, FlatScene::kSquareY)));
  std::vector<double> x{centre.x()}, y{centre.y()};
  geo::CrsTransform utm("EPSG:32631");
  utm.FromLonLat(x, y);

  for (const char* method : {"-tps", "-rpc"}) {
    const fs::path map = dir / (std::string(method + 1) + ".tif");
    geo::Warp(slant, map, {method, "-t_srs", "EPSG:32631", "-tr", "5", "5", "-r", "bilinear",
                           "-dstnodata", "-1"});
    int count = 0;
    const Eigen::Vector2d got = DarkCentroid(map, &count);
    // 80 m square = 256 pixels of 5 m on the map.
    EXPECT_NEAR(count, 256, 40) << method;
    const double error_px = std::hypot(got.x() - x[0], got.y() - y[0]) / 5.0;
    EXPECT_LT(error_px, 1.0) << method;
    std::printf("[ measured ] %s %s: feature error %.3f px, RPC fit max %.2e px\n", method,
                ToString(GetParam()).c_str(), error_px, report.rpc_max_error_px);
  }
}

class SlantRangeGeoreferenceModes : public ::testing::TestWithParam<ProjectionMode> {};
INSTANTIATE_TEST_SUITE_P(Modes, SlantRangeGeoreferenceModes,
                         ::testing::Values(ProjectionMode::kAffine, ProjectionMode::kExact));

INSTANTIATE_TEST_SUITE_P(Modes, FlatGroundWarp,
                         ::testing::Values(ProjectionMode::kAffine, ProjectionMode::kExact));

TEST(SlantRangeGeoreference, GcpsProjectToTheirPixels) {
  const FlatScene scene(ProjectionMode::kAffine);
  const geo::Georeference g = SlantRangeGeoreference(
      scene.geometry, scene.frame, [&](double x, double y) { return scene.Surface(x, y); }, -60.0, 1.0);
  ASSERT_EQ(g.gcps.size(), 144u);
  // Corner node (0, 0): GDAL pixel (0.5, 0.5), on the ellipsoid.
  EXPECT_NEAR(g.gcps[0].pixel, 0.5, 1e-6);
  EXPECT_NEAR(g.gcps[0].line, 0.5, 1e-6);
  for (const auto& p : g.gcps) {
    EXPECT_NEAR(p.height_m, 0.0, 0.01);
    const Eigen::Vector3d truth = scene.Ground(p.pixel - 0.5, p.line - 0.5);
    const Eigen::Vector3d got = scene.frame.EnuFromGeodetic(p.lon_deg, p.lat_deg, p.height_m);
    EXPECT_LT((truth - got).norm(), 0.05);
  }
}

// Hills with a known slope bound on a plan box (NaN outside): the march
// that leaps by the bound and skips the locus outside the box finds the
// terrain points of the plain quarter-pixel march, with far fewer height
// lookups.
TEST_P(SlantRangeGeoreferenceModes, LimitsLeapToTheSameGcps) {
  const FlatScene scene(GetParam());
  long lookups = 0;
  const auto hills = [&](double x, double y) {
    ++lookups;
    if (x < -500.0 || x > 700.0 || y < -600.0 || y > 450.0) return std::nan("");
    return 60.0 * std::sin(x / 37.0) * std::cos(y / 53.0) + 20.0 * std::sin((x + y) / 11.0);
  };
  // |dz/dx| <= 60/37 + 20/11, |dz/dy| <= 60/53 + 20/11.
  SurfaceLimits limits;
  limits.max_gradient = std::hypot(60.0 / 37.0 + 20.0 / 11.0, 60.0 / 53.0 + 20.0 / 11.0);
  limits.plan = Eigen::AlignedBox2d(Eigen::Vector2d(-500.0, -600.0), Eigen::Vector2d(700.0, 450.0));
  tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);  // a plain counter
  const geo::Georeference plain = SlantRangeGeoreference(scene.geometry, scene.frame, hills, -80.0, 80.0, 30);
  const long plain_lookups = lookups;
  lookups = 0;
  const geo::Georeference leaping =
      SlantRangeGeoreference(scene.geometry, scene.frame, hills, -80.0, 80.0, 30, nullptr, limits);
  ASSERT_GT(plain.gcps.size(), 200u);
  ASSERT_LT(plain.gcps.size(), 900u);  // the box leaves some nodes off the terrain
  ASSERT_EQ(leaping.gcps.size(), plain.gcps.size());
  for (size_t i = 0; i < plain.gcps.size(); ++i) {
    const Eigen::Vector3d a = scene.frame.EnuFromGeodetic(plain.gcps[i].lon_deg, plain.gcps[i].lat_deg,
                                                          plain.gcps[i].height_m);
    const Eigen::Vector3d b = scene.frame.EnuFromGeodetic(leaping.gcps[i].lon_deg, leaping.gcps[i].lat_deg,
                                                          leaping.gcps[i].height_m);
    EXPECT_LT((a - b).norm(), 1e-4) << i;
    EXPECT_NEAR(leaping.gcps[i].pixel, plain.gcps[i].pixel, 1e-6);
    EXPECT_NEAR(leaping.gcps[i].line, plain.gcps[i].line, 1e-6);
  }
  std::printf("[ measured ] %s: %ld height lookups plain, %ld with the limits\n", ToString(GetParam()).c_str(),
              plain_lookups, lookups);
  EXPECT_LT(lookups * 4, plain_lookups);
}

TEST(SlantRangeGeoreference, RejectsTerrainOutsideTheImage) {
  const FlatScene scene(ProjectionMode::kAffine);
  EXPECT_THROW(SlantRangeGeoreference(scene.geometry, scene.frame,
                                      [](double, double) { return std::nan(""); }, -60.0, 1.0),
               ConfigError);
}

}  // namespace
}  // namespace gissar::sensor
