// Is a RANSAC consensus better than chance? The support an affine F needs
// before it counts as a result, derived from the null hypothesis that the
// matches are unrelated (not picked by hand).
//
// The affine F has 4 degrees of freedom: a minimal sample of 4 matches fits
// exactly, so its 4 matches are inliers whatever the data. Under the null
// hypothesis each of the other N - 4 matches is an inlier by chance, with
// probability p (ChanceInlierProbability), independently: the number of
// chance inliers X is Binomial(N - 4, p). A consensus of k inliers has the
// p-value P(X >= k - 4). The best of M hypotheses (the RANSAC samples) is
// kept, so the test is Bonferroni-corrected: the consensus is significant
// when P(X >= k - 4) <= alpha / M. With alpha = kConsensusAlpha = 1e-3, a set
// of unrelated matches gives a result at most once in a thousand runs.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "gissar/mvg/point_match.h"

namespace gissar::mvg {

// Family-wise false-alarm rate of the consensus test: the probability that
// unrelated matches pass it, over all the hypotheses RANSAC tried.
inline constexpr double kConsensusAlpha = 1e-3;

// Upper tail P(X >= k) of X ~ Binomial(n, p), n >= 0, p in [0, 1] (clamped):
// 1 for k <= 0, 0 for k > n. Summed in log space (no overflow for large n;
// tails below ~1e-308 underflow to 0).
double BinomialUpperTail(int n, double p, int k);

// Number of distinct hypotheses RANSAC can draw from `matches` matches with
// samples of `sample_size`: the binomial coefficient C(matches, sample_size),
// saturated at INT64_MAX.
int64_t DistinctSamples(int matches, int sample_size);

struct ConsensusTest {
  int matches = 0;                  // N
  int inliers = 0;                  // k, the observed consensus
  int sample_size = 4;              // matches a hypothesis fits exactly
  double chance_probability = 0.0;  // p: an unrelated match is an inlier
  int64_t hypotheses = 1;           // M: hypotheses tried
  double alpha = kConsensusAlpha;
  // Inliers a hypothesis gets from unrelated matches on average:
  // sample_size + (N - sample_size) p.
  double expected_by_chance = 0.0;
  double p_value = 1.0;   // P(X >= k - sample_size), X ~ Binomial(N - sample_size, p)
  // The smallest k with P(X >= k - sample_size) <= alpha / M; -1 when even all
  // N matches would not be enough.
  int required = -1;
  bool significant = false;  // p_value <= alpha / M
};

// The test described at the top. Throws ConfigError for alpha outside (0, 1)
// or hypotheses < 1; inliers and p are clamped to [0, N] and [0, 1].
ConsensusTest TestConsensus(int matches, int inliers, double chance_probability, int64_t hypotheses,
                            double alpha = kConsensusAlpha, int sample_size = 4);

// Probability that an unrelated match is an inlier of the affine F `f`
// (|Gold Standard residual| < threshold_px). With (a, b, c, d) normalised
// to unit length, the GS residual is r = (a x2 + b y2) + (c x1 + d y1 + e).
// When x2 is unrelated to x1, r < t in magnitude requires the image-2 term
// v = a x2 + b y2 (= ||(a, b)|| times the coordinate of x2 across the
// parallel epipolar lines of image 2) to fall in an interval of width 2t.
// With v spread evenly over its extent w' = max v - min v over the matches'
// image-2 points (= ||(a, b)|| times their extent w across the epipolar
// lines): p = min(1, 2t / w') = min(1, 2 t2 / w), t2 = t / ||(a, b)|| being
// the GS threshold as a distance from the epipolar line in image 2. 1 when
// w' is 0. Throws as GoldStandardResidual when `f` is not an affine F.
double ChanceInlierProbability(const Eigen::Matrix3d& f, const std::vector<PointMatch>& matches,
                               double threshold_px);

}  // namespace gissar::mvg
