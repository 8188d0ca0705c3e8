#include "gissar/image/point_target.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <sstream>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

// Largest upsampled chip side (samples): 4096^2 complex doubles = 256 MiB.
constexpr int kMaxUpsampledSide = 4096;

std::string Num(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

// One cut through the peak: samples at 1 / upsampling pixel spacing over
// the chip's sample extent.
struct CutAnalysis {
  double width_px = 0.0;      // -3 dB width
  double main_lobe_px = 0.0;  // null to null
  double pslr_db = 0.0;
  double islr_db = 0.0;
  int null_first = 0;  // main lobe = [null_first, null_last] (cut indices)
  int null_last = 0;
};

std::optional<CutAnalysis> AnalyseCut(const std::vector<double>& cut, int peak, int upsampling,
                                      const std::string& axis, std::string* why) {
  const int n = static_cast<int>(cut.size());
  GISSAR_CHECK(peak > 0 && peak < n - 1);
  // Peak power: vertex of the parabola through the maximum and its
  // neighbours (the grid maximum can sit up to half a grid step off).
  double peak_power = cut[peak];
  const double curvature = cut[peak - 1] - 2.0 * cut[peak] + cut[peak + 1];
  if (curvature < 0.0) {
    const double slope = cut[peak + 1] - cut[peak - 1];
    peak_power -= slope * slope / (8.0 * curvature);
  }
  const double half = 0.5 * peak_power;
  int lo = peak;  // last sample >= half, going left
  while (lo > 0 && cut[lo - 1] >= half) --lo;
  int hi = peak;
  while (hi < n - 1 && cut[hi + 1] >= half) ++hi;
  if (lo == 0 || hi == n - 1) {
    *why = "the " + axis + " cut has no -3 dB crossing inside the chip (response wider than the chip)";
    return std::nullopt;
  }
  const double left = (lo - 1) + (half - cut[lo - 1]) / (cut[lo] - cut[lo - 1]);
  const double right = hi + (cut[hi] - half) / (cut[hi] - cut[hi + 1]);
  // First minima beyond the crossings.
  int null_first = lo - 1;
  while (null_first > 0 && cut[null_first - 1] < cut[null_first]) --null_first;
  int null_last = hi + 1;
  while (null_last < n - 1 && cut[null_last + 1] < cut[null_last]) ++null_last;
  if (null_first == 0 || null_last == n - 1) {
    *why = "the " + axis + " cut has no first null inside the chip (main lobe wider than the chip)";
    return std::nullopt;
  }
  double side_max = 0.0, side_energy = 0.0, main_energy = 0.0;
  for (int i = 0; i < n; ++i) {
    if (i >= null_first && i <= null_last) {
      main_energy += cut[i];
    } else {
      side_energy += cut[i];
      side_max = std::max(side_max, cut[i]);
    }
  }
  if (side_max > peak_power) {
    *why = "the " + axis + " cut holds a sample brighter than the peak inside the chip (the search found a " +
           "sidelobe, or a brighter target is nearby)";
    return std::nullopt;
  }
  CutAnalysis result;
  result.width_px = (right - left) / upsampling;
  result.main_lobe_px = double(null_last - null_first) / upsampling;
  result.pslr_db = 10.0 * std::log10(side_max / peak_power);
  result.islr_db = 10.0 * std::log10(side_energy / main_energy);
  result.null_first = null_first;
  result.null_last = null_last;
  return result;
}

// Offset (fraction of the grid step, |.| <= 0.5) of the vertex of the
// parabola through (-1, a), (0, b), (1, c); 0 when b is not a maximum.
double ParabolaOffset(double a, double b, double c) {
  const double curvature = a - 2.0 * b + c;
  if (!(curvature < 0.0)) return 0.0;
  return std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
}

// Where the N spectrum bins go in the M-point padded spectrum, with the
// Nyquist bin (even N) split half and half between both ends.
struct BinTarget {
  int index[2];
  double weight[2];
  int count;
};

BinTarget PaddedBin(int k, int n, int m) {
  if (2 * k < n) return {{k, 0}, {1.0, 0.0}, 1};
  if (2 * k > n) return {{k - n + m, 0}, {1.0, 0.0}, 1};
  return {{k, m - k}, {0.5, 0.5}, 2};
}

}  // namespace

