#include "gissar/image/polarimetry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

#include "gissar/material/scattering.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

using cd = std::complex<double>;
constexpr double kDeg = M_PI / 180.0;

// A width x height image whose pixel (row, col) has the matrix f(row, col).
QuadPolImage MakeImage(int width, int height, const std::function<material::ScatteringMatrix(int, int)>& f) {
  QuadPolImage image;
  image.width = width;
  image.height = height;
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const material::ScatteringMatrix s = f(r, c);
      image.hh.emplace_back(s(0, 0));
      image.hv.emplace_back(s(0, 1));
      image.vh.emplace_back(s(1, 0));
      image.vv.emplace_back(s(1, 1));
    }
  }
  return image;
}

// Samples of a distributed target with the given law (material's seeded,
// library-independent generator).
QuadPolImage RandomImage(int width, int height, const material::PolarimetricSigma0& law, uint64_t seed) {
  std::mt19937_64 rng(seed);
  return MakeImage(width, height, [&](int, int) { return material::DrawScatteringMatrix(law, rng); });
}

// Sets up a pure target of matrix s scaled by a random amplitude and phase
// per pixel: k k^H keeps rank 1, so every multilooked T3 is rank 1.
QuadPolImage PureTargetImage(const material::ScatteringMatrix& s, int width, int height, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> amp(0.2, 3.0), phase(-M_PI, M_PI);
  return MakeImage(width, height, [&](int, int) {
    const double a = amp(rng);
    return material::ScatteringMatrix(s * std::polar(a, phase(rng)));
  });
}

double MaxAbs(const Eigen::Matrix3cd& m) { return m.cwiseAbs().maxCoeff(); }

TEST(PolarimetryTest, PureTrihedralHasOnlyT11) {
  // S = I: k = (2, 0, 0) / sqrt 2, T3 = diag(2, 0, 0) |a|^2; k_L = (1, 0, 1),
  // C3 = [[1, 0, 1], [0, 0, 0], [1, 0, 1]] |a|^2. Eigenvector e_1 = (1, 0, 0):
  // alpha_1 = acos 1 = 0, p = (1, 0, 0): H = 0, mean alpha 0, A := 0 (rank 1).
  const QuadPolImage image = PureTargetImage(material::TrihedralMatrix(), 8, 6, 1);
  const PolarimetricMatrixImage t3 = MultilookCoherency(image, 2, 3);
  const PolarimetricMatrixImage c3 = MultilookCovariance(image, 2, 3);
  ASSERT_EQ(t3.width, 4);
  ASSERT_EQ(t3.height, 2);
  for (int r = 0; r < t3.height; ++r) {
    for (int c = 0; c < t3.width; ++c) {
      const Eigen::Matrix3cd t = t3.At(r, c), cv = c3.At(r, c);
      const double span = t(0, 0).real();
      ASSERT_GT(span, 0.0);
      Eigen::Matrix3cd only = Eigen::Matrix3cd::Zero();
      only(0, 0) = span;
      EXPECT_LT(MaxAbs(t - only), 1e-6 * span);
      // C11 = C33 = C13 = span / 2.
      Eigen::Matrix3cd expected_c = Eigen::Matrix3cd::Zero();
      expected_c(0, 0) = expected_c(2, 2) = expected_c(0, 2) = expected_c(2, 0) = span / 2;
      EXPECT_LT(MaxAbs(cv - expected_c), 1e-6 * span);
      const CloudePottierParameters p = CloudePottier(t);
      EXPECT_NEAR(p.entropy, 0.0, 1e-9);
      EXPECT_EQ(p.anisotropy, 0.0);
      EXPECT_NEAR(p.alpha_deg, 0.0, 1e-6);
    }
  }
  const CloudePottierImage planes = CloudePottierPlanes(c3);  // from C3: converted to T3 first
  for (size_t i = 0; i < planes.entropy.size(); ++i) {
    EXPECT_NEAR(planes.entropy[i], 0.0, 1e-5);
    EXPECT_EQ(planes.anisotropy[i], 0.0f);
    EXPECT_NEAR(planes.alpha_deg[i], 0.0, 0.05);
  }
}

