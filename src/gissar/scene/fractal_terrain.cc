#include "gissar/scene/fractal_terrain.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "gissar/util/error.h"

namespace gissar::scene {
namespace {

// SplitMix64 finaliser of (seed, level, index): a uniform value in [-1, 1).
double Uniform(uint64_t seed, uint64_t level, uint64_t index) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (index * 64 + level + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return double(z >> 11) * 0x1.0p-52 - 1.0;
}

}  // namespace

void FractalTerrainOptions::Check() const {
  constexpr int kMaxSide = 16384;
  if (width < 2 || height < 2 || width > kMaxSide || height > kMaxSide) {
    throw ConfigError("fractal terrain size must be in [2, 16384] posts per side, got " +
                          std::to_string(width) + " x " + std::to_string(height),
                      "width/height");
  }
  if (!(hurst > 0.0 && hurst <= 1.0)) throw ConfigError("Hurst exponent must be in (0, 1]", "hurst");
  if (!(relief_m > 0.0) || !std::isfinite(relief_m)) throw ConfigError("relief must be positive", "relief_m");
  if (!std::isfinite(base_m)) throw ConfigError("base height must be finite", "base_m");
}

std::vector<float> FractalHeights(const FractalTerrainOptions& options) {
  options.Check();
  int n = 2;
  while (n < std::max(options.width, options.height)) n *= 2;
  // Periodic tile of n x n posts (indices wrap), built coarse to fine.
  std::vector<double> tile(size_t(n) * n, 0.0);
  auto at = [&](int r, int c) -> double& { return tile[size_t(r & (n - 1)) * n + (c & (n - 1))]; };
  // Uniform in [-1, 1) has variance 1/3: sqrt(3) makes the displacement of
  // unit variance at the coarsest scale.
  const double unit = std::sqrt(3.0);
  double scale = unit;
  uint64_t level = 0;
  for (int step = n; step > 1; step /= 2, ++level) {
    const int half = step / 2;
    // Diamond step: square centres from their four corners.
    for (int r = half; r < n; r += step) {
      for (int c = half; c < n; c += step) {
        const double mean = 0.25 * (at(r - half, c - half) + at(r - half, c + half) +
                                    at(r + half, c - half) + at(r + half, c + half));
        at(r, c) = mean + scale * Uniform(options.seed, level, uint64_t(r) * n + c);
      }
    }
    // Square step: edge midpoints from their four diamond neighbours.
    for (int r = 0; r < n; r += half) {
      for (int c = (r / half) % 2 == 0 ? half : 0; c < n; c += step) {
        const double mean =
            0.25 * (at(r - half, c) + at(r + half, c) + at(r, c - half) + at(r, c + half));
        at(r, c) = mean + scale * Uniform(options.seed, level, uint64_t(r) * n + c);
      }
    }
    scale *= std::pow(0.5, options.hurst);
  }
  double lo = tile[0], hi = tile[0];
  for (int r = 0; r < options.height; ++r) {
    for (int c = 0; c < options.width; ++c) {
      lo = std::min(lo, tile[size_t(r) * n + c]);
      hi = std::max(hi, tile[size_t(r) * n + c]);
    }
  }
  const double gain = hi > lo ? options.relief_m / (hi - lo) : 0.0;
  std::vector<float> heights(size_t(options.width) * options.height);
  for (int r = 0; r < options.height; ++r) {
    for (int c = 0; c < options.width; ++c) {
      heights[size_t(r) * options.width + c] =
          static_cast<float>(options.base_m + (tile[size_t(r) * n + c] - lo) * gain);
    }
  }
  return heights;
}

}  // namespace gissar::scene