void ValidatePointTargetOptions(const PointTargetOptions& options) {
  if (!(options.range_spacing_m > 0.0) || !std::isfinite(options.range_spacing_m)) {
    throw ConfigError("range spacing must be a positive number of metres, got " + Num(options.range_spacing_m),
                      "range_spacing_m");
  }
  if (!(options.azimuth_spacing_m > 0.0) || !std::isfinite(options.azimuth_spacing_m)) {
    throw ConfigError("azimuth spacing must be a positive number of metres, got " + Num(options.azimuth_spacing_m),
                      "azimuth_spacing_m");
  }
  if (!(options.search_radius_px >= 0.0) || !std::isfinite(options.search_radius_px)) {
    throw ConfigError("search radius must be >= 0 pixels, got " + Num(options.search_radius_px), "search_radius_px");
  }
  if (options.chip_half_size_px < 4 || options.chip_half_size_px > kMaxUpsampledSide / 4) {
    throw ConfigError("chip half-size must be 4 to " + std::to_string(kMaxUpsampledSide / 4) + " pixels, got " +
                          std::to_string(options.chip_half_size_px),
                      "chip_half_size_px");
  }
  if (options.upsampling < 2) {
    throw ConfigError("upsampling factor must be >= 2, got " + std::to_string(options.upsampling), "upsampling");
  }
  if (2 * options.chip_half_size_px * options.upsampling > kMaxUpsampledSide) {
    throw ConfigError("the upsampled chip (2 x chip_half_size_px x upsampling = " +
                          std::to_string(2 * options.chip_half_size_px * options.upsampling) + ") exceeds " +
                          std::to_string(kMaxUpsampledSide) + " samples per axis",
                      "upsampling");
  }
  if (options.integration_half_size_px != 0 &&
      (options.integration_half_size_px < 2 || options.integration_half_size_px > 4096)) {
    throw ConfigError("integration half-size must be 0 (= chip half-size) or 2 to 4096 pixels, got " +
                          std::to_string(options.integration_half_size_px),
                      "integration_half_size_px");
  }
  if (options.beta0_calibration &&
      (!(*options.beta0_calibration > 0.0) || !std::isfinite(*options.beta0_calibration))) {
    throw ConfigError("beta0 calibration factor must be a positive linear factor, got " +
                          Num(*options.beta0_calibration),
                      "beta0_calibration");
  }
  if (!std::isfinite(options.min_peak_to_background_db)) {
    throw ConfigError("minimum peak-to-background ratio must be a finite number of dB", "min_peak_to_background_db");
  }
}

namespace {

// Refuses an image whose size does not match its samples, and a prediction
// that is not finite.
void CheckImageAndPrediction(const std::vector<std::complex<float>>& slc, int width, int height,
                             double predicted_col, double predicted_row) {
  if (width < 1 || height < 1) {
    throw InputError("image size must be positive, got " + std::to_string(width) + " x " + std::to_string(height),
                     "slc");
  }
  if (slc.size() != size_t(width) * size_t(height)) {
    throw InputError("image has " + std::to_string(slc.size()) + " samples, expected " + std::to_string(width) +
                         " x " + std::to_string(height),
                     "slc");
  }
  if (!std::isfinite(predicted_col) || !std::isfinite(predicted_row)) {
    throw InputError("predicted position is not finite", "predicted_px");
  }
}

// The complex image, read in double; a sample that is not finite is an
// InputError when it is read.
struct SlcImage {
  const std::vector<std::complex<float>>& slc;
  int width = 0, height = 0;

