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

// A new w x h, one-band GeoTIFF at `path` of `type`, 30 m posts from
// (385000, 4711000) in `crs` (UTM 31N unless told): the caller fills its
// band and closes it (GDALClose).
GDALDataset* CreateTestDem(const std::filesystem::path& path, int w, int h, GDALDataType type,
                           const char* crs = "EPSG:32631") {
  EnsureGdal();
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  GDALDataset* ds = gtiff->Create(path.c_str(), w, h, 1, type, nullptr);
  double gt[6] = {385000.0, 30.0, 0.0, 4711000.0, 0.0, -30.0};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.SetFromUserInput(crs);
  ds->SetSpatialRef(&srs);
  return ds;
}

TEST(DemTest, ProjectedDemIsPlacedThroughProj) {
  EnsureGdal();
  const auto dir = testing::MakeTempDir();
  const auto path = dir / "utm.tif";
  {
    GDALDataset* ds = CreateTestDem(path, 4, 3, GDT_Float32);
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

// Posts closer than 64 m are placed by interpolating exactly transformed
// nodes: against every post transformed through PROJ one by one, within
// 0.5 mm (the interpolation's bound is 0.08 mm, plus float rounding), and a
// window off the node lattice places its posts bit for bit as the whole DEM.
TEST(DemTest, InterpolatedPostsMatchTheExactTransformAndWindowsBitForBit) {
  const auto dir = testing::MakeTempDir();
  struct Case {
    const char* crs;
    std::array<double, 6> geotransform;
  };
  // UTM 31N at 5 m (nodes every 12 posts), and WGS84 at 0.5 arc-second
  // (about 15 m north-south, 11 m east-west: nodes every 4 posts).
  const Case cases[] = {{"EPSG:32631", {385000.0, 5.0, 0.0, 4711000.0, 0.0, -5.0}},
                        {"EPSG:4326", {1.45, 0.5 / 3600.0, 0.0, 42.6, 0.0, -0.5 / 3600.0}}};
  const int w = 300, h = 200;
  std::vector<float> heights(size_t(w) * h);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      heights[size_t(r) * w + c] = float(1000.0 + 800.0 * std::sin(c / 17.0) * std::cos(r / 23.0) + 37.0 * ((c * 7 + r * 13) % 5));
    }
  }
  for (const Case& test : cases) {
    const auto path = dir / (std::string(test.crs).substr(5) + ".tif");
    WriteDemGeoTiff(path, heights, w, h, test.geotransform, test.crs);
    const Dem dem = ReadDem(path);
    const GeoPoint centre = ResolveSceneCentre(dem, std::nullopt, std::nullopt);
    const LocalFrame frame(centre.lon_deg, centre.lat_deg);
    const std::vector<Eigen::Vector3f> enu = DemPostsInFrame(dem, frame);
    ASSERT_EQ(enu.size(), heights.size());
    std::vector<double> x, y;
    for (int r = 0; r < h; ++r) {
      for (int c = 0; c < w; ++c) {
        const Eigen::Vector2d m = dem.MapFromPost(c, r);
        x.push_back(m.x());
        y.push_back(m.y());
      }
    }
    CrsTransform(dem.crs_wkt).ToLonLat(x, y);
    double worst_m = 0.0;
    for (size_t k = 0; k < enu.size(); ++k) {
      const Eigen::Vector3d exact = frame.EnuFromGeodetic(x[k], y[k], heights[k]);
      worst_m = std::max(worst_m, (enu[k].cast<double>() - exact).norm());
    }
    std::printf("[ measured ] %s: largest distance to the exact transform %.2e m\n", test.crs, worst_m);
    EXPECT_LT(worst_m, 5e-4) << test.crs;

    DemReadOptions options;
    options.window = std::array<int, 4>{37, 23, 101, 77};
    const Dem window = ReadDem(path, options);
    const std::vector<Eigen::Vector3f> window_enu = DemPostsInFrame(window, frame);
    for (int r = 0; r < 77; ++r) {
      for (int c = 0; c < 101; ++c) {
        ASSERT_EQ(window_enu[size_t(r) * 101 + c], enu[size_t(r + 23) * w + c + 37]) << test.crs << " " << c << "," << r;
      }
    }
  }
}