TEST(PolarimetryTest, PureDihedralsHaveAlpha90AtAnyRoll) {
  // diag(1, -1): k = (0, 2, 0) / sqrt 2, T3 = diag(0, 2, 0): e_1 = (0, 1, 0),
  // alpha = acos 0 = 90 deg, H = 0.
  // Rolled 22.5 deg: S = [[cos 45, sin 45], [sin 45, -cos 45]]:
  // k = (0, 2 cos 45, 2 sin 45) / sqrt 2 = (0, 1, 1): T3 = [[0, 0, 0],
  // [0, 1, 1], [0, 1, 1]], e_1 = (0, 1, 1) / sqrt 2, alpha = 90 deg, H = 0.
  for (double roll_deg : {0.0, 22.5, 45.0, -30.0}) {
    SCOPED_TRACE(roll_deg);
    const material::ScatteringMatrix s = material::DihedralMatrix(roll_deg * kDeg);
    const QuadPolImage image = PureTargetImage(s, 12, 9, 2);
    const PolarimetricMatrixImage t3 = MultilookCoherency(image, 3, 3);
    for (int r = 0; r < t3.height; ++r) {
      for (int c = 0; c < t3.width; ++c) {
        const Eigen::Matrix3cd t = t3.At(r, c);
        const double span = t.trace().real();
        EXPECT_LT(std::abs(t(0, 0)), 1e-6 * span);
        EXPECT_NEAR(t(1, 1).real() / span, std::pow(std::cos(2 * roll_deg * kDeg), 2), 1e-6);
        const CloudePottierParameters p = CloudePottier(t);
        EXPECT_NEAR(p.entropy, 0.0, 1e-5);
        EXPECT_EQ(p.anisotropy, 0.0);
        EXPECT_NEAR(p.alpha_deg, 90.0, 1e-3);
      }
    }
    if (roll_deg == 22.5) {
      const Eigen::Matrix3cd t = t3.At(0, 0);
      const double span = t.trace().real();
      EXPECT_NEAR(t(1, 1).real() / span, 0.5, 1e-6);
      EXPECT_NEAR(t(2, 2).real() / span, 0.5, 1e-6);
      EXPECT_NEAR(t(1, 2).real() / span, 0.5, 1e-6);
    }
  }
}

