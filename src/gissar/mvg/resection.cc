#include "gissar/mvg/resection.h"

#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>

#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRadToDeg = 180.0 / M_PI;

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

void CheckPoints(const std::vector<ControlPoint>& points) {
  if (points.size() < 4) {
    throw InputError(
        "resection needs at least 4 control points, got " + std::to_string(points.size()),
        "control points");
  }
  CheckFinite(points, "control points");
}

// The SAR camera model with parameters p = (psi, delta [rad], 1/res_r,
// 1/res_az, u0, v0) and fixed Xc and look side.
struct SarModel {
  std::vector<Eigen::Vector3d> d;  // X - Xc
  std::vector<Eigen::Vector2d> x;  // observed pixels
  double side = 1.0;               // +1 right, -1 left

  // Residuals (predicted - observed), 2 per point, and optionally the Jacobian.
  void Evaluate(const Vector6d& p, Eigen::VectorXd* r,
                Eigen::Matrix<double, Eigen::Dynamic, 6>* j) const {
    const double cp = std::cos(p(0)), sp = std::sin(p(0));
    const double cd = std::cos(p(1)), sd = std::sin(p(1));
    const Eigen::Vector3d rh = side * Eigen::Vector3d(cp, -sp, 0.0);
    const Eigen::Vector3d l = cd * rh - sd * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d h(sp, cp, 0.0);
    const Eigen::Vector3d dl_dpsi = cd * side * Eigen::Vector3d(-sp, -cp, 0.0);
    const Eigen::Vector3d dl_ddelta = -sd * rh - cd * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d dh_dpsi(cp, -sp, 0.0);
    const int n = static_cast<int>(d.size());
    r->resize(2 * n);
    if (j != nullptr) j->setZero(2 * n, 6);
    for (int i = 0; i < n; ++i) {
      const double ld = l.dot(d[i]);
      const double hd = h.dot(d[i]);
      (*r)(2 * i) = p(2) * ld + p(4) - x[i].x();
      (*r)(2 * i + 1) = p(3) * hd + p(5) - x[i].y();
      if (j == nullptr) continue;
      j->row(2 * i) << p(2) * dl_dpsi.dot(d[i]), p(2) * dl_ddelta.dot(d[i]), ld, 0.0, 1.0, 0.0;
      j->row(2 * i + 1) << p(3) * dh_dpsi.dot(d[i]), 0.0, 0.0, hd, 0.0, 1.0;
    }
  }
};

double RmsDistance(const Eigen::VectorXd& r) {
  const Eigen::Index n = r.size() / 2;
  return n == 0 ? 0.0 : std::sqrt(r.squaredNorm() / static_cast<double>(n));
}

}  // namespace

std::optional<AffineMatrix> ResectAffineCameraLinear(const std::vector<ControlPoint>& points) {
  CheckPoints(points);
  const int n = static_cast<int>(points.size());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const ControlPoint& p : points) mean += p.world;
  mean /= n;
  double scale = 0.0;
  for (const ControlPoint& p : points) scale += (p.world - mean).squaredNorm();
  scale = std::sqrt(scale / n);
  if (!(scale > 0.0)) return std::nullopt;
  Eigen::MatrixXd a(n, 4);
  Eigen::MatrixXd b(n, 2);
  for (int i = 0; i < n; ++i) {
    a.block<1, 3>(i, 0) = ((points[i].world - mean) / scale).transpose();
    a(i, 3) = 1.0;
    b.row(i) = points[i].pixel.transpose();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a.leftCols<3>());
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(0) > 0.0) || sv(2) <= 1e-9 * sv(0)) return std::nullopt;
  const Eigen::MatrixXd m = a.colPivHouseholderQr().solve(b);  // 4 x 2
  AffineMatrix camera = AffineMatrix::Zero();
  for (int row = 0; row < 2; ++row) {
    const Eigen::Vector3d lin = m.block<3, 1>(0, row) / scale;
    camera.block<1, 3>(row, 0) = lin.transpose();
    camera(row, 3) = m(3, row) - lin.dot(mean);
  }
  camera(2, 3) = 1.0;
  return camera;
}

void ResectionOptions::Check() const {
  if (!scene_centre.allFinite()) throw ConfigError("scene centre must be finite", "scene_centre");
  if (slant_range_m && (!std::isfinite(*slant_range_m) || *slant_range_m <= 0.0)) {
    throw ConfigError("slant range must be positive", "slant_range_m");
  }
  if (pixel_sigma_px && (!std::isfinite(*pixel_sigma_px) || *pixel_sigma_px <= 0.0)) {
    throw ConfigError("pixel sigma must be positive", "pixel_sigma_px");
  }
  if (max_iterations < 1) throw ConfigError("max_iterations must be >= 1", "max_iterations");
}

