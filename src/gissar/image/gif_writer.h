// Animated GIF output (giflib) for heading sequences.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace gissar::image {

// Writes 8-bit grey frames (each width x height, row-major) as a looping
// animated GIF with `delay_cs` hundredths of a second per frame. Throws
// IoError naming the path on failure; CHECKs that frames have the size.
void WriteAnimatedGif(const std::filesystem::path& path, const std::vector<std::vector<uint8_t>>& frames,
                      int width, int height, int delay_cs);

}  // namespace gissar::image
