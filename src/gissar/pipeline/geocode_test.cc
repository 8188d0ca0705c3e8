#include "gissar/pipeline/geocode.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

// A local transverse Mercator CRS centred on the scene: map metres are
// ENU metres near the origin (scale error < 1e-8 within 1 km).
const char* kLocalTm = "+proj=tmerc +lat_0=42.5 +lon_0=1.6 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";

// The terrain, in map metres: flat ground at 100 m and a plateau 150 m
// higher of radius 120 m around (kHillX, kHillY), with a raised-cosine
// flank out to 400 m (steepest 40 deg).
constexpr double kHillX = 250.0, kHillY = 150.0, kTop = 150.0, kR0 = 120.0, kR1 = 400.0;
double Height(double x, double y) {
  const double r = std::hypot(x - kHillX, y - kHillY);
  if (r <= kR0) return 100.0 + kTop;
  if (r >= kR1) return 100.0;
  return 100.0 + kTop * 0.5 * (1.0 + std::cos(M_PI * (r - kR0) / (kR1 - kR0)));
}
// Its gradient (dh/dx, dh/dy), closed form.
Eigen::Vector2d Gradient(double x, double y) {
  const double r = std::hypot(x - kHillX, y - kHillY);
  if (r <= kR0 || r >= kR1) return Eigen::Vector2d::Zero();
  const double dhdr = -kTop * 0.5 * std::sin(M_PI * (r - kR0) / (kR1 - kR0)) * M_PI / (kR1 - kR0);
  return Eigen::Vector2d((x - kHillX) / r, (y - kHillY) / r) * dhdr;
}

// Two water squares: A (120 m) on the flat ground, B (100 m) on the plateau.
struct Square {
  double x, y, half;
};
const Square kA{-350.0, -300.0, 60.0}, kB{kHillX, kHillY, 50.0};
bool InSquare(const Square& s, double x, double y) { return std::abs(x - s.x) < s.half && std::abs(y - s.y) < s.half; }

std::string Polygon(const geo::CrsTransform& tm, const Square& s) {
  std::vector<double> x{s.x - s.half, s.x + s.half, s.x + s.half, s.x - s.half, s.x - s.half};
  std::vector<double> y{s.y - s.half, s.y - s.half, s.y + s.half, s.y + s.half, s.y - s.half};
  tm.ToLonLat(x, y);
  std::ostringstream text;
  text.precision(12);
  text << R"({"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[)";
  for (size_t i = 0; i < x.size(); ++i) text << (i ? "," : "") << "[" << x[i] << "," << y[i] << "]";
  text << "]]}}";
  return text.str();
}

