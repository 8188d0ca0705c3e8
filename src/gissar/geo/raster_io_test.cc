#include "gissar/geo/raster_io.h"

#include <gtest/gtest.h>

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

TEST(RasterIoTest, WritingIntoMissingDirectoryIsAnIoError) {
  FloatRaster raster{2, 2, {std::vector<float>(4)}, {}, {}};
  EXPECT_THROW(WriteFloatGeoTiff("/nonexistent/dir/x.tif", raster), IoError);
}

}  // namespace
}  // namespace gissar::geo
