// The affine fundamental matrix of two affine (SAR) views and its robust
// estimation from point matches.
//
// F = [0 0 a; 0 0 b; c d e] with [x2 y2 1] F [x1 y1 1]' = 0 for matching
// pixels (x1, y1) in image 1 and (x2, y2) in image 2. Every F this module
// returns is normalised: ||(a, b, c, d)|| = 1 and c > 0 (when |c| < 1e-6:
// d > 0, then a > 0, then b > 0). Compare two F with
// AffineFundamentalDistance, which ignores the overall sign.
//
// Residuals, in pixels, of a match under F:
//   Gold Standard (GS)  r = (a x2 + b y2 + c x1 + d y1 + e) / ||(a, b, c, d)||,
//   image 2 epipolar    r / ||(a, b)||, distance of x2 from the line F x1,
//   image 1 epipolar    r / ||(c, d)||, distance of x1 from the line F' x2.
// The GS residual is the distance of the 4-vector (x2, y2, x1, y1) from the
// hyperplane F defines; minimising its sum of squares is the maximum
// likelihood estimate of F under isotropic Gaussian pixel noise.
//
// Failures: invalid input (non-finite coordinates, fewer than 4 matches, an F
// or camera that is not of the affine form, invalid options) throws
// gissar::InputError (gissar::ConfigError for options); a degenerate
// configuration (the centred match 4-vectors span fewer than 3 dimensions,
// e.g. collinear points, a planar scene, identical views) or RANSAC finding
// no model gives std::nullopt.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/point_match.h"

