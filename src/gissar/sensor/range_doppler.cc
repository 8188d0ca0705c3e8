#include "gissar/sensor/range_doppler.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "gissar/geo/local_frame.h"
#include "gissar/util/error.h"

namespace gissar::sensor {

using Eigen::Vector3d;

Orbit::Orbit(std::vector<double> time_s, std::vector<Vector3d> position_m, std::vector<Vector3d> velocity_mps)
    : time_s_(std::move(time_s)), position_m_(std::move(position_m)), velocity_mps_(std::move(velocity_mps)) {
  if (time_s_.size() < 2) throw InputError("an orbit needs at least 2 state vectors", "orbit");
  if (position_m_.size() != time_s_.size() || velocity_mps_.size() != time_s_.size()) {
    throw InputError("orbit times, positions and velocities differ in length", "orbit");
  }
  for (size_t i = 0; i < time_s_.size(); ++i) {
    if (!std::isfinite(time_s_[i]) || !position_m_[i].allFinite() || !velocity_mps_[i].allFinite()) {
      throw InputError("orbit state vector " + std::to_string(i) + " is not finite", "orbit");
    }
    if (i > 0 && !(time_s_[i] > time_s_[i - 1])) {
      throw InputError("orbit times are not strictly increasing at vector " + std::to_string(i), "orbit");
    }
  }
}

OrbitState Orbit::Interpolate(double t) const {
  const auto it = std::upper_bound(time_s_.begin(), time_s_.end(), t);
  size_t i = it == time_s_.begin() ? 0 : size_t(it - time_s_.begin()) - 1;
  i = std::min(i, time_s_.size() - 2);
  const double h = time_s_[i + 1] - time_s_[i];
  const double s = (t - time_s_[i]) / h;
  const Vector3d& p0 = position_m_[i];
  const Vector3d& p1 = position_m_[i + 1];
  const Vector3d m0 = h * velocity_mps_[i];
  const Vector3d m1 = h * velocity_mps_[i + 1];
  const double s2 = s * s, s3 = s2 * s;
  OrbitState state;
  state.position_m = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1;
  if (time_s_.size() < kVelocityPoints) {
    // Too few vectors for the velocity interpolation: the cubic's derivatives.
    state.velocity_mps =
        ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1) / h;
    state.acceleration_mps2 =
        ((12 * s - 6) * p0 + (6 * s - 4) * m0 + (-12 * s + 6) * p1 + (6 * s - 2) * m1) / (h * h);
    return state;
  }
  // Velocity: the Lagrange cubic through the velocities of the four nearest
  // vectors (two each side of t where the orbit allows), and its derivative.
  const size_t first = std::min(i > 0 ? i - 1 : size_t{0}, time_s_.size() - kVelocityPoints);
  state.velocity_mps.setZero();
  state.acceleration_mps2.setZero();
  for (size_t j = first; j < first + kVelocityPoints; ++j) {
    double basis = 1.0, derivative = 0.0;
    for (size_t k = first; k < first + kVelocityPoints; ++k) {
      if (k == j) continue;
      const double inverse_gap = 1.0 / (time_s_[j] - time_s_[k]);
      derivative = derivative * (t - time_s_[k]) * inverse_gap + basis * inverse_gap;
      basis *= (t - time_s_[k]) * inverse_gap;
    }
    state.velocity_mps += basis * velocity_mps_[j];
    state.acceleration_mps2 += derivative * velocity_mps_[j];
  }
  return state;
}

std::optional<RadarCoordinate> Geo2Rdr(const Orbit& orbit, const Vector3d& target, double time_guess_s,
                                       const Geo2RdrOptions& options) {
  double t = std::clamp(time_guess_s, orbit.start_time_s(), orbit.end_time_s());
  for (int k = 0; k < options.max_iterations; ++k) {
    const OrbitState s = orbit.Interpolate(t);
    const Vector3d d = target - s.position_m;
    const double f = s.velocity_mps.dot(d);
    const double df = s.acceleration_mps2.dot(d) - s.velocity_mps.squaredNorm();
    if (!(std::abs(df) > 0.0)) return std::nullopt;
    const double step = f / df;
    t -= step;
    if (!std::isfinite(t) || t < orbit.start_time_s() - 1.0 || t > orbit.end_time_s() + 1.0) return std::nullopt;
    if (std::abs(step) < options.time_tolerance_s) {
      if (!orbit.Covers(t)) return std::nullopt;
      return RadarCoordinate{t, (target - orbit.Interpolate(t).position_m).norm()};
    }
  }
  return std::nullopt;
}

