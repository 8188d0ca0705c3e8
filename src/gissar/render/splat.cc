#include "gissar/render/splat.h"

#include <cmath>
#include <cstddef>

namespace gissar::render {

void SplatBilinear(std::vector<float>& plane, int width, int height, double col, double row, float value,
                   bool amplitude) {
  const double c0f = std::floor(col), r0f = std::floor(row);
  const int c0 = static_cast<int>(c0f), r0 = static_cast<int>(r0f);
  const float fc = static_cast<float>(col - c0f), fr = static_cast<float>(row - r0f);
  float w[2][2] = {{(1 - fr) * (1 - fc), (1 - fr) * fc}, {fr * (1 - fc), fr * fc}};
  if (amplitude) {
    for (auto& line : w)
      for (float& x : line) x = std::sqrt(x);
  }
  for (int dr = 0; dr < 2; ++dr) {
    const int r = r0 + dr;
    if (r < 0 || r >= height) continue;
    for (int dc = 0; dc < 2; ++dc) {
      const int c = c0 + dc;
      if (c < 0 || c >= width) continue;
      plane[size_t(r) * width + c] += value * w[dr][dc];
    }
  }
}

}  // namespace gissar::render
