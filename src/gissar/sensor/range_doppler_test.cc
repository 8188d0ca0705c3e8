#include "gissar/sensor/range_doppler.h"

#include <gtest/gtest.h>

#include <random>

#include "gissar/geo/local_frame.h"
#include "gissar/util/error.h"

namespace gissar::sensor {
namespace {

using Eigen::Vector3d;
using geo::LocalFrame;

// A cubic trajectory p(t) = a + b t + c t^2 + d t^3 sampled at irregular
// times: Hermite interpolation reproduces it (and its derivatives) exactly.
TEST(OrbitTest, HermiteIsExactOnCubicTrajectory) {
  const Vector3d a(-528670.0, -4145426.0, 4818706.0), b(-135.5, 138.7, 103.8), c(0.02, -0.03, 0.01),
      d(-1e-4, 2e-4, 5e-5);
  auto pos = [&](double t) { return Vector3d(a + b * t + c * t * t + d * t * t * t); };
  auto vel = [&](double t) { return Vector3d(b + 2 * c * t + 3 * d * t * t); };
  auto acc = [&](double t) { return Vector3d(2 * c + 6 * d * t); };
  std::vector<double> times = {0.0, 6.5, 14.0, 20.0, 27.5, 35.0};
  std::vector<Vector3d> p, v;
  for (double t : times) {
    p.push_back(pos(t));
    v.push_back(vel(t));
  }
  const Orbit orbit(times, p, v);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 35.0);
  for (int k = 0; k < 200; ++k) {
    const double t = u(rng);
    const OrbitState s = orbit.Interpolate(t);
    EXPECT_LT((s.position_m - pos(t)).norm(), 1e-6) << t;
    EXPECT_LT((s.velocity_mps - vel(t)).norm(), 1e-8) << t;
    EXPECT_LT((s.acceleration_mps2 - acc(t)).norm(), 1e-8) << t;
  }
  EXPECT_TRUE(orbit.Covers(0.0));
  EXPECT_FALSE(orbit.Covers(35.01));
}

// Velocities that are not the positions' derivatives (as in real state
// vectors, by millimetres per second): the orbit's velocity is the Lagrange
// cubic through the given velocities, here a quadratic in time, reproduced
// exactly with its derivative, while the position stays the Hermite cubic.
// With two vectors the velocity is the position cubic's derivative.
TEST(OrbitTest, VelocityInterpolatesTheGivenVelocities) {
  const Vector3d p0(5144003.8, 4431712.6, -2003048.0), v0(2635.4, 148.0, 7119.2), w(1e-4, -2e-4, 3e-4);
  std::vector<double> times = {0.0, 10.0, 20.0, 30.0, 40.0, 50.0};
  std::vector<Vector3d> p, v;
  for (double t : times) {
    p.push_back(p0 + v0 * t);
    v.push_back(v0 + w * t * t);
  }
  const Orbit orbit(times, p, v);
  for (double t : {0.0, 3.0, 15.0, 27.5, 44.0, 50.0}) {
    const OrbitState s = orbit.Interpolate(t);
    EXPECT_LT((s.velocity_mps - (v0 + w * t * t)).norm(), 1e-9) << t;
    EXPECT_LT((s.acceleration_mps2 - 2.0 * w * t).norm(), 1e-9) << t;
  }
  // At the vectors the position is the given one.
  EXPECT_LT((orbit.Interpolate(20.0).position_m - p[2]).norm(), 1e-6);

  const Orbit two({0.0, 10.0}, {p[0], p[1]}, {v[0], v[1]});
  // The Hermite cubic between (p0, v0) and (p0 + 10 v0, v0 + 100 w) has at
  // s = 1/2 the derivative 1.5 (p1 - p0) / h - (v_0 + v_1) / 4
  // = 1.5 v0 - 0.25 (2 v0 + 100 w) = v0 - 25 w.
  EXPECT_LT((two.Interpolate(5.0).velocity_mps - (v0 - 25.0 * w)).norm(), 1e-9);
}

TEST(OrbitTest, RejectsBadStateVectors) {
  const Vector3d z = Vector3d::Zero();
  EXPECT_THROW(Orbit({0.0}, {z}, {z}), InputError);
  EXPECT_THROW(Orbit({0.0, 0.0}, {z, z}, {z, z}), InputError);
  EXPECT_THROW(Orbit({0.0, 1.0}, {z, z}, {z}), InputError);
  EXPECT_THROW(Orbit({0.0, 1.0}, {z, Vector3d(NAN, 0, 0)}, {z, z}), InputError);
}

// A straight, constant-velocity track (no acceleration): the zero-Doppler
// time has the closed form t* = v.(X - p0) / |v|^2 and the range |X - p(t*)|.
struct StraightTrack {
  Vector3d p0, v;
  Orbit orbit;
  static StraightTrack Make() {
    const Vector3d p0 = LocalFrame::EcefFromGeodetic(-97.7, 49.47, 12500.0);
    // 220 m/s towards north-west, level.
    const Vector3d east = LocalFrame::EcefFromGeodetic(-97.6999, 49.47, 12500.0) - p0;
    const Vector3d north = LocalFrame::EcefFromGeodetic(-97.7, 49.4701, 12500.0) - p0;
    const Vector3d vel = 220.0 * (-east.normalized() + north.normalized()).normalized();
    std::vector<double> t;
    std::vector<Vector3d> p, vv;
    for (int i = -10; i <= 10; ++i) {
      t.push_back(7.0 * i);
      p.push_back(p0 + vel * 7.0 * i);
      vv.push_back(vel);
    }
    return {p0, vel, Orbit(t, p, vv)};
  }
};

TEST(Geo2RdrTest, MatchesClosedFormOnStraightTrack) {
  const StraightTrack track = StraightTrack::Make();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> lon(-97.8, -97.6), lat(49.4, 49.55), h(0.0, 500.0);
  for (int k = 0; k < 100; ++k) {
    const Vector3d x = LocalFrame::EcefFromGeodetic(lon(rng), lat(rng), h(rng));
    const double t_star = track.v.dot(x - track.p0) / track.v.squaredNorm();
    const double r_star = (x - (track.p0 + track.v * t_star)).norm();
    const auto rc = Geo2Rdr(track.orbit, x, 0.0);
    ASSERT_TRUE(rc.has_value());
    EXPECT_NEAR(rc->time_s, t_star, 1e-9);
    EXPECT_NEAR(rc->range_m, r_star, 1e-6);
  }
  // Outside the track's time span: no solution.
  const Vector3d far = track.p0 + track.v * 1000.0;
  EXPECT_FALSE(Geo2Rdr(track.orbit, far, 0.0).has_value());
}

TEST(Rdr2GeoTest, PointAtHeightHasThatRangeHeightAndZeroDoppler) {
  const StraightTrack track = StraightTrack::Make();
  const OrbitState s = track.orbit.Interpolate(3.0);
  for (LookSide side : {LookSide::kLeft, LookSide::kRight}) {
    const auto x = PointAtHeight(s, 14000.0, side, 240.0);
    ASSERT_TRUE(x.has_value());
    EXPECT_NEAR((*x - s.position_m).norm(), 14000.0, 1e-6);
    EXPECT_NEAR(LocalFrame::GeodeticFromEcef(*x).z(), 240.0, 1e-4);
    EXPECT_NEAR(s.velocity_mps.normalized().dot((*x - s.position_m).normalized()), 0.0, 1e-12);
    EXPECT_TRUE(IsOnSide(track.orbit, *x, 3.0, side));
  }
  // A range shorter than the height difference cannot reach the ground.
  EXPECT_FALSE(PointAtHeight(s, 12000.0, LookSide::kLeft, 240.0).has_value());
}

// rdr2geo then geo2rdr returns the pixel: < 1 mm in range, < 1 us in time,
// on a sloping surface, on a curved (cubic) track.
TEST(Rdr2GeoTest, RoundTripWithGeo2RdrBelowOneMillimetre) {
  std::vector<double> t;
  std::vector<Vector3d> p, v;
  const Vector3d p0 = LocalFrame::EcefFromGeodetic(-118.42, 34.17, 12500.0);
  const Vector3d vel(250.7, -130.9, 24.2), acc(0.05, 0.08, -0.02);
  for (int i = -10; i <= 10; ++i) {
    const double ti = 21.0 * i;
    t.push_back(ti);
    p.push_back(p0 + vel * ti + 0.5 * acc * ti * ti);
    v.push_back(vel + acc * ti);
  }
  const Orbit orbit(t, p, v);
  const HeightFunction surface = [](double lon, double lat) -> std::optional<double> {
    return 200.0 + 3000.0 * (lon + 118.42) - 2000.0 * (lat - 34.17) + 20.0 * std::sin(400.0 * lon);
  };
  int solved = 0;
  for (double time : {-2.0, 0.0, 1.5}) {
    for (double range : {13500.0, 15000.0, 17000.0}) {
      for (LookSide side : {LookSide::kLeft, LookSide::kRight}) {
        const auto llh = Rdr2Geo(orbit, time, range, side, surface);
        ASSERT_TRUE(llh.has_value()) << time << " " << range;
        EXPECT_NEAR(llh->z(), *surface(llh->x(), llh->y()), 1e-4);
        const Vector3d x = LocalFrame::EcefFromGeodetic(llh->x(), llh->y(), llh->z());
        const auto rc = Geo2Rdr(orbit, x, 0.0);
        ASSERT_TRUE(rc.has_value());
        EXPECT_NEAR(rc->range_m, range, 1e-3);
        EXPECT_NEAR(rc->time_s, time, 1e-6);
        EXPECT_TRUE(IsOnSide(orbit, x, time, side));
        ++solved;
      }
    }
  }
  EXPECT_EQ(solved, 18);
}

TEST(RadarGridTest, RowsAndColumnsInvertTimesAndRanges) {
  RadarGrid g;
  g.t0_s = 100.0;
  g.dt_s = 0.02;
  g.r0_m = 13000.0;
  g.dr_m = 6.25;
  EXPECT_DOUBLE_EQ(g.RowOfTime(g.TimeOfRow(12.5)), 12.5);
  EXPECT_DOUBLE_EQ(g.ColOfRange(g.RangeOfCol(7.25)), 7.25);
  EXPECT_DOUBLE_EQ(g.RangeOfCol(4.0), 13025.0);
}

}  // namespace
}  // namespace gissar::sensor
