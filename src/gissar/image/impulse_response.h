// The SAR impulse response and noise applied to simulated intensity images:
// a separable sinc^2 point-spread function (optionally with a Hamming or
// Taylor spectral window) at the configured range and azimuth resolution,
// applied by FFT (OpenCV DFT), multiplicative L-look gamma speckle, and a
// thermal-noise floor (NESZ).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace gissar::image {

enum class SpectralWindow { kNone, kHamming, kTaylor };

// "none", "hamming", "taylor"; throws ConfigError naming `option` otherwise.
SpectralWindow ParseSpectralWindow(const std::string& text, const std::string& option);
std::string ToString(SpectralWindow window);

// Samples of the 1-D intensity impulse response whose 3 dB (half-power)
// width is `resolution_px` pixels: |IFT(window over a rectangular band)|^2,
// its band scaled so the main lobe's half-power width is exactly the
// resolution; centred at index size/2, covering +-`half_width_res` times the
// resolution, normalised to unit sum (the filter preserves total power).
// resolution_px must be > 0.
std::vector<double> IntensityImpulseResponse(double resolution_px, SpectralWindow window,
                                             double half_width_res = 12.0);

// Half-power width (pixels) of a sampled 1-D profile around its maximum,
// by linear interpolation of the -3 dB crossings.
double HalfPowerWidth(const std::vector<double>& profile);

// Convolves a row-major intensity image (width x height) with the separable
// impulse response of the given resolutions (pixels; 0 = no filtering along
// that axis), by FFT with zero padding (no wrap-around).
void ApplyImpulseResponse(std::vector<float>& intensity, int width, int height,
                          double range_resolution_px, double azimuth_resolution_px,
                          SpectralWindow window);

// Multiplies every pixel by an independent Gamma(L, 1/L) variate (mean 1,
// variance 1/L): fully developed L-look speckle. Deterministic for a seed
// (pixels drawn in row-major order). looks must be >= 1.
void ApplyMultiplicativeSpeckle(std::vector<float>& intensity, double looks, uint64_t seed);

// Adds thermal noise of mean power 10^(nesz_db / 10) (same units as the
// image: flat unit-Lambertian ground at depression d reads sin d) as an
// exponentially distributed intensity per pixel (circular complex Gaussian
// noise). Deterministic for a seed.
void AddThermalNoise(std::vector<float>& intensity, double nesz_db, uint64_t seed);

}  // namespace gissar::image
