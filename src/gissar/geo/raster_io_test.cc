#include "gissar/geo/raster_io.h"

#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cerrno>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>

#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::geo {
namespace {

TEST(RasterIoTest, FloatGeoTiffRoundTripsBandsAndMetadata) {
  const auto dir = testing::MakeTempDir();
  FloatRaster raster;
  raster.width = 5;
  raster.height = 3;
  raster.bands = {std::vector<float>(15), std::vector<float>(15, 2.5f)};
  for (int i = 0; i < 15; ++i) raster.bands[0][i] = 0.1f * i;
  raster.band_names = {"total", "single"};
  raster.metadata = {{"GISSAR_HEADING_DEG", "30"}};
  WriteFloatGeoTiff(dir / "x.tif", raster);
  const FloatRaster back = ReadFloatRaster(dir / "x.tif");
  EXPECT_EQ(back.width, 5);
  EXPECT_EQ(back.height, 3);
  ASSERT_EQ(back.bands.size(), 2u);
  EXPECT_EQ(back.bands[0], raster.bands[0]);
  EXPECT_EQ(back.band_names[1], "single");
  EXPECT_EQ(back.metadata.at("GISSAR_HEADING_DEG"), "30");
}

TEST(RasterIoTest, ByteGeoTiffAndPngRoundTrip) {
  const auto dir = testing::MakeTempDir();
  std::vector<uint8_t> mask = {0, 1, 2, 3, 0, 1};
  WriteByteGeoTiff(dir / "m.tif", mask, 3, 2, {});
  int w = 0, h = 0;
  EXPECT_EQ(ReadByteRaster(dir / "m.tif", &w, &h), mask);
  EXPECT_EQ(w, 3);
  WritePng(dir / "q.png", mask, 3, 2, 1);
  EXPECT_EQ(ReadByteRaster(dir / "q.png", &w, &h), mask);
  EXPECT_FALSE(std::filesystem::exists(dir / "q.png.aux.xml"));
}

// The PNG encoder (libpng, Up filter): grey, RGB and RGBA pictures of
// seeded random bytes (every filter difference wraps somewhere) read back
// through GDAL exactly, band by band.
TEST(RasterIoTest, PngRoundTripsGreyRgbAndRgba) {
  const auto dir = testing::MakeTempDir();
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> byte(0, 255);
  const int w = 37, h = 23;
  for (const int channels : {1, 3, 4}) {
    std::vector<uint8_t> data(size_t(w) * h * channels);
    for (uint8_t& v : data) v = static_cast<uint8_t>(byte(rng));
    const auto path = dir / ("p" + std::to_string(channels) + ".png");
    WritePng(path, data, w, h, channels);
    const FloatRaster back = ReadFloatRaster(path);
    ASSERT_EQ(back.width, w);
    ASSERT_EQ(back.height, h);
    ASSERT_EQ(back.bands.size(), size_t(channels));
    for (int c = 0; c < channels; ++c) {
      for (size_t p = 0; p < size_t(w) * h; ++p) {
        ASSERT_EQ(back.bands[size_t(c)][p], float(data[p * channels + c])) << channels << " " << c << " " << p;
      }
    }
  }
}

TEST(RasterIoTest, GeoreferencingUnitsAndCategoriesAreWritten) {
  const auto dir = testing::MakeTempDir();
  Georeference g;
  g.gcps = {{0.5, 0.5, 1.5, 42.5, 1000.0}, {3.5, 0.5, 1.6, 42.5, 1100.0}, {0.5, 2.5, 1.5, 42.4, 900.0}};
  FloatRaster raster{4, 3, {std::vector<float>(12, 1.0f)}, {"total"}, {}};
  raster.band_units = {"linear intensity"};
  raster.georeference = g;
  WriteFloatGeoTiff(dir / "f.tif", raster);
  const Georeference back = ReadGeoreference(dir / "f.tif");
  ASSERT_EQ(back.gcps.size(), 3u);
  EXPECT_DOUBLE_EQ(back.gcps[1].pixel, 3.5);
  EXPECT_DOUBLE_EQ(back.gcps[1].lon_deg, 1.6);
  EXPECT_DOUBLE_EQ(back.gcps[2].lat_deg, 42.4);
  EXPECT_DOUBLE_EQ(back.gcps[1].height_m, 1100.0);
  WriteByteGeoTiff(dir / "m.tif", std::vector<uint8_t>(12, 1), 4, 3, {}, {},
                   ByteCategories{{"none", "layover"}, {{0, 0, 0, 0}, {255, 0, 0, 255}}});
  GDALDataset* f = GDALDataset::Open((dir / "f.tif").c_str());
  ASSERT_NE(f, nullptr);
  EXPECT_STREQ(f->GetRasterBand(1)->GetUnitType(), "linear intensity");
  EXPECT_NE(std::string(f->GetGCPSpatialRef() ? "srs" : ""), "");
  GDALClose(f);
  GDALDataset* m = GDALDataset::Open((dir / "m.tif").c_str());
  ASSERT_NE(m, nullptr);
  ASSERT_NE(m->GetRasterBand(1)->GetMetadataItem("CATEGORY_1"), nullptr);
  EXPECT_STREQ(m->GetRasterBand(1)->GetMetadataItem("CATEGORY_1"), "layover");
  EXPECT_FALSE(std::filesystem::exists(dir / "m.tif.aux.xml"));
  ASSERT_NE(m->GetRasterBand(1)->GetColorTable(), nullptr);
  EXPECT_EQ(m->GetRasterBand(1)->GetColorTable()->GetColorEntry(1)->c1, 255);
  GDALClose(m);
}

std::string Layout(GDALDataset* ds) {
  const char* layout = ds->GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE");
  return layout != nullptr ? layout : "";
}

TEST(RasterIoTest, LargeFloatRasterIsACogWithOverviewsAndKeepsEverything) {
  const auto dir = testing::MakeTempDir();
  constexpr int kW = 2048, kH = 1500;
  FloatRaster raster;
  raster.width = kW;
  raster.height = kH;
  raster.bands = {std::vector<float>(size_t(kW) * kH, 1.0f), std::vector<float>(size_t(kW) * kH, 2.0f)};
  // Top-left 2x2 block of band 1: NaN, 3, 5, 7 -> AVERAGE overview pixel (3+5+7)/3 = 5.
  raster.bands[0][0] = std::numeric_limits<float>::quiet_NaN();
  raster.bands[0][1] = 3.0f;
  raster.bands[0][kW] = 5.0f;
  raster.bands[0][kW + 1] = 7.0f;
  raster.band_names = {"total", "lon"};
  raster.band_units = {"linear intensity", "degree"};
  raster.metadata = {{"GISSAR_HEADING_DEG", "30"}, {"GISSAR_SENSOR", "test"}};
  raster.nodata_nan = true;
  raster.georeference.gcps = {{0.5, 0.5, 1.5, 42.5, 1000.0}, {2047.5, 0.5, 1.6, 42.5, 1100.0},
                              {0.5, 1499.5, 1.5, 42.4, 900.0}};
  // A complete RPC set (GDAL writes the RPC tag only for a parsable model).
  const std::string unit_numerator = "1 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";
  const std::string lon_numerator = "0 1 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0";
  raster.georeference.rpc = {{"LINE_OFF", "750"},      {"SAMP_OFF", "1024"},     {"LAT_OFF", "42.45"},
                             {"LONG_OFF", "1.55"},     {"HEIGHT_OFF", "1000"},   {"LINE_SCALE", "750"},
                             {"SAMP_SCALE", "1024"},   {"LAT_SCALE", "0.05"},    {"LONG_SCALE", "0.05"},
                             {"HEIGHT_SCALE", "500"},  {"LINE_NUM_COEFF", unit_numerator},
                             {"LINE_DEN_COEFF", unit_numerator}, {"SAMP_NUM_COEFF", lon_numerator},
                             {"SAMP_DEN_COEFF", unit_numerator}};
  raster.georeference.geolocation = LonLatGeolocation(2, 2);
  WriteFloatGeoTiff(dir / "big.tif", raster);
  // Only the file itself: the COG driver's temporary overviews stayed in memory.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 1);

  GDALDataset* ds = GDALDataset::Open((dir / "big.tif").c_str());
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(Layout(ds), "COG");
  GDALRasterBand* b1 = ds->GetRasterBand(1);
  // 2048x1500 -> 1024x750 -> 512x375 (halving until both sides <= 512).
  ASSERT_EQ(b1->GetOverviewCount(), 2);
  EXPECT_EQ(b1->GetOverview(0)->GetXSize(), 1024);
  EXPECT_EQ(b1->GetOverview(1)->GetYSize(), 375);
  float corner = 0.0f;
  ASSERT_EQ(b1->GetOverview(0)->RasterIO(GF_Read, 0, 0, 1, 1, &corner, 1, 1, GDT_Float32, 0, 0, nullptr), CE_None);
  EXPECT_FLOAT_EQ(corner, 5.0f);
  EXPECT_EQ(ds->GetGCPCount(), 3);
  ASSERT_NE(ds->GetGCPSpatialRef(), nullptr);
  EXPECT_STREQ(ds->GetGCPSpatialRef()->GetAuthorityCode(nullptr), "4326");
  int block_w = 0, block_h = 0;
  b1->GetBlockSize(&block_w, &block_h);
  EXPECT_EQ(block_w, 512);
  const Metadata geolocation = raster.georeference.geolocation;
  for (const auto& [key, value] : geolocation) {
    ASSERT_NE(ds->GetMetadataItem(key.c_str(), "GEOLOCATION"), nullptr) << key;
    EXPECT_EQ(ds->GetMetadataItem(key.c_str(), "GEOLOCATION"), value) << key;
  }
  EXPECT_EQ(ds->GetMetadataItem("GISSAR_GEOLOCATION_RESERVED"), nullptr);
  GDALClose(ds);

  const Georeference g = ReadGeoreference(dir / "big.tif");
  ASSERT_EQ(g.gcps.size(), 3u);
  EXPECT_DOUBLE_EQ(g.gcps[1].pixel, 2047.5);
  EXPECT_DOUBLE_EQ(g.gcps[1].lon_deg, 1.6);
  EXPECT_DOUBLE_EQ(g.gcps[2].lat_deg, 42.4);
  EXPECT_DOUBLE_EQ(g.gcps[1].height_m, 1100.0);
  // Every RPC item reads back with the same numbers (GDAL reformats them and
  // adds ERR_BIAS/ERR_RAND).
  auto numbers = [](const std::string& text) {
    std::istringstream in(text);
    std::vector<double> v;
    for (double x; in >> x;) v.push_back(x);
    return v;
  };
  for (const auto& [key, value] : raster.georeference.rpc) {
    ASSERT_EQ(g.rpc.count(key), 1u) << key;
    EXPECT_EQ(numbers(g.rpc.at(key)), numbers(value)) << key;
  }
  const FloatRaster back = ReadFloatRaster(dir / "big.tif");
  EXPECT_EQ(back.width, kW);
  EXPECT_EQ(back.height, kH);
  ASSERT_EQ(back.bands.size(), 2u);
  EXPECT_TRUE(std::isnan(back.bands[0][0]));
  EXPECT_EQ(back.bands[0][kW + 1], 7.0f);
  EXPECT_EQ(back.bands[1], raster.bands[1]);
  EXPECT_EQ(back.band_names, raster.band_names);
  EXPECT_EQ(back.band_units, raster.band_units);
  EXPECT_TRUE(back.nodata_nan);
  EXPECT_EQ(back.metadata.at("GISSAR_HEADING_DEG"), "30");
  EXPECT_EQ(back.metadata.at("GISSAR_SENSOR"), "test");
  EXPECT_EQ(back.metadata.count("GISSAR_GEOLOCATION_RESERVED"), 0u);
  EXPECT_TRUE(back.geotransform.empty());
}

// Overviews of an odd-sized COG: every level's pixel is the mean of the
// finite base pixels of its block (not the mean of the means below it), and
// the last, partial blocks average what they cover.
TEST(RasterIoTest, CogFloatOverviewsAreMeansOfTheFiniteBasePixels) {
  const auto dir = testing::MakeTempDir();
  constexpr int kW = 1101, kH = 1030;  // -> 551 x 515 -> 276 x 258
  const float nan = std::numeric_limits<float>::quiet_NaN();
  FloatRaster raster;
  raster.width = kW;
  raster.height = kH;
  raster.bands = {std::vector<float>(size_t(kW) * kH, 1.0f)};
  std::vector<float>& v = raster.bands[0];
  // Top-left 4 x 4 block: 1 .. 16 row by row, with 1, 2 and 5 NaN: the
  // factor-4 pixel is (136 - 8) / 13, the factor-2 pixel of its first 2 x 2
  // block is 6.
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) v[size_t(r) * kW + c] = float(4 * r + c + 1);
  }
  v[0] = v[1] = v[kW] = nan;
  // Last column (1100): the factor-2 pixel (0, 550) covers (0, 1100) = 8 and
  // (1, 1100) = NaN only.
  v[1100] = 8.0f;
  v[size_t(kW) + 1100] = nan;
  raster.nodata_nan = true;
  WriteFloatGeoTiff(dir / "odd.tif", raster);
  GDALDataset* ds = GDALDataset::Open((dir / "odd.tif").c_str());
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(Layout(ds), "COG");
  GDALRasterBand* b = ds->GetRasterBand(1);
  ASSERT_EQ(b->GetOverviewCount(), 2);
  EXPECT_EQ(b->GetOverview(0)->GetXSize(), 551);
  EXPECT_EQ(b->GetOverview(0)->GetYSize(), 515);
  EXPECT_EQ(b->GetOverview(1)->GetXSize(), 276);
  EXPECT_EQ(b->GetOverview(1)->GetYSize(), 258);
  auto pixel = [&](int level, int x, int y) {
    float value = 0.0f;
    EXPECT_EQ(b->GetOverview(level)->RasterIO(GF_Read, x, y, 1, 1, &value, 1, 1, GDT_Float32, 0, 0, nullptr), CE_None);
    return value;
  };
  EXPECT_FLOAT_EQ(pixel(0, 0, 0), 6.0f);
  EXPECT_FLOAT_EQ(pixel(1, 0, 0), 128.0f / 13.0f);
  EXPECT_FLOAT_EQ(pixel(0, 550, 0), 8.0f);
  EXPECT_FLOAT_EQ(pixel(0, 100, 100), 1.0f);
  EXPECT_FLOAT_EQ(pixel(1, 275, 257), 1.0f);
  GDALClose(ds);
}

