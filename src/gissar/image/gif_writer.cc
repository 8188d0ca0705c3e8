#include "gissar/image/gif_writer.h"

#include <gif_lib.h>

#include <cerrno>
#include <cstring>

#include "gissar/util/atomic_output.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::image {

void WriteAnimatedGif(const std::filesystem::path& path, const std::vector<std::vector<uint8_t>>& frames,
                      int width, int height, int delay_cs) {
  GISSAR_CHECK(!frames.empty());
  int error = 0;
  GifFileType* gif = EGifOpenFileName(path.c_str(), false, &error);
  if (gif == nullptr) throw WriteError(std::string("cannot create GIF: ") + GifErrorString(error), path, errno);
  // A full disk says so, naming the output (util's WriteError).
  auto fail = [&](const char* what) {
    const int write_error = errno;
    int close_error = 0;
    EGifCloseFile(gif, &close_error);
    throw WriteError(std::string("failed writing GIF: ") + what, path, write_error);
  };
  GifColorType grey[256];
  for (int i = 0; i < 256; ++i) grey[i] = {static_cast<GifByteType>(i), static_cast<GifByteType>(i), static_cast<GifByteType>(i)};
  ColorMapObject* palette = GifMakeMapObject(256, grey);
  EGifSetGifVersion(gif, true);
  if (EGifPutScreenDesc(gif, width, height, 8, 0, palette) == GIF_ERROR) {
    GifFreeMapObject(palette);
    fail("screen descriptor");
  }
  GifFreeMapObject(palette);
  // NETSCAPE2.0 application extension: loop forever.
  const GifByteType netscape[] = {'N', 'E', 'T', 'S', 'C', 'A', 'P', 'E', '2', '.', '0'};
  const GifByteType loop[] = {1, 0, 0};
  if (EGifPutExtensionLeader(gif, APPLICATION_EXT_FUNC_CODE) == GIF_ERROR ||
      EGifPutExtensionBlock(gif, sizeof(netscape), netscape) == GIF_ERROR ||
      EGifPutExtensionBlock(gif, sizeof(loop), loop) == GIF_ERROR || EGifPutExtensionTrailer(gif) == GIF_ERROR) {
    fail("loop extension");
  }
  std::vector<GifPixelType> line(width);
  for (const auto& frame : frames) {
    GISSAR_CHECK(frame.size() == size_t(width) * height);
    GraphicsControlBlock gcb;
    gcb.DisposalMode = DISPOSE_DO_NOT;
    gcb.UserInputFlag = false;
    gcb.DelayTime = delay_cs;
    gcb.TransparentColor = NO_TRANSPARENT_COLOR;
    GifByteType extension[4];
    EGifGCBToExtension(&gcb, extension);
    if (EGifPutExtension(gif, GRAPHICS_EXT_FUNC_CODE, 4, extension) == GIF_ERROR ||
        EGifPutImageDesc(gif, 0, 0, width, height, false, nullptr) == GIF_ERROR) {
      fail("frame header");
    }
    for (int r = 0; r < height; ++r) {
      std::memcpy(line.data(), frame.data() + size_t(r) * width, width);
      if (EGifPutLine(gif, line.data(), width) == GIF_ERROR) fail("frame data");
    }
  }
  errno = 0;
  if (EGifCloseFile(gif, &error) == GIF_ERROR) {
    throw WriteError(std::string("failed closing GIF: ") + GifErrorString(error), path, errno);
  }
  // giflib creates the file owner-only (0600); give it ordinary permissions.
  std::error_code ec;
  std::filesystem::permissions(path,
                               std::filesystem::perms::owner_read | std::filesystem::perms::owner_write |
                                   std::filesystem::perms::group_read | std::filesystem::perms::others_read,
                               ec);
}

}  // namespace gissar::image
