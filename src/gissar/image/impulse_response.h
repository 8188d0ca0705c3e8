// The SAR impulse response and noise applied to simulated intensity images:
// a separable sinc^2 point-spread function (optionally with a Hamming or
// Taylor spectral window) at the configured range and azimuth resolution,
// applied by FFT (OpenCV DFT), multiplicative L-look gamma speckle, and a
// thermal-noise floor (NESZ).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gissar/util/enum_table.h"

namespace gissar::image {

enum class SpectralWindow { kNone, kHamming, kTaylor };
inline constexpr auto kSpectralWindows = util::MakeEnumTable<SpectralWindow>(
    "window", {{SpectralWindow::kNone, "none"}, {SpectralWindow::kHamming, "hamming"}, {SpectralWindow::kTaylor, "taylor"}});

// kSpectralWindows.Parse: "none", "hamming", "taylor"; throws ConfigError
// naming `option` and the windows otherwise.
SpectralWindow ParseSpectralWindow(const std::string& text, const std::string& option);
std::string ToString(SpectralWindow window);

// The 3 dB (half-power) width of |IFT(window over a band B)|^2 in units of
// 1 / B: 0.886 for "none" (a sinc), wider for the tapered windows. A band
// of B Hz (range: metres c / (2 B)) has the resolution
// UnitHalfPowerWidth(window) / B.
double UnitHalfPowerWidth(SpectralWindow window);

// Samples of the 1-D intensity impulse response whose 3 dB (half-power)
// width is `resolution_px` pixels: |IFT(window over a rectangular band)|^2,
// its band scaled so the main lobe's half-power width is exactly the
// resolution; centred at index size/2, covering +-`half_width_res` times the
// resolution, normalised to unit sum (the filter preserves total power).
// resolution_px must be > 0.
std::vector<double> IntensityImpulseResponse(double resolution_px, SpectralWindow window,
                                             double half_width_res = 12.0);

// The amplitude (complex-domain) response of the same band and window: real
// and symmetric, IFT(window over the band) with |.|^2 the intensity
// response above; normalised so that the sum of its squares is 1 (the
// convolution keeps the mean intensity of uncorrelated scatterers).
std::vector<double> AmplitudeImpulseResponse(double resolution_px, SpectralWindow window,
                                             double half_width_res = 12.0);

// Samples at integer pixels k of the amplitude response centred at the
// fractional pixel `centre_px`, over +-half_width_res resolutions (0 =
// none: all in the nearest pixel), normalised to unit sum of squares: a
// point target of amplitude A then integrates to |A|^2 exactly. The first
// sample is at pixel *first.
std::vector<double> ShiftedAmplitudeResponse(double centre_px, double resolution_px, SpectralWindow window,
                                             int* first, double half_width_res = 12.0);

// Convolves a complex image (row-major real and imaginary planes, width x
// height) with the separable amplitude response of the given resolutions
// (pixels; 0 = none along that axis), by FFT with zero padding.
void ApplyComplexImpulseResponse(std::vector<float>& real, std::vector<float>& imag, int width, int height,
                                 double range_resolution_px, double azimuth_resolution_px,
                                 SpectralWindow window);

// Speckle correlated over the resolution cell: round(looks) (>= 1)
// independent circular complex Gaussian fields of power `intensity` per
// pixel (the image before the impulse response), each convolved with the
// amplitude response of the resolutions (pixels) and detected, averaged.
// The result's mean is the intensity response applied to `intensity`; its
// single-look statistics are exponential with the autocorrelation of the
// PSF. Deterministic for a seed.
std::vector<float> CorrelatedSpeckle(const std::vector<float>& intensity, int width, int height,
                                     double range_resolution_px, double azimuth_resolution_px,
                                     SpectralWindow window, double looks, uint64_t seed);

// Adds circular complex Gaussian noise of mean power 10^(nesz_db / 10)
// (half in each of the real and imaginary planes). Deterministic for a seed.
void AddComplexThermalNoise(std::vector<float>& real, std::vector<float>& imag, double nesz_db, uint64_t seed);

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
// image: sigma0 in simulations, docs/radiometry.md) as an
// exponentially distributed intensity per pixel (circular complex Gaussian
// noise). Deterministic for a seed.
void AddThermalNoise(std::vector<float>& intensity, double nesz_db, uint64_t seed);

}  // namespace gissar::image
