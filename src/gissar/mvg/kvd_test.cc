#include "gissar/mvg/kvd.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gissar/mvg/affine_fundamental.h"
#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::JsonMatrix;
using testing::kCase2;
using testing::kCase3;
using testing::LoadReferenceCase;

double AngleDiff(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d <= -180.0) d += 360.0;
  return d;
}

TEST(KvdTest, Case2FromFTrueAndFromTheEstimateEqualGroundTruth) {
  const auto rc = LoadReferenceCase(kCase2);
  const nlohmann::json& gt = rc.json["kvd_ground_truth_from_R"];
  const double theta_gt = gt["theta_deg"].get<double>();
  const double phi_gt = gt["phi_deg"].get<double>();
  // KvD of the calibrated F_true and of the Gold Standard estimate.
  const auto f = EstimateAffineFundamental(rc.Matches());
  ASSERT_TRUE(f.has_value());
  const Eigen::Matrix3d k1 = JsonMatrix<3, 3>(rc.json["K1"]);
  const Eigen::Matrix3d k2 = JsonMatrix<3, 3>(rc.json["K2"]);
  for (const Eigen::Matrix3d& fcal :
       {JsonMatrix<3, 3>(rc.json["F_true_calibrated"]).eval(), CalibrateFundamental(*f, k1, k2)}) {
    const KvdParameters k = KvdFromFundamental(fcal);
    EXPECT_NEAR(k.theta_deg, theta_gt, 1e-7);
    EXPECT_NEAR(k.phi_deg, phi_gt, 1e-7);
    EXPECT_NEAR(k.s, 1.0, 1e-9);
    EXPECT_FALSE(k.rho_recoverable);
    // Equal depressions: the closed form gives the heading change of 30 deg.
    EXPECT_NEAR(HeadingChangeEqualDepressionDeg(k.theta_deg, 40.0), 30.0, 1e-6);
    const auto candidates = HeadingChangeCandidatesDeg(k.theta_deg, 40.0, 40.0);
    ASSERT_EQ(candidates.size(), 1u);
    EXPECT_NEAR(candidates[0], 30.0, 1e-6);
  }
  // README: theta = 23.19895, phi = 11.59948, |rho| = 19.15316 (theta = 2 phi).
  EXPECT_NEAR(theta_gt, 23.19895, 1e-5);
  EXPECT_NEAR(phi_gt, 11.59948, 1e-5);
  EXPECT_NEAR(RhoMagnitudeEqualDepressionDeg(30.0, 40.0), 19.15316, 1e-5);
  EXPECT_NEAR(RhoMagnitudeEqualDepressionDeg(30.0, 40.0), std::abs(gt["rho_deg"].get<double>()),
              1e-9);
}

TEST(KvdTest, RotationDecompositionEqualsTheReference) {
  for (const char* name : {kCase2, kCase3}) {
    SCOPED_TRACE(name);
    const auto rc = LoadReferenceCase(name);
    const nlohmann::json& gt = rc.json["kvd_ground_truth_from_R"];
    const Eigen::Matrix3d r_rel = JsonMatrix<3, 3>(rc.json["R_rel"]);
    const KvdRotation k = KvdFromRotation(r_rel);
    EXPECT_NEAR(k.theta_deg, gt["theta_deg"].get<double>(), 1e-9);
    EXPECT_NEAR(k.phi_deg, gt["phi_deg"].get<double>(), 1e-9);
    EXPECT_NEAR(k.rho_deg, gt["rho_deg"].get<double>(), 1e-9);
    EXPECT_LT((RotationFromKvd(k.theta_deg, k.phi_deg, k.rho_deg) - r_rel).cwiseAbs().maxCoeff(),
              1e-12);
    // The same from the SAR model.
    const nlohmann::json& g = rc.json["geometry"];
    const KvdRotation s =
        SarKvd(g["heading_change_deg"].get<double>(), g["depression1_deg"].get<double>(),
               g["depression2_deg"].get<double>());
    EXPECT_NEAR(s.theta_deg, k.theta_deg, 1e-9);
    EXPECT_NEAR(s.phi_deg, k.phi_deg, 1e-9);
    EXPECT_NEAR(s.rho_deg, k.rho_deg, 1e-9);
  }
}