TEST(PolarimetryTest, CloudePottierHandValues) {
  const auto t_of = [](double a, double b, double c) {
    return Eigen::Matrix3cd(Eigen::Vector3cd(a, b, c).asDiagonal());
  };
  // diag(2, 1, 0): p = (2/3, 1/3, 0); H = (2/3 ln 1.5 + 1/3 ln 3) / ln 3 =
  // 0.579380; A = (1 - 0) / (1 + 0) = 1; alpha = 2/3 0 + 1/3 90 = 30 deg.
  // A roll psi turns the Pauli components 2 and 3 by 2 psi and changes none
  // of the three.
  for (double roll_deg : {0.0, 17.0}) {
    const double c = std::cos(2 * roll_deg * kDeg), s = std::sin(2 * roll_deg * kDeg);
    Eigen::Matrix3cd rot = Eigen::Matrix3cd::Identity();
    rot(1, 1) = c, rot(1, 2) = s, rot(2, 1) = -s, rot(2, 2) = c;
    const CloudePottierParameters p = CloudePottier(rot * t_of(2, 1, 0) * rot.adjoint());
    EXPECT_NEAR(p.entropy, 0.579380, 1e-6);
    EXPECT_NEAR(p.anisotropy, 1.0, 1e-12);
    EXPECT_NEAR(p.alpha_deg, 30.0, 1e-9);
    EXPECT_NEAR(p.eigenvalues[0], 2.0, 1e-12);
    EXPECT_NEAR(p.eigenvalues[2], 0.0, 1e-12);
  }
  // diag(1, 0.5, 0.5): p = (1/2, 1/4, 1/4); H = (0.5 ln 2 + 0.5 ln 4) / ln 3
  // = 1.5 ln 2 / ln 3 = 0.946395; A = 0; any eigenvectors of the double
  // eigenvalue lie in span(e2, e3): alpha 90, mean 0.5 90 = 45 deg.
  CloudePottierParameters p = CloudePottier(t_of(1, 0.5, 0.5));
  EXPECT_NEAR(p.entropy, 1.5 * std::log(2.0) / std::log(3.0), 1e-9);
  EXPECT_NEAR(p.anisotropy, 0.0, 1e-12);
  EXPECT_NEAR(p.alpha_deg, 45.0, 1e-9);
  // The boundary curve diag(1, m, m) (Cloude-Pottier curve I): mean alpha =
  // 90 2m / (1 + 2m) -> 60 deg as m -> 1 (H -> 1).
  p = CloudePottier(t_of(1, 0.999, 0.999));
  EXPECT_NEAR(p.alpha_deg, 90.0 * 1.998 / 2.998, 1e-9);
  EXPECT_GT(p.entropy, 0.99999);
  // All-zero and non-finite pixels: NaN.
  p = CloudePottier(Eigen::Matrix3cd::Zero());
  EXPECT_TRUE(std::isnan(p.entropy) && std::isnan(p.anisotropy) && std::isnan(p.alpha_deg));
  Eigen::Matrix3cd bad = t_of(1, 1, 1);
  bad(1, 0) = cd(std::nan(""), 0.0);
  p = CloudePottier(bad);
  EXPECT_TRUE(std::isnan(p.entropy) && std::isnan(p.anisotropy) && std::isnan(p.alpha_deg));
}

TEST(PolarimetryTest, CloudePottierOfIsotropicRandomMedium) {
  // Uncorrelated Pauli components of equal power: C3 = I <=> sigma0_hh =
  // sigma0_vv = 1, 2 sigma0_hv = 1, rho = 0, and T3 = U C3 U^T = I.
  // 300 x 300 samples, 15 x 15 looks: 400 pixels of N = 225 looks. The sample
  // T3 is complex Wishart, its eigenvalues spread by ~ 1/sqrt N = 0.067, so
  // H ~ 1 - O(1/N) and A = (l2 - l3) / (l2 + l3) ~ 0.05.
  // Mean alpha: the Wishart law is unitarily invariant, so the eigenvectors
  // are Haar-random and independent of the eigenvalues: E[mean alpha] =
  // E[acos |u_1|] for u uniform on the unit sphere of C^3, where |u_1|^2 has
  // the density 2 (1 - x) on [0, 1] (Beta(1, 2)). With x = cos^2 a:
  // E[a] = int_0^{pi/2} 4 a sin^3 a cos a da = [a sin^4 a] - int sin^4 a da
  // = pi/2 - 3 pi/16 = 5 pi/16 = 56.25 deg. Not 60 deg: sum |e_i1|^2 = 1 does
  // not make sum acos |e_i1| = 180 deg (it does only for eigenvectors along
  // the Pauli axes, the diag(1, m, m) limit of the H-alpha boundary, 60 deg).
  const QuadPolImage image = RandomImage(300, 300, {1.0, 0.5, 1.0, cd(0.0, 0.0)}, 20240611);
  const PolarimetricMatrixImage t3 = MultilookCoherency(image, 15, 15);
  ASSERT_EQ(t3.width, 20);
  ASSERT_EQ(t3.height, 20);
  const CloudePottierImage planes = CloudePottierPlanes(t3);
  const size_t n = planes.entropy.size();
  double h = 0.0, a = 0.0, alpha = 0.0, alpha2 = 0.0, h_min = 1.0, t11 = 0.0, t22 = 0.0, t33 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    h += planes.entropy[i];
    h_min = std::min(h_min, double(planes.entropy[i]));
    a += planes.anisotropy[i];
    alpha += planes.alpha_deg[i];
    alpha2 += double(planes.alpha_deg[i]) * planes.alpha_deg[i];
    t11 += t3.bands[0][i], t22 += t3.bands[1][i], t33 += t3.bands[2][i];
  }
  h /= n, a /= n, alpha /= n, t11 /= n, t22 /= n, t33 /= n;
  const double alpha_sd = std::sqrt(alpha2 / n - alpha * alpha);
  std::printf("isotropic: mean H %.4f (min %.4f), mean A %.4f, mean alpha %.3f deg (sd %.3f, sd of mean %.3f), "
              "T11 %.4f T22 %.4f T33 %.4f\n",
              h, h_min, a, alpha, alpha_sd, alpha_sd / std::sqrt(double(n)), t11, t22, t33);
  EXPECT_GE(h, 0.97);
  EXPECT_GE(h_min, 0.9);
  EXPECT_LE(a, 0.1);
  // Mean over 400 pixels; tolerance > 4 standard errors of the mean.
  EXPECT_NEAR(alpha, 56.25, 1.0);
  // Channel powers: each T_ii averages 1 over 90 000 samples (sd 0.0033).
  EXPECT_NEAR(t11, 1.0, 0.02);
  EXPECT_NEAR(t22, 1.0, 0.02);
  EXPECT_NEAR(t33, 1.0, 0.02);
}

