#include "gissar/nav/product_locate.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "gissar/image/impulse_response.h"
#include "gissar/image/radiometry.h"
#include "gissar/nav/nav_testing.h"
#include "gissar/render/product_renderer.h"
#include "gissar/util/error.h"

namespace gissar::nav {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A straight, level track in the ENU frame of `frame`: heading `heading_deg`,
// speed `speed_mps`, through `start_enu` at time 0; state vectors every 2 s
// from -span to +span seconds (ECEF).
TrackVectors StraightTrack(const geo::LocalFrame& frame, const Eigen::Vector3d& start_enu, double heading_deg,
                           double speed_mps, double span_s) {
  const Eigen::Vector3d f(std::sin(heading_deg * kDeg), std::cos(heading_deg * kDeg), 0.0);
  auto ecef = [&](const Eigen::Vector3d& enu) {
    const Eigen::Vector3d llh = frame.GeodeticFromEnu(enu);
    return geo::LocalFrame::EcefFromGeodetic(llh.x(), llh.y(), llh.z());
  };
  TrackVectors t;
  for (double s = -span_s; s <= span_s + 1e-9; s += 2.0) {
    const Eigen::Vector3d enu = start_enu + speed_mps * s * f;
    t.time_s.push_back(s);
    t.position_m.push_back(ecef(enu));
    t.velocity_mps.push_back((ecef(enu + 0.5 * f) - ecef(enu - 0.5 * f)) * speed_mps);
  }
  return t;
}

TEST(TrackOffsetTest, DisplacementHasTheGivenComponentsAndTurnsTheTrack) {
  const geo::LocalFrame frame(7.4, 43.7, 0.0);
  const TrackVectors track = StraightTrack(frame, {-6000.0, 0.0, 6000.0}, 30.0, 150.0, 20.0);
  const sensor::Orbit orbit = track.ToOrbit();
  const TrackFrame f = TrackFrameAt(orbit, 0.0);
  // The frame: along the velocity (heading 30 deg), cross to its right, up.
  const Eigen::Vector3d east = (geo::LocalFrame::EcefFromGeodetic(7.4001, 43.7, 0) -
                                geo::LocalFrame::EcefFromGeodetic(7.3999, 43.7, 0)).normalized();
  EXPECT_NEAR((f.along.cross(f.up) - f.cross).norm(), 0.0, 1e-12);  // right of along, horizontal
  EXPECT_NEAR(f.along.dot(f.up), 0.0, 1e-12);
  // 30 deg in the ENU frame at the origin; at the sensor 5.2 km west, north
  // turns by the meridian convergence (-0.045 deg).
  EXPECT_NEAR(TrackAngleDeg(orbit, 0.0), 30.0 - 0.045, 0.01);
  EXPECT_GT(f.cross.dot(east), 0.8);  // heading 30: the right-hand side is east-south-east

  // A shift: every position moves by exactly (along, cross, up) in that frame.
  const TrackVectors moved = DisplaceTrack(track, f, {10.0, -20.0, 5.0, 0.0});
  for (size_t i = 0; i < track.time_s.size(); ++i) {
    const Eigen::Vector3d d = f.Components(moved.position_m[i] - track.position_m[i]);
    EXPECT_NEAR(d.x(), 10.0, 1e-6);
    EXPECT_NEAR(d.y(), -20.0, 1e-6);
    EXPECT_NEAR(d.z(), 5.0, 1e-6);
    EXPECT_NEAR((moved.velocity_mps[i] - track.velocity_mps[i]).norm(), 0.0, 1e-9);
  }
  // A turn of +90 deg (clockwise seen from above) takes along to cross; the
  // sensor at the frame time stays where it was; the track angle turns by +2 deg for +2.
  const TrackVectors turned = DisplaceTrack(track, f, {0.0, 0.0, 0.0, 90.0});
  const sensor::Orbit turned_orbit = turned.ToOrbit();
  EXPECT_NEAR((turned_orbit.Interpolate(0.0).position_m - f.origin_ecef).norm(), 0.0, 1e-6);
  EXPECT_NEAR(turned_orbit.Interpolate(0.0).velocity_mps.normalized().dot(f.cross), 1.0, 1e-6);
  EXPECT_NEAR(TrackAngleDeg(DisplaceTrack(track, f, {0.0, 0.0, 0.0, 2.0}).ToOrbit(), 0.0) - TrackAngleDeg(orbit, 0.0),
              2.0, 1e-9);
}

TEST(MultilookTest, GridPixelsSitAtTheBlockCentres) {
  sensor::RadarGrid g;
  g.t0_s = 10.0;
  g.dt_s = 0.5;
  g.rows = 5;
  g.r0_m = 1000.0;
  g.dr_m = 2.0;
  g.cols = 7;
  const sensor::RadarGrid m = MultilookGrid(g, 2, 3);
  EXPECT_DOUBLE_EQ(m.t0_s, 10.25);  // the centre of lines 0 and 1
  EXPECT_DOUBLE_EQ(m.dt_s, 1.0);
  EXPECT_EQ(m.rows, 2);
  EXPECT_DOUBLE_EQ(m.r0_m, 1002.0);  // the centre of bins 0..2
  EXPECT_DOUBLE_EQ(m.dr_m, 6.0);
  EXPECT_EQ(m.cols, 2);
}

// Every matcher finds a known placement of a crop in its reference.
TEST(ShiftScoresTest, EveryMatcherPeaksAtTheKnownShift) {
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  cv::Mat reference(60, 80, CV_32F);
  for (int y = 0; y < reference.rows; ++y)
    for (int x = 0; x < reference.cols; ++x) reference.at<float>(y, x) = noise(rng);
  cv::GaussianBlur(reference, reference, cv::Size(5, 5), 1.2);
  const cv::Mat observed = reference(cv::Rect(7, 4, 60, 44)).clone();  // u = 7, v = 4
  for (ShiftMatcher m : {ShiftMatcher::kNcc, ShiftMatcher::kGradient, ShiftMatcher::kPhase,
                         ShiftMatcher::kMutualInformation}) {
    const cv::Mat scores = ShiftScores(m, reference, observed);
    ASSERT_EQ(scores.rows, 17);
    ASSERT_EQ(scores.cols, 21);
    cv::Point best;
    cv::minMaxLoc(scores, nullptr, nullptr, nullptr, &best);
    EXPECT_EQ(best, cv::Point(7, 4)) << ToString(m);
  }
  EXPECT_EQ(ParseShiftMatcher("mi", "--matcher"), ShiftMatcher::kMutualInformation);
  EXPECT_THROW(ParseShiftMatcher("chamfer", "--matcher"), ConfigError);
}

using testing::Hills;

// The geometry of the LocateProductTests: a straight track (heading 30,
// 150 m/s, 6 km up, right-looking, the scene centre 6 km to its right) and a
// side x side zero-Doppler grid of 10 m lines and 10 m bins centred on the
// scene centre at time 0.
struct StraightTrackProduct {
  TrackVectors truth;
  ProductObservation observed;
};
StraightTrackProduct StraightTrackGeometry(const geo::LocalFrame& frame, int side) {
  StraightTrackProduct p;
  const Eigen::Vector3d right(std::cos(30.0 * kDeg), -std::sin(30.0 * kDeg), 0.0);
  p.truth = StraightTrack(frame, -6000.0 * right + Eigen::Vector3d(0, 0, 6000.0), 30.0, 150.0, 40.0);
  sensor::RadarGrid& g = p.observed.grid;
  g.dt_s = 10.0 / 150.0;
  g.rows = side;
  g.t0_s = -0.5 * side * g.dt_s;
  g.dr_m = 10.0;
  g.cols = side;
  g.r0_m = std::hypot(6000.0, 6000.0) - 0.5 * side * g.dr_m;
  g.look_side = sensor::LookSide::kRight;
  g.wavelength_m = 0.031;
  return p;
}

// A known track recovered: the observed image is simulated (with 4-look
// speckle) on a zero-Doppler grid from a straight track; the prior is that
// track moved 60 m along and -45 m across (and 0.05 deg in heading). The
// vertical is held by the prior's 2 m sigma: a chip cannot separate it from
// cross-track.
TEST(LocateProductTest, RecoversAKnownTrackOffset) {
  const geo::LocalFrame frame(7.4, 43.7, 0.0);
  const scene::TriangleMesh mesh = Hills();
  const render::EmbreeScene embree(mesh);
  const material::MaterialTable materials;
  const NavScene scene{&mesh, &embree, &materials, 4.0, 1};
  auto [truth, observed] = StraightTrackGeometry(frame, 120);
  const sensor::RadarGrid& g = observed.grid;
  render::RenderOptions ro;
  ro.rays_per_cell = 4.0;
  ro.max_bounces = 1;
  ro.wavelength_m = g.wavelength_m;
  observed.intensity = render::RenderProduct(embree, mesh, materials, frame, truth.ToOrbit(), g, ro).image.intensity;
  image::ApplyMultiplicativeSpeckle(observed.intensity, 4.0, 11);

  const sensor::Orbit truth_orbit = truth.ToOrbit();
  const TrackFrame f = TrackFrameAt(truth_orbit, 0.0);
  ProductLocateOptions options;
  options.looks_range = options.looks_azimuth = 2;  // 20 m cells
  options.prior_sigma = {60.0, 60.0, 2.0, 0.05};
  // A shift alone is recovered within a quarter cell. A heading error moves
  // the scene's zero-Doppler time like an along-track shift (by the ground
  // range, 6 km, times the angle: 5 m for 0.05 deg), and the chip's shear
  // separates them only partly: half a cell, within the stated sigmas.
  for (const auto& [offset, tolerance_cells] :
       std::vector<std::pair<TrackOffset, double>>{{{60.0, -45.0, 0.0, 0.0}, 0.25}, {{60.0, -45.0, 0.0, 0.05}, 0.5}}) {
    const TrackVectors prior = DisplaceTrack(truth, f, offset);
    const ProductLocateResult r = LocateProduct(scene, frame, observed, prior, options);
    ASSERT_TRUE(r.converged) << r.failure_reason;
    EXPECT_NEAR(r.fix_time_s, g.TimeOfRow(59.5), 1e-9);
    EXPECT_DOUBLE_EQ(r.cell_m, 20.0);
    const Eigen::Vector3d true_position = truth_orbit.Interpolate(r.fix_time_s).position_m;
    const Eigen::Vector3d prior_error = prior.ToOrbit().Interpolate(r.fix_time_s).position_m - true_position;
    const Eigen::Vector3d error = f.Components(r.sensor_ecef - true_position);
    std::printf("[ measured ] heading offset %.2f deg: prior error %.1f m -> fix error %.2f m (along/cross/up %.2f "
                "%.2f %.2f; sigmas %.1f %.1f %.1f), %d renders\n",
                offset.heading_deg, prior_error.norm(), error.norm(), error.x(), error.y(), error.z(),
                std::sqrt(r.covariance(0, 0)), std::sqrt(r.covariance(1, 1)), std::sqrt(r.covariance(2, 2)),
                r.renders);
    EXPECT_GT(prior_error.norm(), 70.0);
    EXPECT_LT(error.norm(), tolerance_cells * r.cell_m);
    EXPECT_LT(std::abs(error.x()), 3.0 * std::sqrt(r.covariance(0, 0)));
    EXPECT_LT(std::abs(error.y()), 3.0 * std::sqrt(r.covariance(1, 1)));
  }
}

// An 8 km square plane at height 0 (class 0): ground with nothing to match.
scene::TriangleMesh FlatPlane() {
  scene::TriangleMesh mesh;
  mesh.vertices = {{-4000, -4000, 0}, {4000, -4000, 0}, {4000, 4000, 0}, {-4000, 4000, 0}};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  mesh.classes = {0, 0};
  return mesh;
}

// Nothing to match (a flat plane): no fix, with a reason.
TEST(LocateProductTest, FlatTerrainGivesNoFix) {
  const geo::LocalFrame frame(7.4, 43.7, 0.0);
  const scene::TriangleMesh mesh = FlatPlane();
  const render::EmbreeScene embree(mesh);
  const material::MaterialTable materials;
  const NavScene scene{&mesh, &embree, &materials, 4.0, 1};
  auto [truth, observed] = StraightTrackGeometry(frame, 80);
  const sensor::RadarGrid& g = observed.grid;
  observed.intensity.assign(size_t(g.rows) * g.cols, 1.0f);
  image::ApplyMultiplicativeSpeckle(observed.intensity, 4.0, 2);
  const ProductLocateResult r = LocateProduct(scene, frame, observed, truth, ProductLocateOptions());
  EXPECT_FALSE(r.converged);
  EXPECT_FALSE(r.failure_reason.empty());
  std::printf("[ measured ] flat plane: %s\n", r.failure_reason.c_str());
}

// Point landmarks on flat ground (issue 45 item 3): a trihedral on a flat
// plane, in the observed image with 4-look speckle on the clutter. As a
// landmark it fixes along and cross track within a metre or two from a prior
// 50 m along and -40 m across; up and heading are the prior's (the fix says
// so, and their covariance is the prior's). Without it in the observed image
// the landmark has no peak: no fix, the reason naming its row.
TEST(LocateProductTest, LandmarkFixesAlongAndCrossOnFlatGround) {
  const geo::LocalFrame frame(7.4, 43.7, 0.0);
  const scene::TriangleMesh mesh = FlatPlane();
  const render::EmbreeScene embree(mesh);
  const material::MaterialTable materials;
  auto [truth, observed] = StraightTrackGeometry(frame, 80);
  const sensor::RadarGrid& g = observed.grid;
  const Eigen::Vector3d right(std::cos(30.0 * kDeg), -std::sin(30.0 * kDeg), 0.0);
  render::SceneReflector trihedral;
  trihedral.size_m = 1.0;
  trihedral.apex_enu = Eigen::Vector3d(100.0, -50.0, 0.5);
  trihedral.boresight_enu = (-6000.0 * right + Eigen::Vector3d(0, 0, 6000.0) - trihedral.apex_enu).normalized();
  trihedral.row = 7;
  const std::vector<render::SceneReflector> landmarks = {trihedral};
  render::RenderOptions ro;
  ro.rays_per_cell = 4.0;
  ro.max_bounces = 1;
  ro.wavelength_m = g.wavelength_m;
  ro.reflectors = landmarks;
  render::ProductImage img = render::RenderProduct(embree, mesh, materials, frame, truth.ToOrbit(), g, ro);
  ASSERT_EQ(img.image.points.size(), 1u);
  image::ApplyMultiplicativeSpeckle(img.image.intensity, 4.0, 5);
  const std::vector<float> clutter_only = img.image.intensity;
  image::SensorEffects psf;
  psf.range_resolution_px = psf.azimuth_resolution_px = 1.5;
  image::AddPointIntensities(img.image, psf);
  observed.intensity = img.image.intensity;

  const NavScene scene{&mesh, &embree, &materials, 4.0, 1, &landmarks};
  const sensor::Orbit truth_orbit = truth.ToOrbit();
  const TrackFrame f = TrackFrameAt(truth_orbit, 0.0);
  ProductLocateOptions options;
  options.looks_range = options.looks_azimuth = 2;
  options.prior_sigma = {60.0, 60.0, 2.0, 0.01};
  const TrackVectors prior = DisplaceTrack(truth, f, {50.0, -40.0, 0.0, 0.0});
  const ProductLocateResult r = LocateProduct(scene, frame, observed, prior, options);
  ASSERT_TRUE(r.converged) << r.failure_reason;
  EXPECT_EQ(r.source, "landmarks");
  EXPECT_EQ(r.from_image, (std::array<bool, 4>{true, true, false, false}));
  ASSERT_EQ(r.landmarks.size(), 1u);
  EXPECT_TRUE(r.landmarks[0].used);
  EXPECT_EQ(r.landmarks[0].row, 7);
  const Eigen::Vector3d error = f.Components(r.sensor_ecef - truth_orbit.Interpolate(r.fix_time_s).position_m);
  std::printf("[ measured ] landmark on a flat plane: fix error along/cross/up %.2f %.2f %.2f m (sigmas %.2f %.2f %.2f), "
              "peak %.1f dB over the clutter median\n",
              error.x(), error.y(), error.z(), std::sqrt(r.covariance(0, 0)), std::sqrt(r.covariance(1, 1)),
              std::sqrt(r.covariance(2, 2)), r.landmarks[0].contrast_db);
  EXPECT_LT(std::abs(error.x()), 3.0);
  EXPECT_LT(std::abs(error.y()), 3.0);
  EXPECT_NEAR(r.covariance(2, 2), 4.0, 1e-9);   // the prior's
  EXPECT_NEAR(r.covariance(3, 3), 1e-4, 1e-12);
  EXPECT_EQ(r.covariance(2, 3), 0.0);
  EXPECT_NE(r.covariance(1, 2), 0.0);  // cross carries the prior's vertical error along the line of sight

  observed.intensity = clutter_only;  // the landmark is not in the image
  const ProductLocateResult none = LocateProduct(scene, frame, observed, prior, options);
  EXPECT_FALSE(none.converged);
  std::printf("[ measured ] landmark absent: %s\n", none.failure_reason.c_str());
  EXPECT_NE(none.failure_reason.find("row 7"), std::string::npos) << none.failure_reason;
}

}  // namespace
}  // namespace gissar::nav
