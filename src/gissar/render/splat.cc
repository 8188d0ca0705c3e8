#include "gissar/render/splat.h"

#include <algorithm>
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

namespace {

// Integral of the unit tent max(0, 1 - |u|) from -inf to u.
double TentIntegral(double u) {
  if (u <= -1.0) return 0.0;
  if (u <= 0.0) return 0.5 * (u + 1.0) * (u + 1.0);
  if (u <= 1.0) return 1.0 - 0.5 * (1.0 - u) * (1.0 - u);
  return 1.0;
}

}  // namespace

int FootprintShares(double x, double w, int* first, double* share) {
  w = std::min(w, kMaxBoxWidthPx);
  if (!(w > 1e-6)) {  // a point: the bilinear weights
    const double f = std::floor(x);
    *first = static_cast<int>(f);
    share[0] = 1.0 - (x - f);
    share[1] = x - f;
    return 2;
  }
  const double x0 = x - 0.5 * w, x1 = x + 0.5 * w;
  if (w <= 1.0) {
    // A box inside one unit interval [k, k + 1]: the tents of k and k + 1
    // are linear there, so their means over the box are their values at its
    // centre (the bilinear weights of x).
    const double k = std::floor(x0);
    if (std::floor(x1) == k) {
      *first = static_cast<int>(k);
      share[0] = 1.0 - (x - k);
      share[1] = x - k;
      return 2;
    }
  }
  const int c0 = static_cast<int>(std::ceil(x0 - 1.0)), c1 = static_cast<int>(std::floor(x1 + 1.0));
  *first = c0;
  int n = 0;
  for (int c = c0; c <= c1; ++c) {
    const double v = (TentIntegral(x1 - c) - TentIntegral(x0 - c)) / w;
    share[n++] = v > 1e-9 ? v : 0.0;  // rounding residues of 1 - 1
  }
  return n;
}

bool SplatBoxPlanes(float* const* planes, int count, int width, int row0, int rows, double col, double row,
                    double wc, double wr, float value, bool clip) {
  double col_share[kMaxShares], row_share[kMaxShares];
  int c_first = 0, r_first = 0;
  const int nc = FootprintShares(col, wc, &c_first, col_share);
  const int nr = FootprintShares(row, wr, &r_first, row_share);
  if (!clip && (r_first < row0 || r_first + nr > row0 + rows)) {
    // Shares of zero at the ends do not count.
    int lo = 0, hi = nr - 1;
    while (lo < nr && row_share[lo] == 0.0) ++lo;
    while (hi >= 0 && row_share[hi] == 0.0) --hi;
    if (lo > hi) return true;
    if (r_first + lo < row0 || r_first + hi >= row0 + rows) return false;
  }
  for (int i = 0; i < nr; ++i) {
    const int r = r_first + i;
    if (r < row0 || r >= row0 + rows || row_share[i] == 0.0) continue;
    const size_t line = size_t(r - row0) * width;
    for (int k = 0; k < nc; ++k) {
      const int c = c_first + k;
      if (c < 0 || c >= width) continue;
      const float v = static_cast<float>(value * row_share[i] * col_share[k]);
      for (int p = 0; p < count; ++p) planes[p][line + c] += v;
    }
  }
  return true;
}

bool SplatBox(float* plane, int width, int row0, int rows, double col, double row, double wc, double wr,
              float value, bool clip) {
  return SplatBoxPlanes(&plane, 1, width, row0, rows, col, row, wc, wr, value, clip);
}

}  // namespace gissar::render
