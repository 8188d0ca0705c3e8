#include "gissar/mvg/stereo.h"

#include <cmath>
#include <string>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

// The stacked system of two affine cameras.
struct StereoSystem {
  Eigen::Matrix<double, 4, 3> a;
  Eigen::Vector4d t;
  Eigen::Matrix3d normal_inverse;  // (A'A)^-1
};

std::optional<StereoSystem> MakeSystem(const AffineMatrix& camera1, const AffineMatrix& camera2,
                                       double pixel_sigma_px) {
  CheckAffineCamera(camera1, "camera 1");
  CheckAffineCamera(camera2, "camera 2");
  if (!std::isfinite(pixel_sigma_px) || pixel_sigma_px < 0.0) {
    throw InputError("pixel sigma must be finite and >= 0", "pixel_sigma_px");
  }
  StereoSystem s;
  s.a.topRows<2>() = camera1.block<2, 3>(0, 0);
  s.a.bottomRows<2>() = camera2.block<2, 3>(0, 0);
  s.t << camera1(0, 3), camera1(1, 3), camera2(0, 3), camera2(1, 3);
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix<double, 4, 3>>(s.a).singularValues();
  if (!(sv(0) > 0.0) || sv(2) <= 1e-9 * sv(0)) return std::nullopt;
  s.normal_inverse = (s.a.transpose() * s.a).inverse();
  return s;
}

StereoPoint Solve(const StereoSystem& s, const PointMatch& match, double pixel_sigma_px,
                  size_t index) {
  if (!match.p1.allFinite() || !match.p2.allFinite()) {
    throw InputError("match has a non-finite coordinate (NaN or infinity)",
                     "matches, match " + std::to_string(index));
  }
  const Eigen::Vector4d b =
      Eigen::Vector4d(match.p1.x(), match.p1.y(), match.p2.x(), match.p2.y()) - s.t;
  StereoPoint out;
  out.position = s.normal_inverse * (s.a.transpose() * b);
  out.covariance = pixel_sigma_px * pixel_sigma_px * s.normal_inverse;
  out.height_m = out.position.z();
  out.height_sigma_m = std::sqrt(out.covariance(2, 2));
  out.residual_px = (s.a * out.position - b).norm();
  return out;
}

}  // namespace

std::optional<StereoPoint> Triangulate(const AffineMatrix& camera1, const AffineMatrix& camera2,
                                       const PointMatch& match, double pixel_sigma_px) {
  const std::optional<StereoSystem> s = MakeSystem(camera1, camera2, pixel_sigma_px);
  if (!s) return std::nullopt;
  return Solve(*s, match, pixel_sigma_px, 0);
}

std::optional<std::vector<StereoPoint>> TriangulateAll(const AffineMatrix& camera1,
                                                       const AffineMatrix& camera2,
                                                       const std::vector<PointMatch>& matches,
                                                       double pixel_sigma_px) {
  const std::optional<StereoSystem> s = MakeSystem(camera1, camera2, pixel_sigma_px);
  if (!s) return std::nullopt;
  std::vector<StereoPoint> out;
  out.reserve(matches.size());
  for (size_t i = 0; i < matches.size(); ++i)
    out.push_back(Solve(*s, matches[i], pixel_sigma_px, i));
  return out;
}

std::optional<double> HeightSigma(const AffineMatrix& camera1, const AffineMatrix& camera2,
                                  double pixel_sigma_px) {
  const std::optional<StereoSystem> s = MakeSystem(camera1, camera2, pixel_sigma_px);
  if (!s) return std::nullopt;
  return pixel_sigma_px * std::sqrt(s->normal_inverse(2, 2));
}

}  // namespace gissar::mvg
