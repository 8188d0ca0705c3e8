#include "gissar/image/polarimetry.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "gissar/image/quicklook.h"
#include "gissar/material/scattering.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

using cd = std::complex<double>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kRadToDeg = 180.0 / M_PI;

// Band indices of the storage order.
enum Band { k11 = 0, k22, k33, k12Re, k12Im, k13Re, k13Im, k23Re, k23Im };

inline bool Finite(std::complex<float> z) { return std::isfinite(z.real()) && std::isfinite(z.imag()); }

void CheckLooks(const QuadPolImage& image, int looks_range, int looks_azimuth) {
  if (looks_range < 1) {
    throw ConfigError("look count must be >= 1, got " + std::to_string(looks_range), "looks_range");
  }
  if (looks_azimuth < 1) {
    throw ConfigError("look count must be >= 1, got " + std::to_string(looks_azimuth), "looks_azimuth");
  }
  if (looks_range > image.width) {
    throw ConfigError("look count " + std::to_string(looks_range) + " exceeds the image width " +
                          std::to_string(image.width),
                      "looks_range");
  }
  if (looks_azimuth > image.height) {
    throw ConfigError("look count " + std::to_string(looks_azimuth) + " exceeds the image height " +
                          std::to_string(image.height),
                      "looks_azimuth");
  }
}

void CheckPercentiles(double low_percentile, double high_percentile) {
  if (!(low_percentile >= 0.0 && low_percentile < 100.0)) {
    throw ConfigError("percentile must be in [0, 100) and below the high percentile", "low_percentile");
  }
  if (!(high_percentile > low_percentile && high_percentile <= 100.0)) {
    throw ConfigError("percentile must be in (low_percentile, 100]", "high_percentile");
  }
}

PolarimetricMatrixImage EmptyLike(PolarimetricMatrix kind, int width, int height, int lr, int la) {
  PolarimetricMatrixImage out;
  out.kind = kind;
  out.width = width;
  out.height = height;
  out.looks_range = lr;
  out.looks_azimuth = la;
  for (auto& band : out.bands) band.assign(size_t(width) * height, 0.0f);
  return out;
}

void SetPixel(PolarimetricMatrixImage& image, size_t i, const Eigen::Matrix3cd& m) {
  image.bands[k11][i] = static_cast<float>(m(0, 0).real());
  image.bands[k22][i] = static_cast<float>(m(1, 1).real());
  image.bands[k33][i] = static_cast<float>(m(2, 2).real());
  image.bands[k12Re][i] = static_cast<float>(m(0, 1).real());
  image.bands[k12Im][i] = static_cast<float>(m(0, 1).imag());
  image.bands[k13Re][i] = static_cast<float>(m(0, 2).real());
  image.bands[k13Im][i] = static_cast<float>(m(0, 2).imag());
  image.bands[k23Re][i] = static_cast<float>(m(1, 2).real());
  image.bands[k23Im][i] = static_cast<float>(m(1, 2).imag());
}

Eigen::Matrix3cd PixelAt(const PolarimetricMatrixImage& image, size_t i) {
  const auto& b = image.bands;
  const cd m12(b[k12Re][i], b[k12Im][i]), m13(b[k13Re][i], b[k13Im][i]), m23(b[k23Re][i], b[k23Im][i]);
  Eigen::Matrix3cd m;
  m << cd(b[k11][i], 0.0), m12, m13,  //
      std::conj(m12), cd(b[k22][i], 0.0), m23,  //
      std::conj(m13), std::conj(m23), cd(b[k33][i], 0.0);
  return m;
}

