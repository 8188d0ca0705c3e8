#include "gissar/geo/dem.h"

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::geo {
namespace {

const auto kRawDem = [] { return testing::DataPath("andorra/andorra_srtm3_dem_raw.tif"); };
const auto kFilledDem = [] { return testing::DataPath("andorra/andorra_srtm3_dem_filled.tif"); };

TEST(DemTest, RawAndorraFailsNamingTheVoidCount) {
  try {
    ReadDem(kRawDem());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.message().find("403 no-data cells"), std::string::npos) << e.what();
    EXPECT_EQ(e.where(), kRawDem().string());
  }
}

TEST(DemTest, RawAndorraFillsEveryVoid) {
  DemReadOptions options;
  options.fill_nodata = true;
  const Dem dem = ReadDem(kRawDem(), options);
  EXPECT_EQ(dem.width, 480);
  EXPECT_EQ(dem.height, 300);
  EXPECT_EQ(dem.filled_nodata_cells, 403);
  float lo = 1e9f, hi = -1e9f;
  for (float h : dem.heights_m) {
    ASSERT_TRUE(std::isfinite(h));
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  EXPECT_GE(lo, 800.0f);
  EXPECT_LE(hi, 3100.0f);
  // GDAL's FillNodata with a different search distance gave the bundled
  // filled DEM: the two agree closely on the filled cells.
  const Dem reference = ReadDem(kFilledDem());
  double sum_abs = 0.0;
  for (size_t i = 0; i < dem.heights_m.size(); ++i) {
    sum_abs += std::abs(dem.heights_m[i] - reference.heights_m[i]);
  }
  EXPECT_LT(sum_abs / 403.0, 30.0);
}

TEST(DemTest, GeographicGridHasSrtm3Spacing) {
  const Dem dem = ReadDem(kFilledDem());
  const GeoPoint centre = ResolveSceneCentre(dem, std::nullopt, std::nullopt);
  EXPECT_NEAR(centre.lon_deg, 1.60, 1e-3);
  EXPECT_NEAR(centre.lat_deg, 42.545, 1e-3);
  const LocalFrame frame(centre.lon_deg, centre.lat_deg);
  const Eigen::Vector2d spacing = DemPostSpacingMetres(dem, frame);
  // 3 arc-seconds: ~92.6 m north-south, times cos(latitude) east-west.
  EXPECT_NEAR(spacing.y(), 92.6, 0.5);
  EXPECT_NEAR(spacing.x(), 92.6 * std::cos(42.545 * M_PI / 180.0), 0.5);
}

TEST(DemTest, PostsInFrameFollowTheGeotransform) {
  const Dem dem = ReadDem(kFilledDem());
  const GeoPoint centre = ResolveSceneCentre(dem, std::nullopt, std::nullopt);
  const LocalFrame frame(centre.lon_deg, centre.lat_deg);
  const auto enu = DemPostsInFrame(dem, frame);
  ASSERT_EQ(enu.size(), size_t(480 * 300));
  const Eigen::Vector2d lonlat = dem.MapFromPost(17, 42);
  const Eigen::Vector3d expected = frame.EnuFromGeodetic(lonlat.x(), lonlat.y(), dem.HeightAt(17, 42));
  EXPECT_NEAR((enu[42 * 480 + 17].cast<double>() - expected).norm(), 0.0, 0.01);
  // North-up raster: row 0 is the northern edge.
  EXPECT_GT(enu[0].y(), enu[299 * 480].y());
  EXPECT_LT(enu[0].x(), enu[479].x());
}

TEST(DemTest, ProjectedDemIsPlacedThroughProj) {
  EnsureGdal();
  const auto dir = testing::MakeTempDir();
  const auto path = dir / "utm.tif";
  {
    GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
    GDALDataset* ds = gtiff->Create(path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
    double gt[6] = {385000.0, 30.0, 0.0, 4711000.0, 0.0, -30.0};
    ds->SetGeoTransform(gt);
    OGRSpatialReference srs;
    srs.importFromEPSG(32631);
    ds->SetSpatialRef(&srs);
    std::vector<float> h(12, 1000.0f);
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 4, 3, h.data(), 4, 3, GDT_Float32,
                                             0, 0, nullptr),
              CE_None);
    GDALClose(ds);
  }
  const Dem dem = ReadDem(path);
  const GeoPoint centre = ResolveSceneCentre(dem, std::nullopt, std::nullopt);
  const LocalFrame frame(centre.lon_deg, centre.lat_deg);
  const auto enu = DemPostsInFrame(dem, frame);
  // UTM cells are 30 m; a local ENU frame sees them as 30 m times the UTM
  // scale error (~1.0002 here, 1.4 degrees off the central meridian).
  const double dx = (enu[1] - enu[0]).norm();
  EXPECT_NEAR(dx, 30.0, 0.03);
  EXPECT_NEAR(enu[5].z(), 1000.0, 0.5);
}

TEST(DemTest, MissingFileIsAnInputError) {
  try {
    ReadDem("/nonexistent/dem.tif");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.message(), "DEM file does not exist");
  }
}

TEST(DemTest, NonRasterFileIsAnInputError) {
  const auto dir = testing::MakeTempDir();
  std::ofstream(dir / "notes.tif") << "this is not a raster\n";
  try {
    ReadDem(dir / "notes.tif");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.message(), "not a raster GDAL can read");
  }
}

TEST(DemTest, CentreOutsideDemIsAConfigError) {
  const Dem dem = ReadDem(kFilledDem());
  EXPECT_THROW(ResolveSceneCentre(dem, Eigen::Vector2d(5.0, 45.0), std::nullopt), ConfigError);
}

}  // namespace
}  // namespace gissar::geo

namespace gissar::geo {
namespace {

TEST(DemTest, WindowReadsOnlyThatPart) {
  const Dem whole = ReadDem(testing::DataPath("andorra/andorra_srtm3_dem_filled.tif"));
  DemReadOptions options;
  options.window = std::array<int, 4>{100, 50, 64, 32};
  const Dem window = ReadDem(testing::DataPath("andorra/andorra_srtm3_dem_filled.tif"), options);
  EXPECT_EQ(window.width, 64);
  EXPECT_EQ(window.height, 32);
  EXPECT_EQ(window.HeightAt(0, 0), whole.HeightAt(100, 50));
  EXPECT_EQ(window.HeightAt(63, 31), whole.HeightAt(163, 81));
  EXPECT_NEAR((window.MapFromPost(0, 0) - whole.MapFromPost(100, 50)).norm(), 0.0, 1e-12);
  options.window = std::array<int, 4>{450, 0, 64, 32};  // sticks out of the 480-wide DEM
  EXPECT_THROW(ReadDem(testing::DataPath("andorra/andorra_srtm3_dem_filled.tif"), options), ConfigError);
}

}  // namespace
}  // namespace gissar::geo