// The message of the InputError ReadDem throws for `path`, or "" if none.
std::string ReadDemError(const std::filesystem::path& path, const DemReadOptions& options = {}) {
  try {
    ReadDem(path, options);
  } catch (const InputError& e) {
    EXPECT_EQ(e.where(), path.string());
    return e.message();
  }
  return "";
}

std::vector<float> Flat(int n) { return std::vector<float>(size_t(n) * n, 500.0f); }

TEST(DemTest, GeographicDemsNearAPoleOrAcrossTheAntimeridianAreRefused) {
  const auto dir = testing::MakeTempDir();
  WriteDemGeoTiff(dir / "pole.tif", Flat(8), 8, 8, {10.0, 0.1, 0.0, 89.85, 0.0, -0.1}, "EPSG:4326");
  EXPECT_NE(ReadDemError(dir / "pole.tif").find("polar stereographic"), std::string::npos);
  WriteDemGeoTiff(dir / "beyond.tif", Flat(8), 8, 8, {10.0, 0.5, 0.0, 92.0, 0.0, -0.5}, "EPSG:4326");
  EXPECT_NE(ReadDemError(dir / "beyond.tif").find("beyond 90 degrees"), std::string::npos);
  WriteDemGeoTiff(dir / "am.tif", Flat(8), 8, 8, {179.7, 0.1, 0.0, 10.0, 0.0, -0.1}, "EPSG:4326");
  EXPECT_NE(ReadDemError(dir / "am.tif").find("antimeridian"), std::string::npos);
  // 88 degrees and longitudes up to 180 are fine; so are projected DEMs anywhere.
  WriteDemGeoTiff(dir / "north.tif", Flat(8), 8, 8, {179.15, 0.1, 0.0, 88.8, 0.0, -0.1}, "EPSG:4326");
  EXPECT_EQ(ReadDemError(dir / "north.tif"), "");
  WriteDemGeoTiff(dir / "polar.tif", Flat(8), 8, 8, {0.0, 100.0, 0.0, 0.0, 0.0, -100.0}, "EPSG:3413");
  EXPECT_EQ(ReadDemError(dir / "polar.tif"), "");
}

TEST(DemTest, BandScaleAndOffsetAreApplied) {
  EnsureGdal();
  const auto dir = testing::MakeTempDir();
  const auto path = dir / "dm.tif";
  {
    // Int16 decimetres above 1000 m: height = stored * 0.1 + 1000; -32768 is no-data.
    GDALDataset* ds = CreateTestDem(path, 4, 3, GDT_Int16);
    GDALRasterBand* band = ds->GetRasterBand(1);
    band->SetScale(0.1);
    band->SetOffset(1000.0);
    band->SetNoDataValue(-32768);
    std::vector<int16_t> h = {0, 10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 12345};
    ASSERT_EQ(band->RasterIO(GF_Write, 0, 0, 4, 3, h.data(), 4, 3, GDT_Int16, 0, 0, nullptr), CE_None);
    GDALClose(ds);
  }
  const Dem dem = ReadDem(path);
  ASSERT_EQ(dem.heights_m.size(), 12u);
  EXPECT_FLOAT_EQ(dem.heights_m[0], 1000.0f);
  EXPECT_FLOAT_EQ(dem.heights_m[5], 1005.0f);
  EXPECT_FLOAT_EQ(dem.heights_m[11], 2234.5f);
}