TEST(PolarimetryTest, ReflectionSymmetricCovariance) {
  // sigma0 HH 1, HV 0.1, VV 0.5, rho = 0.6 at 40 deg, HV uncorrelated: the
  // expected C3 = [[1, 0, rho sqrt 0.5], [0, 0.2, 0], [., 0, 0.5]]. 100 x 100
  // looks: the sample coherence of a zero-coherence pair has rms 1/sqrt N =
  // 0.01; the error of that of rho has sd ~ (1 - |rho|^2) / sqrt(2 N) =
  // 0.0045 along and across rho, so the largest |gamma13 - rho| of 9 pixels
  // is typically 0.008 - 0.018 (20 seeds tried): 0.03 per pixel, and 0.01
  // for the whole image as one 300 x 300-look pixel (sd 0.0015).
  const cd rho = std::polar(0.6, 40.0 * kDeg);
  const QuadPolImage image = RandomImage(300, 300, {1.0, 0.1, 0.5, rho}, 7);
  const PolarimetricMatrixImage c3 = MultilookCovariance(image, 100, 100);
  ASSERT_EQ(c3.width, 3);
  ASSERT_EQ(c3.height, 3);
  double worst_rho = 0.0, worst_cross = 0.0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const Eigen::Matrix3cd m = c3.At(r, c);
      const double c11 = m(0, 0).real(), c22 = m(1, 1).real(), c33 = m(2, 2).real();
      const cd gamma13 = m(0, 2) / std::sqrt(c11 * c33);
      const double g12 = std::abs(m(0, 1)) / std::sqrt(c11 * c22);
      const double g23 = std::abs(m(1, 2)) / std::sqrt(c22 * c33);
      worst_rho = std::max(worst_rho, std::abs(gamma13 - rho));
      worst_cross = std::max({worst_cross, g12, g23});
      EXPECT_NEAR(std::abs(gamma13 - rho), 0.0, 0.03);
      EXPECT_LT(g12, 0.04);  // 4 rms
      EXPECT_LT(g23, 0.04);
      EXPECT_NEAR(c11, 1.0, 0.06);  // sd 1 / sqrt(10 000) = 1 %
      EXPECT_NEAR(c22, 0.2, 0.012);
      EXPECT_NEAR(c33, 0.5, 0.03);
    }
  }
  const Eigen::Matrix3cd all = MultilookCovariance(image, 300, 300).At(0, 0);
  const cd gamma_all = all(0, 2) / std::sqrt(all(0, 0).real() * all(2, 2).real());
  EXPECT_LT(std::abs(gamma_all - rho), 0.01);
  EXPECT_LT(std::abs(all(0, 1)) / std::sqrt(all(0, 0).real() * all(1, 1).real()), 0.015);
  EXPECT_LT(std::abs(all(1, 2)) / std::sqrt(all(1, 1).real() * all(2, 2).real()), 0.015);
  std::printf("reflection symmetric: worst |gamma13 - rho| %.4f, worst |gamma12|, |gamma23| %.4f (100 x 100 looks); "
              "whole image |gamma13 - rho| %.4f\n",
              worst_rho, worst_cross, std::abs(gamma_all - rho));
}

