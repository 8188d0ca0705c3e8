#include "gissar/image/radiometry.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::image {

Radiometry ParseRadiometry(const std::string& text, const std::string& option) {
  return kRadiometries.Parse(text, option);
}

std::string ToString(Radiometry radiometry) { return std::string(kRadiometries.Name(radiometry)); }

std::string RadiometryUnit(bool db) { return db ? "dB" : "m2/m2"; }

double FactorFromBeta0(Radiometry target, double incidence_deg) {
  const double t = incidence_deg * M_PI / 180.0;
  switch (target) {
    case Radiometry::kBeta0: return 1.0;
    case Radiometry::kGamma0: return std::tan(t);
    default: return std::sin(t);
  }
}

void ScaleColumns(std::vector<float>& image, int width, int height, const std::vector<double>& factors) {
  GISSAR_CHECK(factors.size() == size_t(width));
  GISSAR_CHECK(image.size() == size_t(width) * height);
  // Rows in parallel (each pixel's product does not depend on the order).
  tbb::parallel_for(tbb::blocked_range<int>(0, height, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r != rows.end(); ++r) {
      float* line = image.data() + size_t(r) * width;
      for (int c = 0; c < width; ++c) line[c] = static_cast<float>(line[c] * factors[c]);
    }
  });
}

void ToDecibels(std::vector<float>& image) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, image.size(), size_t(1) << 16),
                    [&](const tbb::blocked_range<size_t>& range) {
                      for (size_t i = range.begin(); i != range.end(); ++i) {
                        const float v = image[i];
                        image[i] = v > 0.0f ? static_cast<float>(10.0 * std::log10(double(v)))
                                            : std::numeric_limits<float>::quiet_NaN();
                      }
                    });
}

namespace {

// Calls visit(pixel index, range amplitude, azimuth amplitude) for every
// pixel of the width x height image under the amplitude response centred at
// (col, row).
template <typename Visit>
void ForEachResponsePixel(int width, int height, double col, double row, const SensorEffects& e, Visit&& visit) {
  int c0 = 0, r0 = 0;
  const std::vector<double> hx = ShiftedAmplitudeResponse(col, e.range_resolution_px, e.window, &c0);
  const std::vector<double> hy = ShiftedAmplitudeResponse(row, e.azimuth_resolution_px, e.window, &r0);
  for (size_t j = 0; j < hy.size(); ++j) {
    const int r = r0 + int(j);
    if (r < 0 || r >= height) continue;
    for (size_t i = 0; i < hx.size(); ++i) {
      const int c = c0 + int(i);
      if (c < 0 || c >= width) continue;
      visit(size_t(r) * width + c, hx[i], hy[j]);
    }
  }
}

// Adds the intensity response centred at (col, row) integrating to `total`.
void AddPointIntensity(std::vector<float>& plane, int width, int height, double col, double row, double total,
                       const SensorEffects& e) {
  ForEachResponsePixel(width, height, col, row, e, [&](size_t pixel, double hx, double hy) {
    plane[pixel] += static_cast<float>(total * hx * hx * hy * hy);
  });
}

// Adds the amplitude response of a phasor A exp(i phase) at (col, row).
void AddPointPhasor(std::vector<float>& re, std::vector<float>& im, int width, int height, double col, double row,
                    double amplitude, double phase, const SensorEffects& e) {
  const double a_re = amplitude * std::cos(phase), a_im = amplitude * std::sin(phase);
  ForEachResponsePixel(width, height, col, row, e, [&](size_t pixel, double hx, double hy) {
    const double w = hx * hy;
    re[pixel] += static_cast<float>(a_re * w);
    im[pixel] += static_cast<float>(a_im * w);
  });
}

// A canonical reflector returns into its bounce layer whatever the bounces
// traced: a layer the renderer left empty (no return of that order) becomes
// a plane of zeros for the reflectors that land in it.
void MaterializePointLayers(render::SarImage& image) {
  const size_t n = image.intensity.size();
  const bool coherent = !image.real.empty();
  for (const render::PointReturn& p : image.points) {
    if (p.layer < 0 || p.layer >= render::kBounceLayers) continue;
    if (image.bounce_layers[p.layer].empty()) image.bounce_layers[p.layer].assign(n, 0.0f);
    if (coherent && image.bounce_real[p.layer].empty()) {
      image.bounce_real[p.layer].assign(n, 0.0f);
      image.bounce_imag[p.layer].assign(n, 0.0f);
    }
  }
}

}  // namespace

