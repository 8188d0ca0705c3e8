// Comparison pictures of two radar images of the same grid: a side-by-side
// strip and a histogram of their differences.
#pragma once

#include <cstdint>
#include <vector>

namespace gissar::image {

// Places grey images (each width x height, row-major, 1 byte per pixel)
// left to right with `gap` columns of white between them; returns the
// strip (grey, (n * width + (n - 1) * gap) x height). Every image must have
// width * height bytes (CHECK).
std::vector<uint8_t> SideBySide(const std::vector<std::vector<uint8_t>>& images, int width, int height,
                                int gap, int* out_width);

// A histogram of `values` (non-finite ones skipped) over [low, high] in
// `bins` bars, drawn as a grey image of plot_width x plot_height: dark bars
// on white, bar heights scaled to the fullest bin, a vertical mid-grey line
// at value 0 when 0 lies inside the range. Returns the bin counts in
// `counts` when given. bins >= 1, low < high (CHECK).
std::vector<uint8_t> HistogramPlot(const std::vector<float>& values, double low, double high, int bins,
                                   int plot_width, int plot_height, std::vector<int64_t>* counts = nullptr);

}  // namespace gissar::image
