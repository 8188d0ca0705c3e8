#include "gissar/mvg/affine_fundamental.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using testing::JsonMatrix;
using testing::kCase2;
using testing::kCase3;
using testing::LoadReferenceCase;

Eigen::Matrix3d Estimate(const nlohmann::json& j, const std::string& name) {
  return JsonMatrix<3, 3>(j["estimates"][name]["F"]);
}

TEST(AffineFundamentalTest, FromCamerasEqualsFTrue) {
  for (const char* name : {kCase2, kCase3}) {
    SCOPED_TRACE(name);
    const auto rc = LoadReferenceCase(name);
    const auto f =
        FundamentalFromCameras(JsonMatrix<3, 4>(rc.json["P1"]), JsonMatrix<3, 4>(rc.json["P2"]));
    ASSERT_TRUE(f.has_value());
    const Eigen::Matrix3d f_true = JsonMatrix<3, 3>(rc.json["F_true"]);
    EXPECT_LT(((*f) - f_true).cwiseAbs().maxCoeff(), 1e-12) << *f;  // same sign convention
    // Calibrated with the reference intrinsics.
    const Eigen::Matrix3d f_cal =
        CalibrateFundamental(*f, JsonMatrix<3, 3>(rc.json["K1"]), JsonMatrix<3, 3>(rc.json["K2"]));
    EXPECT_LT(AffineFundamentalDistance(f_cal, JsonMatrix<3, 3>(rc.json["F_true_calibrated"])),
              1e-12);
  }
}

TEST(AffineFundamentalTest, Case2GoldStandardEqualsFTrue) {
  const auto rc = LoadReferenceCase(kCase2);
  const auto matches = rc.Matches();
  ASSERT_EQ(matches.size(), 50u);
  const auto f = EstimateAffineFundamental(matches);
  ASSERT_TRUE(f.has_value());
  const double distance = AffineFundamentalDistance(*f, JsonMatrix<3, 3>(rc.json["F_true"]));
  EXPECT_LT(distance, 1e-10);
  RecordProperty("case2_gs_vs_ftrue", testing::Sci(distance));
  // Normalisation of the README: ||(a, b, c, d)|| = 1 and c > 0.
  EXPECT_NEAR(std::hypot(std::hypot((*f)(0, 2), (*f)(1, 2)), std::hypot((*f)(2, 0), (*f)(2, 1))),
              1.0, 1e-15);
  EXPECT_GT((*f)(2, 0), 0.0);
  const auto residuals = ComputeResiduals(*f, matches);
  EXPECT_LT(RootMeanSquare(residuals.gs_px), 1e-9);
  EXPECT_LT(RootMeanSquare(residuals.epi1_px), 1e-9);
  EXPECT_LT(RootMeanSquare(residuals.epi2_px), 1e-9);
}

