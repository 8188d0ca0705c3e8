#include "gissar/mvg/resection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::JsonMatrix;
using testing::kCase3;
using testing::LoadReferenceCase;

SarPose TruePose() {
  SarPose pose;
  pose.heading_deg = 37.0;
  pose.depression_deg = 42.0;
  pose.look_side = LookSide::kRight;
  pose.range_spacing_m = 0.8;
  pose.azimuth_spacing_m = 1.1;
  pose.scene_centre = {100.0, 200.0, 50.0};
  pose.u0 = 400.5;
  pose.v0 = 600.25;
  return pose;
}

std::vector<ControlPoint> Points(const AffineSarCamera& camera, int count, double extent_m,
                                 double max_height_m, double noise_px, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ground(-extent_m, extent_m);
  std::uniform_real_distribution<double> height(0.0, max_height_m);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<ControlPoint> points;
  for (int i = 0; i < count; ++i) {
    ControlPoint p;
    p.world = camera.pose().scene_centre + Eigen::Vector3d(ground(rng), ground(rng), height(rng));
    p.pixel = camera.Project(p.world);
    if (noise_px > 0.0) p.pixel += Eigen::Vector2d(noise(rng), noise(rng));
    points.push_back(p);
  }
  return points;
}

ResectionOptions OptionsFor(const SarPose& pose) {
  ResectionOptions options;
  options.scene_centre = pose.scene_centre;
  return options;
}

TEST(ResectionTest, NoiseFreeRecoversEveryParameter) {
  const SarPose truth = TruePose();
  const AffineSarCamera camera(truth);
  for (int count : {6, 8, 50}) {
    SCOPED_TRACE(count);
    const auto points = Points(camera, count, 500.0, 200.0, 0.0, 3);
    const auto r = ResectSarCamera(points, OptionsFor(truth));
    ASSERT_TRUE(r.has_value());
    EXPECT_NEAR(r->pose.heading_deg, truth.heading_deg, 1e-6);
    EXPECT_NEAR(r->pose.depression_deg, truth.depression_deg, 1e-6);
    EXPECT_EQ(r->pose.look_side, LookSide::kRight);
    EXPECT_NEAR(r->pose.range_spacing_m, truth.range_spacing_m, 1e-9);
    EXPECT_NEAR(r->pose.azimuth_spacing_m, truth.azimuth_spacing_m, 1e-9);
    EXPECT_NEAR(r->pose.u0, truth.u0, 1e-6);
    EXPECT_NEAR(r->pose.v0, truth.v0, 1e-6);
    EXPECT_LT(r->rms_px, 1e-8);
    EXPECT_LT(r->linear_rms_px, 1e-8);
    EXPECT_LT((r->linear_camera - camera.Matrix()).cwiseAbs().maxCoeff(), 1e-8);
    EXPECT_LT((r->camera - camera.Matrix()).cwiseAbs().maxCoeff(), 1e-8);
    EXPECT_TRUE(r->converged);
    RecordProperty("noisefree_heading_error_deg_n" + std::to_string(count),
                   testing::Sci(std::abs(r->pose.heading_deg - truth.heading_deg)));
  }
}

TEST(ResectionTest, NoisyPointsWithinTolerance) {
  const SarPose truth = TruePose();
  const AffineSarCamera camera(truth);
  const auto points = Points(camera, 100, 1000.0, 400.0, 0.3, 17);
  ResectionOptions options = OptionsFor(truth);
  const auto r = ResectSarCamera(points, options);
  ASSERT_TRUE(r.has_value());
  const double heading_error = r->pose.heading_deg - truth.heading_deg;
  const double depression_error = r->pose.depression_deg - truth.depression_deg;
  EXPECT_NEAR(heading_error, 0.0, 0.05);
  EXPECT_NEAR(depression_error, 0.0, 0.05);
  // The reported one-sigma errors are consistent with the actual errors and
  // the residuals with the noise (RMS distance = sqrt(2) sigma).
  EXPECT_LT(std::abs(heading_error), 4.0 * r->heading_sigma_deg);
  EXPECT_LT(std::abs(depression_error), 4.0 * r->depression_sigma_deg);
  EXPECT_NEAR(r->rms_px, 0.3 * std::sqrt(2.0), 0.06);
  // The unconstrained linear camera minimises the same sum with more freedom.
  EXPECT_GE(r->rms_px, r->linear_rms_px - 1e-12);
  EXPECT_NEAR(r->pose.range_spacing_m, 0.8, 5.0 * r->range_spacing_sigma_m);
  RecordProperty("noisy_heading_error_deg", testing::Sci(heading_error));
  RecordProperty("noisy_depression_error_deg", testing::Sci(depression_error));
  // With a given pixel sigma the covariance uses it.
  options.pixel_sigma_px = 0.3;
  const auto r2 = ResectSarCamera(points, options);
  ASSERT_TRUE(r2.has_value());
  const double sigma_estimated = r->rms_px * std::sqrt(100.0 / (2.0 * 100.0 - 6.0));
  EXPECT_NEAR(r2->heading_sigma_deg / r->heading_sigma_deg, 0.3 / sigma_estimated, 1e-6);
}