// The reader takes 8- and 16-bit integer and Float32 bands in float (no
// double copy) when no scale or offset applies: the same heights, voids and
// border mask as a band of the same values read in double (Int32, Float64),
// with a unit conversion rounded once (double product, then float).
TEST(DemTest, EveryStorageTypeGivesTheHeightsOfTheDoubleRead) {
  EnsureGdal();
  const auto dir = testing::MakeTempDir();
  constexpr int kW = 6, kH = 5;
  constexpr double kNoData = -32768.0;
  std::vector<double> stored(kW * kH);
  for (int i = 0; i < kW * kH; ++i) stored[size_t(i)] = 1000.0 + 37.0 * i - 3.0 * (i % 4);
  stored[0] = stored[1] = kNoData;  // a void on the border
  stored[2 * kW + 3] = kNoData;     // and one inside
  auto write = [&](const char* name, GDALDataType type) {
    const auto path = dir / name;
    GDALDataset* ds = CreateTestDem(path, kW, kH, type);
    GDALRasterBand* band = ds->GetRasterBand(1);
    band->SetNoDataValue(kNoData);
    band->SetUnitType("ft");
    EXPECT_EQ(band->RasterIO(GF_Write, 0, 0, kW, kH, stored.data(), kW, kH, GDT_Float64, 0, 0, nullptr), CE_None);
    GDALClose(ds);
    return path;
  };
  DemReadOptions options;
  options.fill_nodata = true;
  options.border_nodata_outside = true;
  const Dem reference = ReadDem(write("f64.tif", GDT_Float64), options);
  ASSERT_EQ(reference.heights_m.size(), stored.size());
  ASSERT_EQ(reference.nodata_mask.size(), stored.size());
  EXPECT_EQ(reference.nodata_mask[0], 1);
  EXPECT_EQ(reference.nodata_mask[2 * kW + 3], 1);
  EXPECT_EQ(reference.filled_nodata_cells, 1);
  for (size_t i = 3; i < stored.size(); ++i) {
    if (i == 2 * kW + 3) continue;
    EXPECT_EQ(reference.heights_m[i], static_cast<float>(stored[i] * 0.3048)) << i;
  }
  for (const auto& [name, type] : {std::pair{"i16.tif", GDT_Int16}, {"f32.tif", GDT_Float32}, {"i32.tif", GDT_Int32}}) {
    const Dem dem = ReadDem(write(name, type), options);
    EXPECT_EQ(dem.heights_m, reference.heights_m) << name;
    EXPECT_EQ(dem.nodata_mask, reference.nodata_mask) << name;
    EXPECT_EQ(dem.filled_nodata_cells, reference.filled_nodata_cells) << name;
    EXPECT_EQ(dem.vertical_unit_m, 0.3048) << name;
  }
  // Without a void the float values become the heights as they are.
  stored[0] = stored[1] = stored[2 * kW + 3] = 1500.0;
  const Dem whole_f32 = ReadDem(write("whole_f32.tif", GDT_Float32), options);
  const Dem whole_f64 = ReadDem(write("whole_f64.tif", GDT_Float64), options);
  EXPECT_EQ(whole_f32.heights_m, whole_f64.heights_m);
  EXPECT_TRUE(whole_f32.nodata_mask.empty());
  EXPECT_EQ(whole_f32.heights_m[0], static_cast<float>(1500.0 * 0.3048));
}

// A 2x2 Float32 DEM in UTM 31N holding `stored`, with the band unit `unit`
// ("" = none) and the CRS `crs` (any OGR definition).
std::string UnitDem(const std::filesystem::path& path, const std::vector<float>& stored, const char* unit,
                    const char* crs = "EPSG:32631") {
  GDALDataset* ds = CreateTestDem(path, 2, 2, GDT_Float32, crs);
  GDALRasterBand* band = ds->GetRasterBand(1);
  if (unit[0] != '\0') band->SetUnitType(unit);
  std::vector<float> h = stored;
  EXPECT_EQ(band->RasterIO(GF_Write, 0, 0, 2, 2, h.data(), 2, 2, GDT_Float32, 0, 0, nullptr), CE_None);
  GDALClose(ds);
  return path.string();
}