TEST(KvdTest, Case3KvdOfTheEstimatesAndHeadingChangeWithUnequalDepressions) {
  const auto rc = LoadReferenceCase(kCase3);
  const Eigen::Matrix3d k1 = JsonMatrix<3, 3>(rc.json["K1"]);
  const Eigen::Matrix3d k2 = JsonMatrix<3, 3>(rc.json["K2"]);
  // F_true: calibrated s = 1, pixel s = res1/res2 = 4/3, ground-truth angles.
  const Eigen::Matrix3d f_true = JsonMatrix<3, 3>(rc.json["F_true"]);
  const KvdParameters pixel = KvdFromFundamental(f_true);
  const KvdParameters cal = KvdFromFundamental(CalibrateFundamental(f_true, k1, k2));
  const nlohmann::json& gt = rc.json["kvd_ground_truth_from_R"];
  EXPECT_NEAR(pixel.s, 4.0 / 3.0, 1e-9);
  EXPECT_NEAR(cal.s, 1.0, 1e-9);
  EXPECT_NEAR(cal.theta_deg, gt["theta_deg"].get<double>(), 1e-7);
  EXPECT_NEAR(cal.phi_deg, gt["phi_deg"].get<double>(), 1e-7);
  EXPECT_NEAR(pixel.theta_deg, cal.theta_deg, 1e-9);  // square pixels
  // Heading change from theta and the depressions 40 / 45 (numerical root).
  const auto exact = InterpretKvdForSar(cal, 40.0, 45.0);
  ASSERT_TRUE(exact.has_value());
  EXPECT_EQ(exact->candidates, 1);
  EXPECT_NEAR(exact->heading_change_deg, 30.0, 1e-6);
  EXPECT_NEAR(exact->rho_abs_deg, std::abs(gt["rho_deg"].get<double>()), 1e-6);
  EXPECT_NEAR(exact->phi_residual_deg, 0.0, 1e-6);
  // The equal-depression closed form would be wrong here.
  EXPECT_GT(std::abs(HeadingChangeEqualDepressionDeg(cal.theta_deg, 40.0) - 30.0), 0.5);

  // The Gold Standard estimate of the reference (F_gs_inliers): our KvD
  // values equal those listed in the JSON.
  const nlohmann::json& est = rc.json["estimates"]["F_gs_inliers"];
  const Eigen::Matrix3d f_gs = JsonMatrix<3, 3>(est["F"]);
  const KvdParameters k = KvdFromFundamental(CalibrateFundamental(f_gs, k1, k2));
  EXPECT_NEAR(k.theta_deg, est["kvd_calibrated"]["theta_deg"].get<double>(), 1e-9);
  EXPECT_NEAR(k.phi_deg, est["kvd_calibrated"]["phi_deg"].get<double>(), 1e-9);
  EXPECT_NEAR(k.s, est["kvd_calibrated"]["s"].get<double>(), 1e-12);
  const KvdParameters kp = KvdFromFundamental(f_gs);
  EXPECT_NEAR(kp.s, est["kvd_pixel"]["s"].get<double>(), 1e-12);
  const auto noisy = InterpretKvdForSar(k, 40.0, 45.0);
  ASSERT_TRUE(noisy.has_value());
  // theta is 0.019 deg low; d(dpsi)/d(theta) is about 1.3 here.
  EXPECT_NEAR(noisy->heading_change_deg, 30.0, 0.05);
  RecordProperty("case3_gs_heading_change_deg", testing::Sci(noisy->heading_change_deg));
}