TEST(RasterIoTest, LargeMapRasterKeepsGeotransformAndCrs) {
  const auto dir = testing::MakeTempDir();
  FloatRaster raster{1100, 40, {std::vector<float>(1100 * 40, 0.5f)}, {"gamma0"}, {}};
  raster.geotransform = {500000.0, 10.0, 0.0, 4700000.0, 0.0, -10.0};
  raster.crs = "EPSG:32631";
  WriteFloatGeoTiff(dir / "map.tif", raster);
  GDALDataset* ds = GDALDataset::Open((dir / "map.tif").c_str());
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(Layout(ds), "COG");  // 1100 > 1024 on one side is enough
  EXPECT_EQ(ds->GetRasterBand(1)->GetOverviewCount(), 2);  // 550x20, 275x10
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  EXPECT_DOUBLE_EQ(gt[0], 500000.0);
  EXPECT_DOUBLE_EQ(gt[5], -10.0);
  ASSERT_NE(ds->GetSpatialRef(), nullptr);
  EXPECT_STREQ(ds->GetSpatialRef()->GetAuthorityCode(nullptr), "32631");
  GDALClose(ds);
}

TEST(RasterIoTest, SmallRasterIsAPlainTiledGeoTiffWithoutOverviews) {
  const auto dir = testing::MakeTempDir();
  FloatRaster raster{1024, 1024, {std::vector<float>(1024 * 1024, 1.0f)}, {"total"}, {}};
  raster.georeference.geolocation = LonLatGeolocation(1, 1);
  WriteFloatGeoTiff(dir / "small.tif", raster);
  GDALDataset* ds = GDALDataset::Open((dir / "small.tif").c_str());
  ASSERT_NE(ds, nullptr);
  EXPECT_NE(Layout(ds), "COG");
  EXPECT_EQ(ds->GetRasterBand(1)->GetOverviewCount(), 0);
  EXPECT_STREQ(ds->GetMetadataItem("X_BAND", "GEOLOCATION"), "1");
  GDALClose(ds);
}