TEST(AffineFundamentalTest, Case3GoldStandardOnTrueInliersEqualsReference) {
  const auto rc = LoadReferenceCase(kCase3);
  const auto matches = rc.Matches();
  const std::vector<int> inliers = rc.RowsWhereNot("is_outlier");
  ASSERT_EQ(inliers.size(), 170u);
  const auto f = EstimateAffineFundamental(matches, inliers);
  ASSERT_TRUE(f.has_value());
  const nlohmann::json& ref = rc.json["estimates"]["F_gs_inliers"];
  const double distance = AffineFundamentalDistance(*f, Estimate(rc.json, "F_gs_inliers"));
  EXPECT_LT(distance, 1e-9);
  RecordProperty("case3_gs_vs_reference", testing::Sci(distance));
  // Residual figures of the reference.
  const auto r = ComputeResiduals(*f, matches);
  EXPECT_NEAR(RootMeanSquare(r.gs_px, inliers), ref["rms_gs_px_inliers"].get<double>(), 1e-9);
  EXPECT_NEAR(RootMeanSquare(r.epi1_px, inliers), ref["rms_epi1_px_inliers"].get<double>(), 1e-9);
  EXPECT_NEAR(RootMeanSquare(r.epi2_px, inliers), ref["rms_epi2_px_inliers"].get<double>(), 1e-9);
  EXPECT_NEAR(RootMeanSquare(r.gs_px), ref["rms_gs_px_all"].get<double>(), 1e-7);
  // Per-point residual column of the CSV.
  const auto gs_ref = rc.Values("gs_res_Fgs_px");
  const auto epi1_ref = rc.Values("epi1_res_Fgs_px");
  const auto epi2_ref = rc.Values("epi2_res_Fgs_px");
  const double sign =
      (ComputeResiduals(Estimate(rc.json, "F_gs_inliers"), matches).gs_px[0] * gs_ref[0] >= 0.0)
          ? 1.0
          : -1.0;
  for (size_t i = 0; i < matches.size(); ++i) {
    EXPECT_NEAR(r.gs_px[i], sign * gs_ref[i], 1e-7) << i;
    EXPECT_NEAR(r.epi1_px[i], sign * epi1_ref[i], 1e-7) << i;
    EXPECT_NEAR(r.epi2_px[i], sign * epi2_ref[i], 1e-7) << i;
  }
  // Without a robust step the outliers ruin the estimate (F_gs_all).
  const auto f_all = EstimateAffineFundamental(matches);
  ASSERT_TRUE(f_all.has_value());
  EXPECT_LT(AffineFundamentalDistance(*f_all, Estimate(rc.json, "F_gs_all")), 1e-9);
}

TEST(AffineFundamentalTest, Case2RansacKeepsEveryMatch) {
  const auto rc = LoadReferenceCase(kCase2);
  const auto matches = rc.Matches();
  RansacOptions options;
  options.seed = 7;
  const auto fit = EstimateAffineFundamentalRansac(matches, options);
  ASSERT_TRUE(fit.has_value());
  EXPECT_EQ(fit->inliers.size(), matches.size());
  EXPECT_TRUE(fit->refit_converged);
  EXPECT_LT(AffineFundamentalDistance(fit->f, JsonMatrix<3, 3>(rc.json["F_true"])), 1e-10);
}

TEST(AffineFundamentalTest, Case3RansacRejectsEveryOutlier) {
  const auto rc = LoadReferenceCase(kCase3);
  const auto matches = rc.Matches();
  const std::vector<int> outliers = rc.RowsWhere("is_outlier");
  ASSERT_EQ(outliers.size(), 30u);
  const double threshold = rc.json["ransac"]["thr_px_gs"].get<double>();
  for (uint32_t seed : {1u, 2u, 3u, 42u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    RansacOptions options;
    options.threshold_px = threshold;
    options.seed = seed;
    const auto fit = EstimateAffineFundamentalRansac(matches, options);
    ASSERT_TRUE(fit.has_value());
    EXPECT_TRUE(fit->refit_converged);
    for (int o : outliers) {
      EXPECT_FALSE(std::binary_search(fit->inliers.begin(), fit->inliers.end(), o)) << o;
    }
    // The reference refit keeps all 170 true inliers; so do we, and then the
    // refit is exactly the Gold Standard on the true inliers.
    EXPECT_EQ(fit->inliers.size(), rc.json["ransac"]["refit_n_inliers"].get<size_t>());
    EXPECT_LT(AffineFundamentalDistance(fit->f, Estimate(rc.json, "F_gs_refit_from_ransac")), 1e-9);
    EXPECT_GE(fit->iterations, 1);
    RecordProperty("case3_ransac_iterations_seed" + std::to_string(seed), fit->iterations);
  }
}

TEST(AffineFundamentalTest, RansacIsReproducible) {
  const auto rc = LoadReferenceCase(kCase3);
  const auto matches = rc.Matches();
  RansacOptions options;
  options.seed = 99;
  const auto a = EstimateAffineFundamentalRansac(matches, options);
  const auto b = EstimateAffineFundamentalRansac(matches, options);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->iterations, b->iterations);
  EXPECT_EQ(a->ransac_inliers, b->ransac_inliers);
  EXPECT_EQ((a->f_ransac - b->f_ransac).norm(), 0.0);
}