namespace gissar::mvg {

// Relative threshold on the singular values of the centred 4-column data
// matrix: the configuration is degenerate when sigma_3 <= kRankTolerance *
// sigma_1 (rank < 3, so F is not determined).
inline constexpr double kRankTolerance = 1e-9;

// Throws InputError (where = `what`) unless `f` is finite, has a zero
// top-left 2x2 block (entries |F_ij| <= 1e-12 ||F||) and a non-zero
// (a, b, c, d).
void CheckAffineFundamental(const Eigen::Matrix3d& f, const std::string& what);

// `f` scaled and signed as described at the top (the 2x2 block is set to
// exact zeros). Throws as CheckAffineFundamental.
Eigen::Matrix3d NormalizeAffineFundamental(const Eigen::Matrix3d& f);

// Frobenius distance between the normalised forms of `f` and `g`, the
// smaller of ||F - G|| and ||F + G||: 0 for the same epipolar geometry.
double AffineFundamentalDistance(const Eigen::Matrix3d& f, const Eigen::Matrix3d& g);

// F of two affine cameras (3x4, last row [0 0 0 1]; any affine camera, not
// only SAR ones), normalised: (c, d, a, b) is the left null vector of the
// stacked 4x3 matrix [M1; M2] of the cameras' first two rows, computed from
// its 3x3 minors, and e = -(c, d, a, b) . (t1, t2) with the cameras'
// offsets. Throws InputError when a camera is not affine or not finite;
// std::nullopt when [M1; M2] has rank < 3 (e.g. identical views).
std::optional<Eigen::Matrix3d> FundamentalFromCameras(const AffineMatrix& p1,
                                                      const AffineMatrix& p2);

// Gold Standard estimate (Hartley & Zisserman, Alg. 14.1): centre the
// 4-vectors (x2, y2, x1, y1) on their centroid, take (a, b, c, d) as the right
// singular vector of the smallest singular value and e = -(a, b, c, d) .
// centroid. Uses all matches, or those listed in `subset` (0-based indices
// into `matches`). Throws InputError for fewer than 4 matches, a
// non-finite coordinate, or an index out of range; std::nullopt when the
// matches are degenerate (see kRankTolerance).
std::optional<Eigen::Matrix3d> EstimateAffineFundamental(const std::vector<PointMatch>& matches);
std::optional<Eigen::Matrix3d> EstimateAffineFundamental(const std::vector<PointMatch>& matches,
                                                         const std::vector<int>& subset);

// The minimal solver: the F through exactly four matches (the null vector of
// their centred 4x4 data matrix). Throws InputError for non-finite input;
// std::nullopt when the four are degenerate.
std::optional<Eigen::Matrix3d> SolveAffineFundamentalMinimal(const PointMatch& m0,
                                                             const PointMatch& m1,
                                                             const PointMatch& m2,
                                                             const PointMatch& m3);

struct RansacOptions {
  double threshold_px = 1.5;   // inlier when |GS residual| < threshold, pixels, > 0
  double confidence = 0.99;    // probability of drawing one all-inlier sample, in (0, 1)
  int max_iterations = 10000;  // cap on the adaptive number of samples, >= 1
  // Samples drawn at least, in [0, max_iterations]. The adaptive count
  // assumes any all-inlier sample leads to the best model; with noise and a
  // shallow scene (small height range) a sample can instead lead the refit
  // loop to a neighbouring stable inlier set, so a few more are drawn.
  int min_iterations = 100;
  uint32_t seed = 1;    // std::mt19937 seed: results are reproducible
  int max_refits = 50;  // cap on the Gold Standard refit loop, >= 1
  // Throws ConfigError naming the field when a value is out of range.
  void Check() const;
};

struct RobustFundamentalFit {
  // Gold Standard fit on `inliers`, normalised.
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();
  // 0-based, increasing: the matches with |GS residual under f| < threshold.
  std::vector<int> inliers;
  // The minimal-sample model the returned refit started from, and its inliers.
  Eigen::Matrix3d f_ransac = Eigen::Matrix3d::Zero();
  std::vector<int> ransac_inliers;
  int iterations = 0;            // samples drawn
  int refits = 0;                // Gold Standard refits of the returned fit
  bool refit_converged = false;  // its inlier set stopped changing before max_refits
};

// RANSAC over 4-match minimal samples drawn with std::mt19937(seed). Models
// are scored by MSAC, the sum over all matches of min(r², threshold²) with r
// the GS residual (lower is better). Each promising sample (at least 90 % of
// the inliers of the best sample so far, an inlier set not seen before) is
// locally optimised: its inliers are refitted with the Gold Standard, and
// the inliers re-selected under the refit, until the set is stable (or
// max_refits); the refit with the best score is returned. The
// number of samples adapts to the inlier ratio w of that refit as
// log(1 - confidence) / log(1 - w^4), within [min_iterations, max_iterations].
// Throws InputError for fewer than 4 matches or non-finite coordinates and
// ConfigError for invalid options; std::nullopt when no sample gives a
// non-degenerate model with at least min(5, matches) inliers.
std::optional<RobustFundamentalFit> EstimateAffineFundamentalRansac(
    const std::vector<PointMatch>& matches, const RansacOptions& options);

// Signed residuals (pixels) of one match under `f` (see the top).
// Throws InputError when `f` is not an affine F.
double GoldStandardResidual(const Eigen::Matrix3d& f, const PointMatch& match);
double EpipolarResidual1(const Eigen::Matrix3d& f, const PointMatch& match);
double EpipolarResidual2(const Eigen::Matrix3d& f, const PointMatch& match);

struct FundamentalResiduals {
  std::vector<double> gs_px;    // Gold Standard residual per match
  std::vector<double> epi1_px;  // distance from the epipolar line in image 1
  std::vector<double> epi2_px;  // distance from the epipolar line in image 2
};
FundamentalResiduals ComputeResiduals(const Eigen::Matrix3d& f,
                                      const std::vector<PointMatch>& matches);

// Root mean square of `values` (all, or the 0-based `subset`); 0 when empty.
double RootMeanSquare(const std::vector<double>& values);
double RootMeanSquare(const std::vector<double>& values, const std::vector<int>& subset);

// F in metric image coordinates: K2' F K1, normalised, for the intrinsic
// matrices (C_SAR, metres -> pixels) of image 1 and image 2. Throws
// InputError when `f` is not an affine F or a K is not of the affine form
// [sx k u0; 0 sy v0; 0 0 1] with non-zero sx, sy.
Eigen::Matrix3d CalibrateFundamental(const Eigen::Matrix3d& f, const Eigen::Matrix3d& k1,
                                     const Eigen::Matrix3d& k2);

// Epipoles of an affine F lie at infinity: these are their unit directions,
// the common direction of all epipolar lines in image 1, (-d, c)/||(c, d)||,
// and in image 2, (-b, a)/||(a, b)||. Throws InputError when `f` is not an
// affine F or the (c, d) (resp. (a, b)) part is zero.
Eigen::Vector2d EpipoleDirection1(const Eigen::Matrix3d& f);
Eigen::Vector2d EpipoleDirection2(const Eigen::Matrix3d& f);

// Epipolar line (l0, l1, l2), l0 x + l1 y + l2 = 0, scaled so that
// l0² + l1² = 1 (then l . (x, y, 1) is the signed distance in pixels):
// in image 2 for the image-1 point `x1` (F x1), and in image 1 for the
// image-2 point `x2` (F' x2). Throws as EpipoleDirection1/2.
Eigen::Vector3d EpipolarLineInImage2(const Eigen::Matrix3d& f, const Eigen::Vector2d& x1);
Eigen::Vector3d EpipolarLineInImage1(const Eigen::Matrix3d& f, const Eigen::Vector2d& x2);

}  // namespace gissar::mvg
