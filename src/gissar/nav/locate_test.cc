#include "gissar/nav/locate.h"

#include <cmath>
#include <cstdio>
#include <optional>
#include <tuple>

#include <gtest/gtest.h>

#include "gissar/image/impulse_response.h"
#include "gissar/nav/nav_testing.h"
#include "gissar/util/error.h"

namespace gissar::nav {
namespace {

using testing::Hills;

// The drifted-prior case of the tests below: the hills seen at 30 m from
// 8 km (heading 37, depression 40), 4-look speckle, and an INS prior about
// 200 m and 2 deg off.
SensorModel HillsModel() {
  SensorModel model;
  model.range_spacing_m = model.azimuth_spacing_m = 30.0;
  model.width = model.height = 96;
  return model;
}
NavPose HillsTruth(const render::EmbreeScene& embree) {
  NavPose truth;
  truth.heading_deg = 37.0;
  truth.depression_deg = 40.0;
  truth.slant_range_m = 8000.0;
  truth.centre_enu = *SurfaceBelow(embree, 150.0, -220.0);
  return truth;
}
Reference Speckled(Reference observed) {
  image::ApplyMultiplicativeSpeckle(observed.intensity, 4.0, 5);
  return observed;
}
struct DriftedPrior {
  scene::TriangleMesh mesh = Hills();
  render::EmbreeScene embree{mesh};
  material::MaterialTable materials;
  NavScene scene{&mesh, &embree, &materials, 4.0, 1};
  SensorModel model = HillsModel();
  NavPose truth = HillsTruth(embree);
  Reference observed = Speckled(RenderReference(scene, truth, model));
  Eigen::Vector3d sensor = truth.SensorPosition(sensor::LookSide::kRight);
  std::optional<NavPose> prior = PoseFromSensor(scene, sensor + Eigen::Vector3d(150, -120, 40),
                                                truth.heading_deg + 2.0, truth.slant_range_m, 40.0,
                                                sensor::LookSide::kRight);
};

TEST(Locate, RecoversPoseFromDriftedPrior) {
  const DriftedPrior c;
  const auto& [truth, sensor, prior] = std::tie(c.truth, c.sensor, c.prior);
  ASSERT_TRUE(prior);
  EXPECT_GT((prior->SensorPosition(sensor::LookSide::kRight) - sensor).norm(), 150.0);
  const LocateResult r = Locate(c.scene, c.model, c.observed.intensity, *prior, LocateOptions());
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.sensor_enu - sensor).norm(), 30.0);  // one resolution cell
  EXPECT_LT(std::abs(r.pose.heading_deg - truth.heading_deg), 0.1);
  EXPECT_GT(r.similarity, r.prior_similarity);
  EXPECT_GT(r.inliers, 20);
}

// A reference serves the next step when the pose has moved less than
// 0.1 px since it was rendered: the dense stage's first fit starts from the
// patch stage's last reference, and the result's similarity is computed on
// the last reference. Every render goes through the source (counted here),
// and a fix that settles needs fewer renders than one per patch iteration,
// per dense fit and one for the similarity (5 on this scene before).
TEST(Locate, SettledPosesReuseTheirReference) {
  const DriftedPrior c;
  ASSERT_TRUE(c.prior);
  int rendered = 0;
  const LocateResult r = Locate(c.scene, c.model, c.observed.intensity, *c.prior, LocateOptions(),
                                [&](const NavPose& p) {
                                  ++rendered;
                                  return RenderReference(c.scene, p, c.model);
                                });
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(r.renders, rendered);
  EXPECT_GE(r.dense_renders, 1);
  EXPECT_LT(rendered, r.iterations + r.dense_renders + 1);
  EXPECT_LT((r.sensor_enu - c.sensor).norm(), 30.0);
  EXPECT_GT(r.similarity, r.prior_similarity);
  std::printf("[ measured ] %d patch iterations, %d dense fits, %d renders\n", r.iterations, r.dense_renders,
              rendered);
}