  std::complex<double> At(int col, int row) const {
    const std::complex<float> v = slc[size_t(row) * width + col];
    if (!std::isfinite(v.real()) || !std::isfinite(v.imag())) {
      throw InputError("sample (column " + std::to_string(col) + ", row " + std::to_string(row) + ") is not finite",
                       "slc");
    }
    return {v.real(), v.imag()};
  }
};

// The brightest sample near the prediction.
struct PeakSample {
  int col = -1, row = -1;
  double power = -1.0;
  std::string text;  // "(col, row)", for messages
};

// 1. The brightest sample within the search circle; it must be a local
// maximum. nullopt (with the reason in `why`) when there is none.
std::optional<PeakSample> FindPeakSample(const SlcImage& image, double predicted_col, double predicted_row,
                                         double radius, const std::string& where_text, std::string* why) {
  const int width = image.width, height = image.height;
  const double col_lo = std::max(0.0, std::ceil(predicted_col - radius));
  const double col_hi = std::min(width - 1.0, std::floor(predicted_col + radius));
  const double row_lo = std::max(0.0, std::ceil(predicted_row - radius));
  const double row_hi = std::min(height - 1.0, std::floor(predicted_row + radius));
  PeakSample peak;
  for (double r = row_lo; r <= row_hi; ++r) {
    for (double c = col_lo; c <= col_hi; ++c) {
      const double dc = c - predicted_col, dr = r - predicted_row;
      if (dc * dc + dr * dr > radius * radius) continue;
      const double p = std::norm(image.At(int(c), int(r)));
      if (p > peak.power) {
        peak.power = p;
        peak.col = int(c);
        peak.row = int(r);
      }
    }
  }
  if (peak.col < 0) {
    *why = "the search circle of radius " + Num(radius) + " px around the prediction " + where_text +
           " holds no image sample";
    return std::nullopt;
  }
  peak.text = "(" + std::to_string(peak.col) + ", " + std::to_string(peak.row) + ")";
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      const int c = peak.col + dc, r = peak.row + dr;
      if (c < 0 || r < 0 || c >= width || r >= height) continue;
      if (std::norm(image.At(c, r)) > peak.power) {
        *why = "the brightest sample within " + Num(radius) + " px of the prediction " + where_text + ", " +
               peak.text + ", is not a local maximum: the target lies outside the search radius";
        return std::nullopt;
      }
    }
  }
  return peak;
}

// The target's energy above the background, and the background.
struct TargetEnergy {
  double background = 0.0;  // mean power of the four corner boxes
  double energy = 0.0;      // box sum minus the background over the box
};

// 5 (first, for the detection test). Energy and background on the
// original samples: (2 hi + 1)^2 box, four corner boxes of side b. nullopt
// (reason in `why`) when no target stands out of the background.
std::optional<TargetEnergy> IntegrateEnergy(const SlcImage& image, const PeakSample& peak, int hi,
                                            double min_peak_to_background_db, const std::string& where_text,
                                            std::string* why) {
  const int b = std::max(1, hi / 2);
  double box_sum = 0.0, corner_sum = 0.0;
  for (int r = peak.row - hi; r <= peak.row + hi; ++r) {
    for (int c = peak.col - hi; c <= peak.col + hi; ++c) {
      const double p = std::norm(image.At(c, r));
      box_sum += p;
      const bool corner_col = c < peak.col - hi + b || c > peak.col + hi - b;
      const bool corner_row = r < peak.row - hi + b || r > peak.row + hi - b;
      if (corner_col && corner_row) corner_sum += p;
    }
  }
  const double box_count = double(2 * hi + 1) * double(2 * hi + 1);
  const double background = corner_sum / (4.0 * b * b);
  if (!(peak.power > 0.0)) {
    *why = "no target near " + where_text + ": every sample is zero";
    return std::nullopt;
  }
  if (background > 0.0) {
    const double contrast_db = 10.0 * std::log10(peak.power / background);
    if (contrast_db < min_peak_to_background_db) {
      *why = "no target near " + where_text + ": the brightest sample " + peak.text + " is only " +
             Num(contrast_db) + " dB above the background (at least " + Num(min_peak_to_background_db) +
             " dB needed)";
      return std::nullopt;
    }
  }
  const double energy = box_sum - background * box_count;
  if (!(energy > 0.0)) {
    *why = "no target near " + where_text + ": the integrated energy minus the background is not positive";
    return std::nullopt;
  }
  return TargetEnergy{background, energy};
}

// 2. The chip: n x n samples from (col0, row0), row-major.
std::vector<std::complex<double>> ExtractChip(const SlcImage& image, int col0, int row0, int n) {
  std::vector<std::complex<double>> chip(size_t(n) * n);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) chip[size_t(r) * n + c] = image.At(col0 + c, row0 + r);
  }
  return chip;
}