// Builds the scene and simulates it (heading 0: flight north, looking east;
// 5 m pixels); returns the image's prefix.
std::string SimulateScene(const fs::path& dir, sensor::ProjectionMode mode) {
  const int n = 141;  // 10 m posts, +-700 m
  std::vector<float> heights(size_t(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) heights[size_t(r) * n + c] = float(Height(-700.0 + 10.0 * c, 700.0 - 10.0 * r));
  geo::WriteDemGeoTiff(dir / "dem.tif", heights, n, n, {-705.0, 10.0, 0.0, 705.0, 0.0, -10.0}, kLocalTm);
  const geo::CrsTransform tm(kLocalTm);
  std::ofstream(dir / "water.geojson") << R"({"type":"FeatureCollection","features":[)" << Polygon(tm, kA) << ","
                                       << Polygon(tm, kB) << "]}";
  std::ofstream(dir / "config.json") << R"({"layers": [{"path": "water.geojson", "class": "water"}]})";
  SceneBuildRequest build;
  build.dem = (dir / "dem.tif").string();
  build.config = (dir / "config.json").string();
  build.out_prefix = (dir / "scene").string();
  RunSceneBuild(build, "test");
  SimulateRequest o;
  o.scene = (dir / "scene.gscene").string();
  o.geometry.heading_deg = 0.0;
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = 5.0;
  o.geometry.azimuth_spacing_m = 5.0;
  o.geometry.mode = mode;
  o.out_prefix = (dir / "sim").string();
  RunSimulate(o, "test");
  return o.out_prefix;
}

double Pearson(const std::vector<double>& a, const std::vector<double>& b) {
  double ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i], mb += b[i];
  ma /= a.size();
  mb /= b.size();
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

class GeocodeTest : public ::testing::TestWithParam<sensor::ProjectionMode> {};

// Geocoding a simulated image puts a water square on flat ground and one on
// a 150 m plateau (displaced ~36 range pixels by relief in the image) on
// their map positions, and the map agrees with the scene's class map and
// with the local incidence, both computed here from the closed-form terrain.
TEST_P(GeocodeTest, FeaturesLandOnTheirMapPosition) {
  const fs::path dir = testing::MakeTempDir();
  const std::string sim = SimulateScene(dir, GetParam());
  GeocodeRequest request;
  request.image = sim + ".tif";
  request.crs = kLocalTm;
  request.pixel_size_m = 5.0;
  request.out_prefix = (dir / "map").string();
  const GeocodeResult result = RunGeocode(request, "test");
  ASSERT_EQ(result.outputs.size(), 3u);  // .tif .json _stac.json

  const geo::FloatRaster map = geo::ReadFloatRaster(dir / "map.tif");
  // Metadata GIS tools need: CRS, geotransform, NaN no-data, names, units.
  EXPECT_NE(map.crs.find("Transverse_Mercator"), std::string::npos) << map.crs;
  ASSERT_EQ(map.geotransform.size(), 6u);
  EXPECT_DOUBLE_EQ(map.geotransform[1], 5.0);
  EXPECT_DOUBLE_EQ(map.geotransform[5], -5.0);
  EXPECT_TRUE(map.nodata_nan);
  ASSERT_EQ(map.bands.size(), 7u);
  const std::vector<std::string> names{"total", "single", "double", "triple", "four_or_more", "local_incidence", "layover_shadow"};
  EXPECT_EQ(map.band_names, names);
  EXPECT_EQ(map.band_units[0], "m2/m2");
  EXPECT_EQ(map.band_units[5], "deg");

  const auto& gt = map.geotransform;
  const auto& total = map.bands[0];
  const auto& incidence = map.bands[5];
  const auto& mask = map.bands[6];
  auto centre_x = [&](int c) { return gt[0] + (c + 0.5) * gt[1]; };
  auto centre_y = [&](int r) { return gt[3] + (r + 0.5) * gt[5]; };
  // The threshold between the classes' sigma0 on level ground (incidence 50 deg).
  const double cos_inc = std::sin(40 * M_PI / 180);
  const double ground = material::DefaultMaterial(scene::kClassDefault).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  const double water = material::DefaultMaterial(scene::kClassWater).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  const double threshold = 0.5 * (ground + water);

  int64_t nan_pixels = 0;
  for (float v : total) nan_pixels += std::isnan(v);
  EXPECT_GT(nan_pixels, 0);  // the map's corners lie outside the imaged terrain

  for (const Square& s : {kA, kB}) {
    double sx = 0, sy = 0;
    int count = 0;
    for (int r = 0; r < map.height; ++r)
      for (int c = 0; c < map.width; ++c) {
        const double x = centre_x(c), y = centre_y(r);
        if (std::abs(x - s.x) > s.half + 40 || std::abs(y - s.y) > s.half + 40) continue;
        const size_t i = size_t(r) * map.width + c;
        if (!(total[i] < threshold) || mask[i] != 0.0f) continue;
        sx += x;
        sy += y;
        ++count;
      }
    ASSERT_GT(count, 0);
    const double error_px = std::hypot(sx / count - s.x, sy / count - s.y) / 5.0;
    const double area_px = 4 * s.half * s.half / 25.0;
    std::printf("[ measured ] %s square at (%.0f, %.0f): %d dark pixels (%.0f expected), centroid error %.3f px\n",
                sensor::ToString(GetParam()).c_str(), s.x, s.y, count, area_px, error_px);
    EXPECT_NEAR(count, area_px, 0.1 * area_px);
    EXPECT_LT(error_px, 0.5);
  }

  // References on the same grid from the closed-form terrain: the class map
  // (1 ground, 0 water) on level ground, and cos(local incidence) against
  // the line of sight of the scene centre, on ground-class pixels; both
  // outside layover/shadow (the image's mask).
  const Eigen::Vector3d look = sensor::LookDirection(0.0, 40.0, sensor::LookSide::kRight);
  std::vector<double> class_value, class_ref, inc_value, inc_ref, inc_band, inc_truth;
  for (int r = 0; r < map.height; ++r)
    for (int c = 0; c < map.width; ++c) {
      const size_t i = size_t(r) * map.width + c;
      if (std::isnan(total[i]) || mask[i] != 0.0f) continue;
      const double x = centre_x(c), y = centre_y(r);
      if (std::abs(x) > 650 || std::abs(y) > 650) continue;  // away from the scene's edges
      const Eigen::Vector2d g = Gradient(x, y);
      const bool is_water = InSquare(kA, x, y) || InSquare(kB, x, y);
      if (g.norm() == 0.0) {
        class_value.push_back(total[i]);
        class_ref.push_back(is_water ? 0.0 : 1.0);
      }
      if (!is_water && std::hypot(x - kHillX, y - kHillY) < kR1 + 50) {
        const Eigen::Vector3d normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
        inc_value.push_back(total[i]);
        inc_ref.push_back(-look.dot(normal));
        if (GetParam() == sensor::ProjectionMode::kAffine && !std::isnan(incidence[i])) {
          inc_band.push_back(incidence[i]);
          inc_truth.push_back(std::acos(-look.dot(normal)) * 180.0 / M_PI);
        }
      }
    }
  ASSERT_GT(class_value.size(), 1000u);
  ASSERT_GT(inc_value.size(), 1000u);
  const double r_class = Pearson(class_value, class_ref), r_inc = Pearson(inc_value, inc_ref);
  std::printf("[ measured ] %s: r = %.3f against the class map (%zu px), %.3f against cos(local incidence) (%zu px)\n",
              sensor::ToString(GetParam()).c_str(), r_class, class_value.size(), r_inc, inc_value.size());
  EXPECT_GE(r_class, 0.9);
  EXPECT_GE(r_inc, 0.9);
  // The local-incidence band (affine: one line of sight) matches the closed
  // form to the mesh's facetting.
  if (!inc_band.empty()) {
    double sum = 0;
    for (size_t i = 0; i < inc_band.size(); ++i) sum += std::abs(inc_band[i] - inc_truth[i]);
    std::printf("[ measured ] local incidence band: mean |error| %.3f deg\n", sum / inc_band.size());
    EXPECT_LT(sum / inc_band.size(), 1.0);
  }
}

INSTANTIATE_TEST_SUITE_P(Modes, GeocodeTest,
                         ::testing::Values(sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact));

TEST(GeocodeRequestTest, CheckNamesTheFlag) {
  GeocodeRequest r;
  r.out_prefix = "/tmp/x";
  try {
    r.Check();
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--image"), std::string::npos);
  }
  r.image = "a.tif";
  r.resampling = "cubic";
  EXPECT_THROW(r.Check(), ConfigError);
  r.resampling = "average";
  r.pixel_size_m = -1;
  EXPECT_THROW(r.Check(), ConfigError);
  r.pixel_size_m = 0;
  r.out_prefix = "a";
  EXPECT_THROW(r.Check(), ConfigError);  // a.tif would be overwritten
}

TEST(GeocodeRequestTest, UtmZoneOfLongitudeLatitude) {
  EXPECT_EQ(UtmCrsOf(1.6, 42.5), "EPSG:32631");     // Andorra: zone 31 N
  EXPECT_EQ(UtmCrsOf(-120.5, 36.0), "EPSG:32610");  // California: zone 10 N
  EXPECT_EQ(UtmCrsOf(151.2, -33.9), "EPSG:32756");  // Sydney: zone 56 S
}

}  // namespace
}  // namespace gissar::pipeline
