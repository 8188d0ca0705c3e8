#include "gissar/mvg/affine_camera.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Geometry>

#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRadToDeg = 180.0 / M_PI;

std::string Num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

}  // namespace


Eigen::Matrix3d SarRotation(double heading_deg, double depression_deg, LookSide look_side) {
  const Eigen::Vector3d l = LookDirection(heading_deg, depression_deg, look_side);
  const Eigen::Vector3d h = FlightDirection(heading_deg);
  Eigen::Matrix3d r;
  r.row(0) = l.transpose();
  r.row(1) = h.transpose();
  r.row(2) = l.cross(h).transpose();
  return r;
}

AffineSarCamera::AffineSarCamera(const SarPose& pose) : pose_(pose) {
  if (!std::isfinite(pose.heading_deg)) throw ConfigError("heading must be finite", "heading_deg");
  if (!std::isfinite(pose.depression_deg) || pose.depression_deg <= 0.0 ||
      pose.depression_deg >= 90.0) {
    throw ConfigError("depression must be in (0, 90) degrees, got " + Num(pose.depression_deg),
                      "depression_deg");
  }
  if (!std::isfinite(pose.range_spacing_m) || pose.range_spacing_m <= 0.0) {
    throw ConfigError("range pixel spacing must be positive, got " + Num(pose.range_spacing_m),
                      "range_spacing_m");
  }
  if (!std::isfinite(pose.azimuth_spacing_m) || pose.azimuth_spacing_m <= 0.0) {
    throw ConfigError("azimuth pixel spacing must be positive, got " + Num(pose.azimuth_spacing_m),
                      "azimuth_spacing_m");
  }
  if (!pose.scene_centre.allFinite())
    throw ConfigError("scene centre must be finite", "scene_centre");
  if (!std::isfinite(pose.u0) || !std::isfinite(pose.v0)) {
    throw ConfigError("principal point must be finite", "u0/v0");
  }
  l_ = LookDirection(pose.heading_deg, pose.depression_deg, pose.look_side);
  h_ = FlightDirection(pose.heading_deg);
  n_ = l_.cross(h_);
}

Eigen::Matrix3d AffineSarCamera::Rotation() const {
  Eigen::Matrix3d r;
  r.row(0) = l_.transpose();
  r.row(1) = h_.transpose();
  r.row(2) = n_.transpose();
  return r;
}

Eigen::Matrix3d SarIntrinsics(double range_spacing_m, double azimuth_spacing_m, double u0,
                              double v0) {
  if (!std::isfinite(range_spacing_m) || range_spacing_m <= 0.0) {
    throw ConfigError("range pixel spacing must be positive, got " + Num(range_spacing_m),
                      "range_spacing_m");
  }
  if (!std::isfinite(azimuth_spacing_m) || azimuth_spacing_m <= 0.0) {
    throw ConfigError("azimuth pixel spacing must be positive, got " + Num(azimuth_spacing_m),
                      "azimuth_spacing_m");
  }
  if (!std::isfinite(u0) || !std::isfinite(v0)) {
    throw ConfigError("principal point must be finite", "u0/v0");
  }
  Eigen::Matrix3d c = Eigen::Matrix3d::Identity();
  c(0, 0) = 1.0 / range_spacing_m;
  c(1, 1) = 1.0 / azimuth_spacing_m;
  c(0, 2) = u0;
  c(1, 2) = v0;
  return c;
}

Eigen::Matrix3d AffineSarCamera::Intrinsics() const {
  return SarIntrinsics(pose_.range_spacing_m, pose_.azimuth_spacing_m, pose_.u0, pose_.v0);
}

Eigen::Matrix4d AffineSarCamera::Extrinsics() const {
  Eigen::Matrix4d g = Eigen::Matrix4d::Identity();
  const Eigen::Matrix3d r = Rotation();
  g.topLeftCorner<3, 3>() = r;
  g.topRightCorner<3, 1>() = -r * pose_.scene_centre;
  return g;
}