// The chip's spectral centroid (cycles per pixel, columns and rows) from its
// lag-one correlations, removed from the chip (phase 0 at index h).
RangeAzimuth RemoveSpectralCentroid(std::vector<std::complex<double>>& chip, int n, int h) {
  std::complex<double> lag_col = 0.0, lag_row = 0.0;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const std::complex<double> v = chip[size_t(r) * n + c];
      if (c + 1 < n) lag_col += chip[size_t(r) * n + c + 1] * std::conj(v);
      if (r + 1 < n) lag_row += chip[size_t(r + 1) * n + c] * std::conj(v);
    }
  }
  auto centroid = [](std::complex<double> lag) {
    double f = std::arg(lag) / (2.0 * M_PI);  // arg(0) = 0
    if (f >= 0.5) f -= 1.0;
    return f;
  };
  const double f_col = centroid(lag_col), f_row = centroid(lag_row);
  if (f_col != 0.0 || f_row != 0.0) {
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        chip[size_t(r) * n + c] *= std::polar(1.0, -2.0 * M_PI * (f_col * (c - h) + f_row * (r - h)));
      }
    }
  }
  return {f_col, f_row};
}

// The chip upsampled by u: m x m complex samples (m = n u), unscaled.
struct UpsampledChip {
  cv::Mat samples;     // CV_64FC2
  double scale = 1.0;  // 1 / n^2: the inverse DFT's missing factor
  int u = 1;           // grid step 1 / u pixel
  int l = 0;           // the chip's sample extent: l x l, (n - 1) u + 1 (the wrap interval left out)

  double Power(int r, int c) const {
    const cv::Vec2d& v = samples.at<cv::Vec2d>(r, c);
    return (v[0] * v[0] + v[1] * v[1]) * scale * scale;
  }
};

// 3. Upsampling by zero-padding the spectrum.
UpsampledChip UpsampleChip(const std::vector<std::complex<double>>& chip, int n, int u) {
  const int m = n * u;
  cv::Mat chip_mat(n, n, CV_64FC2);
  for (int r = 0; r < n; ++r) {
    auto* row = chip_mat.ptr<cv::Vec2d>(r);
    for (int c = 0; c < n; ++c) row[c] = {chip[size_t(r) * n + c].real(), chip[size_t(r) * n + c].imag()};
  }
  cv::Mat spectrum;
  cv::dft(chip_mat, spectrum, cv::DFT_COMPLEX_OUTPUT);
  cv::Mat padded = cv::Mat::zeros(m, m, CV_64FC2);
  for (int kr = 0; kr < n; ++kr) {
    const BinTarget tr = PaddedBin(kr, n, m);
    for (int kc = 0; kc < n; ++kc) {
      const BinTarget tc = PaddedBin(kc, n, m);
      const cv::Vec2d v = spectrum.at<cv::Vec2d>(kr, kc);
      for (int i = 0; i < tr.count; ++i) {
        for (int j = 0; j < tc.count; ++j) padded.at<cv::Vec2d>(tr.index[i], tc.index[j]) += v * (tr.weight[i] * tc.weight[j]);
      }
    }
  }
  UpsampledChip up;
  // In place (the chip's memory is touched once: 16 MiB for 1024^2).
  cv::Mat& upsampled = padded;
  cv::dft(padded, upsampled, cv::DFT_INVERSE);  // unscaled: divide by n^2
  up.samples = upsampled;
  up.scale = 1.0 / (double(n) * n);
  up.u = u;
  up.l = (n - 1) * u + 1;
  return up;
}

// The peak on the upsampled grid and its sub-sample offsets.
struct UpsampledPeak {
  int r = 0, c = 0;       // grid maximum
  double power = 0.0;     // its power
  double d_col = 0.0, d_row = 0.0;  // parabola vertex offsets, grid steps
};