TEST(AffineFundamentalTest, MinimalSolverFitsFourMatchesExactly) {
  const auto rc = LoadReferenceCase(kCase2);
  const auto matches = rc.Matches();
  const auto f = SolveAffineFundamentalMinimal(matches[0], matches[5], matches[17], matches[33]);
  ASSERT_TRUE(f.has_value());
  // Noise-free: any four non-degenerate matches give F_true.
  EXPECT_LT(AffineFundamentalDistance(*f, JsonMatrix<3, 3>(rc.json["F_true"])), 1e-9);
}

TEST(AffineFundamentalTest, EpipolesAndLines) {
  const auto rc = LoadReferenceCase(kCase2);
  const Eigen::Matrix3d f = JsonMatrix<3, 3>(rc.json["F_true"]);
  const auto matches = rc.Matches();
  const Eigen::Vector2d e1 = EpipoleDirection1(f);
  const Eigen::Vector2d e2 = EpipoleDirection2(f);
  EXPECT_NEAR(e1.norm(), 1.0, 1e-15);
  EXPECT_NEAR(e2.norm(), 1.0, 1e-15);
  // F e1 = 0 and F' e2 = 0 for the points at infinity (e, 0).
  EXPECT_NEAR((f * Eigen::Vector3d(e1.x(), e1.y(), 0.0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((f.transpose() * Eigen::Vector3d(e2.x(), e2.y(), 0.0)).norm(), 0.0, 1e-15);
  for (const PointMatch& m : matches) {
    const Eigen::Vector3d l2 = EpipolarLineInImage2(f, m.p1);
    const Eigen::Vector3d l1 = EpipolarLineInImage1(f, m.p2);
    // The match lies on both lines, which run along the epipole directions.
    EXPECT_NEAR(l2.dot(m.p2.homogeneous()), 0.0, 1e-9);
    EXPECT_NEAR(l1.dot(m.p1.homogeneous()), 0.0, 1e-9);
    EXPECT_NEAR(l2.head<2>().dot(e2), 0.0, 1e-15);
    EXPECT_NEAR(l1.head<2>().dot(e1), 0.0, 1e-15);
  }
  // Signed distances by hand: move x2 by t along the line normal.
  PointMatch m = matches[3];
  const Eigen::Vector3d l2 = EpipolarLineInImage2(f, m.p1);
  m.p2 += 2.5 * l2.head<2>();
  EXPECT_NEAR(EpipolarResidual2(f, m), 2.5, 1e-9);
  // Under the normalisation ||(a, b, c, d)|| = 1 the GS residual is
  // ||(a, b)|| times the image-2 epipolar distance.
  EXPECT_NEAR(GoldStandardResidual(f, m), 2.5 * std::hypot(f(0, 2), f(1, 2)), 1e-9);
}

TEST(AffineFundamentalTest, NormalisationAndSignConvention) {
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();
  f(0, 2) = 3.0;
  f(1, 2) = 0.0;
  f(2, 0) = -4.0;
  f(2, 1) = 0.0;
  f(2, 2) = 10.0;
  const Eigen::Matrix3d n = NormalizeAffineFundamental(f);
  EXPECT_NEAR(n(2, 0), 0.8, 1e-15);
  EXPECT_NEAR(n(0, 2), -0.6, 1e-15);
  EXPECT_NEAR(n(2, 2), -2.0, 1e-15);
  // |c| tiny: the sign of d decides.
  f.setZero();
  f(2, 0) = 1e-9;
  f(2, 1) = -1.0;
  f(0, 2) = 1.0;
  EXPECT_GT(NormalizeAffineFundamental(f)(2, 1), 0.0);
  // c and d tiny: a decides; then b.
  f.setZero();
  f(0, 2) = -2.0;
  EXPECT_NEAR(NormalizeAffineFundamental(f)(0, 2), 1.0, 1e-15);
  f.setZero();
  f(1, 2) = -2.0;
  EXPECT_NEAR(NormalizeAffineFundamental(f)(1, 2), 1.0, 1e-15);
  EXPECT_NEAR(AffineFundamentalDistance(f, -3.0 * f), 0.0, 1e-15);
}

TEST(AffineFundamentalTest, InvalidInputThrowsInputError) {
  const auto rc = LoadReferenceCase(kCase2);
  auto matches = rc.Matches();
  const std::vector<PointMatch> three(matches.begin(), matches.begin() + 3);
  EXPECT_THROW(EstimateAffineFundamental(three), InputError);
  EXPECT_THROW(EstimateAffineFundamentalRansac(three, RansacOptions{}), InputError);
  EXPECT_THROW(EstimateAffineFundamental(matches, {0, 1, 2}), InputError);
  EXPECT_THROW(EstimateAffineFundamental(matches, {0, 1, 2, 50}), InputError);
  matches[7].p2.y() = std::nan("");
  EXPECT_THROW(EstimateAffineFundamental(matches), InputError);
  EXPECT_THROW(EstimateAffineFundamentalRansac(matches, RansacOptions{}), InputError);
  matches[7].p2.y() = INFINITY;
  EXPECT_THROW(EstimateAffineFundamental(matches), InputError);
  RansacOptions bad;
  bad.threshold_px = 0.0;
  EXPECT_THROW(EstimateAffineFundamentalRansac(rc.Matches(), bad), ConfigError);
  bad = RansacOptions{};
  bad.confidence = 1.0;
  EXPECT_THROW(EstimateAffineFundamentalRansac(rc.Matches(), bad), ConfigError);
  Eigen::Matrix3d not_affine = JsonMatrix<3, 3>(rc.json["F_true"]);
  not_affine(0, 0) = 0.1;
  EXPECT_THROW(NormalizeAffineFundamental(not_affine), InputError);
  EXPECT_THROW(NormalizeAffineFundamental(Eigen::Matrix3d::Zero()), InputError);
  AffineMatrix p = JsonMatrix<3, 4>(rc.json["P1"]);
  p(2, 0) = 0.2;  // projective, not affine
  EXPECT_THROW(FundamentalFromCameras(p, JsonMatrix<3, 4>(rc.json["P2"])), InputError);
}

TEST(AffineFundamentalTest, DegenerateConfigurationsGiveNullopt) {
  // Collinear points in both images.
  std::vector<PointMatch> collinear;
  for (int i = 0; i < 10; ++i) {
    PointMatch m;
    m.p1 = {10.0 + i, 20.0 + 2.0 * i};
    m.p2 = {5.0 - 3.0 * i, 7.0 + 0.5 * i};
    collinear.push_back(m);
  }
  EXPECT_FALSE(EstimateAffineFundamental(collinear).has_value());
  EXPECT_FALSE(
      SolveAffineFundamentalMinimal(collinear[0], collinear[3], collinear[5], collinear[9]));
  EXPECT_FALSE(EstimateAffineFundamentalRansac(collinear, RansacOptions{}).has_value());
  // A planar scene: image 2 is an affine map of image 1, rank 2.
  std::vector<PointMatch> planar;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1000.0);
  for (int i = 0; i < 20; ++i) {
    PointMatch m;
    m.p1 = {u(rng), u(rng)};
    m.p2 = {0.9 * m.p1.x() + 0.2 * m.p1.y() + 4.0, -0.1 * m.p1.x() + 1.1 * m.p1.y() - 3.0};
    planar.push_back(m);
  }
  EXPECT_FALSE(EstimateAffineFundamental(planar).has_value());
  // All points identical.
  const std::vector<PointMatch> same(6, planar[0]);
  EXPECT_FALSE(EstimateAffineFundamental(same).has_value());
  // Identical cameras have no fundamental matrix.
  const AffineMatrix p = AffineSarCamera(SarPose{}).Matrix();
  EXPECT_FALSE(FundamentalFromCameras(p, p).has_value());
}

}  // namespace
}  // namespace gissar::mvg
