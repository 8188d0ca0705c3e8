#include "gissar/geo/raster_io.h"

#include <gtest/gtest.h>

#include <gdal_priv.h>

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

TEST(RasterIoTest, WritingIntoMissingDirectoryIsAnIoError) {
  FloatRaster raster{2, 2, {std::vector<float>(4)}, {}, {}};
  EXPECT_THROW(WriteFloatGeoTiff("/nonexistent/dir/x.tif", raster), IoError);
}

}  // namespace
}  // namespace gissar::geo
