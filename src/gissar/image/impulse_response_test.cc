#include "gissar/image/impulse_response.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "gissar/util/error.h"

namespace gissar::image {
namespace {

TEST(ImpulseResponseTest, KernelHalfPowerWidthIsTheResolution) {
  for (auto window : {SpectralWindow::kNone, SpectralWindow::kHamming, SpectralWindow::kTaylor}) {
    for (double res : {2.0, 3.0, 4.5}) {
      const auto k = IntensityImpulseResponse(res, window);
      EXPECT_NEAR(std::accumulate(k.begin(), k.end(), 0.0), 1.0, 1e-12);
      EXPECT_NEAR(HalfPowerWidth(k), res, 0.05 * res) << ToString(window) << " " << res;
    }
  }
}

TEST(ImpulseResponseTest, WindowsLowerTheSidelobes) {
  // Peak sidelobe of sinc^2 is -13.3 dB; Hamming about -43 dB.
  auto peak_sidelobe_db = [](const std::vector<double>& k) {
    const size_t c = k.size() / 2;
    size_t i = c;
    while (i + 1 < k.size() && k[i + 1] < k[i]) ++i;  // first null
    const double side = *std::max_element(k.begin() + i, k.end());
    return 10 * std::log10(side / k[c]);
  };
  EXPECT_NEAR(peak_sidelobe_db(IntensityImpulseResponse(8.0, SpectralWindow::kNone)), -13.3, 0.5);
  EXPECT_LT(peak_sidelobe_db(IntensityImpulseResponse(8.0, SpectralWindow::kHamming)), -38.0);
  EXPECT_LT(peak_sidelobe_db(IntensityImpulseResponse(8.0, SpectralWindow::kTaylor)), -30.0);
}

// A point target's 3 dB width equals the configured resolution (5 %) in
// both axes; total power is preserved.
TEST(ImpulseResponseTest, PointTargetWidthMatchesResolution) {
  // Big enough for the +-12 resolution kernel tails to stay inside.
  const int w = 160, h = 200;
  std::vector<float> image(size_t(w) * h, 0.0f);
  image[size_t(100) * w + 50] = 1000.0f;
  ApplyImpulseResponse(image, w, h, 3.0, 5.0, SpectralWindow::kNone);
  std::vector<double> row(w), col(h);
  for (int c = 0; c < w; ++c) row[c] = image[size_t(100) * w + c];
  for (int r = 0; r < h; ++r) col[r] = image[size_t(r) * w + 50];
  EXPECT_NEAR(HalfPowerWidth(row), 3.0, 0.15);
  EXPECT_NEAR(HalfPowerWidth(col), 5.0, 0.25);
  EXPECT_NEAR(std::accumulate(image.begin(), image.end(), 0.0), 1000.0, 1.0);
  EXPECT_EQ(std::max_element(image.begin(), image.end()) - image.begin(), 100 * w + 50);
}

// Speckle over a uniform area: mean of I/I0 is 1 within 1 %, variance 1/L
// within 3 %.
TEST(SpeckleTest, GammaMomentsMatchTheLooks) {
  for (double looks : {1.0, 4.0}) {
    std::vector<float> image(400000, 2.5f);
    ApplyMultiplicativeSpeckle(image, looks, 1234);
    double sum = 0, sum2 = 0;
    for (float v : image) {
      sum += v / 2.5;
      sum2 += (v / 2.5) * (v / 2.5);
    }
    const double mean = sum / image.size(), var = sum2 / image.size() - mean * mean;
    EXPECT_NEAR(mean, 1.0, 0.01) << looks;
    EXPECT_NEAR(var * looks, 1.0, 0.03) << looks;
  }
}

TEST(SpeckleTest, SeededAndDeterministic) {
  std::vector<float> a(1000, 1.0f), b(1000, 1.0f), c(1000, 1.0f);
  ApplyMultiplicativeSpeckle(a, 1.0, 7);
  ApplyMultiplicativeSpeckle(b, 1.0, 7);
  ApplyMultiplicativeSpeckle(c, 1.0, 8);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
}

TEST(ThermalNoiseTest, AddsTheNoiseFloorPower) {
  std::vector<float> image(200000, 0.0f);
  AddThermalNoise(image, -20.0, 3);
  double sum = 0;
  for (float v : image) sum += v;
  EXPECT_NEAR(sum / image.size(), 0.01, 0.0003);
}

TEST(ImpulseResponseTest, ParsesWindows) {
  EXPECT_EQ(ParseSpectralWindow("taylor", "--psf-window"), SpectralWindow::kTaylor);
  EXPECT_THROW(ParseSpectralWindow("kaiser", "--psf-window"), ConfigError);
}

}  // namespace
}  // namespace gissar::image
