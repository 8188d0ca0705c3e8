#include "gissar/pipeline/views.h"

#include <gif_lib.h>
#include <gtest/gtest.h>

#include "gissar/geo/raster_io.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

SimulateRequest Andorra(const fs::path& dir) {
  SimulateRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = 200.0;
  o.geometry.azimuth_spacing_m = 200.0;
  o.out_prefix = (dir / "seq").string();
  return o;
}

TEST(SequenceTest, RendersEveryHeadingFromOneSceneBuild) {
  const fs::path dir = testing::MakeTempDir();
  SequenceRequest o;
  o.base = Andorra(dir);
  o.heading_from_deg = 0;
  o.heading_to_deg = 30;
  o.frames = 4;
  const SequenceResult result = RunSequence(o, "test");
  EXPECT_EQ(result.outputs.size(), 4u * 2u + 3u);
  EXPECT_EQ(result.frame_seconds.size(), 4u);
  // Frames share one size and carry their own heading.
  const auto f0 = geo::ReadFloatRaster(dir / "seq_f00.tif");
  const auto f3 = geo::ReadFloatRaster(dir / "seq_f03.tif");
  EXPECT_EQ(f0.width, f3.width);
  EXPECT_EQ(f0.height, f3.height);
  EXPECT_EQ(f0.metadata.at("GISSAR_HEADING_DEG"), "0");
  EXPECT_EQ(f3.metadata.at("GISSAR_HEADING_DEG"), "30");
  EXPECT_EQ(f0.metadata.at("GISSAR_DEPRESSION_DEG"), f3.metadata.at("GISSAR_DEPRESSION_DEG"));
  EXPECT_NE(f0.bands[0], f3.bands[0]);
  int error = 0;
  GifFileType* gif = DGifOpenFileName((dir / "seq.gif").c_str(), &error);
  ASSERT_NE(gif, nullptr);
  ASSERT_EQ(DGifSlurp(gif), GIF_OK);
  EXPECT_EQ(gif->ImageCount, 4);
  EXPECT_EQ(gif->SWidth, f0.width);
  DGifCloseFile(gif, &error);
  EXPECT_TRUE(fs::exists(dir / "seq_contact.png"));
}

TEST(SequenceTest, RejectsTooFewFrames) {
  SequenceRequest o;
  o.base = Andorra(testing::MakeTempDir());
  o.frames = 1;
  EXPECT_THROW(o.Check(), ConfigError);
}

TEST(OrthoTest, WritesTheTrio) {
  const fs::path dir = testing::MakeTempDir();
  OrthoRequest o;
  o.base = Andorra(dir);
  o.base.out_prefix = (dir / "ortho").string();
  o.base.geometry.heading_deg = 30;
  const auto outputs = RunOrtho(o, "test");
  ASSERT_EQ(outputs.size(), 5u);
  int w = 0, h = 0, ws = 0, hs = 0;
  geo::ReadByteRaster(dir / "ortho_gperp.png", &w, &h);
  geo::ReadByteRaster(dir / "ortho_sar.png", &ws, &hs);
  // G_perp uses the SAR image's pixel grid.
  EXPECT_EQ(w, ws);
  EXPECT_EQ(h, hs);
}

}  // namespace
}  // namespace gissar::pipeline