// The reference case 3: view 2 (heading 30, depression 45, 0.75 m pixels)
// from its 3D points and image-2 pixels.
TEST(ResectionTest, ReferenceCase3View2) {
  const auto rc = LoadReferenceCase(kCase3);
  const auto xs = rc.Values("X"), ys = rc.Values("Y"), zs = rc.Values("Z");
  const auto xt = rc.Values("x2_true"), yt = rc.Values("y2_true");
  const auto xn = rc.Values("x2"), yn = rc.Values("y2");
  const std::vector<int> inliers = rc.RowsWhereNot("is_outlier");
  std::vector<ControlPoint> exact, noisy;
  for (int i : inliers) {
    exact.push_back({{xs[i], ys[i], zs[i]}, {xt[i], yt[i]}});
    noisy.push_back({{xs[i], ys[i], zs[i]}, {xn[i], yn[i]}});
  }
  const auto r = ResectSarCamera(exact);
  ASSERT_TRUE(r.has_value());
  EXPECT_NEAR(r->pose.heading_deg, 30.0, 1e-6);
  EXPECT_NEAR(r->pose.depression_deg, 45.0, 1e-6);
  EXPECT_NEAR(r->pose.range_spacing_m, 0.75, 1e-9);
  EXPECT_NEAR(r->pose.azimuth_spacing_m, 0.75, 1e-9);
  EXPECT_NEAR(r->pose.u0, 512.0, 1e-6);
  EXPECT_LT((r->camera - JsonMatrix<3, 4>(rc.json["P2"])).cwiseAbs().maxCoeff(), 1e-8);
  // Sigma 0.5 px with heights of only 0..100 m over 1 km: the depression is
  // the weakly determined parameter; the errors stay within the reported
  // uncertainty.
  const auto rn = ResectSarCamera(noisy);
  ASSERT_TRUE(rn.has_value());
  EXPECT_LT(std::abs(rn->pose.heading_deg - 30.0), 4.0 * rn->heading_sigma_deg);
  EXPECT_LT(std::abs(rn->pose.depression_deg - 45.0), 4.0 * rn->depression_sigma_deg);
  EXPECT_NEAR(rn->rms_px, 0.5 * std::sqrt(2.0), 0.1);
  RecordProperty("case3_view2_noisy_heading_deg", testing::Sci(rn->pose.heading_deg));
  RecordProperty("case3_view2_noisy_depression_deg", testing::Sci(rn->pose.depression_deg));
}

TEST(ResectionTest, LeftLookingAndSensorPosition) {
  SarPose truth;
  truth.heading_deg = 0.0;
  truth.depression_deg = 30.0;
  truth.look_side = LookSide::kLeft;  // looking West
  const AffineSarCamera camera(truth);
  ResectionOptions options;
  options.slant_range_m = 10000.0;
  const auto r = ResectSarCamera(Points(camera, 12, 400.0, 100.0, 0.0, 8), options);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->pose.look_side, LookSide::kLeft);
  EXPECT_NEAR(r->pose.depression_deg, 30.0, 1e-6);
  EXPECT_NEAR(std::fmod(r->pose.heading_deg + 180.0, 360.0) - 180.0, 0.0, 1e-6);
  ASSERT_TRUE(r->sensor_position.has_value());
  // Sensor East of the scene (it looks West), 10 km away, 5 km up.
  EXPECT_NEAR(r->sensor_position->x(), 10000.0 * std::cos(M_PI / 6), 1e-5);
  EXPECT_NEAR(r->sensor_position->y(), 0.0, 1e-5);
  EXPECT_NEAR(r->sensor_position->z(), 5000.0, 1e-5);
}

TEST(ResectionTest, DegenerateAndInvalidInput) {
  const AffineSarCamera camera(TruePose());
  // Flat ground: depression and range spacing cannot be separated.
  auto flat = Points(camera, 20, 500.0, 0.0, 0.0, 4);
  EXPECT_FALSE(ResectAffineCameraLinear(flat).has_value());
  EXPECT_FALSE(ResectSarCamera(flat).has_value());
  auto points = Points(camera, 10, 500.0, 100.0, 0.0, 5);
  const std::vector<ControlPoint> three(points.begin(), points.begin() + 3);
  EXPECT_THROW(ResectSarCamera(three), InputError);
  points[4].pixel.x() = std::nan("");
  EXPECT_THROW(ResectSarCamera(points), InputError);
  points[4].pixel.x() = 0.0;
  points[2].world.z() = INFINITY;
  EXPECT_THROW(ResectAffineCameraLinear(points), InputError);
  ResectionOptions bad;
  bad.slant_range_m = -5.0;
  EXPECT_THROW(ResectSarCamera(Points(camera, 10, 500.0, 100.0, 0.0, 5), bad), ConfigError);
}

}  // namespace
}  // namespace gissar::mvg
