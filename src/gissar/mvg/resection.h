// Camera resection: the affine SAR camera (heading, depression, pixel
// spacings, principal point) from control points with known 3D positions.
//
// Two stages: (1) the general affine camera by linear least squares (each
// image coordinate is an affine function of (X, Y, Z): two independent
// 4-parameter fits, on centred and scaled coordinates); (2) Levenberg-
// Marquardt refinement of the six SAR parameters (heading, depression,
// 1/range spacing, 1/azimuth spacing, u0, v0; the scene centre Xc and the look
// side fixed) started from the decomposition of (1), minimising the sum of
// squared pixel residuals (the maximum likelihood estimate under isotropic
// Gaussian pixel noise).
//
// Failures: fewer than 4 control points, non-finite values or invalid
// options throw gissar::InputError (gissar::ConfigError for options);
// coplanar control points (the linear problem has rank < 4) or a refinement
// that leaves the radar geometry (depression outside (0, 90)) give
// std::nullopt.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/point_match.h"

namespace gissar::mvg {

// The least-squares affine camera (3x4, last row [0 0 0 1]) through the
// control points. Throws InputError for fewer than 4 points or non-finite
// values; std::nullopt when the points are coplanar (or collinear).
std::optional<AffineMatrix> ResectAffineCameraLinear(const std::vector<ControlPoint>& points);

struct ResectionOptions {
  // Xc (ENU metres), held fixed: the refined (u0, v0) is its pixel.
  Eigen::Vector3d scene_centre = Eigen::Vector3d::Zero();
  // Look side; unset: taken from the linear camera's decomposition.
  std::optional<LookSide> look_side;
  // Measured slant range (metres, > 0) from the sensor to Xc; when set the
  // result includes the sensor position Xc - R l.
  std::optional<double> slant_range_m;
  // Pixel noise (standard deviation per coordinate, pixels) for the
  // parameter covariance; unset: estimated from the residuals as
  // sqrt(sum r² / (2N - 6)).
  std::optional<double> pixel_sigma_px;
  int max_iterations = 100;  // Levenberg-Marquardt iterations, >= 1
  // Throws ConfigError naming the field when a value is out of range.
  void Check() const;
};

struct ResectionResult {
  SarPose pose;                                    // refined heading, depression, spacings, u0, v0
  AffineMatrix camera;                             // AffineSarCamera(pose).Matrix()
  AffineMatrix linear_camera;                      // stage (1), unconstrained
  AffineCameraDecomposition linear_decomposition;  // stage (1) read as SAR camera
  // RMS reprojection distance sqrt(sum |x - P X|² / N), pixels, of the
  // refined and of the linear camera.
  double rms_px = 0.0;
  double linear_rms_px = 0.0;
  std::vector<double> residuals_px;  // |x - P X| per control point, refined camera
  // One-sigma standard deviations from the Gauss-Newton covariance
  // sigma² (J'J)^-1 at the solution (NaN when 2N <= 6 and no pixel sigma is
  // given): degrees, metres, pixels.
  double heading_sigma_deg = 0.0;
  double depression_sigma_deg = 0.0;
  double range_spacing_sigma_m = 0.0;
  double azimuth_spacing_sigma_m = 0.0;
  double u0_sigma_px = 0.0;
  double v0_sigma_px = 0.0;
  std::optional<Eigen::Vector3d> sensor_position;  // ENU metres, when slant_range_m is set
  int iterations = 0;
  bool converged = false;  // the relative step fell below 1e-12
};

// Both stages. Throws as described at the top; std::nullopt for coplanar
// points or a depression leaving (0, 90) degrees.
std::optional<ResectionResult> ResectSarCamera(const std::vector<ControlPoint>& points,
                                               const ResectionOptions& options = {});

}  // namespace gissar::mvg