TEST(RasterIoTest, LargeMaskKeepsColourTableAndCategoriesWithNearestOverviews) {
  const auto dir = testing::MakeTempDir();
  constexpr int kW = 1500, kH = 1200;
  std::vector<uint8_t> mask(size_t(kW) * kH, 0);
  // Top-left 2x2 block 1,2 / 2,2: NEAREST keeps a class value (1), never an average.
  mask[0] = 1;
  mask[1] = 2;
  mask[kW] = 2;
  mask[kW + 1] = 2;
  WriteByteGeoTiff(dir / "m.tif", mask, kW, kH, {{"GISSAR_KIND", "classes"}}, {},
                   ByteCategories{{"none", "layover", "shadow"}, {{0, 0, 0, 255}, {255, 0, 0, 255}, {0, 0, 255, 255}}});
  GDALDataset* m = GDALDataset::Open((dir / "m.tif").c_str());
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(Layout(m), "COG");
  GDALRasterBand* band = m->GetRasterBand(1);
  ASSERT_EQ(band->GetOverviewCount(), 2);  // 750x600, 375x300
  uint8_t corner = 0;
  ASSERT_EQ(band->GetOverview(0)->RasterIO(GF_Read, 0, 0, 1, 1, &corner, 1, 1, GDT_Byte, 0, 0, nullptr), CE_None);
  EXPECT_TRUE(corner == 1 || corner == 2) << int(corner);
  EXPECT_STREQ(band->GetMetadataItem("CATEGORY_2"), "shadow");
  EXPECT_STREQ(m->GetMetadataItem("GISSAR_KIND"), "classes");
  ASSERT_NE(band->GetColorTable(), nullptr);
  EXPECT_EQ(band->GetColorTable()->GetColorEntry(2)->c3, 255);
  EXPECT_EQ(band->GetColorInterpretation(), GCI_PaletteIndex);
  GDALClose(m);
  int w = 0, h = 0;
  EXPECT_EQ(ReadByteRaster(dir / "m.tif", &w, &h), mask);
}