TEST(PolarimetryTest, CoherencyIsUnitaryTransformOfCovariance) {
  // U = (1/sqrt 2) [[1, 0, 1], [1, 0, -1], [0, sqrt 2, 0]] maps k_L = (HH,
  // sqrt 2 X, VV) to k = ((HH + VV), (HH - VV), 2 X) / sqrt 2, so <k k^H> =
  // U <k_L k_L^H> U^T. Random independent channels (HV != VH: both use the
  // symmetrised X = (HV + VH) / 2).
  const Eigen::Matrix3d u = LexicographicToPauli();
  EXPECT_LT((u * u.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-15);
  std::mt19937_64 rng(99);
  std::normal_distribution<double> g;
  const QuadPolImage image = MakeImage(60, 40, [&](int, int) {
    material::ScatteringMatrix s;
    for (int i = 0; i < 4; ++i) s(i / 2, i % 2) = cd(g(rng), g(rng)) * (1.0 + i);
    return s;
  });
  const PolarimetricMatrixImage c3 = MultilookCovariance(image, 3, 2);
  const PolarimetricMatrixImage t3 = MultilookCoherency(image, 3, 2);
  const PolarimetricMatrixImage t3_from_c3 = ConvertPolarimetricMatrix(c3, PolarimetricMatrix::kCoherency);
  const PolarimetricMatrixImage c3_back = ConvertPolarimetricMatrix(t3, PolarimetricMatrix::kCovariance);
  EXPECT_EQ(t3_from_c3.kind, PolarimetricMatrix::kCoherency);
  double worst = 0.0;
  for (int r = 0; r < t3.height; ++r) {
    for (int c = 0; c < t3.width; ++c) {
      const double span = t3.At(r, c).trace().real();
      EXPECT_NEAR(span, c3.At(r, c).trace().real(), 1e-6 * span);
      const Eigen::Matrix3cd expected = u.cast<cd>() * c3.At(r, c) * u.transpose().cast<cd>();
      worst = std::max(worst, MaxAbs(t3.At(r, c) - expected) / span);
      EXPECT_LT(MaxAbs(t3.At(r, c) - expected), 1e-6 * span);
      EXPECT_LT(MaxAbs(t3_from_c3.At(r, c) - t3.At(r, c)), 1e-6 * span);
      EXPECT_LT(MaxAbs(c3_back.At(r, c) - c3.At(r, c)), 1e-6 * span);
    }
  }
  std::printf("T3 vs U C3 U^T: worst relative difference %.2e\n", worst);
  // One look: exactly material's Coherency3 / Covariance3 of the pixel.
  const PolarimetricMatrixImage t1 = MultilookCoherency(image, 1, 1), c1 = MultilookCovariance(image, 1, 1);
  const material::ScatteringMatrix s00 =
      material::MakeScatteringMatrix(image.hh[0], image.hv[0], image.vh[0], image.vv[0]);
  const double span = t1.At(0, 0).trace().real();
  EXPECT_LT(MaxAbs(t1.At(0, 0) - material::Coherency3(s00)), 1e-6 * span);
  EXPECT_LT(MaxAbs(c1.At(0, 0) - material::Covariance3(s00)), 1e-6 * span);
}

TEST(PolarimetryTest, MultilookGridAveragesAndNanPropagation) {
  // 7 x 5 with looks 2 (range) x 2 (azimuth): 3 x 2 output; the last column
  // and row are dropped. Pixel (row r, col c): HH = r + 10 c, VV = 0, HV =
  // VH = 0: C11 of block (R, C) = mean of (r + 10 c)^2 over r in {2R, 2R+1},
  // c in {2C, 2C+1}.
  QuadPolImage image = MakeImage(7, 5, [](int r, int c) {
    material::ScatteringMatrix s = material::ScatteringMatrix::Zero();
    s(0, 0) = r + 10.0 * c;
    return s;
  });
  PolarimetricMatrixImage c3 = MultilookCovariance(image, 2, 2);
  ASSERT_EQ(c3.width, 3);
  ASSERT_EQ(c3.height, 2);
  for (const auto& band : c3.bands) ASSERT_EQ(band.size(), 6u);
  for (int R = 0; R < 2; ++R) {
    for (int C = 0; C < 3; ++C) {
      double expected = 0.0;
      for (int r = 2 * R; r < 2 * R + 2; ++r) {
        for (int c = 2 * C; c < 2 * C + 2; ++c) expected += std::pow(r + 10.0 * c, 2) / 4;
      }
      EXPECT_NEAR(c3.At(R, C)(0, 0).real(), expected, 1e-4) << R << " " << C;
      EXPECT_EQ(c3.At(R, C)(1, 1).real(), 0.0);
    }
  }
  // Make block (1, 2) all zero and put a NaN (in VH only) into block (0, 1).
  for (int r = 2; r < 4; ++r) {
    for (int c = 4; c < 6; ++c) image.hh[size_t(r) * 7 + c] = 0.0f;
  }
  image.vh[size_t(1) * 7 + 3] = std::complex<float>(std::nanf(""), 0.0f);
  // A NaN in the dropped last column changes nothing.
  image.vv[size_t(0) * 7 + 6] = std::complex<float>(0.0f, INFINITY);
  c3 = MultilookCovariance(image, 2, 2);
  const CloudePottierImage cp = CloudePottierPlanes(c3);
  for (int R = 0; R < 2; ++R) {
    for (int C = 0; C < 3; ++C) {
      const size_t i = size_t(R) * 3 + C;
      const bool nan_block = R == 0 && C == 1, zero_block = R == 1 && C == 2;
      for (const auto& band : c3.bands) EXPECT_EQ(std::isnan(band[i]), nan_block) << R << " " << C;
      EXPECT_EQ(std::isnan(cp.entropy[i]), nan_block || zero_block) << R << " " << C;
      EXPECT_EQ(std::isnan(cp.anisotropy[i]), nan_block || zero_block);
      EXPECT_EQ(std::isnan(cp.alpha_deg[i]), nan_block || zero_block);
    }
  }
  // The HH-only blocks: k = (HH, HH, 0) / sqrt 2, T3 rank 1 with e_1 = (1, 1,
  // 0) / sqrt 2: H = 0, alpha = acos(1 / sqrt 2) = 45 deg.
  EXPECT_NEAR(cp.entropy[0], 0.0, 1e-5);
  EXPECT_NEAR(cp.alpha_deg[0], 45.0, 0.01);
  // Pauli RGB of the matrix image: NaN and zero blocks black.
  const RgbImage rgb = PauliRgb(c3);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(rgb.rgb[3 * 1 + k], 0);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(rgb.rgb[3 * 5 + k], 0);
  EXPECT_GT(rgb.rgb[3 * 0 + 2], 0);
}

TEST(PolarimetryTest, BadInputThrowsNamingTheArgument) {
  const auto where = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const Error& e) {
      return e.where();
    }
    return "no exception";
  };
  QuadPolImage good = MakeImage(4, 3, [](int, int) { return material::TrihedralMatrix(); });
  QuadPolImage bad = good;
  bad.hv.pop_back();
  EXPECT_THROW(MultilookCoherency(bad, 1, 1), InputError);
  EXPECT_EQ(where([&] { MultilookCoherency(bad, 1, 1); }), "hv");
  bad = good;
  bad.vv.push_back({});
  EXPECT_EQ(where([&] { MultilookCovariance(bad, 1, 1); }), "vv");
  EXPECT_EQ(where([&] { PauliRgb(bad); }), "vv");
  bad = good;
  bad.width = 0;
  EXPECT_THROW(bad.Check(), InputError);
  EXPECT_EQ(where([&] { bad.Check(); }), "width");
  EXPECT_THROW(MultilookCoherency(good, 0, 1), ConfigError);
  EXPECT_EQ(where([&] { MultilookCoherency(good, 0, 1); }), "looks_range");
  EXPECT_EQ(where([&] { MultilookCoherency(good, 1, -2); }), "looks_azimuth");
  EXPECT_EQ(where([&] { MultilookCoherency(good, 5, 1); }), "looks_range");
  EXPECT_EQ(where([&] { MultilookCoherency(good, 1, 4); }), "looks_azimuth");
  EXPECT_NO_THROW(MultilookCoherency(good, 4, 3));
  EXPECT_EQ(where([&] { PauliRgb(good, nullptr, 50.0, 40.0); }), "high_percentile");
  EXPECT_EQ(where([&] { PauliRgb(good, nullptr, -1.0, 40.0); }), "low_percentile");
  EXPECT_EQ(where([&] { PauliRgbWithStretch(good, {3.0, 3.0}); }), "stretch");
}

