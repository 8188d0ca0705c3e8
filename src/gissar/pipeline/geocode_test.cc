#include "gissar/pipeline/geocode.h"
#include "gissar/pipeline/simulate_door.h"
#include "gissar/pipeline/geocode_fields.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

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
  // The image's bands (three bounces traced), then the terrain's.
  ASSERT_EQ(map.bands.size(), 6u);
  const std::vector<std::string> names{"total", "single", "double", "triple", "local_incidence", "layover_shadow"};
  EXPECT_EQ(map.band_names, names);
  EXPECT_EQ(map.band_units[0], "m2/m2");
  EXPECT_EQ(map.band_units[4], "deg");

  const auto& gt = map.geotransform;
  const auto& total = map.bands[0];
  const auto& incidence = map.bands[4];
  const auto& mask = map.bands[5];
  auto centre_x = [&](int c) { return gt[0] + (c + 0.5) * gt[1]; };
  auto centre_y = [&](int r) { return gt[3] + (r + 0.5) * gt[5]; };

  int64_t nan_pixels = 0;
  for (float v : total) nan_pixels += std::isnan(v);
  EXPECT_GT(nan_pixels, 0);  // the map's corners lie outside the imaged terrain

  // Each square's centroid on the map, weighted by darkness (0 at the
  // ground's level around the square, 1 at the water's level inside it: in
  // exact mode the plateau sees another incidence), outside layover/shadow.
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  auto check_squares = [&](const geo::FloatRaster& m, const std::string& label) {
    const auto& g = m.geotransform;
    const double px = g[1];
    for (const Square& s : {kA, kB}) {
      std::vector<double> inside, outside;
      for (int r = 0; r < m.height; ++r)
        for (int c = 0; c < m.width; ++c) {
          const double x = g[0] + (c + 0.5) * px, y = g[3] - (r + 0.5) * px;
          const double d = std::max(std::abs(x - s.x), std::abs(y - s.y));  // from the centre, Chebyshev
          const float v = m.bands[0][size_t(r) * m.width + c];
          if (std::isnan(v) || m.bands[5][size_t(r) * m.width + c] != 0.0f) continue;
          if (d < s.half - 15) inside.push_back(v);
          if (d > s.half + 15 && d < s.half + 40) outside.push_back(v);
        }
      ASSERT_GT(inside.size(), 10u);
      ASSERT_GT(outside.size(), 10u);
      const double ground = median(outside), water = median(inside);
      double sx = 0, sy = 0, sw = 0;
      for (int r = 0; r < m.height; ++r)
        for (int c = 0; c < m.width; ++c) {
          const double x = g[0] + (c + 0.5) * px, y = g[3] - (r + 0.5) * px;
          if (std::abs(x - s.x) > s.half + 40 || std::abs(y - s.y) > s.half + 40) continue;
          const size_t i = size_t(r) * m.width + c;
          const float v = m.bands[0][i];
          if (std::isnan(v) || m.bands[5][i] != 0.0f) continue;
          const double w = std::clamp((ground - v) / (ground - water), 0.0, 1.0);
          sx += w * x;
          sy += w * y;
          sw += w;
        }
      ASSERT_GT(sw, 0.0);
      const double error_px = std::hypot(sx / sw - s.x, sy / sw - s.y) / px;
      const double area_px = 4 * s.half * s.half / (px * px);
      std::printf("[ measured ] %s %s square at (%.0f, %.0f): dark area %.1f px (%.0f expected), centroid error %.3f px\n",
                  sensor::ToString(GetParam()).c_str(), label.c_str(), s.x, s.y, sw, area_px, error_px);
      EXPECT_NEAR(sw, area_px, 0.1 * area_px) << label;
      EXPECT_LT(error_px, 0.5) << label;
    }
  };
  check_squares(map, "bilinear 5 m");
  // Average resampling onto 10 m pixels (2 x 2 points each).
  request.pixel_size_m = 10.0;
  request.resampling = GeocodeResampling::kAverage;
  request.out_prefix = (dir / "map10").string();
  RunGeocode(request, "test");
  check_squares(geo::ReadFloatRaster(dir / "map10.tif"), "average 10 m");
  // A map grid over 2^28 pixels (5 cm pixels over the scene's 1.4 km) is
  // refused without --force, naming --pixel-size, and writes nothing.
  {
    GeocodeRequest fine = request;
    fine.pixel_size_m = 0.05;
    fine.resampling = GeocodeResampling::kBilinear;
    fine.out_prefix = (dir / "fine").string();
    try {
      RunGeocode(fine, "test");
      ADD_FAILURE() << "expected ConfigError";
    } catch (const ConfigError& e) {
      EXPECT_NE(e.message().find("is over the 2^28-pixel limit (268435456 pixels); choose a larger --pixel-size, or "
                                 "run it anyway with --force"),
                std::string::npos)
          << e.message();
      EXPECT_EQ(e.where(), "--pixel-size");
    }
    EXPECT_FALSE(fs::exists(dir / "fine.tif"));
  }

  // References on the same grid, from the closed-form terrain, the class
  // map (the two squares) and the sensor track of the sidecar, not from
  // geocode: the image value the calibrated radiometry predicts
  // (docs/radiometry.md: a slope at local incidence tl holds 1 / sin tl of
  // ground per slant-range area, so the sigma0 image reads
  // sigma0_class(tl) sin ti / sin tl, ti the ellipsoid incidence). On level
  // ground it is the class map through the class laws; on the hill's ground
  // it is a function of the local-incidence map alone. Outside layover/shadow.
  nlohmann::json sidecar;
  std::ifstream(sim + ".json") >> sidecar;
  const auto s0 = sidecar["geometry"]["sensor_enu_m_at_centre"].get<std::vector<double>>();
  const auto hv = sidecar["geometry"]["flight_direction_enu"].get<std::vector<double>>();
  const auto lv = sidecar["geometry"]["look_direction_enu"].get<std::vector<double>>();
  const auto xcv = sidecar["scene_centre"]["enu_m"].get<std::vector<double>>();
  const Eigen::Vector3d sensor0(s0[0], s0[1], s0[2]), flight(hv[0], hv[1], hv[2]), look(lv[0], lv[1], lv[2]);
  const Eigen::Vector3d xc(xcv[0], xcv[1], xcv[2]);
  const double sensor_height = sensor0.z() - xc.z();
  auto law = [&](scene::ClassId id, double cos_local) {
    return material::DefaultMaterial(id).Sigma0(cos_local, 0.031, material::Polarization::kVV);
  };
  std::vector<double> class_value, class_ref, inc_value, inc_ref, inc_band, inc_truth;
  for (int r = 0; r < map.height; ++r)
    for (int c = 0; c < map.width; ++c) {
      const size_t i = size_t(r) * map.width + c;
      if (std::isnan(total[i]) || mask[i] != 0.0f) continue;
      const double x = centre_x(c), y = centre_y(r);
      if (std::abs(x) > 650 || std::abs(y) > 650) continue;  // away from the scene's edges
      const Eigen::Vector2d g = Gradient(x, y);
      const Eigen::Vector3d normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
      const Eigen::Vector3d point(x, y, Height(x, y));
      Eigen::Vector3d ray = look;  // affine: parallel rays
      double sin_ti = std::cos(40.0 * M_PI / 180.0);
      if (GetParam() == sensor::ProjectionMode::kExact) {
        const Eigen::Vector3d from = sensor0 + (point - xc).dot(flight) * flight;  // zero-Doppler position
        ray = (point - from).normalized();
        const double range = (point - from).norm();
        sin_ti = std::sqrt(1.0 - std::pow(sensor_height / range, 2));
      }
      const double cos_tl = -ray.dot(normal);
      const double sin_tl = std::sqrt(1.0 - cos_tl * cos_tl);
      const bool is_water = InSquare(kA, x, y) || InSquare(kB, x, y);
      const double predicted = law(is_water ? scene::kClassWater : scene::kClassDefault, cos_tl) * sin_ti / sin_tl;
      if (g.norm() == 0.0) {
        class_value.push_back(total[i]);
        class_ref.push_back(predicted);
      } else if (!is_water) {
        inc_value.push_back(total[i]);
        inc_ref.push_back(predicted);
        if (!std::isnan(incidence[i])) {
          inc_band.push_back(incidence[i]);
          inc_truth.push_back(std::acos(cos_tl) * 180.0 / M_PI);
        }
      }
    }
  ASSERT_GT(class_value.size(), 1000u);
  ASSERT_GT(inc_value.size(), 1000u);
  const double r_class = Pearson(class_value, class_ref), r_inc = Pearson(inc_value, inc_ref);
  std::printf("[ measured ] %s: r = %.3f against the class map (level ground, %zu px), %.3f against the local-incidence map (hill, %zu px)\n",
              sensor::ToString(GetParam()).c_str(), r_class, class_value.size(), r_inc, inc_value.size());
  EXPECT_GE(r_class, 0.9);
  EXPECT_GE(r_inc, 0.9);
  // The local-incidence band matches the closed form to the mesh's facetting.
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
  EXPECT_EQ(kGeocodeResamplings.Parse("average", "--resampling"), GeocodeResampling::kAverage);
  EXPECT_EQ(kGeocodeResamplings.Name(GeocodeResampling::kBilinear), "bilinear");
  try {
    kGeocodeResamplings.Parse("cubic", "--resampling");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "unknown resampling 'cubic': must be bilinear or average");
    EXPECT_EQ(e.where(), "--resampling");
  }
  r.resampling = GeocodeResampling::kAverage;
  r.pixel_size_m = -1;
  EXPECT_THROW(r.Check(), ConfigError);
  r.pixel_size_m = 0;
  r.out_prefix = "a";
  EXPECT_THROW(r.Check(), ConfigError);  // a.tif would be overwritten
}

