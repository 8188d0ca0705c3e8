#include "gissar/mvg/two_view.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::JsonMatrix;
using testing::kCase2;
using testing::kCase3;
using testing::LoadReferenceCase;

TEST(TwoViewTest, Case3RobustAnalysis) {
  const auto rc = LoadReferenceCase(kCase3);
  const auto matches = rc.Matches();
  TwoViewOptions options;
  options.ransac.threshold_px = rc.json["ransac"]["thr_px_gs"].get<double>();
  options.ransac.seed = 2024;
  options.k1 = SarIntrinsics(1.0, 1.0, 512.0, 512.0);
  options.k2 = SarIntrinsics(0.75, 0.75, 512.0, 512.0);
  EXPECT_LT((options.k2 - JsonMatrix<3, 3>(rc.json["K2"])).norm(), 1e-12);
  options.depression1_deg = 40.0;
  options.depression2_deg = 45.0;
  const auto a = AnalyseTwoViews(matches, options);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->num_matches, 200);
  // Every outlier rejected, every true inlier kept.
  EXPECT_EQ(a->inliers, rc.RowsWhereNot("is_outlier"));
  const nlohmann::json& ref = rc.json["estimates"]["F_gs_refit_from_ransac"];
  EXPECT_LT(AffineFundamentalDistance(a->f, JsonMatrix<3, 3>(ref["F"])), 1e-9);
  EXPECT_NEAR(a->rms_gs_px, ref["rms_gs_px_inliers"].get<double>(), 1e-9);
  EXPECT_NEAR(a->rms_epi1_px, ref["rms_epi1_px_inliers"].get<double>(), 1e-9);
  EXPECT_NEAR(a->rms_epi2_px, ref["rms_epi2_px_inliers"].get<double>(), 1e-9);
  // theta within 0.05 deg of the reference RANSAC estimates.
  EXPECT_NEAR(a->kvd.theta_deg, ref["kvd_calibrated"]["theta_deg"].get<double>(), 0.05);
  EXPECT_NEAR(a->kvd.theta_deg,
              rc.json["estimates"]["F_ransac"]["kvd_calibrated"]["theta_deg"].get<double>(), 0.05);
  EXPECT_NEAR(a->kvd.s, ref["kvd_calibrated"]["s"].get<double>(), 1e-6);
  EXPECT_FALSE(a->kvd.rho_recoverable);
  ASSERT_TRUE(a->sar.has_value());
  EXPECT_NEAR(a->sar->heading_change_deg, 30.0, 0.05);
  EXPECT_NEAR(a->sar->rho_abs_deg,
              std::abs(rc.json["kvd_ground_truth_from_R"]["rho_deg"].get<double>()), 0.1);
  EXPECT_GT(a->ransac_iterations, 0);
  EXPECT_TRUE(a->refit_converged);
  RecordProperty("case3_theta_deg", testing::Sci(a->kvd.theta_deg));
  RecordProperty("case3_heading_change_deg", testing::Sci(a->sar->heading_change_deg));
  // Epipole directions are unit vectors along the epipolar lines.
  EXPECT_NEAR(a->epipole1.norm(), 1.0, 1e-12);
  EXPECT_EQ(a->residuals.gs_px.size(), 200u);
}

TEST(TwoViewTest, Case3WithoutRobustStepIsRuinedByOutliers) {
  const auto rc = LoadReferenceCase(kCase3);
  TwoViewOptions options;
  options.robust = false;
  const auto a = AnalyseTwoViews(rc.Matches(), options);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->inliers.size(), 200u);
  EXPECT_LT(
      AffineFundamentalDistance(a->f, JsonMatrix<3, 3>(rc.json["estimates"]["F_gs_all"]["F"])),
      1e-9);
  EXPECT_FALSE(a->sar.has_value());  // no depressions given
}

TEST(TwoViewTest, Case2NoiseFree) {
  const auto rc = LoadReferenceCase(kCase2);
  TwoViewOptions options;
  options.depression1_deg = 40.0;
  options.depression2_deg = 40.0;
  const auto a = AnalyseTwoViews(rc.Matches(), options);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->inliers.size(), 50u);
  EXPECT_LT(a->rms_gs_px, 1e-9);
  ASSERT_TRUE(a->sar.has_value());
  EXPECT_NEAR(a->sar->heading_change_deg, 30.0, 1e-6);
  EXPECT_NEAR(a->sar->rho_abs_deg, 19.15316, 1e-5);
  EXPECT_NEAR(a->kvd.theta_deg, 23.19895, 1e-5);
  EXPECT_NEAR(a->kvd.phi_deg, 11.59948, 1e-5);
}

TEST(TwoViewTest, InvalidInput) {
  const auto rc = LoadReferenceCase(kCase2);
  auto matches = rc.Matches();
  TwoViewOptions options;
  options.depression1_deg = 95.0;
  options.depression2_deg = 40.0;
  EXPECT_THROW(AnalyseTwoViews(matches, options), ConfigError);
  options = TwoViewOptions{};
  options.k1(2, 0) = 0.1;
  EXPECT_THROW(AnalyseTwoViews(matches, options), ConfigError);
  options = TwoViewOptions{};
  matches.resize(3);
  EXPECT_THROW(AnalyseTwoViews(matches, options), InputError);
}

}  // namespace
}  // namespace gissar::mvg
