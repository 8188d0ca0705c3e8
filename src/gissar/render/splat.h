// Bilinear splatting of a return into an image plane, shared by the
// renderers (internal to the render module).
#pragma once

#include <vector>

namespace gissar::render {

// Adds `value` at fractional pixel (col, row) of the row-major `plane`
// (width x height) with bilinear weights over the four neighbouring pixel
// centres; with `amplitude` the weights are square-rooted (coherent
// amplitudes keep the power split). Parts falling outside the plane are
// dropped. The plane must hold width * height values.
void SplatBilinear(std::vector<float>& plane, int width, int height, double col, double row, float value,
                   bool amplitude = false);

// Widest box footprint SplatBox spreads (pixels); wider boxes are narrowed
// to it (their value is kept).
inline constexpr double kMaxBoxWidthPx = 64.0;

// Most shares FootprintShares returns.
inline constexpr int kMaxShares = static_cast<int>(kMaxBoxWidthPx) + 4;

// Shares of the pixels c = *first, *first + 1, ... of a footprint of width
// w (pixels) centred at x: the box [x - w/2, x + w/2] integrated against
// each pixel's bilinear (tent) weight max(0, 1 - |u - c|), divided by w.
// They sum to 1; a width of 0 gives the bilinear weights of the point x;
// boxes that tile a line give every pixel a total weight of 1 (the tents
// are a partition of unity). Returns their count (<= kMaxShares); w is
// capped at kMaxBoxWidthPx.
int FootprintShares(double x, double w, int* first, double* share);

// Adds `value` spread uniformly over the box footprint [col - wc/2,
// col + wc/2] x [row - wr/2, row + wr/2] (pixels) with the separable
// FootprintShares: area integration of the bilinear splat, so boxes that
// tile a surface's image cover every pixel of it evenly, and a vanishing
// box is the bilinear splat of its centre. `plane` holds rows [row0, row0 + rows) of a
// width-column image. When a touched row lies outside those rows: with
// `clip` the parts outside are dropped, otherwise nothing is added and the
// function returns false.
bool SplatBox(float* plane, int width, int row0, int rows, double col, double row, double wc, double wr,
              float value, bool clip);

// SplatBox of the same value into `count` planes at once (each laid out as
// SplatBox's `plane`): the shares are computed once, and every plane gets
// exactly the sums SplatBox would give it.
bool SplatBoxPlanes(float* const* planes, int count, int width, int row0, int rows, double col, double row,
                    double wc, double wr, float value, bool clip);

}  // namespace gissar::render