// The three Pauli powers |k_1|^2 (B), |k_2|^2 (R), |k_3|^2 (G) of every
// pixel, pooled as [R plane, G plane, B plane]; NaN for all three where a
// sample is not finite.
std::vector<float> PauliPowers(const QuadPolImage& image) {
  image.Check();
  const size_t n = size_t(image.width) * image.height;
  std::vector<float> pooled(3 * n);
  for (size_t i = 0; i < n; ++i) {
    if (!Finite(image.hh[i]) || !Finite(image.hv[i]) || !Finite(image.vh[i]) || !Finite(image.vv[i])) {
      pooled[i] = pooled[n + i] = pooled[2 * n + i] = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    const Eigen::Vector3cd k = material::PauliVector(
        material::MakeScatteringMatrix(image.hh[i], image.hv[i], image.vh[i], image.vv[i]));
    pooled[i] = static_cast<float>(std::norm(k(1)));
    pooled[n + i] = static_cast<float>(std::norm(k(2)));
    pooled[2 * n + i] = static_cast<float>(std::norm(k(0)));
  }
  return pooled;
}

std::vector<float> PauliPowers(const PolarimetricMatrixImage& image) {
  const PolarimetricMatrixImage t3 = ConvertPolarimetricMatrix(image, PolarimetricMatrix::kCoherency);
  const size_t n = size_t(t3.width) * t3.height;
  std::vector<float> pooled(3 * n);
  for (size_t i = 0; i < n; ++i) {
    bool finite = true;
    for (const auto& band : t3.bands) finite = finite && std::isfinite(band[i]);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    pooled[i] = finite ? t3.bands[k22][i] : nan;
    pooled[n + i] = finite ? t3.bands[k33][i] : nan;
    pooled[2 * n + i] = finite ? t3.bands[k11][i] : nan;
  }
  return pooled;
}

RgbImage Interleave(const std::vector<uint8_t>& grey, int width, int height) {
  const size_t n = size_t(width) * height;
  GISSAR_CHECK(grey.size() == 3 * n);
  RgbImage out;
  out.width = width;
  out.height = height;
  out.rgb.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    out.rgb[3 * i] = grey[i];
    out.rgb[3 * i + 1] = grey[n + i];
    out.rgb[3 * i + 2] = grey[2 * n + i];
  }
  return out;
}

RgbImage StretchedRgb(const std::vector<float>& pooled, int width, int height, PauliStretch* stretch,
                      double low_percentile, double high_percentile) {
  DbStretch s;
  std::vector<uint8_t> grey = DbQuicklook(pooled, low_percentile, high_percentile, &s);
  const bool any_positive = std::any_of(grey.begin(), grey.end(), [](uint8_t g) { return g != 0; });
  if (any_positive && s.high_db - s.low_db < 1e-3) {
    // Coinciding percentiles (a uniform image): the common value maps to 255.
    s.low_db = s.high_db - 1.0;
    grey = DbQuicklookWithStretch(pooled, s);
  }
  if (stretch != nullptr) *stretch = {s.low_db, s.high_db};
  return Interleave(grey, width, height);
}

void CheckStretch(const PauliStretch& s) {
  if (!(std::isfinite(s.low_db) && std::isfinite(s.high_db) && s.high_db > s.low_db)) {
    throw ConfigError("stretch needs finite low_db < high_db", "stretch");
  }
}

}  // namespace

void QuadPolImage::Check() const {
  if (width < 1) throw InputError("image width must be >= 1, got " + std::to_string(width), "width");
  if (height < 1) throw InputError("image height must be >= 1, got " + std::to_string(height), "height");
  const size_t n = size_t(width) * size_t(height);
  const std::pair<const std::vector<std::complex<float>>*, const char*> channels[] = {
      {&hh, "hh"}, {&hv, "hv"}, {&vh, "vh"}, {&vv, "vv"}};
  for (const auto& [channel, name] : channels) {
    if (channel->size() != n) {
      throw InputError("channel has " + std::to_string(channel->size()) + " samples, expected " +
                           std::to_string(width) + " x " + std::to_string(height) + " = " + std::to_string(n),
                       name);
    }
  }
}

Eigen::Matrix3cd PolarimetricMatrixImage::At(int row, int col) const {
  GISSAR_CHECK_MSG(row >= 0 && row < height && col >= 0 && col < width,
                   "pixel (" << row << ", " << col << ") outside " << width << " x " << height);
  for (const auto& band : bands) GISSAR_CHECK(band.size() == size_t(width) * height);
  return PixelAt(*this, size_t(row) * width + col);
}

std::vector<std::string> PolarimetricBandNames(PolarimetricMatrix kind) {
  const std::string p = kind == PolarimetricMatrix::kCovariance ? "C" : "T";
  return {p + "11",      p + "22",      p + "33",      p + "12_real", p + "12_imag",
          p + "13_real", p + "13_imag", p + "23_real", p + "23_imag"};
}

Eigen::Matrix3d LexicographicToPauli() {
  const double r = 1.0 / std::sqrt(2.0);
  Eigen::Matrix3d u;
  u << r, 0.0, r,  //
      r, 0.0, -r,  //
      0.0, 1.0, 0.0;
  return u;
}

