#include "gissar/nav/locate.h"

#include <cmath>

#include <gtest/gtest.h>

#include "gissar/image/impulse_response.h"
#include "gissar/nav/nav_testing.h"
#include "gissar/util/error.h"

namespace gissar::nav {
namespace {

using testing::Hills;

TEST(Locate, RecoversPoseFromDriftedPrior) {
  const scene::TriangleMesh mesh = Hills();
  const render::EmbreeScene embree(mesh);
  const material::MaterialTable materials;
  const NavScene scene{&mesh, &embree, &materials, 4.0, 1};
  SensorModel model;
  model.range_spacing_m = model.azimuth_spacing_m = 30.0;
  model.width = model.height = 96;
  NavPose truth;
  truth.heading_deg = 37.0;
  truth.depression_deg = 40.0;
  truth.slant_range_m = 8000.0;
  truth.centre_enu = *SurfaceBelow(embree, mesh, 150.0, -220.0);
  Reference observed = RenderReference(scene, truth, model);
  image::ApplyMultiplicativeSpeckle(observed.intensity, 4.0, 5);
  const Eigen::Vector3d sensor = truth.SensorPosition(sensor::LookSide::kRight);
  const auto prior = PoseFromSensor(scene, sensor + Eigen::Vector3d(150, -120, 40), truth.heading_deg + 2.0,
                                    truth.slant_range_m, 40.0, sensor::LookSide::kRight);
  ASSERT_TRUE(prior);
  EXPECT_GT((prior->SensorPosition(sensor::LookSide::kRight) - sensor).norm(), 150.0);
  const LocateResult r = Locate(scene, model, observed.intensity, *prior, LocateOptions());
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.sensor_enu - sensor).norm(), 30.0);  // one resolution cell
  EXPECT_LT(std::abs(r.pose.heading_deg - truth.heading_deg), 0.1);
  EXPECT_GT(r.similarity, r.prior_similarity);
  EXPECT_GT(r.inliers, 20);
}

TEST(Locate, PoseFromSensorIsConsistent) {
  const scene::TriangleMesh mesh = Hills();
  const render::EmbreeScene embree(mesh);
  const material::MaterialTable materials;
  const NavScene scene{&mesh, &embree, &materials, 4.0, 1};
  NavPose truth;
  truth.heading_deg = 200.0;
  truth.depression_deg = 35.0;
  truth.slant_range_m = 9000.0;
  truth.centre_enu = *SurfaceBelow(embree, mesh, -300.0, 400.0);
  const Eigen::Vector3d sensor = truth.SensorPosition(sensor::LookSide::kRight);
  const auto p = PoseFromSensor(scene, sensor, truth.heading_deg, truth.slant_range_m, 45.0, sensor::LookSide::kRight);
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->depression_deg, 35.0, 1e-3);
  EXPECT_LT((p->centre_enu - truth.centre_enu).norm(), 0.5);
}

TEST(Locate, RejectsBadOptions) {
  LocateOptions o;
  o.initial_search_px = 2;
  EXPECT_THROW(o.Check(), ConfigError);
  SensorModel m;
  m.width = 10;
  EXPECT_THROW(m.Check(), ConfigError);
}

}  // namespace
}  // namespace gissar::nav