// Heights in feet become metres: 1 ft = 0.3048 m exactly, 1 US survey foot
// = 1200/3937 m; a unit the reader does not know is an error naming the way
// out; --vertical-units overrides the file.
TEST(DemTest, VerticalUnitsFromTheFileOrTheOptionBecomeMetres) {
  const auto dir = testing::MakeTempDir();
  const std::vector<float> stored = {0.0f, 100.0f, 1000.0f, 10000.0f};
  const Dem feet = ReadDem(UnitDem(dir / "ft.tif", stored, "ft"));
  EXPECT_FLOAT_EQ(feet.heights_m[1], 30.48f);
  EXPECT_FLOAT_EQ(feet.heights_m[3], 3048.0f);  // 10,000 ft: in range only once converted
  EXPECT_DOUBLE_EQ(feet.vertical_unit_m, 0.3048);
  EXPECT_EQ(feet.vertical_unit_source, "band unit type");

  const Dem us = ReadDem(UnitDem(dir / "us.tif", stored, "US survey foot"));
  EXPECT_NEAR(us.heights_m[2], 1000.0 * 1200.0 / 3937.0, 1e-3);

  const Dem metres = ReadDem(UnitDem(dir / "m.tif", stored, "metre"));
  EXPECT_FLOAT_EQ(metres.heights_m[3], 10000.0f);
  const Dem none = ReadDem(UnitDem(dir / "none.tif", stored, ""));
  EXPECT_FLOAT_EQ(none.heights_m[1], 100.0f);
  EXPECT_EQ(none.vertical_unit_source, "default (the file names no unit)");

  const std::string furlong = UnitDem(dir / "furlong.tif", stored, "furlong");
  try {
    ReadDem(furlong);
    ADD_FAILURE() << "an unknown unit must be an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'furlong'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--vertical-units"), std::string::npos) << e.what();
  }
  DemReadOptions as_metres;
  as_metres.vertical_units = "m";
  EXPECT_FLOAT_EQ(ReadDem(furlong, as_metres).heights_m[1], 100.0f);
  DemReadOptions as_feet;
  as_feet.vertical_units = "ft";
  EXPECT_FLOAT_EQ(ReadDem(UnitDem(dir / "m2.tif", stored, "m"), as_feet).heights_m[1], 30.48f);

  EXPECT_EQ(MetresPerVerticalUnit("Meters"), 1.0);
  EXPECT_EQ(MetresPerVerticalUnit("foot"), 0.3048);
  EXPECT_EQ(MetresPerVerticalUnit("ftUS"), 1200.0 / 3937.0);
  EXPECT_FALSE(MetresPerVerticalUnit("km").has_value());
}

// With no unit set on the band, a compound CRS's vertical axis gives the
// unit (EPSG:6360: NAVD88 height in US survey feet). GDAL's GeoTIFF driver
// reports it as the band's unit type (VerticalUnitsGeoKey), other drivers
// only in the CRS: either way the heights become metres.
TEST(DemTest, VerticalUnitOfACompoundCrs) {
  const auto dir = testing::MakeTempDir();
  const Dem dem = ReadDem(UnitDem(dir / "navd88ft.tif", {0.0f, 100.0f, 200.0f, 300.0f}, "", "EPSG:32631+6360"));
  EXPECT_TRUE(dem.vertical_unit_source == "vertical CRS" || dem.vertical_unit_source == "band unit type")
      << dem.vertical_unit_source;
  EXPECT_NEAR(dem.heights_m[1], 100.0 * 1200.0 / 3937.0, 1e-3);
  EXPECT_NEAR(dem.vertical_unit_m, 1200.0 / 3937.0, 1e-12);
}

TEST(DemTest, HeightsOutsideEarthsRangeAreUnmarkedNoData) {
  const auto dir = testing::MakeTempDir();
  std::vector<float> z = Flat(8);
  z[3] = -3.4028235e38f;
  z[9] = 29032.0f;  // Everest in feet
  WriteDemGeoTiff(dir / "dem.tif", z, 8, 8, {0.0, 30.0, 0.0, 0.0, 0.0, -30.0}, "EPSG:32631");
  EXPECT_NE(ReadDemError(dir / "dem.tif").find("DEM has 2 heights outside [-12000, 10000] m"),
            std::string::npos);
}

