#include "gissar/image/composite.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gissar/image/annotated.h"
#include "gissar/image/quicklook.h"

namespace gissar::image {
namespace {

TEST(CompositeTest, FirstImageGreenSecondMagenta) {
  const std::vector<uint8_t> green = {0, 200, 100, 7}, magenta = {0, 0, 100, 250};
  const RgbImage c = GreenMagentaComposite(green, magenta, 2, 2);
  ASSERT_EQ(c.rgb.size(), 12u);
  EXPECT_EQ(std::vector<uint8_t>(c.rgb.begin() + 3, c.rgb.begin() + 6), (std::vector<uint8_t>{0, 200, 0}));
  EXPECT_EQ(std::vector<uint8_t>(c.rgb.begin() + 6, c.rgb.begin() + 9), (std::vector<uint8_t>{100, 100, 100}));
  EXPECT_EQ(std::vector<uint8_t>(c.rgb.begin() + 9, c.rgb.end()), (std::vector<uint8_t>{250, 7, 250}));
}

TEST(CompositeTest, IdenticalImagesUpToAGainAreGrey) {
  // A gain (a calibration offset in dB) changes nothing: each image has its own stretch.
  std::vector<float> a(64 * 48), b(a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    a[i] = static_cast<float>(std::pow(10.0, 0.03 * double(i % 97)));
    b[i] = 5.0f * a[i];
  }
  const RgbImage c = IntensityComposite(a, b, 64, 48);
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_NEAR(c.rgb[3 * i], c.rgb[3 * i + 1], 1) << i;
    ASSERT_EQ(c.rgb[3 * i], c.rgb[3 * i + 2]);
  }
}

TEST(AnnotatedQuicklookTest, HoldsTheQuicklookInsideAxesAndColourBar) {
  const int w = 120, h = 80;
  std::vector<float> intensity(size_t(w) * h);
  for (size_t i = 0; i < intensity.size(); ++i) intensity[i] = 1.0f + float(i % 13);
  const RgbImage a = AnnotatedQuicklook(intensity, w, h, 30.0, 15.0, "test");
  // Margins of annotated.cc: 70 px left (azimuth axis), 34 top (title),
  // 50 bottom (range axis), 90 + 20 right (colour bar).
  ASSERT_EQ(a.width, w + 70 + 90 + 20);
  ASSERT_EQ(a.height, h + 34 + 50);
  const std::vector<uint8_t> grey = DbQuicklook(intensity, 2.0, 98.0);
  for (int y = 0; y < h; y += 7) {
    for (int x = 0; x < w; x += 5) {
      const uint8_t* p = &a.rgb[(size_t(y + 34) * a.width + x + 70) * 3];
      ASSERT_EQ(p[0], grey[size_t(y) * w + x]);
      ASSERT_EQ(p[1], p[0]);
    }
  }
}

}  // namespace
}  // namespace gissar::image
