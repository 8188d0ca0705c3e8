// Stereo (radargrammetric) triangulation with two known affine cameras:
// the 3D position, and so the height, of a point from its pixels in both
// images (its parallax), with the error propagated from the pixel noise.
//
// The two cameras give four linear equations M X = x - t in the three
// unknowns X (ENU metres); their least-squares solution is the maximum
// likelihood estimate under isotropic Gaussian pixel noise of standard
// deviation sigma, with covariance sigma² (A'A)^-1, A the stacked 4x3 matrix
// of the cameras' first two rows. The one redundant equation measures the
// epipolar inconsistency of the pair.
//
// Failures: a camera that is not affine, non-finite pixels or a negative
// sigma throw gissar::InputError; cameras that cannot triangulate (A of
// rank < 3, e.g. identical views) give std::nullopt.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/point_match.h"

namespace gissar::mvg {

struct StereoPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    // ENU metres
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // of `position`, m²
  double height_m = 0.0;                                 // position.z()
  double height_sigma_m = 0.0;  // sqrt(covariance(2, 2)): one-sigma height error
  // Distance (pixels) of the four observed coordinates from the nearest
  // consistent ones, |A X - (x - t)|: 0 for a pair on its epipolar line.
  double residual_px = 0.0;
};

// Triangulates `match` (p1 in the image of `camera1`, p2 in that of
// `camera2`) with pixel noise `pixel_sigma_px` (standard deviation per
// coordinate, pixels, >= 0).
std::optional<StereoPoint> Triangulate(const AffineMatrix& camera1, const AffineMatrix& camera2,
                                       const PointMatch& match, double pixel_sigma_px);

// The same for many matches (one result per match, in order); std::nullopt
// when the cameras cannot triangulate.
std::optional<std::vector<StereoPoint>> TriangulateAll(const AffineMatrix& camera1,
                                                       const AffineMatrix& camera2,
                                                       const std::vector<PointMatch>& matches,
                                                       double pixel_sigma_px);

// One-sigma height error (metres) the camera pair gives for pixel noise
// `pixel_sigma_px`; independent of the point (affine cameras). std::nullopt
// when the cameras cannot triangulate. Throws as Triangulate.
std::optional<double> HeightSigma(const AffineMatrix& camera1, const AffineMatrix& camera2,
                                  double pixel_sigma_px);

}  // namespace gissar::mvg
