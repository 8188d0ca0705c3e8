#include "gissar/geo/local_frame.h"

#include <gtest/gtest.h>
#include <proj.h>

#include <array>
#include <random>
#include <string>
#include <thread>

#include "gissar/util/error.h"

namespace gissar::geo {
namespace {

// PROJ's own geodetic -> topocentric (ENU) pipeline, the independent reference.
class ProjTopocentric {
 public:
  ProjTopocentric(double lon0, double lat0, double h0) {
    ctx_ = proj_context_create();
    const std::string pipeline =
        "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
        "+step +proj=cart +ellps=WGS84 "
        "+step +proj=topocentric +ellps=WGS84 +lon_0=" +
        std::to_string(lon0) + " +lat_0=" + std::to_string(lat0) + " +h_0=" + std::to_string(h0);
    pj_ = proj_create(ctx_, pipeline.c_str());
  }
  ~ProjTopocentric() {
    proj_destroy(pj_);
    proj_context_destroy(ctx_);
  }
  bool ok() const { return pj_ != nullptr; }
  Eigen::Vector3d Enu(double lon, double lat, double h) const {
    const PJ_COORD out = proj_trans(pj_, PJ_FWD, proj_coord(lon, lat, h, 0));
    return {out.xyz.x, out.xyz.y, out.xyz.z};
  }

 private:
  PJ_CONTEXT* ctx_;
  PJ* pj_;
};

TEST(LocalFrameTest, OriginMapsToZeroAndUpIsUp) {
  const LocalFrame frame(1.6, 42.545, 0.0);
  EXPECT_NEAR(frame.EnuFromGeodetic(1.6, 42.545, 0.0).norm(), 0.0, 1e-6);
  const Eigen::Vector3d up = frame.EnuFromGeodetic(1.6, 42.545, 1000.0);
  EXPECT_NEAR(up.x(), 0.0, 1e-6);
  EXPECT_NEAR(up.y(), 0.0, 1e-6);
  EXPECT_NEAR(up.z(), 1000.0, 1e-6);
}

TEST(LocalFrameTest, AgreesWithProjTopocentricWithinOneCentimetre) {
  // Andorra-like scene centre and points over a 40 km x 30 km DEM extent,
  // heights 800-3100 m, plus a high-latitude and a southern-hemisphere frame.
  const std::vector<std::array<double, 2>> origins = {{1.6, 42.545}, {-97.1, 49.9}, {147.3, -42.9}};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> dlon(-0.25, 0.25), dlat(-0.15, 0.15), dh(800, 3100);
  for (const auto& [lon0, lat0] : origins) {
    const LocalFrame frame(lon0, lat0, 0.0);
    const ProjTopocentric proj(lon0, lat0, 0.0);
    ASSERT_TRUE(proj.ok());
    double worst = 0.0;
    for (int i = 0; i < 500; ++i) {
      const double lon = lon0 + dlon(rng), lat = lat0 + dlat(rng), h = dh(rng);
      const Eigen::Vector3d ours = frame.EnuFromGeodetic(lon, lat, h);
      const Eigen::Vector3d ref = proj.Enu(lon, lat, h);
      worst = std::max(worst, (ours - ref).norm());
    }
    EXPECT_LT(worst, 0.01) << "origin " << lon0 << "," << lat0;
  }
}

TEST(LocalFrameTest, RoundTripsGeodetic) {
  const LocalFrame frame(1.6, 42.545, 0.0);
  const Eigen::Vector3d enu(12345.6, -7890.1, 2500.0);
  const Eigen::Vector3d geo = frame.GeodeticFromEnu(enu);
  EXPECT_NEAR((frame.EnuFromGeodetic(geo.x(), geo.y(), geo.z()) - enu).norm(), 0.0, 1e-6);
}

TEST(LocalFrameTest, KeepsEarthCurvature) {
  // 15 km east at height 0 lies about d^2 / (2 R) = 17.6 m below the plane.
  const LocalFrame frame(0.0, 0.0, 0.0);
  const double dlon = 15000.0 / 6378137.0 * 180.0 / M_PI;
  const Eigen::Vector3d p = frame.EnuFromGeodetic(dlon, 0.0, 0.0);
  EXPECT_NEAR(p.z(), -15000.0 * 15000.0 / (2 * 6378137.0), 0.05);
}

TEST(LocalFrameTest, RejectsInvalidOrigin) {
  EXPECT_THROW(LocalFrame(0.0, 91.0), ConfigError);
  EXPECT_THROW(LocalFrame(std::nan(""), 10.0), ConfigError);
}

TEST(CrsTransformTest, UtmRoundTrip) {
  const CrsTransform utm("EPSG:32631");
  std::vector<double> x{1.6}, y{42.545};
  utm.FromLonLat(x, y);
  // Andorra in UTM 31N: easting ~385 km, northing ~4711 km.
  EXPECT_NEAR(x[0], 385000.0, 2000.0);
  EXPECT_NEAR(y[0], 4711000.0, 2000.0);
  utm.ToLonLat(x, y);
  EXPECT_NEAR(x[0], 1.6, 1e-9);
  EXPECT_NEAR(y[0], 42.545, 1e-9);
}

TEST(CrsTransformTest, TransformsOfOneCrsAgreeOnEveryThread) {
  // The second and later CrsTransforms of a definition are clones of the
  // first's operations, each in its own thread's PROJ context. Zone 31's
  // central meridian is 3 deg E: false easting 500 km there, northing 0 on
  // the equator.
  const std::string definition = "EPSG:32631";
  std::vector<std::array<double, 4>> results(6);
  std::vector<std::thread> threads;
  for (size_t i = 0; i < results.size(); ++i) {
    threads.emplace_back([&, i] {
      const CrsTransform utm(definition);
      std::vector<double> x{500000.0}, y{0.0};
      utm.ToLonLat(x, y);
      std::vector<double> e{3.0}, n{45.0};
      utm.FromLonLat(e, n);
      results[i] = {x[0], y[0], e[0], n[0]};
    });
  }
  for (std::thread& t : threads) t.join();
  for (const auto& r : results) {
    EXPECT_NEAR(r[0], 3.0, 1e-12);
    EXPECT_NEAR(r[1], 0.0, 1e-12);
    EXPECT_NEAR(r[2], 500000.0, 1e-6);
    EXPECT_EQ(r, results[0]);
  }
  EXPECT_FALSE(CrsTransform(definition).source_is_geographic());
  EXPECT_TRUE(CrsTransform("EPSG:4326").source_is_geographic());
}

TEST(CrsTransformTest, BadCrsIsAnInputError) {
  EXPECT_THROW(CrsTransform("not a crs at all"), InputError);
}

}  // namespace
}  // namespace gissar::geo