// Noise-free synthetic pairs over a dense grid of heading changes and
// depressions: the heading change comes back to 1e-6 deg, rho is reported
// as not recoverable and |rho| follows the camera model (and the closed
// form for equal depressions).
TEST(KvdTest, DenseSyntheticGridRecoversTheHeadingChange) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ground(-500.0, 500.0);
  std::uniform_real_distribution<double> height(0.0, 150.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 40; ++i) points.emplace_back(ground(rng), ground(rng), height(rng));
  int tested = 0, degenerate = 0;
  double worst = 0.0;
  for (double dep1 = 30.0; dep1 <= 50.0; dep1 += 5.0) {
    for (double dep2 = 30.0; dep2 <= 50.0; dep2 += 5.0) {
      for (double dpsi = -90.0; dpsi <= 90.0; dpsi += 7.5) {
        SarPose p1, p2;
        p1.heading_deg = 25.0;
        p1.depression_deg = dep1;
        p1.range_spacing_m = 1.0;
        p1.azimuth_spacing_m = 1.0;
        p1.u0 = p1.v0 = 512.0;
        p2 = p1;
        p2.heading_deg = 25.0 + dpsi;
        p2.depression_deg = dep2;
        p2.range_spacing_m = 0.75;  // non-square pixels in view 2
        p2.azimuth_spacing_m = 1.25;
        const AffineSarCamera c1(p1), c2(p2);
        std::vector<PointMatch> matches;
        for (const Eigen::Vector3d& x : points) matches.push_back({c1.Project(x), c2.Project(x)});
        const auto f = EstimateAffineFundamental(matches);
        if (dpsi == 0.0 && dep1 == dep2) {
          // Identical viewing geometry up to scale: image 2 is an affine
          // map of image 1 and F is not determined.
          EXPECT_FALSE(f.has_value());
          ++degenerate;
          continue;
        }
        ASSERT_TRUE(f.has_value()) << dep1 << " " << dep2 << " " << dpsi;
        const KvdParameters k =
            KvdFromFundamental(CalibrateFundamental(*f, c1.Intrinsics(), c2.Intrinsics()));
        EXPECT_FALSE(k.rho_recoverable);
        EXPECT_NEAR(k.s, 1.0, 1e-9);
        const KvdRotation truth = SarKvd(dpsi, dep1, dep2);
        EXPECT_NEAR(AngleDiff(k.theta_deg, truth.theta_deg), 0.0, 1e-7);
        const auto sar = InterpretKvdForSar(k, dep1, dep2);
        ASSERT_TRUE(sar.has_value());
        EXPECT_EQ(sar->candidates, 1);
        EXPECT_NEAR(sar->heading_change_deg, dpsi, 1e-6) << dep1 << " " << dep2 << " " << dpsi;
        worst = std::max(worst, std::abs(sar->heading_change_deg - dpsi));
        EXPECT_NEAR(sar->rho_abs_deg, std::abs(truth.rho_deg), 1e-6);
        EXPECT_NEAR(sar->phi_residual_deg, 0.0, 1e-6);
        if (dep1 == dep2) {
          EXPECT_NEAR(sar->rho_abs_deg, RhoMagnitudeEqualDepressionDeg(dpsi, dep1), 1e-6);
          EXPECT_NEAR(HeadingChangeEqualDepressionDeg(k.theta_deg, dep1), dpsi, 1e-6);
        }
        ++tested;
      }
    }
  }
  EXPECT_EQ(tested, 5 * 5 * 25 - 5);
  EXPECT_EQ(degenerate, 5);
  RecordProperty("grid_worst_heading_error_deg", testing::Sci(worst));
}

TEST(KvdTest, LeftLookingPairs) {
  for (double dpsi : {-60.0, -15.0, 20.0, 75.0}) {
    const KvdRotation truth = SarKvd(dpsi, 35.0, 48.0, LookSide::kLeft, LookSide::kLeft);
    KvdParameters k;
    k.theta_deg = truth.theta_deg;
    k.phi_deg = truth.phi_deg;
    const auto sar = InterpretKvdForSar(k, 35.0, 48.0, LookSide::kLeft, LookSide::kLeft);
    ASSERT_TRUE(sar.has_value());
    EXPECT_NEAR(sar->heading_change_deg, dpsi, 1e-6);
  }
}

TEST(KvdTest, EqualDepressionClosedFormsByHand) {
  // dpsi = 90, delta = 60: tan(theta/2) = cos 60 tan 45 = 1/2.
  const double theta = 2.0 * std::atan(0.5) * 180.0 / M_PI;
  EXPECT_NEAR(SarKvd(90.0, 60.0, 60.0).theta_deg, theta, 1e-10);
  EXPECT_NEAR(HeadingChangeEqualDepressionDeg(theta, 60.0), 90.0, 1e-10);
  // theta = 2 phi for equal depressions.
  EXPECT_NEAR(SarKvd(90.0, 60.0, 60.0).phi_deg, theta / 2.0, 1e-10);
  // |rho| = acos(sin² 60 cos 90 + cos² 60) = acos(1/4).
  EXPECT_NEAR(RhoMagnitudeEqualDepressionDeg(90.0, 60.0), std::acos(0.25) * 180.0 / M_PI, 1e-10);
  EXPECT_NEAR(RhoMagnitudeDeg(90.0, 60.0, 60.0), std::acos(0.25) * 180.0 / M_PI, 1e-10);
  // Same heading, different depressions: a pure rotation about the flight
  // direction (phi = 90, theta = 0, |rho| = the depression difference).
  const KvdRotation same = SarKvd(0.0, 40.0, 45.0);
  EXPECT_NEAR(same.theta_deg, 0.0, 1e-10);
  EXPECT_NEAR(same.phi_deg, 90.0, 1e-10);
  EXPECT_NEAR(std::abs(same.rho_deg), 5.0, 1e-10);
}

