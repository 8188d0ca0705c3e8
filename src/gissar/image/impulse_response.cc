#include "gissar/image/impulse_response.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <opencv2/core.hpp>
#include <random>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

// Spectral weight at normalised frequency u in [-0.5, 0.5] (band edges).
double Weight(SpectralWindow window, double u) {
  switch (window) {
    case SpectralWindow::kHamming:
      return 0.54 + 0.46 * std::cos(2 * M_PI * u);
    case SpectralWindow::kTaylor: {
      // Taylor window, nbar = 4, -35 dB sidelobes (the usual SAR choice).
      constexpr int kNbar = 4;
      const double sll = 35.0;
      const double a = std::acosh(std::pow(10.0, sll / 20.0)) / M_PI;
      const double sigma2 = double(kNbar * kNbar) / (a * a + (kNbar - 0.5) * (kNbar - 0.5));
      double w = 1.0;
      for (int m = 1; m < kNbar; ++m) {
        double num = 1.0, den = 1.0;
        for (int n = 1; n < kNbar; ++n) {
          num *= 1.0 - double(m * m) / (sigma2 * (a * a + (n - 0.5) * (n - 0.5)));
          if (n != m) den *= 1.0 - double(m * m) / double(n * n);
        }
        const double fm = ((m + 1) % 2 == 0 ? 1.0 : -1.0) * num / (2.0 * den);
        w += 2.0 * fm * std::cos(2 * M_PI * m * u);
      }
      return w;
    }
    default:
      return 1.0;
  }
}

// Amplitude response at x (in units of 1/bandwidth) of the windowed band,
// by numerical integration over the band (symmetric: cosine transform).
double Amplitude(SpectralWindow window, double x) {
  constexpr int kSteps = 256;
  double sum = 0.0;
  for (int k = 0; k < kSteps; ++k) {
    const double u = -0.5 + (k + 0.5) / kSteps;
    sum += Weight(window, u) * std::cos(2 * M_PI * u * x);
  }
  return sum / kSteps;
}

}  // namespace

double UnitHalfPowerWidth(SpectralWindow window) {
  const double peak = Amplitude(window, 0.0);
  double lo = 0.0, hi = 2.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double a = Amplitude(window, mid) / peak;
    (a * a > 0.5 ? lo : hi) = mid;
  }
  return 2.0 * lo;
}

SpectralWindow ParseSpectralWindow(const std::string& text, const std::string& option) {
  return kSpectralWindows.Parse(text, option);
}

std::string ToString(SpectralWindow window) { return std::string(kSpectralWindows.Name(window)); }

std::vector<double> IntensityImpulseResponse(double resolution_px, SpectralWindow window,
                                             double half_width_res) {
  GISSAR_CHECK(resolution_px > 0.0);
  // Band scaled so that the half-power width equals the resolution.
  const double unit = UnitHalfPowerWidth(window);
  const double scale = unit / resolution_px;  // x_unit = x_px * scale
  const int half = std::max(2, static_cast<int>(std::ceil(half_width_res * resolution_px)));
  std::vector<double> kernel(2 * half + 1);
  double sum = 0.0;
  for (int i = -half; i <= half; ++i) {
    const double a = Amplitude(window, i * scale);
    kernel[i + half] = a * a;
    sum += a * a;
  }
  for (double& k : kernel) k /= sum;
  return kernel;
}

double HalfPowerWidth(const std::vector<double>& profile) {
  const auto peak_it = std::max_element(profile.begin(), profile.end());
  const int p = static_cast<int>(peak_it - profile.begin());
  const double half = *peak_it / 2.0;
  auto crossing = [&](int step) {
    int i = p;
    while (i + step >= 0 && i + step < static_cast<int>(profile.size()) && profile[i + step] > half) i += step;
    if (i + step < 0 || i + step >= static_cast<int>(profile.size())) return double(i);
    const double a = profile[i], b = profile[i + step];
    return i + step * (a - half) / (a - b);
  };
  return crossing(1) - crossing(-1);
}

