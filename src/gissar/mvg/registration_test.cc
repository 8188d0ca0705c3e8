#include "gissar/mvg/registration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

#include <Eigen/Geometry>

#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

using Map = std::function<Eigen::Vector2d(const Eigen::Vector2d&)>;

Eigen::Matrix3d Similarity(double angle_deg, double scale, double tx, double ty) {
  const double a = angle_deg * M_PI / 180.0;
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m << scale * std::cos(a), -scale * std::sin(a), tx, scale * std::sin(a), scale * std::cos(a), ty,
      0, 0, 1;
  return m;
}

Eigen::Matrix3d Affine() {
  Eigen::Matrix3d m;
  m << 1.05, 0.12, -14.0, -0.08, 0.93, 22.5, 0, 0, 1;
  return m;
}

Eigen::Matrix3d Projective() {
  Eigen::Matrix3d m;
  m << 0.98, 0.05, 12.0, -0.04, 1.03, -7.0, 2e-5, -3e-5, 1.0;
  return m;
}

Map FromMatrix(const Eigen::Matrix3d& m) {
  return [m](const Eigen::Vector2d& p) -> Eigen::Vector2d {
    const Eigen::Vector3d q = m * p.homogeneous();
    return q.head<2>() / q.z();
  };
}

// Mild polynomial warps (in pixels), as from terrain or a curved track.
Eigen::Vector2d Poly2(const Eigen::Vector2d& p) {
  const double x = p.x(), y = p.y();
  return {4.0 + 1.01 * x + 0.02 * y + 2e-5 * x * x - 1e-5 * x * y + 1.5e-5 * y * y,
          -3.0 - 0.015 * x + 0.99 * y - 1e-5 * x * x + 2e-5 * x * y - 1e-5 * y * y};
}

Eigen::Vector2d Poly3(const Eigen::Vector2d& p) {
  const double x = p.x(), y = p.y();
  const Eigen::Vector2d q = Poly2(p);
  return {q.x() + 2e-8 * x * x * x - 1e-8 * x * x * y + 1e-8 * y * y * y,
          q.y() - 1e-8 * x * x * x + 1.5e-8 * x * y * y - 1e-8 * y * y * y};
}

struct Case {
  TransformType type;
  Map map;
};

std::vector<Case> Cases() {
  return {{TransformType::kSimilarity, FromMatrix(Similarity(12.0, 1.07, 30.0, -12.0))},
          {TransformType::kAffine, FromMatrix(Affine())},
          {TransformType::kProjective, FromMatrix(Projective())},
          {TransformType::kPolynomial2, Poly2},
          {TransformType::kPolynomial3, Poly3}};
}

// Moving points spread over a 1000 x 800 image and their fixed positions.
std::vector<PointMatch> Pairs(const Map& map, int count, double noise_px, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(0.0, 1000.0), uy(0.0, 800.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<PointMatch> pairs;
  for (int i = 0; i < count; ++i) {
    PointMatch m;
    m.p2 = {ux(rng), uy(rng)};
    m.p1 = map(m.p2);
    if (noise_px > 0.0) m.p1 += Eigen::Vector2d(noise(rng), noise(rng));
    pairs.push_back(m);
  }
  return pairs;
}

TEST(RegistrationTest, KnownWarpsAreRecoveredExactly) {
  for (const Case& c : Cases()) {
    SCOPED_TRACE(ToString(c.type));
    const auto pairs = Pairs(c.map, 60, 0.0, 1);
    RegistrationOptions options;
    options.type = c.type;
    options.robust = false;
    const auto reg = RegisterControlPoints(pairs, options);
    ASSERT_TRUE(reg.has_value());
    EXPECT_EQ(reg->type, c.type);
    EXPECT_LT(reg->rms_px, 1e-8);
    EXPECT_EQ(reg->inliers.size(), pairs.size());
    // The fitted map agrees with the true one away from the control points.
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(37.0, 51.0), Eigen::Vector2d(512.3, 400.9),
                                     Eigen::Vector2d(990.0, 10.0)}) {
      EXPECT_LT((reg->moving_to_fixed.Apply(p) - c.map(p)).norm(), 1e-7);
      // And the inverse maps back: exactly for matrices; for polynomials the
      // inverse is a least-squares polynomial approximation (the inverse of
      // these warps, which bend the image by up to 20 px, is not itself a
      // polynomial), good to a fraction of a pixel even near the corners.
      const double tol =
          (c.type == TransformType::kPolynomial2 || c.type == TransformType::kPolynomial3) ? 0.5
                                                                                           : 1e-7;
      EXPECT_LT((reg->fixed_to_moving.Apply(c.map(p)) - p).norm(), tol);
    }
    EXPECT_LT(reg->inverse_rms_px, 0.05);
  }
}