TEST(RasterIoTest, LargeComplexRasterIsACfloat32Cog) {
  const auto dir = testing::MakeTempDir();
  constexpr int kW = 1030, kH = 8;
  std::vector<float> re(size_t(kW) * kH, 1.0f), im(size_t(kW) * kH, -2.0f);
  re[3] = 4.0f;
  WriteComplexGeoTiff(dir / "slc.tif", re, im, kW, kH, {{"GISSAR_MODE", "coherent"}}, "amplitude");
  GDALDataset* ds = GDALDataset::Open((dir / "slc.tif").c_str());
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(Layout(ds), "COG");
  GDALRasterBand* band = ds->GetRasterBand(1);
  EXPECT_EQ(band->GetRasterDataType(), GDT_CFloat32);
  EXPECT_EQ(band->GetOverviewCount(), 2);  // 515x4, 257x2
  EXPECT_STREQ(band->GetDescription(), "slc");
  EXPECT_STREQ(band->GetUnitType(), "amplitude");
  EXPECT_STREQ(ds->GetMetadataItem("GISSAR_MODE"), "coherent");
  float z[2] = {0, 0};
  ASSERT_EQ(band->RasterIO(GF_Read, 3, 0, 1, 1, z, 1, 1, GDT_CFloat32, 0, 0, nullptr), CE_None);
  EXPECT_EQ(z[0], 4.0f);
  EXPECT_EQ(z[1], -2.0f);
  GDALClose(ds);
}

