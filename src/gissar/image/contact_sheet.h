// Contact sheets: several grey images tiled in a grid with a caption each.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gissar/image/class_map.h"

namespace gissar::image {

// Tiles `frames` (grey, each width x height) left to right, top to bottom
// in ceil(sqrt(n)) columns, 4 px apart on white, with `captions[i]` drawn
// under frame i. CHECKs sizes and that there are as many captions as frames.
RgbImage ContactSheet(const std::vector<std::vector<uint8_t>>& frames, int width, int height,
                      const std::vector<std::string>& captions);

// Places RGB panels side by side (top-aligned, 8 px apart) with a title over
// each, e.g. the line-of-sight view, the SAR image and the G_perp view.
RgbImage SideBySide(const std::vector<RgbImage>& panels, const std::vector<std::string>& titles);

// Grey image -> RGB image.
RgbImage GreyToRgb(const std::vector<uint8_t>& grey, int width, int height);

}  // namespace gissar::image
