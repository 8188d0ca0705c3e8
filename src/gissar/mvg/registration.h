// Image-to-image registration with control-point transforms: similarity,
// affine, projective and 2nd/3rd-order polynomial maps fitted to point
// pairs (optionally robustly), applied to images with OpenCV, and a
// green/magenta composite to inspect the result.
//
// Pairs are PointMatch values with p1 in the FIXED image and p2 in the
// MOVING image (pixels, centres at integer coordinates, as OpenCV). A
// registration's forward transform maps moving -> fixed: p1 ≈ T(p2).
//
// Failures: fewer pairs than the transform needs, non-finite coordinates,
// mismatched images throw gissar::InputError; invalid options throw
// gissar::ConfigError; a degenerate configuration (e.g. collinear points for
// an affine map) or RANSAC finding no model gives std::nullopt.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "gissar/mvg/point_match.h"
#include "gissar/util/enum_table.h"

namespace gissar::mvg {

enum class TransformType { kSimilarity, kAffine, kProjective, kPolynomial2, kPolynomial3 };
inline constexpr auto kTransformTypes = util::MakeEnumTable<TransformType>(
    "transform", {{TransformType::kSimilarity, "similarity"},
                  {TransformType::kAffine, "affine"},
                  {TransformType::kProjective, "projective"},
                  {TransformType::kPolynomial2, "poly2"},
                  {TransformType::kPolynomial3, "poly3"}});

// "similarity", "affine", "projective", "poly2", "poly3".
std::string ToString(TransformType type);
// Inverse of ToString; throws ConfigError naming `option` and the
// transforms otherwise.
TransformType ParseTransformType(const std::string& text, const std::string& option = "transform");
// Pairs needed to fit the transform: 2, 3, 4, 6, 10.
int MinimumControlPoints(TransformType type);

// A map of the image plane (pixels -> pixels).
class PlaneTransform {
 public:
  // The identity, as an affine transform.
  PlaneTransform();
  // Similarity, affine or projective transform with 3x3 matrix `matrix`
  // (homogeneous pixels, p' ~ matrix * (p, 1)). Throws InputError for a
  // polynomial type, a non-finite or singular matrix.
  static PlaneTransform FromMatrix(TransformType type, const Eigen::Matrix3d& matrix);
  // Polynomial of order 2 or 3 in normalised input u = (p - centre) / scale:
  // p' = coefficients * terms(u), terms (1, u, v, u², uv, v²[, u³, u²v, uv², v³]).
  // Throws InputError for a wrong type or shape, non-finite values or
  // scale <= 0.
  static PlaneTransform FromPolynomial(TransformType type, const Eigen::Vector2d& centre,
                                       double scale, const Eigen::MatrixXd& coefficients);

  TransformType type() const { return type_; }
  // The image of `p` (pixels). For a projective map of a point on its line at
  // infinity the result is not finite.
  Eigen::Vector2d Apply(const Eigen::Vector2d& p) const;
  // The 3x3 matrix of a similarity/affine/projective transform (scaled so
  // that m(2,2) = 1 when possible); std::nullopt for polynomials.
  std::optional<Eigen::Matrix3d> Matrix() const;
  // The exact inverse of a similarity/affine/projective transform;
  // std::nullopt for polynomials (fit the inverse instead).
  std::optional<PlaneTransform> Inverse() const;
  // Polynomial normalisation and coefficients (2 x terms); for the other
  // types: centre 0, scale 1 and an empty matrix.
  const Eigen::Vector2d& centre() const { return centre_; }
  double scale() const { return scale_; }
  const Eigen::MatrixXd& coefficients() const { return coefficients_; }