TEST(RasterIoTest, WritingIntoMissingDirectoryIsAnIoError) {
  FloatRaster raster{2, 2, {std::vector<float>(4)}, {}, {}};
  EXPECT_THROW(WriteFloatGeoTiff("/nonexistent/dir/x.tif", raster), IoError);
  FloatRaster large{1100, 2, {std::vector<float>(2200)}, {}, {}};
  EXPECT_THROW(WriteFloatGeoTiff("/nonexistent/dir/x.tif", large), IoError);
}

// A full disk is named as such, with the directory of the output, instead
// of GDAL's "IO error writing tag data". /dev/full fails every write with
// ENOSPC, as a full file system does.
TEST(RasterIoTest, AFullDiskSaysNoSpaceLeft) {
  ASSERT_TRUE(std::filesystem::exists("/dev/full"));
  auto error_of = [](const std::function<void()>& write) -> std::string {
    try {
      write();
    } catch (const IoError& e) {
      EXPECT_EQ(e.where(), "/dev/full");
      return e.message();
    }
    return "no error";
  };
  const std::string expected = "no space left on the device holding /dev";
  FloatRaster small{4, 3, {std::vector<float>(12, 1.0f)}, {}, {}};
  EXPECT_EQ(error_of([&] { WriteFloatGeoTiff("/dev/full", small); }), "failed writing raster: " + expected);
  FloatRaster large{1100, 1100, {std::vector<float>(1100 * 1100, 2.0f)}, {}, {}};  // a COG
  EXPECT_EQ(error_of([&] { WriteFloatGeoTiff("/dev/full", large); }), "failed writing raster: " + expected);
  EXPECT_EQ(error_of([&] { WriteByteGeoTiff("/dev/full", std::vector<uint8_t>(12, 1), 4, 3, {}); }),
            "failed writing raster: " + expected);
  const std::vector<float> re(12, 1.0f), im(12, 0.5f);
  EXPECT_EQ(error_of([&] { WriteComplexGeoTiff("/dev/full", re, im, 4, 3, {}); }),
            "failed writing raster: " + expected);
  EXPECT_EQ(error_of([&] { WritePng("/dev/full", std::vector<uint8_t>(12 * 3, 7), 4, 3, 3); }),
            "failed writing PNG: " + expected);
  // The test itself: errno ENOSPC or EDQUOT; other errors on a disk with
  // room are not a full disk.
  const std::filesystem::path dir = testing::MakeTempDir();
  EXPECT_TRUE(OutOfSpace(ENOSPC, dir / "x.tif"));
  EXPECT_TRUE(OutOfSpace(EDQUOT, dir / "x.tif"));
  EXPECT_FALSE(OutOfSpace(EACCES, dir / "x.tif"));
  EXPECT_FALSE(OutOfSpace(ENOENT, "/nonexistent/dir/x.tif"));
  EXPECT_EQ(NoSpaceMessage(dir / "sub" / ".." / "x.tif"), "no space left on the device holding " + dir.string());
}