void AddPointIntensities(render::SarImage& image, const SensorEffects& effects) {
  const int w = image.width, h = image.height;
  MaterializePointLayers(image);
  for (const render::PointReturn& p : image.points) {
    AddPointIntensity(image.intensity, w, h, p.col, p.row, p.beta0_sum, effects);
    auto& layer = image.bounce_layers[p.layer];
    if (layer.size() == image.intensity.size()) AddPointIntensity(layer, w, h, p.col, p.row, p.beta0_sum, effects);
  }
}

void ApplySensorEffects(render::SarImage& image, const SensorEffects& effects,
                        const std::vector<double>& incidence_deg) {
  GISSAR_CHECK(incidence_deg.size() == size_t(image.width));
  const bool coherent = !image.real.empty();
  GISSAR_CHECK(!coherent || (image.real.size() == image.intensity.size() && image.imag.size() == image.real.size()));
  GISSAR_CHECK(!coherent || effects.speckle_looks == 0.0);
  const int w = image.width, h = image.height;
  MaterializePointLayers(image);
  std::vector<std::vector<float>*> layers;
  for (auto& layer : image.bounce_layers) {
    if (layer.size() == image.intensity.size()) layers.push_back(&layer);
  }
  std::vector<std::vector<float>*> bands = layers;  // detected bands the PSF/speckle treat as intensity
  if (!coherent) bands.insert(bands.begin(), &image.intensity);
  const bool psf = effects.range_resolution_px > 0.0 || effects.azimuth_resolution_px > 0.0;
  const bool correlated_speckle = psf && effects.speckle_looks >= 1.0 && !coherent;
  const std::vector<float> before_psf = correlated_speckle ? image.intensity : std::vector<float>();
  if (psf) {
    for (auto* band : bands) {
      ApplyImpulseResponse(*band, w, h, effects.range_resolution_px, effects.azimuth_resolution_px, effects.window);
    }
    if (coherent) {
      ApplyComplexImpulseResponse(image.real, image.imag, w, h, effects.range_resolution_px,
                                  effects.azimuth_resolution_px, effects.window);
      for (size_t b = 0; b < image.bounce_real.size(); ++b) {
        if (image.bounce_real[b].size() != image.real.size()) continue;
        ApplyComplexImpulseResponse(image.bounce_real[b], image.bounce_imag[b], w, h, effects.range_resolution_px,
                                    effects.azimuth_resolution_px, effects.window);
      }
    }
  }
  if (correlated_speckle) {
    // Speckle of the total, correlated over the resolution cell; every band
    // takes the same per-pixel factor, so the bands still add up.
    const std::vector<float> speckled =
        CorrelatedSpeckle(before_psf, w, h, effects.range_resolution_px, effects.azimuth_resolution_px,
                          effects.window, effects.speckle_looks, effects.seed);
    for (size_t k = 0; k < speckled.size(); ++k) {
      const float total = image.intensity[k];
      const float factor = total > 1e-30f ? speckled[k] / total : 0.0f;
      for (auto* band : bands) (*band)[k] *= factor;
    }
  } else if (effects.speckle_looks >= 1.0) {
    for (auto* band : bands) ApplyMultiplicativeSpeckle(*band, effects.speckle_looks, effects.seed);
  }
  const double wavenumber2 = 4.0 * M_PI / effects.wavelength_m;
  for (const render::PointReturn& p : image.points) {
    if (p.layer >= 0 && p.layer < static_cast<int>(image.bounce_layers.size()) &&
        image.bounce_layers[p.layer].size() == image.intensity.size()) {
      AddPointIntensity(image.bounce_layers[p.layer], w, h, p.col, p.row, p.beta0_sum, effects);
    }
    if (coherent) {
      // The path phase exp(-j 4 pi R / lambda) (docs/conventions.md) plus
      // the channel's matrix phase (polarimetric passes).
      const double phase = -wavenumber2 * p.range_m + p.phase_offset_rad;
      AddPointPhasor(image.real, image.imag, w, h, p.col, p.row, std::sqrt(p.beta0_sum), phase, effects);
      if (p.layer >= 0 && p.layer < static_cast<int>(image.bounce_real.size()) &&
          image.bounce_real[p.layer].size() == image.real.size()) {
        AddPointPhasor(image.bounce_real[p.layer], image.bounce_imag[p.layer], w, h, p.col, p.row,
                       std::sqrt(p.beta0_sum), phase, effects);
      }
    } else {
      AddPointIntensity(image.intensity, w, h, p.col, p.row, p.beta0_sum, effects);
    }
  }
  std::vector<double> to_sigma0(w), to_target(w), sqrt_sigma0(w), sqrt_target(w);
  for (int c = 0; c < w; ++c) {
    to_sigma0[c] = FactorFromBeta0(Radiometry::kSigma0, incidence_deg[c]);
    to_target[c] = to_sigma0[c] > 0.0 ? FactorFromBeta0(effects.radiometry, incidence_deg[c]) / to_sigma0[c] : 0.0;
    sqrt_sigma0[c] = std::sqrt(to_sigma0[c]);
    sqrt_target[c] = std::sqrt(to_target[c]);
  }
  for (auto* band : layers) ScaleColumns(*band, w, h, to_sigma0);
  auto complex_bounces = [&](auto&& f) {
    for (size_t b = 0; b < image.bounce_real.size(); ++b) {
      if (image.bounce_real[b].size() == image.real.size()) f(image.bounce_real[b], image.bounce_imag[b], b);
    }
  };
  if (coherent) {
    ScaleColumns(image.real, w, h, sqrt_sigma0);
    ScaleColumns(image.imag, w, h, sqrt_sigma0);
    complex_bounces([&](std::vector<float>& re, std::vector<float>& im, size_t) {
      ScaleColumns(re, w, h, sqrt_sigma0);
      ScaleColumns(im, w, h, sqrt_sigma0);
    });
    if (!std::isnan(effects.nesz_db)) AddComplexThermalNoise(image.real, image.imag, effects.nesz_db, effects.seed);
  } else {
    ScaleColumns(image.intensity, w, h, to_sigma0);
    if (!std::isnan(effects.nesz_db)) AddThermalNoise(image.intensity, effects.nesz_db, effects.seed);
  }
  if (effects.radiometry != Radiometry::kSigma0) {
    for (auto* band : layers) ScaleColumns(*band, w, h, to_target);
    if (coherent) {
      ScaleColumns(image.real, w, h, sqrt_target);
      ScaleColumns(image.imag, w, h, sqrt_target);
      complex_bounces([&](std::vector<float>& re, std::vector<float>& im, size_t) {
        ScaleColumns(re, w, h, sqrt_target);
        ScaleColumns(im, w, h, sqrt_target);
      });
    } else {
      ScaleColumns(image.intensity, w, h, to_target);
    }
  }
  if (coherent) {
    for (size_t k = 0; k < image.intensity.size(); ++k) {
      image.intensity[k] = image.real[k] * image.real[k] + image.imag[k] * image.imag[k];
    }
    // The bounce bands: the detected power of their complex images.
    complex_bounces([&](std::vector<float>& re, std::vector<float>& im, size_t b) {
      if (image.bounce_layers[b].size() != re.size()) return;
      for (size_t k = 0; k < re.size(); ++k) image.bounce_layers[b][k] = re[k] * re[k] + im[k] * im[k];
    });
  }
  if (effects.db) {
    ToDecibels(image.intensity);
    for (auto* band : layers) ToDecibels(*band);
  }
}

