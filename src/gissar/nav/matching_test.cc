#include "gissar/nav/matching.h"

#include <algorithm>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "gissar/image/impulse_response.h"
#include "gissar/util/error.h"

namespace gissar::nav {
namespace {

// A textured intensity image (log-normal blobs) and a copy shifted by
// (dx, dy) pixels with 4-look speckle and a 2 dB radiometric offset.
struct Pair {
  cv::Mat ref_log, obs_log;
};

Pair MakePair(double dx, double dy, uint64_t seed) {
  const int n = 128;
  cv::Mat noise(n + 40, n + 40, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 2.5);
  cv::Mat scene;
  cv::exp(noise * 8.0, scene);
  cv::Mat ref = scene(cv::Rect(20, 20, n, n)).clone();
  cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, dx, 0, 1, dy);
  cv::Mat obs;
  cv::warpAffine(scene, obs, shift, scene.size(), cv::INTER_CUBIC);
  obs = obs(cv::Rect(20, 20, n, n)).clone() * 1.585;  // +2 dB
  std::vector<float> r(ref.begin<float>(), ref.end<float>()), o(obs.begin<float>(), obs.end<float>());
  image::ApplyMultiplicativeSpeckle(o, 4.0, seed + 1);
  return {LogIntensity(r, n, n, 3), LogIntensity(o, n, n, 3)};
}

double MedianError(const std::vector<Correspondence>& m, double dx, double dy) {
  std::vector<double> e;
  for (const auto& c : m) e.push_back((c.observed - c.reference - Eigen::Vector2d(dx, dy)).norm());
  std::sort(e.begin(), e.end());
  return e.empty() ? 1e9 : e[e.size() / 2];
}

TEST(Matching, DenseNccRecoversShiftUnderSpeckle) {
  const Pair p = MakePair(3.4, -2.2, 11);
  MatchOptions o;
  o.search_px = 8;
  const auto m = DenseNccMatch(p.ref_log, p.obs_log, o);
  std::printf("DenseNccMatch: %zu matches, median error %.3f px\n", m.size(), MedianError(m, 3.4, -2.2));
  ASSERT_GE(m.size(), 20u);
  EXPECT_LT(MedianError(m, 3.4, -2.2), 0.25);  // measured 0.121 px (36 matches)
}

TEST(Matching, ChamferRecoversShiftUnderSpeckle) {
  const Pair p = MakePair(3.4, -2.2, 12);
  MatchOptions o;
  o.search_px = 8;
  const auto m = ChamferMatch(p.ref_log, p.obs_log, o);
  std::printf("ChamferMatch: %zu matches, median error %.3f px\n", m.size(), MedianError(m, 3.4, -2.2));
  ASSERT_GE(m.size(), 10u);
  EXPECT_LT(MedianError(m, 3.4, -2.2), 0.4);  // measured 0.181 px (49 matches)
}

TEST(Matching, FeaturesRecoverShiftUnderSpeckle) {
  const Pair p = MakePair(3.4, -2.2, 13);
  MatchOptions o;
  o.search_px = 8;
  const auto m = FeatureMatch(p.ref_log, p.obs_log, o);
  std::printf("FeatureMatch: %zu matches, median error %.3f px\n", m.size(), MedianError(m, 3.4, -2.2));
  ASSERT_GE(m.size(), 5u);
  EXPECT_LT(MedianError(m, 3.4, -2.2), 1.0);  // integer keypoints; measured 0.632 px (57 matches)
}

TEST(Matching, RejectsBadInput) {
  EXPECT_THROW(ParseMatcher("sift", "--matcher"), ConfigError);
  MatchOptions o;
  o.patch_px = 8;
  EXPECT_THROW(o.Check(), ConfigError);
  EXPECT_THROW(DenseNccMatch(cv::Mat(10, 10, CV_32F), cv::Mat(11, 10, CV_32F), MatchOptions()), InputError);
  EXPECT_EQ(ToString(ParseMatcher("chamfer", "x")), "chamfer");
}

TEST(Matching, ImageNccOfIdenticalAndFlatImages) {
  const Pair p = MakePair(0, 0, 3);
  EXPECT_NEAR(ImageNcc(p.ref_log, p.ref_log), 1.0, 1e-9);
  EXPECT_EQ(ImageNcc(cv::Mat(20, 20, CV_32F, cv::Scalar(1)), p.ref_log(cv::Rect(0, 0, 20, 20)).clone()), 0.0);
}

}  // namespace
}  // namespace gissar::nav