// Outputs are written under temporary names (AtomicOutputs): a full disk
// names the output the user asked for, not ".gs-...tmp". The failure is
// injected by making each temporary a link to /dev/full.
TEST(RasterIoTest, AFullDiskNamesTheOutputNotItsTemporary) {
  const std::filesystem::path dir = testing::MakeTempDir();
  AtomicOutputs outputs;
  auto full = [&](const std::string& name) {
    const std::filesystem::path temp = outputs.Add(dir / name);
    std::filesystem::create_symlink("/dev/full", temp);
    return temp;
  };
  auto error_of = [](const std::function<void()>& write) -> IoError {
    try {
      write();
    } catch (const IoError& e) {
      return e;
    }
    return IoError("no error", "");
  };
  const std::string expected = "no space left on the device holding " + dir.string();
  const std::filesystem::path tif = full("sim.tif");
  IoError e = error_of([&] { WriteFloatGeoTiff(tif, FloatRaster{4, 3, {std::vector<float>(12, 1.0f)}, {}, {}}); });
  EXPECT_EQ(e.message(), "failed writing raster: " + expected);
  EXPECT_EQ(e.where(), (dir / "sim.tif").string());
  const std::filesystem::path png = full("sim.png");
  e = error_of([&] { WritePng(png, std::vector<uint8_t>(12, 7), 4, 3, 1); });
  EXPECT_EQ(e.message(), "failed writing PNG: " + expected);
  EXPECT_EQ(e.where(), (dir / "sim.png").string());
  const std::filesystem::path mask = full("sim_mask.tif");
  e = error_of([&] { WriteByteGeoTiff(mask, std::vector<uint8_t>(12, 1), 4, 3, {}); });
  EXPECT_EQ(e.message(), "failed writing raster: " + expected);
  EXPECT_EQ(e.where(), (dir / "sim_mask.tif").string());
}

}  // namespace
}  // namespace gissar::geo