bool IsOnSide(const Orbit& orbit, const Vector3d& target, double time_s, LookSide side) {
  const OrbitState s = orbit.Interpolate(time_s);
  const double right = s.velocity_mps.cross(s.position_m.normalized()).dot(target - s.position_m);
  return side == LookSide::kRight ? right > 0.0 : right < 0.0;
}

std::optional<Vector3d> PointAtHeight(const OrbitState& state, double range_m, LookSide side, double height_m) {
  // Orthonormal basis of the zero-Doppler plane: d (down, the geocentric
  // nadir made perpendicular to v) and c (right of track: d x v).
  const Vector3d v = state.velocity_mps.normalized();
  const Vector3d& p = state.position_m;
  const Vector3d down = (-p.normalized() + p.normalized().dot(v) * v).normalized();
  const Vector3d c = down.cross(v) * (side == LookSide::kRight ? 1.0 : -1.0);
  const Vector3d llh = geo::LocalFrame::GeodeticFromEcef(p);
  const double sensor_height = llh.z();
  if (!(range_m > sensor_height - height_m)) return std::nullopt;  // the range does not reach down
  // Initial look angle: sphere of the local radius through the target height.
  const Vector3d nadir = geo::LocalFrame::EcefFromGeodetic(llh.x(), llh.y(), 0.0);
  const double earth = nadir.norm() + height_m;
  const double cos_a = (p.squaredNorm() + range_m * range_m - earth * earth) / (2.0 * p.norm() * range_m);
  double a = std::acos(std::clamp(cos_a, -1.0, 1.0));
  auto height_of = [&](double angle) {
    const Vector3d x = p + range_m * (std::cos(angle) * down + std::sin(angle) * c);
    return geo::LocalFrame::GeodeticFromEcef(x).z();
  };
  for (int k = 0; k < 30; ++k) {
    const double g = height_of(a) - height_m;
    if (std::abs(g) < 1e-7) break;
    const double da = 1e-7;
    const double slope = (height_of(a + da) - height_of(a - da)) / (2 * da);
    if (!(std::abs(slope) > 1e-6)) return std::nullopt;
    a -= g / slope;
    if (!(a > 0.0 && a < M_PI)) return std::nullopt;
  }
  if (std::abs(height_of(a) - height_m) > 1e-4) return std::nullopt;
  return Vector3d(p + range_m * (std::cos(a) * down + std::sin(a) * c));
}

std::optional<Vector3d> Rdr2Geo(const Orbit& orbit, double time_s, double range_m, LookSide side,
                                const HeightFunction& height, const Rdr2GeoOptions& options) {
  const OrbitState state = orbit.Interpolate(time_s);
  double h = options.initial_height_m;
  double relax = 1.0;
  double previous_change = std::numeric_limits<double>::infinity();
  for (int k = 0; k < options.max_iterations; ++k) {
    const auto x = PointAtHeight(state, range_m, side, h);
    if (!x) return std::nullopt;
    const Vector3d llh = geo::LocalFrame::GeodeticFromEcef(*x);
    const auto surface = height(llh.x(), llh.y());
    if (!surface) return std::nullopt;
    const double change = *surface - h;
    if (std::abs(change) < options.height_tolerance_m) return Vector3d(llh.x(), llh.y(), *surface);
    if (std::abs(change) > 0.9 * previous_change) relax *= 0.5;  // oscillating: damp
    previous_change = std::abs(change);
    h += relax * change;
  }
  return std::nullopt;
}

}  // namespace gissar::sensor
