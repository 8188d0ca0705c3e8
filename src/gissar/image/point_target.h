// Point-target analysis (PTA) of one target in a complex SAR image: the
// measurement core of `gissar pta` (docs/radiometry.md, "Point-target
// analysis"). Axes: columns = slant range, rows = azimuth; pixel centres at
// integer coordinates.
//
// What MeasurePointTarget does, in order:
//  1. peak search: the brightest |s|^2 sample within `search_radius_px` of
//     the prediction; it must be a local maximum of its 8 neighbours;
//  2. spectrum centring: the chip's spectral energy centroid per axis (the
//     phase of its lag-1 autocorrelation, which is the circular centroid of
//     |S(f)|^2) is removed by a linear phase ramp, so a response whose
//     spectrum is not centred at DC (Doppler centroid, range offset) is
//     interpolated like a centred one; a real-valued (centred) chip gets a
//     ramp of exactly zero. |s| is unaffected by the ramp;
//  3. upsampling of the 2 h x 2 h chip (h = chip_half_size_px, brightest
//     sample at chip index h) by zero-padding its centred spectrum (the
//     Nyquist bin split between both ends), `upsampling` times per axis;
//     sub-pixel peak = maximum of the upsampled |s|^2 refined by a
//     3-point parabola per axis;
//  4. range cut (upsampled row) and azimuth cut (upsampled column) through
//     the peak, over the chip's sample extent (first to last sample; the
//     periodic wrap interval after the last sample is excluded): -3 dB
//     width by linear interpolation of the half-power crossings; main lobe
//     = between the first minima after the -3 dB crossings (the first
//     nulls); PSLR = highest cut sample outside the main lobe / peak; ISLR
//     = cut energy outside the main lobe / energy inside it. The 2-D ISLR
//     uses the main-lobe rectangle of both cuts over the whole chip;
//  5. integrated energy on the ORIGINAL samples: sum of |s|^2 over the
//     (2 hi + 1)^2 box centred on the brightest sample (hi =
//     integration_half_size_px) minus the background (mean |s|^2 of the
//     box's four corner boxes of side max(1, hi / 2), which lie off the
//     range and azimuth sidelobe lines) times the box's sample count;
//     RCS (m^2) = beta0_calibration x energy x range_spacing_m x
//     azimuth_spacing_m.
// An unweighted sinc's sidelobe energy decays like 1/distance: a box of
// half-size X px misses about 1 / (pi^2 B X) of it per axis (B = bandwidth
// in cycles per pixel), 0.9 % per axis for X = 16, B = 0.68.
#pragma once

#include <complex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace gissar::image {

// A pair of values along the two image axes.
struct RangeAzimuth {
  double range = 0.0;    // along columns (slant range)
  double azimuth = 0.0;  // along rows (azimuth)
};

struct PointTargetOptions {
  // Pixel spacings (metres per pixel, > 0; no default: must be set).
  double range_spacing_m = 0.0;
  double azimuth_spacing_m = 0.0;
  // Radius (pixels, >= 0) around the prediction searched for the brightest
  // sample.
  double search_radius_px = 8.0;
  // Half-size h (pixels, >= 4) of the upsampled chip: 2h x 2h samples.
  int chip_half_size_px = 16;
  // Upsampling factor per axis (>= 2; >= 16 recommended for -3 dB widths
  // and PSLR to better than 1 % and 0.1 dB).
  int upsampling = 32;
  // Half-size hi of the energy integration box ((2 hi + 1)^2 original
  // samples); 0 = chip_half_size_px. >= 2 when set.
  int integration_half_size_px = 0;
  // Linear factor turning |s|^2 into beta0; unset = uncalibrated (factor 1,
  // reported as PointTargetMeasurement::calibrated = false). > 0.
  std::optional<double> beta0_calibration;
  // The peak's |s|^2 must exceed the background mean by this much (dB),
  // else "no target" is reported.
  double min_peak_to_background_db = 10.0;
};

// One upsampled cut through the peak (for plots): power in dB relative to
// the upsampled grid's maximum; sample i lies at image coordinate
// first_px + i * step_px (a column for the range cut, a row for the
// azimuth cut); the main lobe spans [null_first_px, null_last_px].
struct PointTargetCut {
  double first_px = 0.0;
  double step_px = 1.0;
  std::vector<double> power_db;
  double null_first_px = 0.0;
  double null_last_px = 0.0;
};

