#include "gissar/mvg/consensus.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "gissar/mvg/affine_fundamental.h"
#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::kCase2;
using testing::kCase3;
using testing::LoadReferenceCase;

// Hand-computed tails: sum_{i>=k} C(n, i) p^i (1 - p)^(n - i), exact in
// rational arithmetic, rounded to double.
TEST(BinomialUpperTailTest, HandComputedTails) {
  EXPECT_DOUBLE_EQ(BinomialUpperTail(3, 0.5, 2), 0.5);    // (3 + 1) / 8
  EXPECT_DOUBLE_EQ(BinomialUpperTail(3, 0.5, 3), 0.125);  // 1 / 8
  // 1 - (0.9^10 + 10 0.1 0.9^9 + 45 0.01 0.9^8)
  EXPECT_NEAR(BinomialUpperTail(10, 0.1, 3), 0.0701908264, 1e-12);
  EXPECT_NEAR(BinomialUpperTail(100, 0.01, 1), 1.0 - std::pow(0.99, 100), 1e-12);  // 0.63396765872677
  EXPECT_NEAR(BinomialUpperTail(36, 0.01, 3), 0.0055807584324268494, 1e-14);
  // Far tails keep their relative precision: 0.05^36, 0.004^46.
  EXPECT_NEAR(BinomialUpperTail(36, 0.05, 36) / 1.455191522836685e-47, 1.0, 1e-9);
  EXPECT_NEAR(BinomialUpperTail(46, 0.004, 46) / 4.9517601571415214e-111, 1.0, 1e-9);
  // Bounds and degenerate probabilities.
  EXPECT_EQ(BinomialUpperTail(10, 0.3, 0), 1.0);
  EXPECT_EQ(BinomialUpperTail(10, 0.3, -2), 1.0);
  EXPECT_EQ(BinomialUpperTail(10, 0.3, 11), 0.0);
  EXPECT_EQ(BinomialUpperTail(10, 0.0, 1), 0.0);
  EXPECT_EQ(BinomialUpperTail(10, 1.0, 10), 1.0);
  EXPECT_EQ(BinomialUpperTail(0, 0.5, 1), 0.0);
  // Large n: no overflow; the tail from the mean is about one half.
  EXPECT_NEAR(BinomialUpperTail(100000, 0.5, 50000), 0.5, 0.01);
}

TEST(DistinctSamplesTest, BinomialCoefficients) {
  EXPECT_EQ(DistinctSamples(4, 4), 1);
  EXPECT_EQ(DistinctSamples(5, 4), 5);
  EXPECT_EQ(DistinctSamples(40, 4), 91390);
  EXPECT_EQ(DistinctSamples(3, 4), 0);
  EXPECT_EQ(DistinctSamples(2000000000, 40), std::numeric_limits<int64_t>::max());
}

TEST(ConsensusTest, HandComputedFigures) {
  // 40 matches, 7 inliers, p = 0.01, 1000 hypotheses: X ~ Binomial(36, 0.01),
  // P(X >= 3) = 0.00558 > 1e-3 / 1000; the smallest significant consensus is
  // 11 (P(X >= 7) = 6.47e-8 <= 1e-6 < P(X >= 6)).
  ConsensusTest t = TestConsensus(40, 7, 0.01, 1000, 1e-3);
  EXPECT_NEAR(t.p_value, 0.0055807584324268494, 1e-14);
  EXPECT_NEAR(t.expected_by_chance, 4.36, 1e-12);
  EXPECT_EQ(t.required, 11);
  EXPECT_FALSE(t.significant);
  EXPECT_TRUE(TestConsensus(40, 11, 0.01, 1000, 1e-3).significant);
  EXPECT_FALSE(TestConsensus(40, 10, 0.01, 1000, 1e-3).significant);
  // 50 matches all inliers, p = 0.004, 100 hypotheses: P(X >= 46) = 0.004^46;
  // required 9: P(X >= 5) = 1.22e-6 <= 1e-5 < P(X >= 4) = 3.65e-5.
  t = TestConsensus(50, 50, 0.004, 100, 1e-3);
  EXPECT_NEAR(t.p_value / 4.9517601571415214e-111, 1.0, 1e-9);
  EXPECT_EQ(t.required, 9);
  EXPECT_TRUE(t.significant);
  // A consensus no larger than the sample proves nothing; p = 1 never passes.
  EXPECT_EQ(TestConsensus(40, 4, 0.01, 10).p_value, 1.0);
  t = TestConsensus(40, 40, 1.0, 10);
  EXPECT_FALSE(t.significant);
  EXPECT_EQ(t.required, -1);
  // Five perfect matches cannot beat chance at this spread: every run of 5
  // unrelated matches has probability 0.01 of the same.
  EXPECT_FALSE(TestConsensus(5, 5, 0.01, DistinctSamples(5, 4)).significant);
  EXPECT_THROW(TestConsensus(40, 7, 0.01, 0), ConfigError);
  EXPECT_THROW(TestConsensus(40, 7, 0.01, 10, 0.0), ConfigError);
}