namespace {

// Convolves the row-major plane with the separable kernel kx (along rows) x
// ky (along columns), centred, by FFT with zero padding; with
// `non_negative` values below zero (round-off) are clamped.
void ConvolveSeparable(std::vector<float>& plane, int width, int height, const std::vector<double>& kx,
                       const std::vector<double>& ky, bool non_negative) {
  const int hx = static_cast<int>(kx.size() / 2), hy = static_cast<int>(ky.size() / 2);
  const int pw = cv::getOptimalDFTSize(width + 2 * hx), ph = cv::getOptimalDFTSize(height + 2 * hy);
  cv::Mat image = cv::Mat::zeros(ph, pw, CV_32F);
  cv::Mat(height, width, CV_32F, plane.data()).copyTo(image(cv::Rect(0, 0, width, height)));
  // Kernel placed with its centre at the origin (wrapped), so the result is
  // aligned with the input.
  cv::Mat kernel = cv::Mat::zeros(ph, pw, CV_32F);
  for (int j = 0; j < static_cast<int>(ky.size()); ++j) {
    for (int i = 0; i < static_cast<int>(kx.size()); ++i) {
      const int y = (j - hy + ph) % ph, x = (i - hx + pw) % pw;
      kernel.at<float>(y, x) = static_cast<float>(kx[i] * ky[j]);
    }
  }
  cv::Mat image_f, kernel_f, product;
  cv::dft(image, image_f, cv::DFT_COMPLEX_OUTPUT);
  cv::dft(kernel, kernel_f, cv::DFT_COMPLEX_OUTPUT);
  cv::mulSpectrums(image_f, kernel_f, product, 0);
  cv::Mat result;
  cv::idft(product, result, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  for (int r = 0; r < height; ++r) {
    const float* src = result.ptr<float>(r);
    float* dst = plane.data() + size_t(r) * width;
    for (int c = 0; c < width; ++c) dst[c] = non_negative ? std::max(0.0f, src[c]) : src[c];
  }
}

}  // namespace

void ApplyImpulseResponse(std::vector<float>& intensity, int width, int height,
                          double range_resolution_px, double azimuth_resolution_px,
                          SpectralWindow window) {
  GISSAR_CHECK(intensity.size() == size_t(width) * height);
  if (range_resolution_px <= 0.0 && azimuth_resolution_px <= 0.0) return;
  const std::vector<double> kx = range_resolution_px > 0
                                     ? IntensityImpulseResponse(range_resolution_px, window)
                                     : std::vector<double>{1.0};
  const std::vector<double> ky = azimuth_resolution_px > 0
                                     ? IntensityImpulseResponse(azimuth_resolution_px, window)
                                     : std::vector<double>{1.0};
  ConvolveSeparable(intensity, width, height, kx, ky, /*non_negative=*/true);
}

std::vector<double> AmplitudeImpulseResponse(double resolution_px, SpectralWindow window, double half_width_res) {
  int first = 0;
  std::vector<double> k = ShiftedAmplitudeResponse(0.0, resolution_px, window, &first, half_width_res);
  return k;
}

std::vector<double> ShiftedAmplitudeResponse(double centre_px, double resolution_px, SpectralWindow window,
                                             int* first, double half_width_res) {
  if (!(resolution_px > 0.0)) {
    *first = static_cast<int>(std::floor(centre_px + 0.5));
    return {1.0};
  }
  const double scale = UnitHalfPowerWidth(window) / resolution_px;
  const int half = std::max(2, static_cast<int>(std::ceil(half_width_res * resolution_px)));
  const int c = static_cast<int>(std::floor(centre_px + 0.5));
  *first = c - half;
  std::vector<double> k(2 * half + 1);
  double sum2 = 0.0;
  for (int i = 0; i <= 2 * half; ++i) {
    k[i] = Amplitude(window, (c - half + i - centre_px) * scale);
    sum2 += k[i] * k[i];
  }
  for (double& v : k) v /= std::sqrt(sum2);
  return k;
}

void ApplyComplexImpulseResponse(std::vector<float>& real, std::vector<float>& imag, int width, int height,
                                 double range_resolution_px, double azimuth_resolution_px,
                                 SpectralWindow window) {
  GISSAR_CHECK(real.size() == size_t(width) * height && imag.size() == real.size());
  if (range_resolution_px <= 0.0 && azimuth_resolution_px <= 0.0) return;
  const std::vector<double> kx = range_resolution_px > 0 ? AmplitudeImpulseResponse(range_resolution_px, window)
                                                         : std::vector<double>{1.0};
  const std::vector<double> ky = azimuth_resolution_px > 0
                                     ? AmplitudeImpulseResponse(azimuth_resolution_px, window)
                                     : std::vector<double>{1.0};
  ConvolveSeparable(real, width, height, kx, ky, false);
  ConvolveSeparable(imag, width, height, kx, ky, false);
}

std::vector<float> CorrelatedSpeckle(const std::vector<float>& intensity, int width, int height,
                                     double range_resolution_px, double azimuth_resolution_px,
                                     SpectralWindow window, double looks, uint64_t seed) {
  GISSAR_CHECK(intensity.size() == size_t(width) * height);
  const int n_looks = std::max(1, static_cast<int>(std::lround(looks)));
  std::vector<float> out(intensity.size(), 0.0f);
  std::mt19937_64 rng(seed * 0x2545F4914F6CDD1DULL + 17);
  std::normal_distribution<double> gauss(0.0, std::sqrt(0.5));
  std::vector<float> re(intensity.size()), im(intensity.size());
  for (int look = 0; look < n_looks; ++look) {
    for (size_t k = 0; k < intensity.size(); ++k) {
      const double a = std::sqrt(std::max(0.0f, intensity[k]));
      re[k] = static_cast<float>(a * gauss(rng));
      im[k] = static_cast<float>(a * gauss(rng));
    }
    ApplyComplexImpulseResponse(re, im, width, height, range_resolution_px, azimuth_resolution_px, window);
    for (size_t k = 0; k < out.size(); ++k) out[k] += (re[k] * re[k] + im[k] * im[k]) / float(n_looks);
  }
  return out;
}

void AddComplexThermalNoise(std::vector<float>& real, std::vector<float>& imag, double nesz_db, uint64_t seed) {
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::normal_distribution<double> noise(0.0, std::sqrt(0.5 * std::pow(10.0, nesz_db / 10.0)));
  for (size_t k = 0; k < real.size(); ++k) {
    real[k] = static_cast<float>(real[k] + noise(rng));
    imag[k] = static_cast<float>(imag[k] + noise(rng));
  }
}

void ApplyMultiplicativeSpeckle(std::vector<float>& intensity, double looks, uint64_t seed) {
  GISSAR_CHECK(looks >= 1.0);
  std::mt19937_64 rng(seed);
  std::gamma_distribution<double> gamma(looks, 1.0 / looks);
  for (float& v : intensity) v = static_cast<float>(v * gamma(rng));
}

void AddThermalNoise(std::vector<float>& intensity, double nesz_db, uint64_t seed) {
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::exponential_distribution<double> noise(1.0 / std::pow(10.0, nesz_db / 10.0));
  for (float& v : intensity) v = static_cast<float>(v + noise(rng));
}

}  // namespace gissar::image
