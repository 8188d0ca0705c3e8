#include "gissar/mvg/affine_camera.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::JsonMatrix;
using testing::kCase2;
using testing::kCase3;
using testing::LoadReferenceCase;

SarPose PoseOf(const nlohmann::json& g, int view) {
  const std::string i = std::to_string(view);
  SarPose pose;
  pose.heading_deg = g["heading" + i + "_deg"].get<double>();
  pose.depression_deg = g["depression" + i + "_deg"].get<double>();
  pose.look_side = g["look"].get<std::string>() == "right" ? LookSide::kRight : LookSide::kLeft;
  pose.range_spacing_m = g["res_range" + i + "_m"].get<double>();
  pose.azimuth_spacing_m = g["res_az" + i + "_m"].get<double>();
  pose.scene_centre = {g["scene_centre"][0].get<double>(), g["scene_centre"][1].get<double>(),
                       g["scene_centre"][2].get<double>()};
  pose.u0 = g["u0"].get<double>();
  pose.v0 = g["v0"].get<double>();
  return pose;
}

class ReferenceCameraTest : public ::testing::TestWithParam<const char*> {};

TEST_P(ReferenceCameraTest, MatricesEqualTheReference) {
  const auto rc = LoadReferenceCase(GetParam());
  for (int view : {1, 2}) {
    SCOPED_TRACE("view " + std::to_string(view));
    const std::string i = std::to_string(view);
    const AffineSarCamera camera(PoseOf(rc.json["geometry"], view));
    EXPECT_LT((camera.Matrix() - JsonMatrix<3, 4>(rc.json["P" + i])).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((camera.Rotation() - JsonMatrix<3, 3>(rc.json["R" + i])).cwiseAbs().maxCoeff(),
              1e-12);
    EXPECT_LT((camera.Intrinsics() - JsonMatrix<3, 3>(rc.json["K" + i])).cwiseAbs().maxCoeff(),
              1e-12);
    EXPECT_LT((camera.Extrinsics() - JsonMatrix<4, 4>(rc.json["G" + i])).cwiseAbs().maxCoeff(),
              1e-12);
  }
}

TEST_P(ReferenceCameraTest, ProjectionMatchesTheNoiseFreePixels) {
  const auto rc = LoadReferenceCase(GetParam());
  const AffineSarCamera c1(PoseOf(rc.json["geometry"], 1));
  const AffineSarCamera c2(PoseOf(rc.json["geometry"], 2));
  const auto xs = rc.Values("X"), ys = rc.Values("Y"), zs = rc.Values("Z");
  const auto x1 = rc.Values("x1_true"), y1 = rc.Values("y1_true");
  const auto x2 = rc.Values("x2_true"), y2 = rc.Values("y2_true");
  double worst = 0.0;
  for (size_t k = 0; k < xs.size(); ++k) {
    const Eigen::Vector3d p(xs[k], ys[k], zs[k]);
    worst = std::max(worst, (c1.Project(p) - Eigen::Vector2d(x1[k], y1[k])).norm());
    worst = std::max(worst, (c2.Project(p) - Eigen::Vector2d(x2[k], y2[k])).norm());
    const Eigen::Vector3d ph = c1.Matrix() * p.homogeneous();
    EXPECT_NEAR((ph.head<2>() - c1.Project(p)).norm(), 0.0, 1e-9);
  }
  EXPECT_LT(worst, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Cases, ReferenceCameraTest, ::testing::Values(kCase2, kCase3));

TEST(AffineSarCameraTest, GeometryByHand) {
  SarPose pose;
  pose.heading_deg = 90.0;  // flying East
  pose.depression_deg = 30.0;
  pose.look_side = LookSide::kRight;  // looking South
  const AffineSarCamera right(pose);
  EXPECT_NEAR((right.flight_direction() - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-15);
  const double c = std::cos(M_PI / 6), s = 0.5;
  EXPECT_NEAR((right.look_direction() - Eigen::Vector3d(0, -c, -s)).norm(), 0.0, 1e-15);
  // n = l x h is orthogonal to both and R is a rotation.
  EXPECT_NEAR(right.range_plane_normal().dot(right.look_direction()), 0.0, 1e-15);
  EXPECT_NEAR(right.Rotation().determinant(), 1.0, 1e-15);
  // A point farther from the radar (further South) has a larger range column.
  EXPECT_GT(right.Project({0, -10, 0}).x(), right.Project({0, 0, 0}).x());
  // A point higher up is closer to the radar: layover towards near range.
  EXPECT_LT(right.Project({0, 0, 10}).x(), right.Project({0, 0, 0}).x());
  pose.look_side = LookSide::kLeft;  // looking North
  const AffineSarCamera left(pose);
  EXPECT_NEAR((left.look_direction() - Eigen::Vector3d(0, c, -s)).norm(), 0.0, 1e-15);
  // Sensor 10 km up the line of sight from the scene centre.
  const Eigen::Vector3d sensor = left.SensorPosition(10000.0);
  EXPECT_NEAR(sensor.z(), 5000.0, 1e-9);
  EXPECT_NEAR(sensor.y(), -10000.0 * c, 1e-9);
}

TEST(AffineSarCameraTest, InvalidPosesThrowConfigError) {
  SarPose pose;
  pose.depression_deg = 0.0;
  EXPECT_THROW(AffineSarCamera{pose}, ConfigError);
  pose.depression_deg = 90.0;
  EXPECT_THROW(AffineSarCamera{pose}, ConfigError);
  pose.depression_deg = 40.0;
  pose.range_spacing_m = 0.0;
  EXPECT_THROW(AffineSarCamera{pose}, ConfigError);
  pose.range_spacing_m = 1.0;
  pose.azimuth_spacing_m = std::nan("");
  EXPECT_THROW(AffineSarCamera{pose}, ConfigError);
  pose.azimuth_spacing_m = 1.0;
  pose.heading_deg = INFINITY;
  EXPECT_THROW(AffineSarCamera{pose}, ConfigError);
  pose.heading_deg = 0.0;
  const AffineSarCamera ok(pose);
  EXPECT_THROW(ok.SensorPosition(-1.0), ConfigError);
}

TEST(DecomposeAffineCameraTest, RecoversEveryParameterOfASarCamera) {
  for (double heading : {0.0, 17.0, 135.0, 200.0, 359.0}) {
    for (double depression : {20.0, 45.0, 70.0}) {
      for (LookSide look : {LookSide::kRight, LookSide::kLeft}) {
        SarPose pose;
        pose.heading_deg = heading;
        pose.depression_deg = depression;
        pose.look_side = look;
        pose.range_spacing_m = 0.7;
        pose.azimuth_spacing_m = 1.3;
        pose.scene_centre = {100.0, -250.0, 40.0};
        pose.u0 = 300.5;
        pose.v0 = 700.25;
        const AffineSarCamera camera(pose);
        const AffineCameraDecomposition d =
            DecomposeAffineCamera(camera.Matrix(), pose.scene_centre);
        EXPECT_NEAR(d.pose.heading_deg, heading, 1e-10);
        EXPECT_NEAR(d.pose.depression_deg, depression, 1e-10);
        EXPECT_EQ(d.pose.look_side, look);
        EXPECT_NEAR(d.pose.range_spacing_m, 0.7, 1e-12);
        EXPECT_NEAR(d.pose.azimuth_spacing_m, 1.3, 1e-12);
        EXPECT_NEAR(d.pose.u0, 300.5, 1e-9);
        EXPECT_NEAR(d.pose.v0, 700.25, 1e-9);
        EXPECT_NEAR(d.skew_deg, 0.0, 1e-10);
        EXPECT_NEAR(d.flight_elevation_deg, 0.0, 1e-10);
        // With another scene centre only the principal point changes: it is
        // the pixel of that centre.
        const Eigen::Vector3d other(5.0, 6.0, 7.0);
        const AffineCameraDecomposition d2 = DecomposeAffineCamera(camera.Matrix(), other);
        EXPECT_NEAR((Eigen::Vector2d(d2.pose.u0, d2.pose.v0) - camera.Project(other)).norm(), 0.0,
                    1e-9);
      }
    }
  }
}

TEST(DecomposeAffineCameraTest, RejectsInvalidMatrices) {
  AffineMatrix p = AffineSarCamera(SarPose{}).Matrix();
  AffineMatrix bad = p;
  bad(2, 2) = 0.5;
  EXPECT_THROW(DecomposeAffineCamera(bad), InputError);
  bad = p;
  bad(0, 1) = std::nan("");
  EXPECT_THROW(DecomposeAffineCamera(bad), InputError);
  bad = p;
  bad.block<1, 3>(1, 0).setZero();
  EXPECT_THROW(DecomposeAffineCamera(bad), InputError);
}

}  // namespace
}  // namespace gissar::mvg
