#include "gissar/image/side_by_side.h"

#include <algorithm>
#include <cmath>

#include "gissar/util/check.h"

namespace gissar::image {

std::vector<uint8_t> SideBySide(const std::vector<std::vector<uint8_t>>& images, int width, int height, int gap,
                                int* out_width) {
  GISSAR_CHECK(!images.empty() && width > 0 && height > 0 && gap >= 0);
  const int n = static_cast<int>(images.size());
  const int w = n * width + (n - 1) * gap;
  std::vector<uint8_t> strip(size_t(w) * height, 255);
  for (int k = 0; k < n; ++k) {
    GISSAR_CHECK(images[k].size() == size_t(width) * height);
    for (int r = 0; r < height; ++r) {
      std::copy_n(images[k].begin() + size_t(r) * width, width, strip.begin() + size_t(r) * w + k * (width + gap));
    }
  }
  if (out_width != nullptr) *out_width = w;
  return strip;
}

std::vector<uint8_t> HistogramPlot(const std::vector<float>& values, double low, double high, int bins,
                                   int plot_width, int plot_height, std::vector<int64_t>* counts) {
  GISSAR_CHECK(bins >= 1 && low < high && plot_width >= bins && plot_height >= 2);
  std::vector<int64_t> count(bins, 0);
  for (float v : values) {
    if (!std::isfinite(v) || v < low || v > high) continue;
    const int b = std::min(bins - 1, static_cast<int>((v - low) / (high - low) * bins));
    ++count[b];
  }
  const int64_t peak = std::max<int64_t>(1, *std::max_element(count.begin(), count.end()));
  std::vector<uint8_t> img(size_t(plot_width) * plot_height, 255);
  for (int x = 0; x < plot_width; ++x) {
    const int b = std::min(bins - 1, x * bins / plot_width);
    const int bar = static_cast<int>(std::lround(double(count[b]) / double(peak) * (plot_height - 1)));
    for (int y = plot_height - bar; y < plot_height; ++y) img[size_t(y) * plot_width + x] = 40;
  }
  if (low < 0.0 && high > 0.0) {
    const int x0 = static_cast<int>((0.0 - low) / (high - low) * plot_width);
    for (int y = 0; y < plot_height; ++y) {
      uint8_t& p = img[size_t(y) * plot_width + std::min(x0, plot_width - 1)];
      p = p == 255 ? 160 : 110;
    }
  }
  if (counts != nullptr) *counts = count;
  return img;
}

}  // namespace gissar::image
