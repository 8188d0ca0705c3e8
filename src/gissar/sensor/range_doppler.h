// Range-Doppler geometry of a real acquisition: an orbit (or flight track)
// given by state vectors, the zero-Doppler radar grid of a focused product,
// geo2rdr (ground point -> azimuth time, slant range) and rdr2geo (pixel ->
// ground point on a height model), on the WGS84 ellipsoid. Frames: ECEF
// (WGS84) metres for positions, seconds since the product's epoch for times,
// WGS84 geodetic (lon_deg, lat_deg, ellipsoidal height_m) for ground points.
// See docs/geometry.md ("Real sensor geometry").
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "gissar/sensor/sar_geometry.h"

namespace gissar::sensor {

// Position, velocity and acceleration of the antenna phase centre (ECEF).
struct OrbitState {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d acceleration_mps2 = Eigen::Vector3d::Zero();
};

// State vectors interpolated as focusing processors do. Position: piecewise
// cubic Hermite polynomials (between two consecutive vectors, the unique cubic
// matching both positions and both velocities; C1-continuous). Velocity (the
// one the zero-Doppler condition uses): the Lagrange cubic through the
// velocities of the four nearest vectors, not the derivative of the position
// cubic; acceleration: that cubic's derivative. Real state vectors are not
// exactly each other's derivatives (Sentinel-1 stripmap annotations: about
// 1 cm/s), and ESA's processor puts the interpolated velocities in the Doppler
// equation: with the position cubic's derivative instead, zero-Doppler times
// move by up to 0.37 lines between vectors (docs/sentinel1.md). Both are exact
// for a trajectory that is a cubic polynomial in time. With 2 or 3 vectors the
// velocity is the position cubic's derivative.
class Orbit {
 public:
  static constexpr size_t kVelocityPoints = 4;

  // Throws InputError when there are fewer than 2 vectors, the lengths
  // differ, a value is not finite or the times are not strictly increasing.
  Orbit(std::vector<double> time_s, std::vector<Eigen::Vector3d> position_m,
        std::vector<Eigen::Vector3d> velocity_mps);

  // State at time t; outside [start, end] the first or last cubic is
  // extrapolated (callers check Covers()).
  OrbitState Interpolate(double time_s) const;
  bool Covers(double time_s) const { return time_s >= time_s_.front() && time_s <= time_s_.back(); }
  double start_time_s() const { return time_s_.front(); }
  double end_time_s() const { return time_s_.back(); }
  size_t size() const { return time_s_.size(); }

 private:
  std::vector<double> time_s_;
  std::vector<Eigen::Vector3d> position_m_, velocity_mps_;
};

// The zero-Doppler radar grid of a focused image: line i at time
// t0 + i dt, bin j at slant range r0 + j dr; pixel centres at integers.
struct RadarGrid {
  double t0_s = 0.0;
  double dt_s = 0.0;   // > 0
  int rows = 0;
  double r0_m = 0.0;
  double dr_m = 0.0;   // > 0
  int cols = 0;
  LookSide look_side = LookSide::kRight;
  double wavelength_m = 0.0;

  double TimeOfRow(double row) const { return t0_s + row * dt_s; }
  double RangeOfCol(double col) const { return r0_m + col * dr_m; }
  double RowOfTime(double time_s) const { return (time_s - t0_s) / dt_s; }
  double ColOfRange(double range_m) const { return (range_m - r0_m) / dr_m; }
};

// Azimuth time and slant range of a point.
struct RadarCoordinate {
  double time_s = 0.0;
  double range_m = 0.0;
};

struct Geo2RdrOptions {
  double time_tolerance_s = 1e-10;  // stop when a Newton step is below this
  int max_iterations = 50;
};

// Zero-Doppler time and slant range of the ECEF point `target_ecef`: the time
// t at which the line of sight is perpendicular to the velocity,
// v(t).(X - p(t)) = 0, by Newton iteration from `time_guess_s`, and
// |X - p(t)|. nullopt when Newton does not converge or t falls outside the
// orbit's span.
std::optional<RadarCoordinate> Geo2Rdr(const Orbit& orbit, const Eigen::Vector3d& target_ecef,
                                       double time_guess_s, const Geo2RdrOptions& options = {});

// True when `target_ecef` lies on the `side` of the track at zero-Doppler
// time `time_s` (right: along v x up, up = geocentric radial).
bool IsOnSide(const Orbit& orbit, const Eigen::Vector3d& target_ecef, double time_s, LookSide side);

// Height of the surface (metres above the WGS84 ellipsoid) at WGS84
// (lon_deg, lat_deg); nullopt outside the height model.
using HeightFunction = std::function<std::optional<double>(double lon_deg, double lat_deg)>;

struct Rdr2GeoOptions {
  double height_tolerance_m = 1e-4;  // fixed-point convergence on the height
  int max_iterations = 50;
  double initial_height_m = 0.0;     // start of the iteration (a mean terrain height)
};

// Ground point (lon_deg, lat_deg, height_m) imaged at azimuth time `time_s`
// and slant range `range_m` on `side`: the point of the zero-Doppler plane at
// that range whose ellipsoidal height equals the surface height below it.
// Solved as ISCE does: for a trial height h, the point at height h (a 1-D
// Newton solve of the look angle), then h <- surface height there, until h
// changes by less than the tolerance (relaxed by halving the step when it
// oscillates on steep slopes). nullopt when the range does not reach the
// trial height, the height model has no value there or it does not converge.
std::optional<Eigen::Vector3d> Rdr2Geo(const Orbit& orbit, double time_s, double range_m, LookSide side,
                                       const HeightFunction& height, const Rdr2GeoOptions& options = {});

// The point at ellipsoidal height `height_m` imaged at (time_s, range_m) on
// `side` (ECEF); nullopt when the range cannot reach that height.
std::optional<Eigen::Vector3d> PointAtHeight(const OrbitState& state, double range_m, LookSide side,
                                             double height_m);

}  // namespace gissar::sensor