KvdParameters PairKvd(const SarPose& a, const SarPose& b) {
  const AffineSarCamera ca(a), cb(b);
  const auto f = FundamentalFromCameras(ca.Matrix(), cb.Matrix());
  GISSAR_CHECK(f.has_value());
  return KvdFromFundamental(CalibrateFundamental(*f, ca.Intrinsics(), cb.Intrinsics()));
}

TEST(KvdTest, ThreeViewsRecoverRhoUpToTheNeckerReversal) {
  SarPose p1, p2, p3;
  p1.heading_deg = 10.0;
  p1.depression_deg = 40.0;
  p2.heading_deg = 40.0;
  p2.depression_deg = 45.0;
  p2.range_spacing_m = p2.azimuth_spacing_m = 0.75;
  p3.heading_deg = 85.0;
  p3.depression_deg = 35.0;
  const auto truth = [](const SarPose& a, const SarPose& b) {
    return KvdFromRotation(AffineSarCamera(b).Rotation() *
                           AffineSarCamera(a).Rotation().transpose());
  };
  const KvdRotation t12 = truth(p1, p2), t13 = truth(p1, p3), t23 = truth(p2, p3);
  const auto solutions =
      RecoverRhoFromThreeViews(PairKvd(p1, p2), PairKvd(p1, p3), PairKvd(p2, p3));
  ASSERT_EQ(solutions.size(), 2u);
  // One Necker pair: the truth and its reversal.
  EXPECT_NEAR(solutions[0].rho12_deg, -solutions[1].rho12_deg, 1e-9);
  EXPECT_NEAR(solutions[0].rho13_deg, -solutions[1].rho13_deg, 1e-9);
  EXPECT_NEAR(solutions[0].rho23_deg, -solutions[1].rho23_deg, 1e-9);
  EXPECT_GT(solutions[0].rho12_deg, 0.0);
  const ThreeViewRho& match = (t12.rho_deg > 0.0) ? solutions[0] : solutions[1];
  EXPECT_NEAR(match.rho12_deg, t12.rho_deg, 1e-7);
  EXPECT_NEAR(match.rho13_deg, t13.rho_deg, 1e-7);
  EXPECT_NEAR(match.rho23_deg, t23.rho_deg, 1e-7);
  for (const ThreeViewRho& s : solutions) EXPECT_LT(s.residual, 1e-9);
  // Magnitudes agree with the two-view SAR model.
  EXPECT_NEAR(std::abs(match.rho12_deg), RhoMagnitudeDeg(30.0, 40.0, 45.0), 1e-7);
}

TEST(KvdTest, ThreeViewsWithOneHeadingAreDegenerate) {
  SarPose p1, p2, p3;
  p1.heading_deg = p2.heading_deg = p3.heading_deg = 10.0;
  p1.depression_deg = 40.0;
  p2.depression_deg = 50.0;
  p3.depression_deg = 30.0;
  EXPECT_TRUE(RecoverRhoFromThreeViews(PairKvd(p1, p2), PairKvd(p1, p3), PairKvd(p2, p3)).empty());
}

TEST(KvdTest, InvalidInputThrowsInputError) {
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();
  f(0, 2) = 1.0;  // (c, d) = 0: no decomposition
  EXPECT_THROW(KvdFromFundamental(f), InputError);
  f(2, 0) = 1.0;
  f(0, 0) = 1.0;  // not affine
  EXPECT_THROW(KvdFromFundamental(f), InputError);
  EXPECT_THROW(KvdFromRotation(2.0 * Eigen::Matrix3d::Identity()), InputError);
  EXPECT_THROW(KvdFromRotation(-Eigen::Matrix3d::Identity()), InputError);
  EXPECT_THROW(SarKvd(10.0, 0.0, 40.0), InputError);
  EXPECT_THROW(SarKvd(10.0, 40.0, 90.0), InputError);
  EXPECT_THROW(HeadingChangeCandidatesDeg(std::nan(""), 40.0, 40.0), InputError);
  EXPECT_THROW(HeadingChangeEqualDepressionDeg(10.0, -5.0), InputError);
}

}  // namespace
}  // namespace gissar::mvg
