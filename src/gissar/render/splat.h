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

}  // namespace gissar::render