// Grid maximum within 2 px of the brightest sample (index h), then
// parabolas through it and its neighbours.
UpsampledPeak FitPeak(const UpsampledChip& up, int h) {
  const int u = up.u;
  UpsampledPeak peak;
  peak.r = h * u;
  peak.c = h * u;
  peak.power = up.Power(peak.r, peak.c);
  for (int r = (h - 2) * u; r <= (h + 2) * u; ++r) {
    for (int c = (h - 2) * u; c <= (h + 2) * u; ++c) {
      const double value = up.Power(r, c);
      if (value > peak.power) {
        peak.power = value;
        peak.r = r;
        peak.c = c;
      }
    }
  }
  const int pr = peak.r, pc = peak.c;
  peak.d_col = ParabolaOffset(up.Power(pr, pc - 1), up.Power(pr, pc), up.Power(pr, pc + 1));
  peak.d_row = ParabolaOffset(up.Power(pr - 1, pc), up.Power(pr, pc), up.Power(pr + 1, pc));
  return peak;
}

// 4. The range and azimuth cuts through the peak, over the chip's extent.
struct PeakCuts {
  std::vector<double> range, azimuth;  // power
};

PeakCuts TakeCuts(const UpsampledChip& up, const UpsampledPeak& peak) {
  PeakCuts cuts;
  cuts.range.resize(up.l);
  cuts.azimuth.resize(up.l);
  for (int i = 0; i < up.l; ++i) {
    cuts.range[i] = up.Power(peak.r, i);
    cuts.azimuth[i] = up.Power(i, peak.c);
  }
  return cuts;
}

// The power of the whole chip extent and of the main lobe (the box between
// both cuts' first nulls), for the 2-D ISLR.
struct LobeEnergy {
  double total = 0.0, main = 0.0;
};

LobeEnergy IntegrateMainLobe(const UpsampledChip& up, const CutAnalysis& range, const CutAnalysis& azimuth) {
  LobeEnergy e;
  for (int r = 0; r < up.l; ++r) {
    for (int c = 0; c < up.l; ++c) {
      e.total += up.Power(r, c);
      if (r >= azimuth.null_first && r <= azimuth.null_last && c >= range.null_first && c <= range.null_last) {
        e.main += up.Power(r, c);
      }
    }
  }
  return e;
}

// A cut for plots, relative to the grid maximum, from pixel `first`.
PointTargetCut CutForPlot(const std::vector<double>& power, int first, const CutAnalysis& analysis, int u,
                          double grid_max) {
  PointTargetCut cut;
  cut.first_px = first;
  cut.step_px = 1.0 / u;
  cut.power_db.reserve(power.size());
  for (double value : power) cut.power_db.push_back(10.0 * std::log10(std::max(value / grid_max, 1e-30)));
  cut.null_first_px = first + double(analysis.null_first) / u;
  cut.null_last_px = first + double(analysis.null_last) / u;
  return cut;
}

// Where the chip lies and how it was centred: its first sample, half-size
// and spectral centroid.
struct ChipPlacement {
  int col0 = 0, row0 = 0;
  int h = 0;
  RangeAzimuth centroid;  // cycles per pixel (f_col, f_row)
};

