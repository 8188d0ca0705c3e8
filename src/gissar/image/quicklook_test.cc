#include "gissar/image/quicklook.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

namespace gissar::image {
namespace {

TEST(QuicklookTest, StretchesDecibelsBetweenPercentiles) {
  // Intensities 10^0 .. 10^10: 0 .. 100 dB in 10 dB steps, plus a shadow pixel.
  std::vector<float> intensity;
  for (int i = 0; i <= 10; ++i) intensity.push_back(static_cast<float>(std::pow(10.0, i)));
  intensity.push_back(0.0f);
  DbStretch stretch;
  const auto grey = DbQuicklook(intensity, 0.0, 100.0, &stretch);
  EXPECT_NEAR(stretch.low_db, 0.0, 1e-4);
  EXPECT_NEAR(stretch.high_db, 100.0, 1e-3);
  EXPECT_EQ(grey[0], 1);
  EXPECT_EQ(grey[5], 1 + 127);  // 50 dB: halfway, 254 * 0.5 = 127
  EXPECT_EQ(grey[10], 255);
  EXPECT_EQ(grey[11], 0);       // no return stays black
}

TEST(QuicklookTest, ClipsOutsideThePercentiles) {
  std::vector<float> intensity(100, 1.0f);
  intensity[0] = 1e-6f;
  intensity[1] = 1e6f;
  for (int i = 2; i < 100; ++i) intensity[i] = 1.0f + i * 0.01f;
  const auto grey = DbQuicklook(intensity, 2.0, 98.0);
  EXPECT_EQ(grey[0], 1);
  EXPECT_EQ(grey[1], 255);
}

TEST(QuicklookTest, AllDarkImageIsBlack) {
  const auto grey = DbQuicklook(std::vector<float>(10, 0.0f), 2.0, 98.0);
  for (uint8_t g : grey) EXPECT_EQ(g, 0);
}

// The stretch and every grey level equal their definition evaluated
// directly (sorting the positive values for the percentiles, a logarithm
// per pixel): speckle-like intensities over 60 dB with ties, zeros, NaN and
// infinities, for several percentile pairs.
TEST(QuicklookTest, MatchesTheDefinitionPixelByPixel) {
  std::mt19937 rng(5);
  std::lognormal_distribution<float> speckle(0.0f, 2.0f);
  std::vector<float> intensity;
  for (int i = 0; i < 200000; ++i) {
    const int kind = int(rng() % 50);
    if (kind == 0) intensity.push_back(0.0f);
    else if (kind == 1) intensity.push_back(std::numeric_limits<float>::quiet_NaN());
    else if (kind == 2) intensity.push_back(std::numeric_limits<float>::infinity());
    else if (kind == 3) intensity.push_back(0.25f);  // ties
    else intensity.push_back(1e-3f * speckle(rng));
  }
  for (const auto& [low, high] : {std::pair{2.0, 98.0}, std::pair{0.0, 100.0}, std::pair{10.0, 60.0}}) {
    std::vector<float> positive;
    for (float v : intensity) {
      if (std::isfinite(v) && v > 0.0f) positive.push_back(v);
    }
    std::sort(positive.begin(), positive.end());
    auto at = [&](double p) { return positive[size_t(std::llround(p / 100.0 * double(positive.size() - 1)))]; };
    const double low_db = 10.0f * std::log10(at(low)), high_db = 10.0f * std::log10(at(high));
    DbStretch stretch;
    const std::vector<uint8_t> grey = DbQuicklook(intensity, low, high, &stretch);
    EXPECT_EQ(stretch.low_db, low_db);
    EXPECT_EQ(stretch.high_db, high_db);
    const double span = high_db - low_db;
    for (size_t i = 0; i < intensity.size(); ++i) {
      const float v = intensity[i];
      uint8_t want = 0;
      if (std::isfinite(v) && v > 0.0f) {
        want = uint8_t(1 + std::lround(254.0 * std::clamp((10.0 * std::log10(v) - low_db) / span, 0.0, 1.0)));
      }
      ASSERT_EQ(grey[i], want) << i << " " << v;
    }
  }
}

TEST(MultilookTest, BlockMeansSkipNaNAndDropPartialBlocks) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // 5 rows x 7 cols; 2 x 3 looks -> 2 x 2 (the last row and column dropped).
  std::vector<float> image = {1, 2, 3, 4, 5, 6, 100,   //
                              4, 5, 6, 7, nan, 9, 100,  //
                              0, 0, 0, nan, nan, nan, 100,  //
                              6, 6, 6, nan, nan, nan, 100,  //
                              100, 100, 100, 100, 100, 100, 100};
  const std::vector<float> out = Multilook(image, 5, 7, 2, 3);
  ASSERT_EQ(out.size(), 4u);
  EXPECT_FLOAT_EQ(out[0], 21.0f / 6.0f);
  EXPECT_FLOAT_EQ(out[1], 31.0f / 5.0f);
  EXPECT_FLOAT_EQ(out[2], 3.0f);
  EXPECT_TRUE(std::isnan(out[3]));
}

TEST(MultilookTest, NaNCountsAsZeroWhenAskedAndInfinityIsSkippedEitherWay) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  // 2 x 4, 2 x 2 looks -> 1 x 2: block 0 holds 1, 2, 3 and a NaN; block 1
  // two NaN, an infinity and 6.
  const std::vector<float> image = {1, 2, nan, 6,  //
                                    3, nan, nan, inf};
  const std::vector<float> skip = Multilook(image, 2, 4, 2, 2);
  const std::vector<float> zero = Multilook(image, 2, 4, 2, 2, NanPixels::kAsZero);
  ASSERT_EQ(zero.size(), 2u);
  EXPECT_FLOAT_EQ(skip[0], 6.0f / 3.0f);
  EXPECT_FLOAT_EQ(skip[1], 6.0f);
  EXPECT_FLOAT_EQ(zero[0], 6.0f / 4.0f);  // the NaN is a fourth pixel of 0
  EXPECT_FLOAT_EQ(zero[1], 6.0f / 3.0f);  // two zeros and 6; the infinity left out
  // A block of NaN only: 0 (no return), not NaN.
  EXPECT_EQ(Multilook(std::vector<float>{nan, nan}, 1, 2, 1, 2, NanPixels::kAsZero)[0], 0.0f);
}

}  // namespace
}  // namespace gissar::image