struct PointTargetMeasurement {
  RangeAzimuth predicted_px;       // the prediction (column, row)
  int peak_sample_col = 0;         // brightest sample found by the search
  int peak_sample_row = 0;
  RangeAzimuth peak_px;            // sub-pixel peak (column, row)
  RangeAzimuth location_error_px;  // peak_px - predicted_px
  RangeAzimuth location_error_m;   // location_error_px x spacing
  RangeAzimuth resolution_px;      // -3 dB widths of the range / azimuth cuts
  RangeAzimuth resolution_m;
  RangeAzimuth main_lobe_px;       // null-to-null widths of the cuts
  RangeAzimuth pslr_db;            // per cut, <= 0
  RangeAzimuth islr_db;            // per cut
  double islr_2d_db = 0.0;         // main-lobe rectangle over the chip
  // Spectral energy centroid removed before upsampling, cycles per pixel in
  // [-0.5, 0.5) (range: along columns; azimuth: Doppler centroid / PRF).
  RangeAzimuth spectrum_centre_cycles_per_px;
  // Interpolated complex value at the upsampled grid maximum (SLC units,
  // with the removed phase ramp restored) and its |.|^2.
  std::complex<double> peak_value;
  double peak_power = 0.0;
  double background_power = 0.0;   // mean |s|^2 per sample of the corner boxes
  double energy = 0.0;             // sum |s|^2 - background, original samples
  double scr_db = 0.0;             // 10 log10(peak_power / background_power); +inf for a zero background
  bool calibrated = false;         // beta0_calibration was given
  double beta0_calibration = 1.0;  // the factor used
  double peak_beta0_db = 0.0;      // 10 log10(beta0_calibration x peak_power)
  double rcs_m2 = 0.0;             // beta0_calibration x energy x spacings
  double rcs_dbsm = 0.0;           // 10 log10(rcs_m2)
  PointTargetCut range_cut;        // the upsampled row through the peak
  PointTargetCut azimuth_cut;      // the upsampled column through the peak
};

// Measures the point target predicted at (predicted_col, predicted_row)
// (pixels) in the row-major complex image `slc` (width x height).
// Returns nullopt, with the reason in *why_not (when given), when the
// search circle holds no image sample, the brightest sample is not a local
// maximum (the target lies outside the search radius), the chip or the
// integration box around it leaves the image, the peak is less than
// min_peak_to_background_db above the background, a cut has no -3 dB
// crossing or first null inside the chip, a cut holds a sample brighter
// than the peak (a sidelobe was found, or a brighter target is in the
// chip), or the energy is not positive.
// Throws InputError ("slc") when slc.size() != width x height, width or
// height < 1, the prediction is not finite ("predicted_px") or a sample of
// the search circle, chip or integration box is not finite; ConfigError naming the option
// for an option out of range.
std::optional<PointTargetMeasurement> MeasurePointTarget(const std::vector<std::complex<float>>& slc, int width,
                                                         int height, double predicted_col, double predicted_row,
                                                         const PointTargetOptions& options,
                                                         std::string* why_not = nullptr);

// Throws ConfigError naming the first option out of range.
void ValidatePointTargetOptions(const PointTargetOptions& options);

// The complex value of `slc` at the sub-pixel position (col, row) by the
// Fourier interpolation of MeasurePointTarget: the 2h x 2h chip whose index
// h holds the sample nearest to the position (h = chip_half_size_px >= 1),
// the phase ramp of `spectrum_centre_cycles_per_px` removed (e.g. a
// measurement's spectrum_centre_cycles_per_px, so that every channel of a
// quad-pol image is interpolated with the co-pol channel's Doppler
// centroid), its periodic band-limited interpolant (the Nyquist bin split
// between both ends) evaluated at the position, the ramp restored. At a
// grid point of MeasurePointTarget's upsampled chip this is the upsampled
// value. Returns nullopt when the chip leaves the image. Throws InputError
// ("slc") for a wrong image size or a non-finite chip sample, ("position")
// for a non-finite position.
std::optional<std::complex<double>> InterpolateComplex(const std::vector<std::complex<float>>& slc, int width,
                                                       int height, double col, double row,
                                                       const RangeAzimuth& spectrum_centre_cycles_per_px,
                                                       int chip_half_size_px = 16);

// The per-reflector JSON keys of `gissar pta` that come from the
// measurement: predicted_px, peak_px, location_error_px, location_error_m,
// resolution_m, pslr_db, islr_db (each {"range": ..., "azimuth": ...}) and
// rcs_dbsm (the caller adds id, rcs_expected_dbsm, calibration_offset_db
// and the polarimetric keys).
nlohmann::json ToJson(const PointTargetMeasurement& measurement);

}  // namespace gissar::image
