#include "gissar/image/composite.h"

#include <gtest/gtest.h>

#include <cmath>

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

}  // namespace
}  // namespace gissar::image
