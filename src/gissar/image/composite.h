// Green/magenta composites: two co-registered images in one picture, e.g. a
// registered (warped) moving image over the fixed one, or a real image over
// the simulation of the same pose. Where both agree the composite is grey;
// green where only the first image is bright, magenta where only the second.
#pragma once

#include <cstdint>
#include <vector>

#include "gissar/image/class_map.h"

namespace gissar::image {

// RGB = (magenta, green, magenta) of two 8-bit grey images of the same size
// (width x height, row-major). CHECKs the sizes.
RgbImage GreenMagentaComposite(const std::vector<uint8_t>& green, const std::vector<uint8_t>& magenta,
                               int width, int height);

// The composite of two linear-intensity images (same size): each one is
// dB-stretched on its own (DbQuicklook, 2nd to 98th percentile) so that a
// radiometric offset between them (a real image and a simulation of it)
// does not tint the picture. CHECKs the sizes.
RgbImage IntensityComposite(const std::vector<float>& green, const std::vector<float>& magenta, int width,
                            int height);

}  // namespace gissar::image