// The measurement from the fitted peak, the cut analyses and the energies.
PointTargetMeasurement AssembleMeasurement(const PointTargetOptions& options, double predicted_col,
                                           double predicted_row, const PeakSample& sample,
                                           const TargetEnergy& target, const ChipPlacement& chip,
                                           const UpsampledChip& up, const UpsampledPeak& peak, const PeakCuts& cuts,
                                           const CutAnalysis& range, const CutAnalysis& azimuth,
                                           const LobeEnergy& lobe) {
  const int u = up.u, h = chip.h;
  const double f_col = chip.centroid.range, f_row = chip.centroid.azimuth;
  const double background = target.background, energy = target.energy;
  PointTargetMeasurement out;
  out.predicted_px = {predicted_col, predicted_row};
  out.peak_sample_col = sample.col;
  out.peak_sample_row = sample.row;
  out.peak_px = {chip.col0 + (peak.c + peak.d_col) / u, chip.row0 + (peak.r + peak.d_row) / u};
  out.location_error_px = {out.peak_px.range - predicted_col, out.peak_px.azimuth - predicted_row};
  out.location_error_m = {out.location_error_px.range * options.range_spacing_m,
                          out.location_error_px.azimuth * options.azimuth_spacing_m};
  out.resolution_px = {range.width_px, azimuth.width_px};
  out.resolution_m = {range.width_px * options.range_spacing_m, azimuth.width_px * options.azimuth_spacing_m};
  out.main_lobe_px = {range.main_lobe_px, azimuth.main_lobe_px};
  out.pslr_db = {range.pslr_db, azimuth.pslr_db};
  out.islr_db = {range.islr_db, azimuth.islr_db};
  out.islr_2d_db = 10.0 * std::log10((lobe.total - lobe.main) / lobe.main);
  out.spectrum_centre_cycles_per_px = {f_col, f_row};
  const cv::Vec2d v = up.samples.at<cv::Vec2d>(peak.r, peak.c);
  out.peak_value = std::complex<double>(v[0], v[1]) * up.scale *
                   std::polar(1.0, 2.0 * M_PI * (f_col * (double(peak.c) / u - h) + f_row * (double(peak.r) / u - h)));
  out.peak_power = std::norm(out.peak_value);
  out.background_power = background;
  out.energy = energy;
  out.scr_db = background > 0.0 ? 10.0 * std::log10(out.peak_power / background)
                                 : std::numeric_limits<double>::infinity();
  out.calibrated = options.beta0_calibration.has_value();
  out.beta0_calibration = options.beta0_calibration.value_or(1.0);
  out.peak_beta0_db = 10.0 * std::log10(out.beta0_calibration * out.peak_power);
  out.rcs_m2 = out.beta0_calibration * energy * options.range_spacing_m * options.azimuth_spacing_m;
  out.rcs_dbsm = 10.0 * std::log10(out.rcs_m2);
  out.range_cut = CutForPlot(cuts.range, chip.col0, range, u, peak.power);
  out.azimuth_cut = CutForPlot(cuts.azimuth, chip.row0, azimuth, u, peak.power);
  return out;
}

}  // namespace

std::optional<PointTargetMeasurement> MeasurePointTarget(const std::vector<std::complex<float>>& slc, int width,
                                                         int height, double predicted_col, double predicted_row,
                                                         const PointTargetOptions& options, std::string* why_not) {
  ValidatePointTargetOptions(options);
  CheckImageAndPrediction(slc, width, height, predicted_col, predicted_row);
  std::string why;
  auto fail = [&](const std::string& reason) -> std::optional<PointTargetMeasurement> {
    if (why_not) *why_not = reason;
    return std::nullopt;
  };
  const SlcImage image{slc, width, height};
  const std::string where_text = "(" + Num(predicted_col) + ", " + Num(predicted_row) + ")";

  // 1. The brightest sample near the prediction, far enough from the edges.
  const std::optional<PeakSample> sample =
      FindPeakSample(image, predicted_col, predicted_row, options.search_radius_px, where_text, &why);
  if (!sample) return fail(why);
  const int h = options.chip_half_size_px;
  const int hi = options.integration_half_size_px > 0 ? options.integration_half_size_px : h;
  const int margin = std::max(h, hi);
  if (sample->col - margin < 0 || sample->row - margin < 0 || sample->col + margin > width - 1 ||
      sample->row + margin > height - 1) {
    return fail("target too close to the image edge: the chip of +-" + std::to_string(margin) +
                " px around the peak sample " + sample->text + " leaves the " + std::to_string(width) + " x " +
                std::to_string(height) + " image");
  }
  // 5 (first, for the detection test).
  const std::optional<TargetEnergy> target =
      IntegrateEnergy(image, *sample, hi, options.min_peak_to_background_db, where_text, &why);
  if (!target) return fail(why);

  // 2. Chip (2h x 2h, brightest sample at index h) with its spectral
  // centroid removed.
  const int n = 2 * h;
  ChipPlacement placement;
  placement.col0 = sample->col - h;
  placement.row0 = sample->row - h;
  placement.h = h;
  std::vector<std::complex<double>> chip = ExtractChip(image, placement.col0, placement.row0, n);
  placement.centroid = RemoveSpectralCentroid(chip, n, h);

  // 3. Upsampling, and the peak on the upsampled grid.
  const UpsampledChip up = UpsampleChip(chip, n, options.upsampling);
  const UpsampledPeak peak = FitPeak(up, h);

  // 4. Cuts: resolution, PSLR and ISLR per axis; the 2-D ISLR.
  const PeakCuts cuts = TakeCuts(up, peak);
  const auto range = AnalyseCut(cuts.range, peak.c, up.u, "range", &why);
  if (!range) return fail(why + " (target at " + sample->text + ")");
  const auto azimuth = AnalyseCut(cuts.azimuth, peak.r, up.u, "azimuth", &why);
  if (!azimuth) return fail(why + " (target at " + sample->text + ")");
  const LobeEnergy lobe = IntegrateMainLobe(up, *range, *azimuth);

  return AssembleMeasurement(options, predicted_col, predicted_row, *sample, *target, placement, up, peak, cuts,
                             *range, *azimuth, lobe);
}

