// Two-view analysis in one call: robust affine F from matches, residuals,
// calibrated F, KvD decomposition and (with known depressions) the SAR
// heading change and |rho|. Everything a report of the epipolar geometry of
// an image pair needs.
//
// Failures: as EstimateAffineFundamental(Ransac) (affine_fundamental.h):
// InputError for fewer than 4 matches or non-finite coordinates,
// ConfigError for invalid options (including a K that is not of the C_SAR
// form or a depression outside (0, 90)), std::nullopt when the matches are
// degenerate, RANSAC finds no model, or the F found has a zero (a, b) or
// (c, d) part (no KvD decomposition).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/affine_fundamental.h"
#include "gissar/mvg/kvd.h"
#include "gissar/mvg/point_match.h"

namespace gissar::mvg {

struct TwoViewOptions {
  // RANSAC + Gold Standard refit (true) or one Gold Standard fit to all
  // matches (false).
  bool robust = true;
  RansacOptions ransac;
  // Intrinsics C_SAR (metres -> pixels, e.g. SarIntrinsics) of image 1 and
  // image 2, for the calibrated F and so the KvD parameters. The identity
  // gives the KvD parameters of the pixel F (same theta and phi when the
  // pixels are square; s is then the ratio of the pixel spacings).
  Eigen::Matrix3d k1 = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d k2 = Eigen::Matrix3d::Identity();
  // Depressions (degrees, (0, 90)) and look sides of the two views: with
  // both depressions set the result includes the SAR reading (heading
  // change, |rho|).
  std::optional<double> depression1_deg;
  std::optional<double> depression2_deg;
  LookSide look1 = LookSide::kRight;
  LookSide look2 = LookSide::kRight;
};

struct TwoViewAnalysis {
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();             // pixel F, normalised
  Eigen::Matrix3d f_calibrated = Eigen::Matrix3d::Zero();  // K2' F K1, normalised
  int num_matches = 0;
  std::vector<int> inliers;  // 0-based, increasing (all matches without `robust`)
  // RMS over the inliers (pixels) of the Gold Standard and the image 1 /
  // image 2 epipolar residuals.
  double rms_gs_px = 0.0;
  double rms_epi1_px = 0.0;
  double rms_epi2_px = 0.0;
  FundamentalResiduals residuals;  // signed residuals of every match under f
  int ransac_iterations = 0;       // 0 without `robust`
  int refits = 0;
  bool refit_converged = true;
  KvdParameters kvd;  // of f_calibrated; kvd.rho_recoverable is false
  // Heading change and |rho|: set when both depressions are given and a
  // heading change reproduces theta.
  std::optional<SarRelativePose> sar;
  Eigen::Vector2d epipole1 = Eigen::Vector2d::Zero();  // epipolar line direction, image 1
  Eigen::Vector2d epipole2 = Eigen::Vector2d::Zero();  // epipolar line direction, image 2
};

// Estimates F from `matches` (pixels; p1 in image 1, p2 in image 2) with
// RANSAC and Gold Standard refits (or one Gold Standard fit), then fills
// every field of TwoViewAnalysis. Throws and returns std::nullopt as
// described at the top.
std::optional<TwoViewAnalysis> AnalyseTwoViews(const std::vector<PointMatch>& matches,
                                               const TwoViewOptions& options);

}  // namespace gissar::mvg