TEST(ConsensusTest, ChanceProbabilityFromTheSpreadAcrossTheEpipolarLines) {
  // F with (a, b, c, d) = (3, 0, 4, 0), normalised to (0.6, 0, 0.8, 0): the
  // image-2 term is v = 0.6 x2; x2 spans 0..500 so v spans 300 and
  // p = 2 * 1.5 / 300 = 0.01 (the GS threshold 1.5 is 2.5 px from the
  // epipolar lines of image 2, whose points spread over 500 px across them).
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();
  f(0, 2) = 3.0;
  f(2, 0) = 4.0;
  f(2, 2) = -7.0;
  std::vector<PointMatch> matches(3);
  matches[0].p2 = {0.0, 10.0};
  matches[1].p2 = {100.0, -40.0};
  matches[2].p2 = {500.0, 900.0};  // y2 lies along the epipolar lines: no effect
  EXPECT_NEAR(ChanceInlierProbability(f, matches, 1.5), 0.01, 1e-15);
  EXPECT_EQ(ChanceInlierProbability(f, matches, 1000.0), 1.0);
  // All image-2 points on one epipolar line: any match may be an inlier.
  for (PointMatch& m : matches) m.p2.x() = 7.0;
  EXPECT_EQ(ChanceInlierProbability(f, matches, 1.5), 1.0);
}

// 40 unrelated matches (uniform over 1000 x 1000 px in both images): RANSAC
// finds some F with a handful of inliers, but no better than chance.
std::vector<PointMatch> RandomMatches(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  auto coordinate = [&] { return 1000.0 * double(rng()) / 4294967296.0; };
  std::vector<PointMatch> matches(n);
  for (PointMatch& m : matches) {
    m.p1 = {coordinate(), coordinate()};
    m.p2 = {coordinate(), coordinate()};
  }
  return matches;
}

ConsensusTest TestFit(const std::vector<PointMatch>& matches, const RansacOptions& options) {
  const std::optional<RobustFundamentalFit> fit = EstimateAffineFundamentalRansac(matches, options);
  if (!fit) return {};
  const int n = static_cast<int>(matches.size());
  return TestConsensus(n, static_cast<int>(fit->inliers.size()),
                       ChanceInlierProbability(fit->f, matches, options.threshold_px),
                       std::min<int64_t>(fit->iterations, DistinctSamples(n, 4)));
}

TEST(ConsensusTest, UnrelatedMatchesAreNoBetterThanChance) {
  for (uint32_t seed : {1u, 2u, 3u, 4u, 5u}) {
    RansacOptions options;
    options.seed = seed;
    const std::vector<PointMatch> matches = RandomMatches(40, 1000 + seed);
    const std::optional<RobustFundamentalFit> fit = EstimateAffineFundamentalRansac(matches, options);
    ASSERT_TRUE(fit.has_value()) << seed;  // RANSAC alone accepts a model
    EXPECT_GE(fit->inliers.size(), 5u) << seed;
    const ConsensusTest t = TestFit(matches, options);
    EXPECT_FALSE(t.significant) << seed << ": " << t.inliers << " inliers, p-value " << t.p_value;
    EXPECT_GT(t.required, t.inliers) << seed;
  }
}

TEST(ConsensusTest, ReferenceCasesAreFarBeyondChance) {
  for (const char* name : {kCase2, kCase3}) {
    const auto rc = LoadReferenceCase(name);
    RansacOptions options;
    options.threshold_px = rc.json["ransac"]["thr_px_gs"].get<double>();
    const ConsensusTest t = TestFit(rc.Matches(), options);
    EXPECT_TRUE(t.significant) << name;
    EXPECT_LT(t.p_value, 1e-30) << name;
    EXPECT_LT(t.required, t.inliers / 2) << name;
  }
}

}  // namespace
}  // namespace gissar::mvg
