#include "gissar/mvg/stereo.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::JsonMatrix;
using testing::kCase3;
using testing::LoadReferenceCase;

TEST(StereoTest, ReferenceCase3NoiseFreePixelsGiveTheTruePoints) {
  const auto rc = LoadReferenceCase(kCase3);
  const AffineMatrix p1 = JsonMatrix<3, 4>(rc.json["P1"]);
  const AffineMatrix p2 = JsonMatrix<3, 4>(rc.json["P2"]);
  const auto xs = rc.Values("X"), ys = rc.Values("Y"), zs = rc.Values("Z");
  const auto x1 = rc.Values("x1_true"), y1 = rc.Values("y1_true");
  const auto x2 = rc.Values("x2_true"), y2 = rc.Values("y2_true");
  for (size_t i = 0; i < xs.size(); ++i) {
    const auto s = Triangulate(p1, p2, {{x1[i], y1[i]}, {x2[i], y2[i]}}, 0.5);
    ASSERT_TRUE(s.has_value());
    EXPECT_LT((s->position - Eigen::Vector3d(xs[i], ys[i], zs[i])).norm(), 1e-8);
    EXPECT_NEAR(s->height_m, zs[i], 1e-8);
    EXPECT_LT(s->residual_px, 1e-9);
  }
}

TEST(StereoTest, ReferenceCase3NoisyInliersWithinTheErrorBound) {
  const auto rc = LoadReferenceCase(kCase3);
  const AffineMatrix p1 = JsonMatrix<3, 4>(rc.json["P1"]);
  const AffineMatrix p2 = JsonMatrix<3, 4>(rc.json["P2"]);
  const auto zs = rc.Values("Z");
  const auto matches = rc.Matches();
  const double sigma = rc.json["sigma_px"].get<double>();
  const auto inliers = rc.RowsWhereNot("is_outlier");
  const auto all = TriangulateAll(p1, p2, matches, sigma);
  ASSERT_TRUE(all.has_value());
  int within_one_sigma = 0;
  for (int i : inliers) {
    const double error = (*all)[i].height_m - zs[i];
    EXPECT_LT(std::abs(error), 4.0 * (*all)[i].height_sigma_m) << i;
    within_one_sigma += std::abs(error) <= (*all)[i].height_sigma_m;
  }
  // About 68 % of 170.
  EXPECT_GT(within_one_sigma, 95);
  EXPECT_LT(within_one_sigma, 140);
  RecordProperty("case3_height_sigma_m", testing::Sci((*all)[0].height_sigma_m));
}

TEST(StereoTest, KnownHeightAndSeededNoiseAgainstThePropagatedBound) {
  // Same-side stereo: equal headings, depressions 35 and 55 deg.
  SarPose a, b;
  a.heading_deg = b.heading_deg = 20.0;
  a.depression_deg = 35.0;
  b.depression_deg = 55.0;
  a.u0 = a.v0 = b.u0 = b.v0 = 256.0;
  const AffineSarCamera c1(a), c2(b);
  const Eigen::Vector3d point(12.0, -40.0, 37.0);
  const PointMatch exact{c1.Project(point), c2.Project(point)};
  const auto s = Triangulate(c1.Matrix(), c2.Matrix(), exact, 1.0);
  ASSERT_TRUE(s.has_value());
  EXPECT_NEAR(s->height_m, 37.0, 1e-9);
  // By hand: with D = dr r_h + da h + dz z the range coordinates are
  // x_i = cos(delta_i) dr - sin(delta_i) dz (metres, 1 m pixels) and both
  // azimuths are da, so the range parallax is
  // x1 - x2 = (sin 55 - sin 35) dz + (cos 35 - cos 55) dr.
  const auto height_sigma = HeightSigma(c1.Matrix(), c2.Matrix(), 1.0);
  ASSERT_TRUE(height_sigma.has_value());
  EXPECT_NEAR(*height_sigma, s->height_sigma_m, 1e-12);
  // Least squares over (dr, dz) with two unit-variance range equations:
  // var(dz) = (c1² + c2²) / (c1 s2 - c2 s1)² with ci = cos, si = sin.
  const double c1d = std::cos(35.0 * M_PI / 180), s1d = std::sin(35.0 * M_PI / 180);
  const double c2d = std::cos(55.0 * M_PI / 180), s2d = std::sin(55.0 * M_PI / 180);
  EXPECT_NEAR(*height_sigma, std::sqrt(c1d * c1d + c2d * c2d) / std::abs(c1d * s2d - c2d * s1d),
              1e-9);

  // Seeded noise: the propagated one-sigma bound holds about 68 % of the
  // time and a 4-sigma bound always.
  std::mt19937 rng(21);
  std::normal_distribution<double> noise(0.0, 0.5);
  int inside = 0;
  const int trials = 2000;
  for (int t = 0; t < trials; ++t) {
    PointMatch m = exact;
    m.p1 += Eigen::Vector2d(noise(rng), noise(rng));
    m.p2 += Eigen::Vector2d(noise(rng), noise(rng));
    const auto r = Triangulate(c1.Matrix(), c2.Matrix(), m, 0.5);
    ASSERT_TRUE(r.has_value());
    const double error = r->height_m - 37.0;
    EXPECT_LT(std::abs(error), 4.0 * r->height_sigma_m);
    inside += std::abs(error) <= r->height_sigma_m;
  }
  EXPECT_NEAR(static_cast<double>(inside) / trials, 0.6827, 0.03);
}

TEST(StereoTest, DegenerateAndInvalidInput) {
  const AffineMatrix p = AffineSarCamera(SarPose{}).Matrix();
  const PointMatch m{{1.0, 2.0}, {1.0, 2.0}};
  EXPECT_FALSE(Triangulate(p, p, m, 0.5).has_value());  // identical views
  EXPECT_FALSE(HeightSigma(p, p, 0.5).has_value());
  SarPose other;
  other.heading_deg = 30.0;
  const AffineMatrix q = AffineSarCamera(other).Matrix();
  EXPECT_THROW(Triangulate(p, q, {{std::nan(""), 0.0}, {0.0, 0.0}}, 0.5), InputError);
  EXPECT_THROW(Triangulate(p, q, m, -1.0), InputError);
  AffineMatrix bad = q;
  bad(2, 0) = 1.0;
  EXPECT_THROW(Triangulate(p, bad, m, 0.5), InputError);
}

}  // namespace
}  // namespace gissar::mvg