void ConvertPixelRadiometry(render::SarImage& image, const std::vector<float>& incidence_deg, Radiometry radiometry,
                            double nesz_db, uint64_t seed, bool db) {
  GISSAR_CHECK(incidence_deg.size() == image.intensity.size());
  GISSAR_CHECK(image.real.empty());
  std::vector<std::vector<float>*> bands = {&image.intensity};
  for (auto& layer : image.bounce_layers) {
    if (layer.size() == image.intensity.size()) bands.push_back(&layer);
  }
  auto scale = [&](auto factor_of) {
    for (size_t k = 0; k < incidence_deg.size(); ++k) {
      if (std::isnan(incidence_deg[k])) continue;
      const float factor = static_cast<float>(factor_of(incidence_deg[k]));
      for (auto* band : bands) (*band)[k] *= factor;
    }
  };
  scale([](double incidence) { return FactorFromBeta0(Radiometry::kSigma0, incidence); });
  if (!std::isnan(nesz_db)) AddThermalNoise(image.intensity, nesz_db, seed);
  if (radiometry != Radiometry::kSigma0) {
    scale([&](double incidence) {
      const double to_sigma0 = FactorFromBeta0(Radiometry::kSigma0, incidence);
      return to_sigma0 > 0.0 ? FactorFromBeta0(radiometry, incidence) / to_sigma0 : 0.0;
    });
  }
  if (db) {
    for (auto* band : bands) ToDecibels(*band);
  }
}

}  // namespace gissar::image