TEST(RegistrationTest, MatricesByHand) {
  const auto pairs = Pairs(FromMatrix(Similarity(30.0, 2.0, 5.0, 6.0)), 10, 0.0, 2);
  RegistrationOptions options;
  options.type = TransformType::kSimilarity;
  options.robust = false;
  const auto reg = RegisterControlPoints(pairs, options);
  ASSERT_TRUE(reg.has_value());
  const Eigen::Matrix3d m = *reg->moving_to_fixed.Matrix();
  EXPECT_NEAR(m(0, 0), 2.0 * std::cos(M_PI / 6), 1e-12);
  EXPECT_NEAR(m(1, 0), 2.0 * std::sin(M_PI / 6), 1e-12);
  EXPECT_NEAR(m(0, 2), 5.0, 1e-9);
  EXPECT_NEAR(m(1, 2), 6.0, 1e-9);
  EXPECT_FALSE(reg->fixed_to_moving.coefficients().size() > 0);
}

TEST(RegistrationTest, RobustFitIgnoresOutliers) {
  for (const Case& c : Cases()) {
    SCOPED_TRACE(ToString(c.type));
    auto pairs = Pairs(c.map, 100, 0.2, 3);
    // 25 % outliers displaced by 20..80 px.
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> offset(20.0, 80.0);
    std::uniform_real_distribution<double> angle(0.0, 2 * M_PI);
    std::vector<int> expected_inliers;
    for (int i = 0; i < 100; ++i) {
      if (i % 4 == 1) {
        const double a = angle(rng);
        pairs[i].p1 += offset(rng) * Eigen::Vector2d(std::cos(a), std::sin(a));
      } else {
        expected_inliers.push_back(i);
      }
    }
    RegistrationOptions options;
    options.type = c.type;
    options.threshold_px = 2.0;
    options.seed = 5;
    const auto reg = RegisterControlPoints(pairs, options);
    ASSERT_TRUE(reg.has_value());
    EXPECT_EQ(reg->inliers, expected_inliers);
    // RMS of 2-D Gaussian noise of 0.2 px per coordinate: about 0.28 px.
    EXPECT_NEAR(reg->rms_px, 0.2 * std::sqrt(2.0), 0.06);
    EXPECT_LT((reg->moving_to_fixed.Apply({500.0, 400.0}) - c.map({500.0, 400.0})).norm(), 0.2);
    EXPECT_GT(reg->iterations, 0);
    // A least-squares fit to everything is pulled away by the outliers.
    options.robust = false;
    const auto plain = RegisterControlPoints(pairs, options);
    ASSERT_TRUE(plain.has_value());
    EXPECT_GT(plain->rms_px, 5.0);
  }
}

// f(x, y) on the moving grid; smooth so that bilinear interpolation is
// accurate to a few hundredths.
double Pattern(double x, double y) { return 100.0 + 50.0 * std::sin(x / 9.0) * std::cos(y / 13.0); }

TEST(RegistrationTest, WarpResamplesTheMovingImage) {
  cv::Mat moving(150, 200, CV_32FC1);
  for (int r = 0; r < moving.rows; ++r)
    for (int c = 0; c < moving.cols; ++c)
      moving.at<float>(r, c) = static_cast<float>(Pattern(c, r));
  const std::vector<Case> cases = {
      {TransformType::kSimilarity, FromMatrix(Similarity(10.0, 1.1, 5.0, -3.0))},
      {TransformType::kAffine, FromMatrix(Affine())},
      {TransformType::kProjective, FromMatrix(Projective())},
      {TransformType::kPolynomial2, Poly2}};
  for (const Case& c : cases) {
    SCOPED_TRACE(ToString(c.type));
    RegistrationOptions options;
    options.type = c.type;
    options.robust = false;
    const auto reg = RegisterControlPoints(Pairs(c.map, 40, 0.0, 4), options);
    ASSERT_TRUE(reg.has_value());
    const cv::Mat fixed = WarpToFixed(moving, *reg, cv::Size(220, 170));
    ASSERT_EQ(fixed.type(), CV_32FC1);
    ASSERT_EQ(fixed.cols, 220);
    ASSERT_EQ(fixed.rows, 170);
    int checked = 0;
    double worst = 0.0;
    for (int r = 0; r < fixed.rows; ++r) {
      for (int col = 0; col < fixed.cols; ++col) {
        const Eigen::Vector2d m = reg->fixed_to_moving.Apply(Eigen::Vector2d(col, r));
        if (m.x() < 1.0 || m.y() < 1.0 || m.x() > moving.cols - 2.0 || m.y() > moving.rows - 2.0) {
          if (m.x() < -1.0 || m.y() < -1.0 || m.x() > moving.cols || m.y() > moving.rows) {
            EXPECT_EQ(fixed.at<float>(r, col), 0.0f);  // outside: zero
          }
          continue;
        }
        worst = std::max(worst, std::abs(fixed.at<float>(r, col) - Pattern(m.x(), m.y())));
        ++checked;
      }
    }
    EXPECT_GT(checked, 10000);
    EXPECT_LT(worst, 0.2);
  }
}

