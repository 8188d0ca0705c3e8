// Display products of radar images.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace gissar::image {

struct DbStretch {
  double low_db = 0.0;   // maps to grey 1
  double high_db = 0.0;  // maps to grey 255
};

// Robust dB stretch of a linear intensity image: 10 log10(I) of the pixels
// with I > 0 is mapped linearly from its `low_percentile` (grey 1) to its
// `high_percentile` (grey 255), clipped; pixels with I <= 0 or not finite
// (no return, shadow) are 0. Percentiles in [0, 100], low < high. When no
// pixel is positive every grey value is 0 and the stretch is {0, 0}.
std::vector<uint8_t> DbQuicklook(std::span<const float> intensity, double low_percentile,
                                 double high_percentile, DbStretch* stretch = nullptr);

// The same mapping with a given stretch (e.g. the first frame's, so that a
// sequence shares one grey scale).
std::vector<uint8_t> DbQuicklookWithStretch(std::span<const float> intensity, const DbStretch& stretch);

// What Multilook does with a NaN pixel: skips it (the mean of the block's
// finite pixels) or counts it as 0 (no return; a block of no-data is then 0).
enum class NanPixels { kSkip, kAsZero };

// Block average (multilook) of a rows x cols row-major image by la rows x lr
// columns (la, lr >= 1): output (rows / la) x (cols / lr), partial blocks at
// the end dropped, NaN pixels as `nan` says, infinite ones skipped; a block
// without a pixel counted is NaN. Output pixel (r, c) sits at input position
// (r la + (la - 1) / 2, c lr + (lr - 1) / 2).
std::vector<float> Multilook(std::span<const float> image, int rows, int cols, int la, int lr,
                             NanPixels nan = NanPixels::kSkip);

}  // namespace gissar::image