std::optional<ResectionResult> ResectSarCamera(const std::vector<ControlPoint>& points,
                                               const ResectionOptions& options) {
  options.Check();
  const std::optional<AffineMatrix> linear = ResectAffineCameraLinear(points);
  if (!linear) return std::nullopt;
  ResectionResult out;
  out.linear_camera = *linear;
  out.linear_decomposition = DecomposeAffineCamera(*linear, options.scene_centre);
  const SarPose& start = out.linear_decomposition.pose;
  const LookSide look = options.look_side.value_or(start.look_side);

  SarModel model;
  model.side = look == LookSide::kRight ? 1.0 : -1.0;
  for (const ControlPoint& p : points) {
    model.d.push_back(p.world - options.scene_centre);
    model.x.push_back(p.pixel);
  }
  {
    Eigen::VectorXd r(2 * points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector2d pred = linear->topRows<2>() * points[i].world.homogeneous();
      r.segment<2>(2 * i) = pred - points[i].pixel;
    }
    out.linear_rms_px = RmsDistance(r);
  }

  // Levenberg-Marquardt with Marquardt's diagonal scaling.
  Vector6d p;
  p << start.heading_deg * kDegToRad, start.depression_deg * kDegToRad, 1.0 / start.range_spacing_m,
      1.0 / start.azimuth_spacing_m, start.u0, start.v0;
  Eigen::VectorXd r;
  Eigen::Matrix<double, Eigen::Dynamic, 6> jac;
  model.Evaluate(p, &r, &jac);
  double cost = r.squaredNorm();
  double lambda = -1.0;
  int iterations = 0;
  bool converged = false;
  while (iterations < options.max_iterations && !converged) {
    ++iterations;
    const Matrix6d jtj = jac.transpose() * jac;
    const Vector6d jtr = jac.transpose() * r;
    if (lambda < 0.0) lambda = 1e-3 * jtj.diagonal().maxCoeff();
    bool accepted = false;
    while (!accepted) {
      Matrix6d a = jtj;
      a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
      const Vector6d step = a.ldlt().solve(-jtr);
      const Vector6d trial = p + step;
      Eigen::VectorXd r_trial;
      model.Evaluate(trial, &r_trial, nullptr);
      const double trial_cost = r_trial.squaredNorm();
      if (trial_cost <= cost) {
        const bool small_step =
            step.cwiseAbs().cwiseQuotient(p.cwiseAbs().cwiseMax(1e-6)).maxCoeff() < 1e-12;
        const bool small_gain = cost - trial_cost <= 1e-15 * cost;
        p = trial;
        cost = trial_cost;
        model.Evaluate(p, &r, &jac);
        lambda = std::max(lambda / 10.0, 1e-15);
        accepted = true;
        converged = small_step || small_gain || cost == 0.0;
      } else {
        lambda *= 10.0;
        if (lambda > 1e20) {
          converged = true;  // no step decreases the cost: at the minimum
          break;
        }
      }
    }
  }
  out.iterations = iterations;
  out.converged = converged;

  const double heading = std::fmod(std::fmod(p(0) * kRadToDeg, 360.0) + 360.0, 360.0);
  const double depression = p(1) * kRadToDeg;
  if (!(depression > 0.0 && depression < 90.0) || !(p(2) > 0.0) || !(p(3) > 0.0)) {
    return std::nullopt;
  }
  SarPose& pose = out.pose;
  pose.heading_deg = heading;
  pose.depression_deg = depression;
  pose.look_side = look;
  pose.range_spacing_m = 1.0 / p(2);
  pose.azimuth_spacing_m = 1.0 / p(3);
  pose.scene_centre = options.scene_centre;
  pose.u0 = p(4);
  pose.v0 = p(5);
  const AffineSarCamera camera(pose);
  out.camera = camera.Matrix();
  out.rms_px = RmsDistance(r);
  out.residuals_px.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) out.residuals_px[i] = r.segment<2>(2 * i).norm();

  const int dof = 2 * static_cast<int>(points.size()) - 6;
  double sigma2 = std::numeric_limits<double>::quiet_NaN();
  if (options.pixel_sigma_px) {
    sigma2 = (*options.pixel_sigma_px) * (*options.pixel_sigma_px);
  } else if (dof > 0) {
    sigma2 = r.squaredNorm() / dof;
  }
  const Matrix6d jtj = jac.transpose() * jac;
  const Eigen::FullPivLU<Matrix6d> lu(jtj);
  Matrix6d cov = Matrix6d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (lu.isInvertible()) cov = sigma2 * lu.inverse();
  out.heading_sigma_deg = std::sqrt(cov(0, 0)) * kRadToDeg;
  out.depression_sigma_deg = std::sqrt(cov(1, 1)) * kRadToDeg;
  out.range_spacing_sigma_m = std::sqrt(cov(2, 2)) / (p(2) * p(2));
  out.azimuth_spacing_sigma_m = std::sqrt(cov(3, 3)) / (p(3) * p(3));
  out.u0_sigma_px = std::sqrt(cov(4, 4));
  out.v0_sigma_px = std::sqrt(cov(5, 5));
  if (options.slant_range_m) out.sensor_position = camera.SensorPosition(*options.slant_range_m);
  return out;
}

}  // namespace gissar::mvg
