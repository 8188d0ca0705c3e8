// Synthetic fractal terrain for benchmarks and tests: periodic
// diamond-square midpoint displacement, seeded and platform-independent
// (every random number is a hash of the seed and the post, so the heights do
// not depend on the standard library or on evaluation order).
#pragma once

#include <cstdint>
#include <vector>

namespace gissar::scene {

struct FractalTerrainOptions {
  int width = 1024;   // posts per row, >= 2
  int height = 1024;  // rows, >= 2
  // Hurst exponent in (0, 1]: the displacement added at scale s is
  // proportional to s^hurst, so height differences over a lag L have a
  // standard deviation growing like L^hurst (larger = smoother).
  double hurst = 0.8;
  double relief_m = 1000.0;  // highest minus lowest height, metres, > 0
  double base_m = 0.0;       // lowest height, metres (finite)
  uint64_t seed = 1;

  // Throws ConfigError naming the field when a value is out of range (sizes
  // above 16384 posts per side are refused).
  void Check() const;
};

// Heights (metres, row-major, width x height) of a diamond-square terrain
// generated on the smallest power-of-two square tile holding the grid (its
// top-left corner is the grid), rescaled so that the lowest post is exactly
// base_m and the highest exactly base_m + relief_m (up to float rounding).
// The same options give the same heights on every platform. Calls Check().
std::vector<float> FractalHeights(const FractalTerrainOptions& options);

}  // namespace gissar::scene