std::optional<std::complex<double>> InterpolateComplex(const std::vector<std::complex<float>>& slc, int width,
                                                       int height, double col, double row,
                                                       const RangeAzimuth& centre, int chip_half_size_px) {
  if (width < 1 || height < 1 || slc.size() != size_t(width) * size_t(height)) {
    throw InputError("image has " + std::to_string(slc.size()) + " samples, expected " + std::to_string(width) +
                         " x " + std::to_string(height),
                     "slc");
  }
  if (!std::isfinite(col) || !std::isfinite(row) || !std::isfinite(centre.range) || !std::isfinite(centre.azimuth)) {
    throw InputError("position or spectrum centre is not finite", "position");
  }
  GISSAR_CHECK(chip_half_size_px >= 1 && chip_half_size_px <= kMaxUpsampledSide / 4);
  const int h = chip_half_size_px, n = 2 * h;
  if (!(std::abs(col) < 1e9 && std::abs(row) < 1e9)) return std::nullopt;
  const int c0 = int(std::lround(col)) - h, r0 = int(std::lround(row)) - h;
  if (c0 < 0 || r0 < 0 || c0 + n > width || r0 + n > height) return std::nullopt;
  // Periodic band-limited kernel of n samples: (1/n) sum_k w_k exp(j 2 pi k t / n),
  // k = -n/2 .. n/2 with half weights at +-n/2 (real).
  auto kernel = [n](double t) {
    double sum = std::cos(M_PI * t);  // the split Nyquist bin
    for (int k = 1; k < n / 2; ++k) sum += 2.0 * std::cos(2.0 * M_PI * k * t / n);
    return (1.0 + sum) / n;
  };
  const double x = col - c0, y = row - r0;  // chip coordinates
  std::vector<double> kx(n), ky(n);
  for (int i = 0; i < n; ++i) {
    kx[i] = kernel(x - i);
    ky[i] = kernel(y - i);
  }
  std::complex<double> value = 0.0;
  for (int r = 0; r < n; ++r) {
    std::complex<double> line = 0.0;
    for (int c = 0; c < n; ++c) {
      const std::complex<float> v = slc[size_t(r0 + r) * width + (c0 + c)];
      if (!std::isfinite(v.real()) || !std::isfinite(v.imag())) {
        throw InputError("sample (column " + std::to_string(c0 + c) + ", row " + std::to_string(r0 + r) +
                             ") is not finite",
                         "slc");
      }
      const std::complex<double> ramp =
          std::polar(1.0, -2.0 * M_PI * (centre.range * (c - h) + centre.azimuth * (r - h)));
      line += std::complex<double>(v.real(), v.imag()) * ramp * kx[c];
    }
    value += line * ky[r];
  }
  return value * std::polar(1.0, 2.0 * M_PI * (centre.range * (x - h) + centre.azimuth * (y - h)));
}

nlohmann::json ToJson(const PointTargetMeasurement& measurement) {
  auto pair = [](const RangeAzimuth& value) {
    return nlohmann::json{{"range", value.range}, {"azimuth", value.azimuth}};
  };
  nlohmann::json out;
  out["predicted_px"] = pair(measurement.predicted_px);
  out["peak_px"] = pair(measurement.peak_px);
  out["location_error_px"] = pair(measurement.location_error_px);
  out["location_error_m"] = pair(measurement.location_error_m);
  out["resolution_m"] = pair(measurement.resolution_m);
  out["pslr_db"] = pair(measurement.pslr_db);
  out["islr_db"] = pair(measurement.islr_db);
  out["rcs_dbsm"] = measurement.rcs_dbsm;
  return out;
}

}  // namespace gissar::image