// The geocode table (geocode_fields.cc) writes the sidecar's seven keys and
// reads them back (the resampling by name, null keeps the default); an
// unknown key or resampling is a ConfigError naming it and the source.
TEST(GeocodeFields, RoundTripNullAndResampling) {
  GeocodeRequest o;
  o.image = "sim.tif";
  o.dem = "dem.tif";
  o.vertical_datum = "egm2008";
  o.crs = "EPSG:32631";
  o.pixel_size_m = 12.5;
  o.resampling = GeocodeResampling::kAverage;
  o.out_prefix = "map";
  const nlohmann::json j = o.ToJson();
  EXPECT_EQ(j, nlohmann::json({{"image", "sim.tif"}, {"dem", "dem.tif"}, {"vertical_datum", "egm2008"},
                               {"crs", "EPSG:32631"}, {"pixel_size_m", 12.5}, {"resampling", "average"},
                               {"out_prefix", "map"}}));
  GeocodeRequest round;
  round.ApplyJson(j, "test");
  EXPECT_EQ(round.ToJson(), j);
  EXPECT_EQ(round.resampling, GeocodeResampling::kAverage);
  EXPECT_EQ(round.pixel_size_m, 12.5);
  GeocodeRequest kept;
  kept.ApplyJson({{"crs", nullptr}, {"resampling", nullptr}, {"pixel_size_m", nullptr}}, "test");
  EXPECT_EQ(kept.ToJson(), GeocodeRequest().ToJson());
  try {
    kept.ApplyJson({{"pixel_size", 10.0}}, "gissar.geocode keyword");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "unknown key 'pixel_size'; did you mean pixel_size_m?");
    EXPECT_EQ(e.where(), "gissar.geocode keyword");
  }
  try {
    kept.ApplyJson({{"resampling", "cubic"}}, "opts.json");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "unknown resampling 'cubic': must be bilinear or average");
    EXPECT_EQ(e.where(), "--resampling");
  }
  EXPECT_THROW(kept.ApplyJson({{"pixel_size_m", "ten"}}, "test"), ConfigError);
  EXPECT_EQ(GeocodeFields().at("pixel_size_m").Flag(), "--pixel-size");
  EXPECT_EQ(GeocodeFields().at("out_prefix").Flag(), "--out");
  EXPECT_EQ(GeocodeFields().at("resampling").help, "bilinear or average");
}

TEST(GeocodeRequestTest, UtmZoneOfLongitudeLatitude) {
  EXPECT_EQ(UtmCrsOf(1.6, 42.5), "EPSG:32631");     // Andorra: zone 31 N
  EXPECT_EQ(UtmCrsOf(-120.5, 36.0), "EPSG:32610");  // California: zone 10 N
  EXPECT_EQ(UtmCrsOf(151.2, -33.9), "EPSG:32756");  // Sydney: zone 56 S
}

}  // namespace
}  // namespace gissar::pipeline