TEST(RegistrationTest, GreenMagentaComposite) {
  cv::Mat fixed(4, 5, CV_8UC1, cv::Scalar(0));
  fixed.at<uint8_t>(1, 2) = 200;
  cv::Mat moving(4, 5, CV_32FC1, cv::Scalar(1.0f));
  moving.at<float>(0, 0) = 0.0f;
  moving.at<float>(3, 4) = 2.0f;
  moving.at<float>(2, 2) = std::nanf("");
  const cv::Mat out = GreenMagentaComposite(fixed, moving);
  ASSERT_EQ(out.type(), CV_8UC3);
  const cv::Vec3b a = out.at<cv::Vec3b>(1, 2);  // fixed 200, moving 1 -> 127/128
  EXPECT_EQ(a[1], 200);
  EXPECT_EQ(a[0], a[2]);
  EXPECT_NEAR(a[0], 127.5, 0.6);
  EXPECT_EQ(out.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(out.at<cv::Vec3b>(3, 4), cv::Vec3b(255, 0, 255));  // magenta only
  EXPECT_EQ(out.at<cv::Vec3b>(2, 2), cv::Vec3b(0, 0, 0));      // NaN -> 0
  EXPECT_THROW(GreenMagentaComposite(fixed, cv::Mat(3, 5, CV_8UC1)), InputError);
  EXPECT_THROW(GreenMagentaComposite(fixed, cv::Mat(4, 5, CV_8UC3)), InputError);
  EXPECT_THROW(GreenMagentaComposite(cv::Mat(), moving), InputError);
}

TEST(RegistrationTest, DegenerateAndInvalidInput) {
  // Collinear points: no affine map.
  std::vector<PointMatch> line;
  for (int i = 0; i < 8; ++i) {
    PointMatch m;
    m.p2 = {10.0 * i, 5.0 * i};
    m.p1 = {3.0 + 10.0 * i, 1.0 + 5.0 * i};
    line.push_back(m);
  }
  RegistrationOptions options;
  options.robust = false;
  EXPECT_FALSE(RegisterControlPoints(line, options).has_value());
  options.robust = true;
  EXPECT_FALSE(RegisterControlPoints(line, options).has_value());
  options.type = TransformType::kProjective;
  EXPECT_FALSE(RegisterControlPoints(line, options).has_value());
  // Too few pairs.
  options.type = TransformType::kPolynomial3;
  EXPECT_THROW(RegisterControlPoints(Pairs(Poly3, 9, 0.0, 1), options), InputError);
  options.type = TransformType::kAffine;
  auto pairs = Pairs(FromMatrix(Affine()), 10, 0.0, 1);
  pairs[3].p1.y() = std::nan("");
  EXPECT_THROW(RegisterControlPoints(pairs, options), InputError);
  options.threshold_px = -1.0;
  EXPECT_THROW(RegisterControlPoints(Pairs(FromMatrix(Affine()), 10, 0.0, 1), options),
               ConfigError);
  EXPECT_THROW(ParseTransformType("rigid"), ConfigError);
  EXPECT_EQ(ParseTransformType("poly3"), TransformType::kPolynomial3);
  EXPECT_EQ(MinimumControlPoints(TransformType::kPolynomial2), 6);
  EXPECT_THROW(PlaneTransform::FromMatrix(TransformType::kAffine, Eigen::Matrix3d::Zero()),
               InputError);
  EXPECT_THROW(WarpToFixed(cv::Mat(), Registration{}, cv::Size(4, 4)), InputError);
}

}  // namespace
}  // namespace gissar::mvg
