#include "gissar/scene/fractal_terrain.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "gissar/util/error.h"

namespace gissar::scene {
namespace {

FractalTerrainOptions Options(int width, int height, uint64_t seed = 1) {
  FractalTerrainOptions o;
  o.width = width;
  o.height = height;
  o.seed = seed;
  return o;
}

TEST(FractalTerrainTest, SpansExactlyTheRequestedRelief) {
  FractalTerrainOptions o = Options(300, 200);
  o.relief_m = 750.0;
  o.base_m = 120.0;
  const std::vector<float> h = FractalHeights(o);
  ASSERT_EQ(h.size(), 300u * 200u);
  const auto [lo, hi] = std::minmax_element(h.begin(), h.end());
  EXPECT_NEAR(*lo, 120.0f, 1e-4f);
  EXPECT_NEAR(*hi, 870.0f, 1e-4f);
}

TEST(FractalTerrainTest, SameSeedSameHeightsOtherSeedOtherHeights) {
  const std::vector<float> a = FractalHeights(Options(129, 64, 7));
  const std::vector<float> b = FractalHeights(Options(129, 64, 7));
  const std::vector<float> c = FractalHeights(Options(129, 64, 8));
  EXPECT_EQ(a, b);
  size_t differing = 0;
  for (size_t i = 0; i < a.size(); ++i) differing += a[i] != c[i];
  EXPECT_GT(differing, a.size() * 9 / 10);
}

TEST(FractalTerrainTest, GridIsTheCornerOfItsTile) {
  // A 100 x 60 grid is the top-left corner of the 128 x 128 tile: the same
  // heights as the 128 x 128 grid, up to the rescaling to [base, base+relief].
  const std::vector<float> full = FractalHeights(Options(128, 128, 3));
  const std::vector<float> part = FractalHeights(Options(100, 60, 3));
  double lo = 1e9, hi = -1e9;
  for (int r = 0; r < 60; ++r)
    for (int c = 0; c < 100; ++c) {
      lo = std::min<double>(lo, full[size_t(r) * 128 + c]);
      hi = std::max<double>(hi, full[size_t(r) * 128 + c]);
    }
  for (int r = 0; r < 60; r += 7) {
    for (int c = 0; c < 100; c += 9) {
      const double expected = (full[size_t(r) * 128 + c] - lo) / (hi - lo) * 1000.0;
      EXPECT_NEAR(part[size_t(r) * 100 + c], expected, 0.05);
    }
  }
}

// Midpoint displacement with amplitudes shrinking by 2^-H per halving of
// the scale makes the height differences self-affine: their variance over a
// lag L grows like L^(2H), i.e. multiplying the lag by 4 multiplies it by
// 4^(2H). (Averaging the parents smooths the finest levels a little, a known
// bias of diamond-square: the measured exponent sits up to ~0.1 below H for
// smooth terrain.) Rougher settings must measure rougher.
TEST(FractalTerrainTest, HeightDifferencesScaleWithTheHurstExponent) {
  double previous = 0.0;
  for (double hurst : {0.5, 0.8}) {
    FractalTerrainOptions o = Options(1024, 1024, 11);
    o.hurst = hurst;
    const std::vector<float> h = FractalHeights(o);
    auto variance = [&](int lag) {
      double sum = 0;
      int64_t count = 0;
      for (int r = 0; r < 1024; ++r)
        for (int c = 0; c + lag < 1024; ++c) {
          const double d = double(h[size_t(r) * 1024 + c + lag]) - h[size_t(r) * 1024 + c];
          sum += d * d;
          ++count;
        }
      return sum / count;
    };
    const double exponent = std::log2(variance(32) / variance(8)) / 2.0 / 2.0;
    EXPECT_NEAR(exponent, hurst, 0.12) << "H = " << hurst;
    EXPECT_GT(exponent, previous + 0.15) << "H = " << hurst;
    previous = exponent;
  }
}

TEST(FractalTerrainTest, RejectsBadOptions) {
  EXPECT_THROW(FractalHeights(Options(1, 10)), ConfigError);
  EXPECT_THROW(FractalHeights(Options(10, 20000)), ConfigError);
  FractalTerrainOptions o = Options(16, 16);
  o.hurst = 0.0;
  EXPECT_THROW(o.Check(), ConfigError);
  o.hurst = 0.5;
  o.relief_m = -1.0;
  EXPECT_THROW(o.Check(), ConfigError);
}

}  // namespace
}  // namespace gissar::scene