// The scene's materials are known to a few dB only. Here one class (a
// checkerboard of 1.2 km squares, with the same material as the rest in the
// scene) is 4 dB brighter in the observed image: its edges are features the
// reference does not have. The dense stage fits one gain per class and
// recovers the pose to a fraction of a cell; the patch stage alone matches
// those edges against nothing.
TEST(Locate, DenseStageAbsorbsAClassOffset) {
  scene::TriangleMesh mesh = Hills();
  for (int64_t t = 0; t < int64_t(mesh.triangle_count()); ++t) {
    const auto tri = mesh.Triangle(t);
    const Eigen::Vector3f c = (mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]) / 3.0f;
    const int i = static_cast<int>(std::floor(c.x() / 1200.0f)), j = static_cast<int>(std::floor(c.y() / 1200.0f));
    mesh.classes[t] = ((i + j) & 1) ? scene::kClassForest : scene::kClassDefault;
  }
  const render::EmbreeScene embree(mesh);
  material::MaterialTable materials;
  materials.Set(scene::kClassForest, materials.Get(scene::kClassDefault));
  material::MaterialTable observed_materials = materials;
  material::Material brighter = materials.Get(scene::kClassDefault);
  brighter.gain_db += 4.0;
  observed_materials.Set(scene::kClassForest, brighter);
  const NavScene scene{&mesh, &embree, &materials, 4.0, 1};
  const NavScene observed_scene{&mesh, &embree, &observed_materials, 4.0, 1};
  SensorModel model;
  model.range_spacing_m = model.azimuth_spacing_m = 30.0;
  model.width = model.height = 96;
  NavPose truth;
  truth.heading_deg = 122.0;
  truth.depression_deg = 38.0;
  truth.slant_range_m = 8000.0;
  truth.centre_enu = *SurfaceBelow(embree, -250.0, 300.0);
  Reference observed = RenderReference(observed_scene, truth, model);
  image::ApplyMultiplicativeSpeckle(observed.intensity, 4.0, 11);
  const Eigen::Vector3d sensor = truth.SensorPosition(sensor::LookSide::kRight);
  const auto prior = PoseFromSensor(scene, sensor + Eigen::Vector3d(-90, 140, -30), truth.heading_deg - 1.5,
                                    truth.slant_range_m, 40.0, sensor::LookSide::kRight);
  ASSERT_TRUE(prior);
  LocateOptions patch_only;
  patch_only.dense_renders = 0;
  const LocateResult p = Locate(scene, model, observed.intensity, *prior, patch_only);
  const LocateResult d = Locate(scene, model, observed.intensity, *prior, LocateOptions());
  const double patch_error = (p.sensor_enu - sensor).norm(), dense_error = (d.sensor_enu - sensor).norm();
  std::printf("patch: %.2f m, %.4f deg depression; dense: %.2f m, %.4f deg, heading %.4f deg, %.3f dB rms, %d renders\n", patch_error,
              p.pose.depression_deg - truth.depression_deg, dense_error, d.pose.depression_deg - truth.depression_deg,
              d.pose.heading_deg - truth.heading_deg, d.dense_rms_db, d.dense_renders);
  EXPECT_EQ(p.dense_renders, 0);
  EXPECT_TRUE(d.converged);
  EXPECT_GE(d.dense_renders, 1);
  // Speckle seeds 1, 2, 7, 11 give 6.6, 6.4, 9.4, 2.0 m (dense) against
  // 23-37 m (patch stage alone, depression 0.13-0.24 deg low).
  EXPECT_LT(dense_error, 0.4 * model.range_spacing_m);
  EXPECT_LT(std::abs(d.pose.depression_deg - truth.depression_deg), 0.1);
  EXPECT_LT(std::abs(d.pose.heading_deg - truth.heading_deg), 0.06);
  EXPECT_LT(dense_error, 0.5 * patch_error);
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
  truth.centre_enu = *SurfaceBelow(embree, -300.0, 400.0);
  const Eigen::Vector3d sensor = truth.SensorPosition(sensor::LookSide::kRight);
  const auto p = PoseFromSensor(scene, sensor, truth.heading_deg, truth.slant_range_m, 45.0, sensor::LookSide::kRight);
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->depression_deg, 35.0, 1e-3);
  EXPECT_LT((p->centre_enu - truth.centre_enu).norm(), 0.5);
}

TEST(Locate, FixesFromAStoredReferenceWithoutRendering) {
  const DriftedPrior c;
  const auto& [embree, scene, model] = std::tie(c.embree, c.scene, c.model);
  // The stored reference: another pose 300 m and 2.5 deg away from the truth.
  NavPose stored_pose;
  stored_pose.heading_deg = 34.5;
  stored_pose.depression_deg = 41.0;
  stored_pose.slant_range_m = 8000.0;
  stored_pose.centre_enu = *SurfaceBelow(embree, 400.0, -20.0);
  const Reference rendered = RenderReference(scene, stored_pose, model);
  const StoredReference stored = MakeStoredReference(scene, rendered.geometry, rendered.intensity, {});
  EXPECT_GT(stored.valid_pixels, 0.8 * 96 * 96);
  // Its points are the rendered single-bounce hits (to a fraction of a pixel).
  int compared = 0, close = 0;
  for (int y = 0; y < 96; y += 4)
    for (int x = 0; x < 96; x += 4) {
      if (!rendered.valid.at<uint8_t>(y, x) || !stored.valid.at<uint8_t>(y, x)) continue;
      const cv::Vec3f a = rendered.points.at<cv::Vec3f>(y, x), b = stored.points.at<cv::Vec3f>(y, x);
      ++compared;
      close += cv::norm(a - b) < 30.0;
    }
  EXPECT_GT(close, 0.95 * compared);
  // Warped to its own pose it is itself.
  const Reference same = WarpStoredReference(stored, stored_pose, model);
  double diff = 0.0, sum = 0.0;
  for (size_t i = 0; i < same.intensity.size(); ++i) {
    diff += std::abs(same.intensity[i] - rendered.intensity[i]);
    sum += rendered.intensity[i];
  }
  EXPECT_LT(diff / sum, 0.02);

  // The observed image and the prior: the drifted-prior case.
  ASSERT_TRUE(c.prior);
  const auto& [truth, sensor, prior] = std::tie(c.truth, c.sensor, c.prior);
  int warps = 0;
  const LocateResult r = Locate(scene, model, c.observed.intensity, *prior, LocateOptions(), [&](const NavPose& pose) {
    ++warps;
    return WarpStoredReference(stored, pose, model);
  });
  EXPECT_TRUE(r.converged) << r.failure_reason;
  EXPECT_LT((r.sensor_enu - sensor).norm(), 30.0);  // one resolution cell
  EXPECT_LT(std::abs(r.pose.heading_deg - truth.heading_deg), 0.1);
  EXPECT_EQ(warps, r.renders);
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
