#include "gissar/image/class_map.h"

#include <gtest/gtest.h>

#include <optional>

namespace gissar::image {
namespace {

TEST(ClassMapTest, PaintsEachClassWithItsColour) {
  // West half water, east half forest, 100 m x 50 m.
  scene::TriangleMesh mesh;
  mesh.AddQuad({0, 0, 0}, {50, 0, 0}, {50, 50, 0}, {0, 50, 0}, scene::kClassWater);
  mesh.AddQuad({50, 0, 0}, {100, 0, 0}, {100, 50, 0}, {50, 50, 0}, scene::kClassForest);
  std::vector<std::string> names(scene::ClassNames().begin(), scene::ClassNames().end());
  const RgbImage image = RenderClassMap(mesh, names, 601);
  EXPECT_EQ(image.width, 601);
  EXPECT_EQ(image.height, 301);
  auto pixel = [&](int x, int y) {
    const uint8_t* p = &image.rgb[(size_t(y) * image.width + x) * 3];
    return std::array<int, 3>{p[0], p[1], p[2]};
  };
  // Flat ground: shade = 0.75 + 0.25 * sun.z.
  const float shade = 0.75f + 0.25f * (1.5f / std::sqrt(1 + 1 + 2.25f));
  // Below the legend (top-left, 150 x 142 px).
  const auto water = pixel(200, 250), forest = pixel(500, 250);
  EXPECT_NEAR(water[2], ClassColours()[scene::kClassWater][2] * shade, 1.0);
  EXPECT_NEAR(forest[1], ClassColours()[scene::kClassForest][1] * shade, 1.0);
  EXPECT_LT(forest[2], 60);
}

}  // namespace
}  // namespace gissar::image

#include "gissar/image/contact_sheet.h"

namespace gissar::image {
namespace {

TEST(ContactSheetTest, TilesFramesInAGrid) {
  std::vector<std::vector<uint8_t>> frames = {std::vector<uint8_t>(30 * 20, 10), std::vector<uint8_t>(30 * 20, 200),
                                              std::vector<uint8_t>(30 * 20, 90)};
  const RgbImage sheet = ContactSheet(frames, 30, 20, {"a", "b", "c"});
  // 3 frames -> 2 columns x 2 rows of (30 + 4) x (20 + 24 + 4), plus a 4 px border.
  EXPECT_EQ(sheet.width, 2 * 34 + 4);
  EXPECT_EQ(sheet.height, 2 * 48 + 4);
  auto at = [&](int x, int y) { return sheet.rgb[(size_t(y) * sheet.width + x) * 3]; };
  EXPECT_EQ(at(4 + 15, 4 + 10), 10);
  EXPECT_EQ(at(4 + 34 + 15, 4 + 10), 200);
  EXPECT_EQ(at(4 + 15, 4 + 48 + 10), 90);
}

}  // namespace
}  // namespace gissar::image

#include "gissar/image/annotated.h"

