#include "gissar/image/gif_writer.h"

#include <gif_lib.h>
#include <gtest/gtest.h>

#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::image {
namespace {

TEST(GifWriterTest, WritesEveryFrameLosslessly) {
  const auto path = testing::MakeTempDir() / "seq.gif";
  std::vector<std::vector<uint8_t>> frames;
  for (int f = 0; f < 3; ++f) {
    std::vector<uint8_t> frame(20 * 10);
    for (size_t i = 0; i < frame.size(); ++i) frame[i] = static_cast<uint8_t>((i * 7 + f * 50) % 256);
    frames.push_back(frame);
  }
  WriteAnimatedGif(path, frames, 20, 10, 40);
  int error = 0;
  GifFileType* gif = DGifOpenFileName(path.c_str(), &error);
  ASSERT_NE(gif, nullptr);
  ASSERT_EQ(DGifSlurp(gif), GIF_OK);
  ASSERT_EQ(gif->ImageCount, 3);
  for (int f = 0; f < 3; ++f) {
    const SavedImage& image = gif->SavedImages[f];
    ColorMapObject* map = gif->SColorMap;
    for (int i = 0; i < 200; ++i) {
      EXPECT_EQ(map->Colors[image.RasterBits[i]].Red, frames[f][i]);
    }
    GraphicsControlBlock gcb;
    DGifSavedExtensionToGCB(gif, f, &gcb);
    EXPECT_EQ(gcb.DelayTime, 40);
  }
  DGifCloseFile(gif, &error);
}

TEST(GifWriterTest, UnwritablePathIsAnIoError) {
  EXPECT_THROW(WriteAnimatedGif("/nonexistent/dir/x.gif", {std::vector<uint8_t>(4)}, 2, 2, 10), IoError);
}

// `sequence` writes PREFIX.gif under a temporary name: on a full disk the
// error says so and names PREFIX.gif (the failure injected by making the
// temporary a link to /dev/full, which fails every write with ENOSPC).
TEST(GifWriterTest, AFullDiskSaysNoSpaceLeftNamingTheOutput) {
  const std::filesystem::path dir = testing::MakeTempDir();
  AtomicOutputs outputs;
  const std::filesystem::path temp = outputs.Add(dir / "seq.gif");
  std::filesystem::create_symlink("/dev/full", temp);
  try {
    WriteAnimatedGif(temp, {std::vector<uint8_t>(64 * 64, 9), std::vector<uint8_t>(64 * 64, 200)}, 64, 64, 10);
    ADD_FAILURE() << "expected IoError";
  } catch (const IoError& e) {
    const std::string expected = ": no space left on the device holding " + dir.string();
    ASSERT_GE(e.message().size(), expected.size()) << e.message();
    EXPECT_EQ(e.message().substr(e.message().size() - expected.size()), expected) << e.message();
    EXPECT_EQ(e.message().rfind("failed ", 0), 0u) << e.message();
    EXPECT_EQ(e.where(), (dir / "seq.gif").string());
  }
}

}  // namespace
}  // namespace gissar::image
