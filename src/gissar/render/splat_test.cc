#include "gissar/render/splat.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace gissar::render {
namespace {

// Share of pixel c by midpoint quadrature of (1/w) * integral over the box
// of the tent max(0, 1 - |u - c|): an independent evaluation of the
// definition (the tent is piecewise linear, so 20,000 panels leave an error
// below 1e-8).
double QuadratureShare(double x, double w, int c) {
  const int panels = 20000;
  const double x0 = x - 0.5 * w, h = w / panels;
  double sum = 0.0;
  for (int k = 0; k < panels; ++k) sum += std::max(0.0, 1.0 - std::abs(x0 + (k + 0.5) * h - c));
  return sum * h / w;
}

TEST(FootprintSharesTest, MatchTheTentIntegralForNarrowAndWideBoxes) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> position(-3.0, 40.0);
  // Narrow boxes inside one unit interval and across an integer, a box of
  // exactly one pixel, and wide ones.
  for (double w : {0.01, 0.08, 0.37, 0.999, 1.0, 1.6, 3.3, 7.5}) {
    for (int trial = 0; trial < 40; ++trial) {
      const double x = position(rng);
      double share[kMaxShares];
      int first = 0;
      const int n = FootprintShares(x, w, &first, share);
      ASSERT_LE(n, kMaxShares);
      double total = 0.0;
      for (int k = 0; k < n; ++k) {
        EXPECT_NEAR(share[k], QuadratureShare(x, w, first + k), 1e-7) << "x " << x << " w " << w << " k " << k;
        total += share[k];
      }
      EXPECT_NEAR(total, 1.0, 1e-12);
      // Pixels outside the returned run get nothing.
      EXPECT_LT(QuadratureShare(x, w, first - 1), 1e-12);
      EXPECT_LT(QuadratureShare(x, w, first + n), 1e-12);
    }
  }
}

TEST(FootprintSharesTest, AVanishingBoxIsTheBilinearSplat) {
  double share[kMaxShares];
  int first = 0;
  ASSERT_EQ(FootprintShares(7.25, 0.0, &first, share), 2);
  EXPECT_EQ(first, 7);
  EXPECT_DOUBLE_EQ(share[0], 0.75);
  EXPECT_DOUBLE_EQ(share[1], 0.25);
  // A narrow box inside [7, 8] gives the same weights (the tents are linear there).
  ASSERT_EQ(FootprintShares(7.25, 0.3, &first, share), 2);
  EXPECT_EQ(first, 7);
  EXPECT_DOUBLE_EQ(share[0], 0.75);
  EXPECT_DOUBLE_EQ(share[1], 0.25);
}

}  // namespace
}  // namespace gissar::render