 private:
  TransformType type_ = TransformType::kAffine;
  Eigen::Matrix3d matrix_ = Eigen::Matrix3d::Identity();
  Eigen::Vector2d centre_ = Eigen::Vector2d::Zero();
  double scale_ = 1.0;
  Eigen::MatrixXd coefficients_;
};

// Least-squares fit of `type` mapping from[i] -> to[i] over all pairs or the
// 0-based `subset`: closed form for the similarity (complex least squares,
// the 2-D case of Umeyama's method), linear least squares for the affine and
// polynomial maps (normalised coordinates), normalised DLT refined by
// Levenberg-Marquardt on the transfer error for the projective map. Throws InputError for mismatched sizes, too few pairs or
// non-finite values; std::nullopt when the configuration is degenerate.
std::optional<PlaneTransform> FitPlaneTransform(TransformType type,
                                                const std::vector<Eigen::Vector2d>& from,
                                                const std::vector<Eigen::Vector2d>& to);
std::optional<PlaneTransform> FitPlaneTransform(TransformType type,
                                                const std::vector<Eigen::Vector2d>& from,
                                                const std::vector<Eigen::Vector2d>& to,
                                                const std::vector<int>& subset);

struct RegistrationOptions {
  TransformType type = TransformType::kAffine;
  // With `robust`, RANSAC (MSAC scoring, seeded, adaptive sample count,
  // refit of the inliers until stable) over minimal samples; otherwise one
  // least-squares fit to all pairs.
  bool robust = true;
  double threshold_px = 2.0;   // inlier when |T(p2) - p1| < threshold, fixed-image pixels, > 0
  double confidence = 0.99;    // in (0, 1)
  int max_iterations = 10000;  // >= 1
  int min_iterations = 100;    // in [0, max_iterations]
  uint32_t seed = 1;           // std::mt19937 seed
  int max_refits = 50;         // >= 1
  // Throws ConfigError naming the field when a value is out of range.
  void Check() const;
};

struct Registration {
  TransformType type = TransformType::kAffine;
  PlaneTransform moving_to_fixed;  // p1 ≈ T(p2)
  // The map used to resample the moving image onto the fixed grid: the exact
  // inverse for similarity/affine/projective, a separate least-squares fit
  // (fixed -> moving, on the same inliers) for polynomials.
  PlaneTransform fixed_to_moving;
  std::vector<int> inliers;          // 0-based, increasing (all pairs without `robust`)
  std::vector<double> residuals_px;  // |T(p2) - p1| for every pair, fixed-image pixels
  double rms_px = 0.0;               // RMS of residuals_px over the inliers
  double inverse_rms_px = 0.0;       // RMS |fixed_to_moving(p1) - p2| over the inliers
  int iterations = 0;                // RANSAC samples drawn (0 without `robust`)
};

// Fits `options.type` to the pairs (p1 fixed, p2 moving). Throws InputError
// for fewer than MinimumControlPoints pairs or non-finite coordinates and
// ConfigError for invalid options; std::nullopt when the pairs are
// degenerate for the transform or RANSAC finds no model with at least
// MinimumControlPoints + 1 inliers (or all pairs when there are no more).
std::optional<Registration> RegisterControlPoints(const std::vector<PointMatch>& pairs,
                                                  const RegistrationOptions& options);

// Resamples `moving` (any depth, 1-4 channels) onto the fixed grid of size
// `fixed_size`: output(p) = moving(fixed_to_moving(p)); cv::warpAffine for
// similarity/affine, cv::warpPerspective for projective, cv::remap for
// polynomials; pixels mapping outside `moving` are 0. `interpolation` is an
// OpenCV flag (cv::INTER_NEAREST, cv::INTER_LINEAR, cv::INTER_CUBIC). Throws
// InputError when `moving` is empty or fixed_size is not positive.
cv::Mat WarpToFixed(const cv::Mat& moving, const Registration& registration, cv::Size fixed_size,
                    int interpolation = cv::INTER_LINEAR);

// A CV_8UC3 image in OpenCV's BGR channel order showing `fixed` in green and
// `registered_moving` in magenta (red + blue): aligned structure appears
// grey/white, misalignment as green or magenta fringes. Both images must be
// single-channel with the same size; CV_8U images are used as they are,
// other depths are stretched linearly from their minimum to maximum finite
// value to 0..255 (non-finite pixels are 0); for radar intensities pass a
// dB quicklook. Throws InputError for empty, multi-channel or differently
// sized images.
cv::Mat GreenMagentaComposite(const cv::Mat& fixed, const cv::Mat& registered_moving);

}  // namespace gissar::mvg