AffineMatrix AffineSarCamera::Matrix() const {
  Eigen::Matrix<double, 3, 4> p_par = Eigen::Matrix<double, 3, 4>::Zero();
  p_par(0, 0) = 1.0;
  p_par(1, 1) = 1.0;
  p_par(2, 3) = 1.0;
  return Intrinsics() * p_par * Extrinsics();
}

Eigen::Vector2d AffineSarCamera::Project(const Eigen::Vector3d& world) const {
  const Eigen::Vector3d d = world - pose_.scene_centre;
  return {l_.dot(d) / pose_.range_spacing_m + pose_.u0,
          h_.dot(d) / pose_.azimuth_spacing_m + pose_.v0};
}

Eigen::Vector3d AffineSarCamera::SensorPosition(double slant_range_m) const {
  if (!std::isfinite(slant_range_m) || slant_range_m <= 0.0) {
    throw ConfigError("slant range must be positive, got " + Num(slant_range_m), "slant_range_m");
  }
  return pose_.scene_centre - slant_range_m * l_;
}

void CheckAffineCamera(const AffineMatrix& camera, const std::string& what) {
  if (!camera.allFinite()) throw InputError("camera matrix has a non-finite entry", what);
  const Eigen::RowVector4d last(0.0, 0.0, 0.0, 1.0);
  if ((camera.row(2) - last).cwiseAbs().maxCoeff() > 1e-12) {
    throw InputError("camera matrix is not affine: its last row must be [0 0 0 1]", what);
  }
}

AffineCameraDecomposition DecomposeAffineCamera(const AffineRows& rows,
                                                const Eigen::Vector3d& scene_centre) {
  if (!rows.allFinite() || !scene_centre.allFinite()) {
    throw InputError("affine camera or scene centre has a non-finite entry", "camera");
  }
  const Eigen::Vector3d m1 = rows.block<1, 3>(0, 0).transpose();
  const Eigen::Vector3d m2 = rows.block<1, 3>(1, 0).transpose();
  if (m1.norm() == 0.0 || m2.norm() == 0.0) {
    throw InputError("affine camera has a row with a zero 3D part", "camera");
  }
  const Eigen::Vector3d l = m1.normalized();
  const Eigen::Vector3d h = m2.normalized();

  AffineCameraDecomposition out;
  SarPose& pose = out.pose;
  double heading = std::atan2(h.x(), h.y()) * kRadToDeg;
  if (heading < 0.0) heading += 360.0;
  if (heading >= 360.0) heading -= 360.0;
  pose.heading_deg = heading;
  const Eigen::Vector3d r_h_right = LookDirection(heading, 0.0, LookSide::kRight);
  const Eigen::Vector2d l_xy = l.head<2>();
  pose.look_side = l_xy.dot(r_h_right.head<2>()) >= 0.0 ? LookSide::kRight : LookSide::kLeft;
  pose.depression_deg = std::atan2(-l.z(), l_xy.norm()) * kRadToDeg;
  pose.range_spacing_m = 1.0 / m1.norm();
  pose.azimuth_spacing_m = 1.0 / m2.norm();
  pose.scene_centre = scene_centre;
  pose.u0 = m1.dot(scene_centre) + rows(0, 3);
  pose.v0 = m2.dot(scene_centre) + rows(1, 3);
  out.skew_deg = std::acos(std::clamp(l.dot(h), -1.0, 1.0)) * kRadToDeg - 90.0;
  out.flight_elevation_deg = std::asin(std::clamp(h.z(), -1.0, 1.0)) * kRadToDeg;
  return out;
}

AffineCameraDecomposition DecomposeAffineCamera(const AffineMatrix& camera,
                                                const Eigen::Vector3d& scene_centre) {
  CheckAffineCamera(camera, "camera");
  return DecomposeAffineCamera(AffineRows(camera.topRows<2>()), scene_centre);
}

}  // namespace gissar::mvg
