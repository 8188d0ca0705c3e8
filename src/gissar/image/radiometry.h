// Radiometric quantities of simulated images (docs/radiometry.md): the
// renderers produce beta0 (radar brightness, m^2 of RCS per m^2 of image
// pixel in slant range x azimuth); sigma0 = beta0 sin(theta_i) and
// gamma0 = sigma0 / cos(theta_i) = beta0 tan(theta_i), with theta_i the
// ellipsoid incidence angle of the pixel.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "gissar/image/impulse_response.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/util/enum_table.h"

namespace gissar::image {

enum class Radiometry { kSigma0, kBeta0, kGamma0 };
inline constexpr auto kRadiometries = util::MakeEnumTable<Radiometry>(
    "radiometry", {{Radiometry::kSigma0, "sigma0"}, {Radiometry::kBeta0, "beta0"}, {Radiometry::kGamma0, "gamma0"}});

// kRadiometries.Parse: "sigma0", "beta0", "gamma0"; throws ConfigError
// naming `option` and the quantities otherwise.
Radiometry ParseRadiometry(const std::string& text, const std::string& option);
std::string ToString(Radiometry radiometry);
// Unit text for band metadata: "m2/m2" (linear) or "dB".
std::string RadiometryUnit(bool db);

// Factor that turns beta0 into `target` at incidence theta_i (degrees):
// 1, sin(theta_i) or tan(theta_i).
double FactorFromBeta0(Radiometry target, double incidence_deg);

// Multiplies every pixel of column c of a row-major width x height image by
// factors[c] (factors.size() == width).
void ScaleColumns(std::vector<float>& image, int width, int height, const std::vector<double>& factors);

// 10 log10 of every pixel; pixels <= 0 (no return) become NaN.
void ToDecibels(std::vector<float>& image);

// The sensor chain after rendering, on every band.
// Incoherent (image.real empty):
//  1. the intensity impulse response (resolutions in pixels; 0 = none) on
//     every beta0 band (linear: the bounce bands still add up to the total);
//  2. L-look speckle (looks >= 1; 0 = off), the same factor for every band
//     (they still add up): with an impulse response, correlated over the
//     resolution cell (image::CorrelatedSpeckle of the total before the
//     PSF, round(L) looks); without, independent Gamma(L) per pixel;
//  3. the point returns (image.points: reflectors), each with the intensity
//     response centred on it, integrating to its beta0_sum;
// Coherent (image.real/imag set; speckle must be 0): the complex image is
// convolved with the amplitude response (before detection), the point
// returns are added as phasors of phase -4 pi r / lambda plus their
// phase_offset_rad (a polarimetric pass's arg S_c, else 0), the total is
// detected; the complex bounce images (image.bounce_real/bounce_imag) take
// the same response, phasors and scaling, and each bounce band becomes
// their detected power (so the complex bands add up to the complex total).
// Then, in both modes: conversion to sigma0; thermal noise of mean power
// nesz_db (dB sigma0; NaN = off) on the total (complex noise in coherent
// mode); conversion to `radiometry` (the complex planes by the square root
// of the factor) and, with `db`, decibels (not the complex planes).
struct SensorEffects {
  double range_resolution_px = 0.0;
  double azimuth_resolution_px = 0.0;
  SpectralWindow window = SpectralWindow::kNone;
  double speckle_looks = 0.0;
  double nesz_db = std::numeric_limits<double>::quiet_NaN();
  uint64_t seed = 1;
  Radiometry radiometry = Radiometry::kSigma0;
  bool db = false;
  double wavelength_m = 0.031;  // phase of the point returns
};

// Adds every point return of image.points (incoherent) to the total and to
// its bounce band, with the intensity impulse response of `effects` centred
// on it, integrating to its beta0_sum (the part of ApplySensorEffects'
// step 3 for images that take no other sensor effect from it, e.g. product
// grids).
void AddPointIntensities(render::SarImage& image, const SensorEffects& effects);

// Applies `effects` to `image` (beta0 on entry), with incidence_deg[c] the
// ellipsoid incidence of column c. CHECKs the sizes and that a coherent
// image has no speckle requested. A bounce layer the renderer left empty
// stays empty unless a point return lands in it (it then becomes a plane of
// zeros plus those returns; here and in AddPointIntensities).
void ApplySensorEffects(render::SarImage& image, const SensorEffects& effects,
                        const std::vector<double>& incidence_deg);

// The end of the chain for incoherent images whose incidence varies from
// pixel to pixel (real radar grids, where range and terrain height both move
// it): beta0 -> sigma0 with incidence_deg[k] of pixel k on every band,
// thermal noise of mean power nesz_db (dB sigma0; NaN = off) on the total,
// conversion to `radiometry` and, with `db`, decibels. Pixels whose incidence
// is NaN (no ground point) are left as they are (the caller marks them
// outside the footprint). CHECKs the sizes and that the image is incoherent.
void ConvertPixelRadiometry(render::SarImage& image, const std::vector<float>& incidence_deg, Radiometry radiometry,
                            double nesz_db, uint64_t seed, bool db);

}  // namespace gissar::image
