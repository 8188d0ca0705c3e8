// Matching a SAR image against a simulated SAR image of the same terrain,
// robust to speckle and to radiometric differences (model mismatch).
//
// All matchers take two log-intensity images of the same size (see
// LogIntensity: dB of a box-filtered intensity, the speckle filter) and
// return correspondences `reference` -> `observed` in pixels (x = column =
// slant range, y = row = azimuth, centres at integer coordinates) with a
// score (higher = better; its meaning depends on the matcher). They never
// throw for image content: an empty result means "no match". Images of
// different sizes or types throw gissar::InputError; bad options
// gissar::ConfigError.
//
//  - DenseNccMatch: a grid of reference patches searched in the observed
//    image by normalised cross-correlation of log intensities (OpenCV
//    matchTemplate, TM_CCOEFF_NORMED), parabolic sub-pixel peak.
//  - ChamferMatch: Canny edges of both log images; the reference edges of a
//    grid block are moved over the observed image's distance transform and
//    the shift of the least mean edge distance is kept (sub-pixel by a
//    parabola); score = -mean distance (pixels).
//  - FeatureMatch: SAR-Harris corners on the ratio-of-local-means gradient
//    (SAR-SIFT / SAR-Harris: G = log(mean on one side / mean on the other),
//    insensitive to multiplicative speckle), described by z-normalised log
//    patches, matched by L2 distance with Lowe's ratio test and a
//    cross-check; score = 1 - best/second distance ratio.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "gissar/util/enum_table.h"

namespace gissar::nav {

struct Correspondence {
  Eigen::Vector2d reference = Eigen::Vector2d::Zero();  // pixel in the reference (simulated) image
  Eigen::Vector2d observed = Eigen::Vector2d::Zero();   // pixel in the observed image
  double score = 0.0;
};

enum class Matcher { kNcc, kChamfer, kFeatures };
inline constexpr auto kMatchers = util::MakeEnumTable<Matcher>(
    "matcher", {{Matcher::kNcc, "ncc"}, {Matcher::kChamfer, "chamfer"}, {Matcher::kFeatures, "features"}});
// kMatchers.Parse: "ncc", "chamfer", "features"; throws ConfigError naming
// `option` and the matchers otherwise.
Matcher ParseMatcher(const std::string& text, const std::string& option);
std::string ToString(Matcher matcher);

// Mean over `filter_px` x `filter_px` boxes (reflected at the border) of a
// CV_32F image: the multi-look speckle filter of LogIntensity; a copy for
// filter_px <= 1.
cv::Mat BoxMean(const cv::Mat& image, int filter_px);

// CV_32F image of 10 log10(box mean over `filter_px` x `filter_px` of the
// intensity + floor), a multi-look speckle filter followed by the log.
// `intensity` is row-major width x height, linear; floor > 0 avoids log 0.
cv::Mat LogIntensity(const std::vector<float>& intensity, int width, int height, int filter_px,
                     double floor = 1e-4);

struct MatchOptions {
  int patch_px = 31;        // template / block side, odd, >= 7
  int step_px = 16;         // grid spacing of the patch centres, >= 1
  int search_px = 16;       // largest shift searched in x and y, >= 1
  double min_score = 0.25;  // NCC peak below this is dropped (NCC only)
  double min_contrast_db = 0.4;  // reference patches with a smaller std dev are skipped
  // Throws ConfigError naming the field when a value is out of range.
  void Check() const;
};

// Dispatches to the matcher. `valid` (CV_8U, same size, optional/empty)
// marks reference pixels usable as patch centres.
std::vector<Correspondence> Match(Matcher matcher, const cv::Mat& reference_log,
                                  const cv::Mat& observed_log, const MatchOptions& options,
                                  const cv::Mat& valid = cv::Mat());

std::vector<Correspondence> DenseNccMatch(const cv::Mat& reference_log, const cv::Mat& observed_log,
                                          const MatchOptions& options, const cv::Mat& valid = cv::Mat());
std::vector<Correspondence> ChamferMatch(const cv::Mat& reference_log, const cv::Mat& observed_log,
                                         const MatchOptions& options, const cv::Mat& valid = cv::Mat());
std::vector<Correspondence> FeatureMatch(const cv::Mat& reference_log, const cv::Mat& observed_log,
                                         const MatchOptions& options, const cv::Mat& valid = cv::Mat());

// Zero-mean normalised cross-correlation of two same-size CV_32F images
// over the pixels where `mask` (CV_8U, optional) is non-zero; 0 when either
// is constant there.
double ImageNcc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask = cv::Mat());

}  // namespace gissar::nav