namespace gissar::image {
namespace {

TEST(AnnotatedTest, QuicklookKeepsTheImageAndAddsAxes) {
  std::vector<float> intensity(80 * 60);
  for (size_t i = 0; i < intensity.size(); ++i) intensity[i] = 0.1f + float(i % 80) / 80.0f;
  const RgbImage picture = AnnotatedQuicklook(intensity, 80, 60, QuicklookAxes{9800.0, 2.0, -90.0, 3.0}, "test");
  EXPECT_EQ(picture.width, 80 + 70 + 90 + 20);
  EXPECT_EQ(picture.height, 60 + 44 + 50);
  // The image sits at (70, 44) unchanged (grey values equal in R, G, B).
  const std::vector<uint8_t> grey = DbQuicklook(intensity, 2.0, 98.0);
  for (int y : {0, 30, 59})
    for (int x : {0, 40, 79}) {
      const uint8_t* p = &picture.rgb[((size_t(44 + y) * picture.width) + 70 + x) * 3];
      EXPECT_EQ(p[0], grey[size_t(y) * 80 + x]);
      EXPECT_EQ(p[1], p[0]);
    }
}

// The annotated quicklook is all grey (image, text, colour bar): its grey
// levels are its red channel; one coloured pixel makes it colour.
TEST(AnnotatedTest, TheQuicklookIsNeutralGrey) {
  std::vector<float> intensity(80 * 60);
  for (size_t i = 0; i < intensity.size(); ++i) intensity[i] = 0.1f + float(i % 80) / 80.0f;
  RgbImage picture = AnnotatedQuicklook(intensity, 80, 60, QuicklookAxes{9800.0, 2.0, -90.0, 3.0}, "test");
  const std::optional<std::vector<uint8_t>> grey = NeutralGrey(picture);
  ASSERT_TRUE(grey.has_value());
  ASSERT_EQ(grey->size(), size_t(picture.width) * picture.height);
  int levels[256] = {};
  for (size_t i = 0; i < grey->size(); ++i) {
    ASSERT_EQ((*grey)[i], picture.rgb[3 * i]);
    ++levels[(*grey)[i]];
  }
  EXPECT_GT(levels[0], 100);    // black text and frame
  EXPECT_GT(levels[255], 1000);  // white margins
  picture.rgb[3 * 500 + 2] ^= 1;
  EXPECT_FALSE(NeutralGrey(picture).has_value());
}

TEST(AnnotatedTest, RelativeRangeAxisIsLabelledAsSuchAndCentredOnZero) {
  // Affine geometry: column 0 at -100 m from the scene centre, 2 m per column,
  // 101 columns: the centre column 50 reads 0 and the label changes (only the
  // text under the image differs from the absolute axis of the same origin).
  std::vector<float> intensity(101 * 60, 0.5f);
  const RgbImage relative = AnnotatedQuicklook(intensity, 101, 60, QuicklookAxes{-100.0, 2.0, -90.0, 3.0, true}, "t");
  const RgbImage absolute = AnnotatedQuicklook(intensity, 101, 60, QuicklookAxes{-100.0, 2.0, -90.0, 3.0, false}, "t");
  ASSERT_EQ(relative.width, absolute.width);
  ASSERT_EQ(relative.height, absolute.height);
  const int label_rows_from = 44 + 60 + 21;  // below the tick labels
  int differing_above = 0, differing_label = 0;
  for (int y = 0; y < relative.height; ++y)
    for (int x = 0; x < relative.width; ++x) {
      const size_t i = (size_t(y) * relative.width + x) * 3;
      if (relative.rgb[i] != absolute.rgb[i]) (y < label_rows_from ? differing_above : differing_label) += 1;
    }
  EXPECT_EQ(differing_above, 0);
  EXPECT_GT(differing_label, 20);
  bool zero_at_centre = false;
  for (const AxisTick& t : AxisTicks(-100.0, 2.0, 101, 6, nullptr)) zero_at_centre |= (t.value_m == 0.0 && t.pixel == 50.0);
  EXPECT_TRUE(zero_at_centre);
}

TEST(AnnotatedTest, SlantRangeTicksStartAtTheNearRange) {
  // Scene centre at slant range 10 km on column u0 = 100, 5 m per column,
  // 200 columns: column 0 is at 10000 - 100 * 5 = 9500 m, column 199 at
  // 10495 m. Span 995 m / 6 ticks = 166 m -> nice step 200 m; multiples of
  // 200 m inside: 9600 ... 10400 m at columns (v - 9500) / 5; labels in km
  // (|values| >= 1000 m) with one decimal (step 0.2 km).
  std::string unit;
  const std::vector<AxisTick> ticks = AxisTicks(10000.0 - 100 * 5.0, 5.0, 200, 6, &unit);
  EXPECT_EQ(unit, "km");
  ASSERT_EQ(ticks.size(), 5u);
  const double columns[] = {20, 60, 100, 140, 180};
  const char* labels[] = {"9.6", "9.8", "10.0", "10.2", "10.4"};
  for (size_t i = 0; i < ticks.size(); ++i) {
    EXPECT_NEAR(ticks[i].pixel, columns[i], 1e-9) << i;
    EXPECT_NEAR(ticks[i].value_m, 9600.0 + 200.0 * i, 1e-9) << i;
    EXPECT_EQ(ticks[i].label, labels[i]) << i;
  }
}

TEST(AnnotatedTest, AlongTrackTicksAreRelativeToTheSceneCentre) {
  // 120 rows, scene centre on row v0 = 60, 2.5 m per row: row 0 is at
  // -150 m, row 119 at +147.5 m. Span 297.5 m / 6 = 49.6 m -> step 50 m;
  // ticks -150 ... 100 m at rows (a + 150) / 2.5, labels in metres.
  std::string unit;
  const std::vector<AxisTick> ticks = AxisTicks(-60 * 2.5, 2.5, 120, 6, &unit);
  EXPECT_EQ(unit, "m");
  ASSERT_EQ(ticks.size(), 6u);
  const char* labels[] = {"-150", "-100", "-50", "0", "50", "100"};
  for (size_t i = 0; i < ticks.size(); ++i) {
    EXPECT_NEAR(ticks[i].pixel, 20.0 * i, 1e-9) << i;
    EXPECT_EQ(ticks[i].label, labels[i]) << i;
  }
  // A 2 km span: step 500 m; 1000 m reached, so km with one decimal.
  const std::vector<AxisTick> km = AxisTicks(-1000.0, 10.0, 201, 6, &unit);
  EXPECT_EQ(unit, "km");
  ASSERT_EQ(km.size(), 5u);
  EXPECT_EQ(km.front().label, "-1.0");
  EXPECT_EQ(km[2].label, "0.0");
  EXPECT_NEAR(km[3].pixel, 150.0, 1e-9);
}

TEST(AnnotatedTest, KvdDiagramDraws) {
  const RgbImage d = KvdDiagram(1.0, 23.2, 11.6, 30.0, true);
  EXPECT_EQ(d.width, 420);
  size_t coloured = 0;
  for (size_t i = 0; i + 2 < d.rgb.size(); i += 3) coloured += d.rgb[i] != d.rgb[i + 1] || d.rgb[i + 1] != d.rgb[i + 2];
  EXPECT_GT(coloured, 500u);  // the red and blue strokes
}

}  // namespace
}  // namespace gissar::image
