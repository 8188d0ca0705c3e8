// The affine SAR camera P_SAR = C_SAR P_par G_perp (thesis section 3.4.3)
// and its decomposition back into a SAR pose.
//
// Conventions (tests/data/affine/README.md, docs/geometry.md):
//  - world frame ENU (x East, y North, z Up), metres;
//  - heading psi clockwise from North, flight direction h = [sin psi, cos psi, 0];
//  - right-looking horizontal look r_h = [cos psi, -sin psi, 0] (left: -r_h);
//    line of sight l = cos(delta) r_h - sin(delta) z for depression delta;
//  - R = [l; h; n] (rows) with n = l x h, G_perp = [R, -R Xc; 0 0 0 1],
//    P_par = [1 0 0 0; 0 1 0 0; 0 0 0 1],
//    C_SAR = [1/res_r 0 u0; 0 1/res_az v0; 0 0 1];
//  - pixel x (column) = slant range increasing away from the radar, pixel y
//    (row) = azimuth along the flight; pixel centres at integer coordinates;
//    the scene centre Xc projects to (u0, v0).
#pragma once

#include "gissar/sensor/sar_geometry.h"

#include <string>

#include <Eigen/Core>

namespace gissar::mvg {

// The simulator's geometry conventions (one definition for both).
using LookSide = sensor::LookSide;
using sensor::FlightDirection;
using sensor::LookDirection;
using sensor::ToString;

using AffineMatrix = Eigen::Matrix<double, 3, 4>;  // 3x4 camera, last row [0 0 0 1]
using AffineRows = Eigen::Matrix<double, 2, 4>;    // its first two rows

// The pose and sampling of one SAR image in the affine model.
struct SarPose {
  double heading_deg = 0.0;      // flight direction, degrees clockwise from North
  double depression_deg = 45.0;  // of the line of sight at Xc, degrees in (0, 90)
  LookSide look_side = LookSide::kRight;
  double range_spacing_m = 1.0;    // slant-range pixel spacing, metres, > 0
  double azimuth_spacing_m = 1.0;  // azimuth pixel spacing, metres, > 0
  // Scene centre Xc, ENU metres.
  Eigen::Vector3d scene_centre = Eigen::Vector3d::Zero();
  double u0 = 0.0;  // column (pixels) of Xc
  double v0 = 0.0;  // row (pixels) of Xc
};

// Rotation R = [l; h; n] (rows: line of sight, flight direction, slant-range
// plane normal n = l x h) of a heading/depression (degrees) and look side:
// the virtual orthographic camera G_perp. No validation: any finite values.
Eigen::Matrix3d SarRotation(double heading_deg, double depression_deg, LookSide look_side);

// C_SAR = [1/range_spacing 0 u0; 0 1/azimuth_spacing v0; 0 0 1] (metres of
// slant range / azimuth -> pixels). Throws ConfigError when a spacing is not
// positive and finite or u0, v0 are not finite.
Eigen::Matrix3d SarIntrinsics(double range_spacing_m, double azimuth_spacing_m, double u0 = 0.0,
                              double v0 = 0.0);

class AffineSarCamera {
 public:
  // Throws gissar::ConfigError naming the field when a value is not finite,
  // the depression is outside (0, 90) degrees or a spacing is not positive.
  explicit AffineSarCamera(const SarPose& pose);

  const SarPose& pose() const { return pose_; }

  // Unit vectors (ENU): line of sight l, flight direction h, n = l x h (the
  // direction along which the affine camera cannot resolve position).
  const Eigen::Vector3d& look_direction() const { return l_; }
  const Eigen::Vector3d& flight_direction() const { return h_; }
  const Eigen::Vector3d& range_plane_normal() const { return n_; }

  // R = [l; h; n] (rows): world ENU -> virtual orthographic camera frame.
  Eigen::Matrix3d Rotation() const;
  // C_SAR: metric (slant range, azimuth) in metres -> pixels.
  Eigen::Matrix3d Intrinsics() const;
  // G_perp = [R, -R Xc; 0 0 0 1].
  Eigen::Matrix4d Extrinsics() const;
  // P_SAR = C_SAR P_par G_perp; homogeneous world (X, 1) -> homogeneous pixel.
  AffineMatrix Matrix() const;

  // Pixel (x, y) of world point `world` (ENU metres).
  Eigen::Vector2d Project(const Eigen::Vector3d& world) const;

  // Sensor position (ENU metres) for a measured slant range (metres, > 0)
  // from the sensor to Xc: Xc - slant_range_m * l. Throws ConfigError when
  // slant_range_m is not positive and finite.
  Eigen::Vector3d SensorPosition(double slant_range_m) const;

 private:
  SarPose pose_;
  Eigen::Vector3d l_, h_, n_;
};

// A general affine camera read as a SAR camera.
struct AffineCameraDecomposition {
  // heading (in [0, 360)), depression (may fall outside (0, 90) for a camera
  // that is not a radar looking down), look side, spacings (1/|row|), the
  // given scene centre and its pixel (u0, v0).
  SarPose pose;
  // How far the camera is from the SAR form, 0 for a SAR camera: the angle
  // between the two row directions minus 90 degrees, and the elevation of
  // the second row direction (the flight direction) above the horizontal.
  double skew_deg = 0.0;
  double flight_elevation_deg = 0.0;
};

// Reads an affine camera (rows x = m1 . (X, 1), y = m2 . (X, 1)) as a SAR
// camera with scene centre `scene_centre` (ENU metres): l = m1/|m1|,
// h = m2/|m2|, heading = atan2(h_x, h_y), depression = atan2(-l_z, |l_xy|),
// look side from the sign of l_xy . r_h, spacings 1/|m1|, 1/|m2| (in the
// first three columns), (u0, v0) = the pixel of `scene_centre`. Exact for a
// camera made by AffineSarCamera::Matrix(). Throws InputError when an entry
// is not finite, a row has a zero 3D part, or (3x4 form) the last row is
// not [0 0 0 1].
AffineCameraDecomposition DecomposeAffineCamera(
    const AffineRows& rows, const Eigen::Vector3d& scene_centre = Eigen::Vector3d::Zero());
AffineCameraDecomposition DecomposeAffineCamera(
    const AffineMatrix& camera, const Eigen::Vector3d& scene_centre = Eigen::Vector3d::Zero());

// Throws InputError (where = `what`) unless `camera` is finite with last row
// [0 0 0 1] (exactly, up to 1e-12).
void CheckAffineCamera(const AffineMatrix& camera, const std::string& what);

}  // namespace gissar::mvg