TEST(PolarimetryTest, PauliRgbColoursOfCanonicalTargets) {
  // Trihedral I: k = (sqrt 2, 0, 0): B only, power 2 = 3.0103 dB. Uniform
  // image: p2 = p98 = 3.0103 dB, low set 1 dB below, B = 255, R = G = 0.
  PauliStretch stretch;
  RgbImage rgb = PauliRgb(MakeImage(5, 4, [](int, int) { return material::TrihedralMatrix(); }), &stretch);
  ASSERT_EQ(rgb.width, 5);
  ASSERT_EQ(rgb.height, 4);
  ASSERT_EQ(rgb.rgb.size(), 60u);
  for (size_t i = 0; i < 20; ++i) {
    EXPECT_EQ(rgb.rgb[3 * i], 0);
    EXPECT_EQ(rgb.rgb[3 * i + 1], 0);
    EXPECT_EQ(rgb.rgb[3 * i + 2], 255);
  }
  EXPECT_NEAR(stretch.high_db, 10 * std::log10(2.0), 1e-5);
  EXPECT_NEAR(stretch.low_db, stretch.high_db - 1.0, 1e-9);
  // Dihedral diag(1, -1): k = (0, sqrt 2, 0): red.
  rgb = PauliRgb(MakeImage(5, 4, [](int, int) { return material::DihedralMatrix(0.0); }));
  EXPECT_EQ(std::vector<uint8_t>(rgb.rgb.begin(), rgb.rgb.begin() + 3), (std::vector<uint8_t>{255, 0, 0}));
  // Dihedral rolled 45 deg: S = [[0, 1], [1, 0]], k = (0, 0, sqrt 2): green.
  // Written exactly: DihedralMatrix(45 deg) carries cos 90 deg = 6e-17, whose
  // power (-321 dB) would be a positive value at grey 1 and widen the stretch.
  rgb = PauliRgb(MakeImage(5, 4, [](int, int) { return material::MakeScatteringMatrix(0.0, 1.0, 1.0, 0.0); }));
  EXPECT_EQ(std::vector<uint8_t>(rgb.rgb.begin(), rgb.rgb.begin() + 3), (std::vector<uint8_t>{0, 255, 0}));
  // One common scale: left half trihedral, right half a dihedral 10 dB
  // weaker. Pooled positive dB values: 10 at 3.0103, 10 at -6.9897; p0 and
  // p100 are the two: blue 255, red 1.
  const QuadPolImage mixed = MakeImage(4, 5, [](int, int c) {
    return c < 2 ? material::TrihedralMatrix()
                 : material::ScatteringMatrix(material::DihedralMatrix(0.0) * std::sqrt(0.1));
  });
  rgb = PauliRgb(mixed, &stretch, 0.0, 100.0);
  EXPECT_EQ(std::vector<uint8_t>(rgb.rgb.begin(), rgb.rgb.begin() + 3), (std::vector<uint8_t>{0, 0, 255}));
  EXPECT_EQ(std::vector<uint8_t>(rgb.rgb.begin() + 9, rgb.rgb.begin() + 12), (std::vector<uint8_t>{1, 0, 0}));
  EXPECT_NEAR(stretch.low_db, 10 * std::log10(0.2), 1e-5);
  EXPECT_NEAR(stretch.high_db, 10 * std::log10(2.0), 1e-5);
  // Fixed stretch -10 .. +5 dB: blue 1 + 254 (13.0103 / 15) = 221, red 1 +
  // 254 (3.0103 / 15) = 52. The multilooked image gives the same colours.
  const RgbImage fixed = PauliRgbWithStretch(mixed, {-10.0, 5.0});
  EXPECT_EQ(std::vector<uint8_t>(fixed.rgb.begin(), fixed.rgb.begin() + 3), (std::vector<uint8_t>{0, 0, 221}));
  EXPECT_EQ(std::vector<uint8_t>(fixed.rgb.begin() + 9, fixed.rgb.begin() + 12), (std::vector<uint8_t>{52, 0, 0}));
  const RgbImage multilooked = PauliRgbWithStretch(MultilookCovariance(mixed, 2, 1), {-10.0, 5.0});
  ASSERT_EQ(multilooked.width, 2);
  EXPECT_EQ(std::vector<uint8_t>(multilooked.rgb.begin(), multilooked.rgb.begin() + 6),
            (std::vector<uint8_t>{0, 0, 221, 52, 0, 0}));
  // A pixel with a non-finite sample is black.
  QuadPolImage gap = MakeImage(3, 1, [](int, int) { return material::TrihedralMatrix(); });
  gap.hv[1] = std::complex<float>(std::nanf(""), 0.0f);
  rgb = PauliRgb(gap);
  EXPECT_EQ(std::vector<uint8_t>(rgb.rgb.begin() + 3, rgb.rgb.begin() + 6), (std::vector<uint8_t>{0, 0, 0}));
  EXPECT_EQ(rgb.rgb[2], 255);
}

TEST(PolarimetryTest, BandNamesInStorageOrder) {
  EXPECT_EQ(PolarimetricBandNames(PolarimetricMatrix::kCovariance),
            (std::vector<std::string>{"C11", "C22", "C33", "C12_real", "C12_imag", "C13_real", "C13_imag",
                                      "C23_real", "C23_imag"}));
  EXPECT_EQ(PolarimetricBandNames(PolarimetricMatrix::kCoherency)[5], "T13_real");
  EXPECT_EQ(CloudePottierBandNames(), (std::vector<std::string>{"entropy", "anisotropy", "alpha_deg"}));
  // Band 5 really is Re C13: trihedral C13 = 1.
  const PolarimetricMatrixImage c3 =
      MultilookCovariance(MakeImage(1, 1, [](int, int) { return material::TrihedralMatrix(); }), 1, 1);
  EXPECT_EQ(c3.bands[5][0], 1.0f);
  EXPECT_EQ(c3.bands[6][0], 0.0f);
}

}  // namespace
}  // namespace gissar::image