PolarimetricMatrixImage MultilookPolarimetricMatrix(const QuadPolImage& image, PolarimetricMatrix kind,
                                                    int looks_range, int looks_azimuth) {
  image.Check();
  CheckLooks(image, looks_range, looks_azimuth);
  const int lr = looks_range, la = looks_azimuth;
  const int out_w = image.width / lr, out_h = image.height / la;
  PolarimetricMatrixImage out = EmptyLike(kind, out_w, out_h, lr, la);
  const double inv_looks = 1.0 / (double(lr) * la);

  struct Accumulator {
    double d[3];
    cd o[3];  // 12, 13, 23
    bool bad;
  };
  std::vector<Accumulator> acc(out_w);
  for (int r = 0; r < out_h; ++r) {
    for (Accumulator& a : acc) a = Accumulator{{0.0, 0.0, 0.0}, {cd(), cd(), cd()}, false};
    for (int i = 0; i < la; ++i) {
      const size_t row0 = size_t(r * la + i) * image.width;
      for (int c = 0; c < out_w * lr; ++c) {
        const size_t s = row0 + c;
        Accumulator& a = acc[c / lr];
        if (a.bad) continue;
        if (!Finite(image.hh[s]) || !Finite(image.hv[s]) || !Finite(image.vh[s]) || !Finite(image.vv[s])) {
          a.bad = true;
          continue;
        }
        const material::ScatteringMatrix sm =
            material::MakeScatteringMatrix(image.hh[s], image.hv[s], image.vh[s], image.vv[s]);
        const Eigen::Vector3cd v = kind == PolarimetricMatrix::kCovariance ? material::LexicographicVector(sm)
                                                                            : material::PauliVector(sm);
        a.d[0] += std::norm(v(0));
        a.d[1] += std::norm(v(1));
        a.d[2] += std::norm(v(2));
        a.o[0] += v(0) * std::conj(v(1));
        a.o[1] += v(0) * std::conj(v(2));
        a.o[2] += v(1) * std::conj(v(2));
      }
    }
    for (int c = 0; c < out_w; ++c) {
      const size_t o = size_t(r) * out_w + c;
      const Accumulator& a = acc[c];
      if (a.bad) {
        for (auto& band : out.bands) band[o] = std::numeric_limits<float>::quiet_NaN();
        continue;
      }
      out.bands[k11][o] = static_cast<float>(a.d[0] * inv_looks);
      out.bands[k22][o] = static_cast<float>(a.d[1] * inv_looks);
      out.bands[k33][o] = static_cast<float>(a.d[2] * inv_looks);
      out.bands[k12Re][o] = static_cast<float>(a.o[0].real() * inv_looks);
      out.bands[k12Im][o] = static_cast<float>(a.o[0].imag() * inv_looks);
      out.bands[k13Re][o] = static_cast<float>(a.o[1].real() * inv_looks);
      out.bands[k13Im][o] = static_cast<float>(a.o[1].imag() * inv_looks);
      out.bands[k23Re][o] = static_cast<float>(a.o[2].real() * inv_looks);
      out.bands[k23Im][o] = static_cast<float>(a.o[2].imag() * inv_looks);
    }
  }
  return out;
}

PolarimetricMatrixImage MultilookCovariance(const QuadPolImage& image, int looks_range, int looks_azimuth) {
  return MultilookPolarimetricMatrix(image, PolarimetricMatrix::kCovariance, looks_range, looks_azimuth);
}

PolarimetricMatrixImage MultilookCoherency(const QuadPolImage& image, int looks_range, int looks_azimuth) {
  return MultilookPolarimetricMatrix(image, PolarimetricMatrix::kCoherency, looks_range, looks_azimuth);
}

PolarimetricMatrixImage ConvertPolarimetricMatrix(const PolarimetricMatrixImage& image, PolarimetricMatrix kind) {
  if (image.kind == kind) return image;
  for (const auto& band : image.bands) GISSAR_CHECK(band.size() == size_t(image.width) * image.height);
  PolarimetricMatrixImage out = EmptyLike(kind, image.width, image.height, image.looks_range, image.looks_azimuth);
  const Eigen::Matrix3d u = LexicographicToPauli();
  // C3 -> T3: U C3 U^T; T3 -> C3: U^T T3 U.
  const Eigen::Matrix3cd a = (kind == PolarimetricMatrix::kCoherency ? u : Eigen::Matrix3d(u.transpose())).cast<cd>();
  const size_t n = size_t(image.width) * image.height;
  for (size_t i = 0; i < n; ++i) SetPixel(out, i, a * PixelAt(image, i) * a.transpose());
  return out;
}