TEST(DemTest, MemoryBudgetIsCheckedFromTheHeader) {
  const auto dir = testing::MakeTempDir();
  WriteDemGeoTiff(dir / "dem.tif", Flat(64), 64, 64, {0.0, 30.0, 0.0, 0.0, 0.0, -30.0}, "EPSG:32631");
  DemReadOptions options;
  options.bytes_per_post = 256;
  options.max_bytes = 1 << 20;  // 64 x 64 x 256 B = 1 MiB: just fits
  EXPECT_EQ(ReadDemError(dir / "dem.tif", options), "");
  options.max_bytes = (1 << 20) - 1;
  EXPECT_EQ(ReadDemError(dir / "dem.tif", options),
            "DEM of 64x64 posts needs about 1.0 MiB, over the memory limit of 1024 KiB (--max-memory); "
            "use a window of it or resample it to coarser posts");
}

TEST(DemTest, ReadsGdalVirtualFiles) {
  const auto dir = testing::MakeTempDir();
  WriteDemGeoTiff(dir / "dem.tif", Flat(8), 8, 8, {0.0, 30.0, 0.0, 0.0, 0.0, -30.0}, "EPSG:32631");
  std::ifstream in(dir / "dem.tif", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  VSILFILE* f = VSIFileFromMemBuffer("/vsimem/dem_test.tif", reinterpret_cast<GByte*>(bytes.data()),
                                     bytes.size(), FALSE);
  ASSERT_NE(f, nullptr);
  VSIFCloseL(f);
  EXPECT_EQ(ReadDem("/vsimem/dem_test.tif").width, 8);
  VSIUnlink("/vsimem/dem_test.tif");
  EXPECT_NE(ReadDemError("/vsimem/absent.tif").find("not a raster"), std::string::npos);
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

// DemFile opens the raster once: with the file gone from the directory
// after opening, its header, bounds and any window still read, equal to
// what ReadDemInfo/ReadDem gave before.
TEST(DemTest, DemFileOpensOnceAndReadsAsOftenAsNeeded) {
  const auto dir = testing::MakeTempDir();
  std::vector<float> z(64);
  for (int i = 0; i < 64; ++i) z[i] = 100.0f + float(i);  // 100 .. 163 m
  WriteDemGeoTiff(dir / "dem.tif", z, 8, 8, {0.0, 30.0, 0.0, 0.0, 0.0, -30.0}, "EPSG:32631");
  DemReadOptions window;
  window.window = std::array<int, 4>{2, 3, 4, 2};
  const Dem expected_window = ReadDem(dir / "dem.tif", window);
  const DemFile file(dir / "dem.tif");
  std::filesystem::remove(dir / "dem.tif");
  const DemInfo info = file.Info();
  EXPECT_EQ(info.width, 8);
  EXPECT_EQ(info.height, 8);
  EXPECT_DOUBLE_EQ(info.min_height_m, 100.0);
  EXPECT_DOUBLE_EQ(info.max_height_m, 163.0);
  for (int pass = 0; pass < 2; ++pass) {
    const Dem part = file.Read(window);
    ASSERT_EQ(part.width, 4);
    ASSERT_EQ(part.height, 2);
    EXPECT_EQ(part.heights_m, expected_window.heights_m);
    EXPECT_DOUBLE_EQ(part.HeightAt(0, 0), 100.0 + 3 * 8 + 2);  // row 3, column 2
  }
  EXPECT_EQ(file.Read().heights_m.size(), 64u);
  EXPECT_THROW(DemFile(dir / "dem.tif"), InputError);  // gone: a new open fails
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

TEST(DemTest, RefinementKeepsThePostsAndReproducesQuadraticSurfaces) {
  // Cubic convolution with Keys' boundary rule is exact for quadratics,
  // including the cross term and beyond the edges; a sheared geotransform
  // checks that the refined posts stay on the original grid lines.
  auto quadratic = [](double x, double y) { return 100.0 + 2.0 * x + 3.0 * y + 0.5 * x * x - 0.25 * x * y + 0.1 * y * y; };
  Dem dem;
  dem.source = "quadratic";
  dem.width = 7;
  dem.height = 5;
  dem.geotransform = {1000.0, 30.0, 4.0, 2000.0, -3.0, -25.0};
  for (int r = 0; r < dem.height; ++r) {
    for (int c = 0; c < dem.width; ++c) dem.heights_m.push_back(static_cast<float>(quadratic(c, r)));
  }
  const Dem fine = RefineDem(dem, 4, 1000000);
  ASSERT_EQ(fine.width, 25);
  ASSERT_EQ(fine.height, 17);
  for (int r = 0; r < fine.height; ++r) {
    for (int c = 0; c < fine.width; ++c) {
      EXPECT_NEAR(fine.HeightAt(c, r), quadratic(c / 4.0, r / 4.0), 2e-4) << c << "," << r;
      EXPECT_NEAR((fine.MapFromPost(c, r) - dem.MapFromPost(c / 4.0, r / 4.0)).norm(), 0.0, 1e-9);
    }
  }
  for (int r = 0; r < dem.height; ++r) {
    for (int c = 0; c < dem.width; ++c) EXPECT_EQ(fine.HeightAt(4 * c, 4 * r), dem.HeightAt(c, r));
  }
  EXPECT_EQ(RefineDem(dem, 1, 1000000).heights_m, dem.heights_m);
  EXPECT_THROW(RefineDem(dem, 0, 1000000), ConfigError);
  EXPECT_THROW(RefineDem(dem, kMaxDemOversample + 1, 1000000), ConfigError);
  EXPECT_THROW(RefineDem(dem, 4, 424), InputError);  // 25 x 17 = 425 posts
}

}  // namespace
}  // namespace gissar::geo

namespace gissar::geo {
namespace {

double ShoelaceArea(const PostRing& ring) {
  double twice = 0.0;
  for (size_t i = 0; i + 1 < ring.size(); ++i) {
    twice += ring[i].x() * ring[i + 1].y() - ring[i + 1].x() * ring[i].y();
  }
  return 0.5 * std::abs(twice);
}

// A ramp rising one metre per post eastwards, and a tilted one: the outline
// follows the interpolated contour, not the post grid.
TEST(DemTest, LowlandPolygonsFollowTheContour) {
  Dem dem;
  dem.width = 11;
  dem.height = 11;
  dem.heights_m.resize(121);
  for (int r = 0; r < 11; ++r)
    for (int c = 0; c < 11; ++c) dem.heights_m[size_t(r) * 11 + c] = static_cast<float>(c);
  // h <= 2.5: columns from the raster edge (-0.5) to 2.5, all 11 rows (-0.5 .. 10.5).
  auto lowland = LowlandPolygons(dem, 2.5);
  ASSERT_EQ(lowland.size(), 1u);
  ASSERT_EQ(lowland[0].size(), 1u);
  EXPECT_NEAR(ShoelaceArea(lowland[0][0]), 3.0 * 11.0, 1e-4);  // GDAL nudges exact level hits
  // h = c + 0.5 r <= 4: the line c = 4 - 0.5 r crosses the grid obliquely.
  for (int r = 0; r < 11; ++r)
    for (int c = 0; c < 11; ++c) dem.heights_m[size_t(r) * 11 + c] = static_cast<float>(c + 0.5 * r);
  lowland = LowlandPolygons(dem, 4.0);
  ASSERT_EQ(lowland.size(), 1u);
  const PostRing& ring = lowland[0][0];
  // Every outline point inside the post span lies on the contour c + 0.5 r = 4.
  int on_contour = 0;
  for (const auto& p : ring) {
    if (p.x() > 0.0 && p.x() < 10.0 && p.y() > 0.0 && p.y() < 10.0) {
      EXPECT_NEAR(p.x() + 0.5 * p.y(), 4.0, 1e-4) << p.transpose();
      ++on_contour;
    }
  }
  EXPECT_GE(on_contour, 8);
  // Nothing that low, and everything low.
  EXPECT_TRUE(LowlandPolygons(dem, -1.0).empty());
  const auto all = LowlandPolygons(dem, 100.0);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_NEAR(ShoelaceArea(all[0][0]), 121.0, 1e-9);
}

}  // namespace
}  // namespace gissar::geo