CloudePottierParameters CloudePottier(const Eigen::Matrix3cd& t3) {
  CloudePottierParameters out;
  if (!t3.allFinite()) {
    out.entropy = out.anisotropy = out.alpha_deg = kNaN;
    out.eigenvalues.fill(kNaN);
    out.alpha_i_deg.fill(kNaN);
    return out;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3cd> solver(t3);
  GISSAR_CHECK(solver.info() == Eigen::Success);
  // Eigen sorts ascending: index 2 - i is the i-th largest.
  double span = 0.0;
  for (int i = 0; i < 3; ++i) {
    out.eigenvalues[i] = std::max(0.0, solver.eigenvalues()(2 - i));
    span += out.eigenvalues[i];
    out.alpha_i_deg[i] = std::acos(std::min(1.0, std::abs(solver.eigenvectors()(0, 2 - i)))) * kRadToDeg;
  }
  if (!(span > 0.0)) {
    out.entropy = out.anisotropy = out.alpha_deg = kNaN;
    out.alpha_i_deg.fill(kNaN);
    return out;
  }
  double entropy = 0.0, alpha = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double p = out.eigenvalues[i] / span;
    if (p > 0.0) entropy -= p * std::log(p);
    alpha += p * out.alpha_i_deg[i];
  }
  out.entropy = std::clamp(entropy / std::log(3.0), 0.0, 1.0);
  out.alpha_deg = std::clamp(alpha, 0.0, 90.0);
  const double minor = out.eigenvalues[1] + out.eigenvalues[2];
  out.anisotropy =
      minor <= kRankOneTolerance * span ? 0.0 : std::clamp((out.eigenvalues[1] - out.eigenvalues[2]) / minor, 0.0, 1.0);
  return out;
}

CloudePottierImage CloudePottierPlanes(const PolarimetricMatrixImage& image) {
  const PolarimetricMatrixImage t3 = ConvertPolarimetricMatrix(image, PolarimetricMatrix::kCoherency);
  for (const auto& band : t3.bands) GISSAR_CHECK(band.size() == size_t(t3.width) * t3.height);
  CloudePottierImage out;
  out.width = t3.width;
  out.height = t3.height;
  const size_t n = size_t(t3.width) * t3.height;
  out.entropy.resize(n);
  out.anisotropy.resize(n);
  out.alpha_deg.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const CloudePottierParameters p = CloudePottier(PixelAt(t3, i));
    out.entropy[i] = static_cast<float>(p.entropy);
    out.anisotropy[i] = static_cast<float>(p.anisotropy);
    out.alpha_deg[i] = static_cast<float>(p.alpha_deg);
  }
  return out;
}

std::vector<std::string> CloudePottierBandNames() { return {"entropy", "anisotropy", "alpha_deg"}; }

RgbImage PauliRgb(const QuadPolImage& image, PauliStretch* stretch, double low_percentile,
                  double high_percentile) {
  CheckPercentiles(low_percentile, high_percentile);
  return StretchedRgb(PauliPowers(image), image.width, image.height, stretch, low_percentile, high_percentile);
}

RgbImage PauliRgb(const PolarimetricMatrixImage& image, PauliStretch* stretch, double low_percentile,
                  double high_percentile) {
  CheckPercentiles(low_percentile, high_percentile);
  return StretchedRgb(PauliPowers(image), image.width, image.height, stretch, low_percentile, high_percentile);
}

RgbImage PauliRgbWithStretch(const QuadPolImage& image, const PauliStretch& stretch) {
  CheckStretch(stretch);
  return Interleave(DbQuicklookWithStretch(PauliPowers(image), {stretch.low_db, stretch.high_db}), image.width,
                    image.height);
}

RgbImage PauliRgbWithStretch(const PolarimetricMatrixImage& image, const PauliStretch& stretch) {
  CheckStretch(stretch);
  return Interleave(DbQuicklookWithStretch(PauliPowers(image), {stretch.low_db, stretch.high_db}), image.width,
                    image.height);
}

}  // namespace gissar::image
