// Sentinel-1 measurement images (measurement/*.tiff of a SAFE, read through
// GDAL, /vsizip/ included) and their radiometric calibration with the LUTs of
// sentinel1_safe.h. See docs/sentinel1.md, "Images and calibration".
//
// Conventions (as sentinel1_safe.h): lines and samples are 0-based in the
// measurement's numbering, which is the annotations' `line` and `pixel`
// numbering (in an IW/EW SLC the lines of the concatenated bursts: burst b,
// 1-based, is lines (b - 1) x linesPerBurst .. b x linesPerBurst - 1).
// Images are row-major, line by line (rows = azimuth, time increasing within a
// burst; columns = range, increasing).
//
// Values:
// - DN: the stored digital number; an SLC's complex int16 as
//   std::complex<float> (exact), a GRD's uint16 amplitude as float (exact).
// - Calibrated (sigma0, beta0, gamma0): linear power, float32, dimensionless
//   (units "1"): (|DN|^2 - N) / A^2, with A the calibration LUT (sigmaNought,
//   betaNought or gamma) and N the thermal noise power (range LUT x azimuth
//   LUT, sentinel1_safe.h Sentinel1Noise::At) when noise removal is asked for,
//   else 0; A and N interpolated bilinearly in line and pixel as ESA specifies
//   (Sentinel1LineVectors::At). Arithmetic in double, rounded once to float.
// - No-data is NaN (NaN + NaN i for complex values), at: a DN of exactly 0
//   (ESA's fill value, e.g. outside a GRD's valid swath); in an IW/EW SLC, a
//   sample outside its burst's valid window (swathTiming/burstList/burst/
//   firstValidSample..lastValidSample of its line; a line whose entries are
//   -1 has none); and, with noise removal, where |DN|^2 - N < 0 (clipped to
//   NaN, never to 0, so that a mean over valid pixels is not biased low).
#pragma once

#include <complex>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gissar/geo/sentinel1_safe.h"
#include "gissar/util/enum_table.h"

namespace gissar::geo {

enum class Sentinel1Radiometry { kNone, kSigma0, kBeta0, kGamma0 };
// kNone: the DN, uncalibrated; "" (no radiometry given) reads as none.
inline constexpr auto kSentinel1Radiometries = util::MakeEnumTable<Sentinel1Radiometry>(
    "radiometry",
    {{Sentinel1Radiometry::kSigma0, "sigma0"},
     {Sentinel1Radiometry::kBeta0, "beta0"},
     {Sentinel1Radiometry::kGamma0, "gamma0"},
     {Sentinel1Radiometry::kNone, "none"}},
    {{Sentinel1Radiometry::kNone, ""}}, util::EnumCase::kInsensitive);

// kSentinel1Radiometries.Parse: "sigma0", "beta0", "gamma0"
// (case-insensitive); "" or "none" is kNone. Anything else: ConfigError
// naming `option` and the accepted values.
Sentinel1Radiometry ParseSentinel1Radiometry(const std::string& text, const std::string& option);
// "none", "sigma0", "beta0", "gamma0".
const char* ToString(Sentinel1Radiometry radiometry);

// A rectangle of the measurement: lines [first_line, first_line + lines) and
// samples [first_sample, first_sample + samples).
struct Sentinel1Window {
  int first_line = 0, first_sample = 0, lines = 0, samples = 0;
  int64_t pixels() const { return int64_t(lines) * samples; }
  // True when `w` lies inside this window (an empty `w` too, if its corner does).
  bool Contains(const Sentinel1Window& w) const;
};

// The whole measurement: numberOfLines x numberOfSamples.
Sentinel1Window Sentinel1SwathWindow(const Sentinel1Annotation& annotation);
// Burst `number` (1-based) of an IW/EW SLC: lines (number - 1) x
// linesPerBurst, linesPerBurst of them, every sample. Throws InputError naming
// --burst and the annotation file for a GRD, a product without bursts or a
// number out of range (Sentinel1Annotation::Burst).
Sentinel1Window Sentinel1BurstWindow(const Sentinel1Annotation& annotation, int number);

// Whether (line, sample) lies in its burst's valid window (always true for a
// product without bursts; false for a line beyond the bursts).
bool Sentinel1SampleValid(const Sentinel1Annotation& annotation, int line, int sample);

// The zero-Doppler time of measurement line `line`, seconds since the
// product's epoch: in an IW/EW SLC the line's burst azimuthTime + (line within
// the burst) x azimuthTimeInterval; otherwise productFirstLineUtcTime + line x
// azimuthTimeInterval.
double Sentinel1LineTime(const Sentinel1Annotation& annotation, int line);

// The calibration LUT A of a radiometry: sigmaNought, betaNought or gamma.
// Throws ConfigError (where = `option`) for kNone.
const Sentinel1LineVectors& Sentinel1CalibrationLut(const Sentinel1Calibration& calibration,
                                                    Sentinel1Radiometry radiometry, const std::string& option);

// One line of a LUT over samples [first_sample, first_sample + samples):
// element k equals lut.At(line, first_sample + k) (the same arithmetic, in one
// pass along the line), and noise.At(line, ...) for the noise.
std::vector<double> Sentinel1LutRow(const Sentinel1LineVectors& lut, double line, int first_sample, int samples);
std::vector<double> Sentinel1NoiseRow(const Sentinel1Noise& noise, double line, int first_sample, int samples);

// Calibrates the DN of `window` (row-major, window.pixels() values; NaN DN
// stay NaN): (|DN|^2 - N) / A^2 as float, A from `lut`, N from `noise` (none
// when null), NaN where |DN|^2 - N < 0. Only the LUT arithmetic: the no-data
// rules of DN 0 and valid windows are the reader's (Sentinel1Image). Throws
// InputError when dn.size() != window.pixels() or a LUT is empty.
std::vector<float> CalibrateSentinel1(const std::vector<std::complex<float>>& dn, const Sentinel1Window& window,
                                      const Sentinel1LineVectors& lut, const Sentinel1Noise* noise);

// The measurement TIFF of one swath and polarisation, open for reading.
// Reads are serialised (one GDAL handle); the object may be shared between
// threads.
class Sentinel1Measurement {
 public:
  // Opens product.root/entry.measurement_file. Throws InputError naming the
  // file ("NAME.SAFE/measurement/....tiff") when the manifest lists no
  // measurement for the entry, when the file does not exist ("measurement file
  // does not exist": the Python door's FileNotFoundError), when GDAL cannot
  // open it, when it has no band or its data type is not complex int16 (SLC)
  // or uint16 (GRD), or when its size differs from the annotation's
  // numberOfSamples x numberOfLines (naming those elements).
  Sentinel1Measurement(const Sentinel1Product& product, const Sentinel1Entry& entry,
                       const Sentinel1Annotation& annotation);
  ~Sentinel1Measurement();
  Sentinel1Measurement(Sentinel1Measurement&&) noexcept;
  Sentinel1Measurement& operator=(Sentinel1Measurement&&) noexcept;

  const std::string& file() const;  // "NAME.SAFE/measurement/....tiff"
  bool is_complex() const;          // SLC
  int lines() const;
  int samples() const;
  // The DN of `window` as stored (a GRD's amplitude in the real part, 0
  // imaginary), no no-data rule applied. Throws InputError when the window is
  // not inside the image, IoError when GDAL fails to read it.
  std::vector<std::complex<float>> ReadDn(const Sentinel1Window& window) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct Sentinel1ImageOptions {
  std::string swath;         // "" = the first swath with an annotation (IW1, S3, IW for a GRD)
  std::string polarization;  // "" = the first polarisation present
  int burst = 0;             // 1-based; 0 = the whole swath
  Sentinel1Radiometry radiometry = Sentinel1Radiometry::kNone;
  bool remove_noise = false;  // needs a radiometry
};

// One swath and polarisation of a SAFE (optionally one burst), its
// annotation, the LUTs its radiometry needs, and its measurement, open for
// reading windows of the image.
class Sentinel1Image {
 public:
  // Throws InputError "product does not exist" (path) for a path that is not
  // there, whatever OpenSentinel1, Sentinel1Product::Entry (--swath,
  // --polarization), Sentinel1BurstWindow (--burst), the annotation readers
  // and Sentinel1Measurement throw; InputError "... does not exist (the
  // manifest lists it)" naming the file when the calibration or noise
  // annotation needed is missing from the SAFE; ConfigError naming
  // --noise-removal when noise removal is asked without a radiometry.
  static Sentinel1Image Open(const std::filesystem::path& path, const Sentinel1ImageOptions& options);

  const Sentinel1Product& product() const { return product_; }
  const Sentinel1Entry& entry() const { return entry_; }
  const Sentinel1Annotation& annotation() const { return annotation_; }
  const Sentinel1ImageOptions& options() const { return options_; }
  const Sentinel1Measurement& measurement() const { return *measurement_; }
  // The calibration and noise read (null when the options do not need them).
  const Sentinel1Calibration* calibration() const { return calibration_ ? &*calibration_ : nullptr; }
  const Sentinel1Noise* noise() const { return noise_ ? &*noise_ : nullptr; }
  // The burst's window, or the whole swath.
  const Sentinel1Window& window() const { return window_; }

  // `w` (measurement numbering, inside window()) with the no-data rules
  // applied: the complex DN (radiometry none), or as floats the amplitude |DN|
  // (radiometry none) or the calibrated power (the options' radiometry).
  // Throws InputError when `w` is outside window(), IoError when GDAL fails.
  std::vector<std::complex<float>> ReadDn(const Sentinel1Window& w) const;
  std::vector<float> ReadFloat(const Sentinel1Window& w) const;

 private:
  Sentinel1Image() = default;
  Sentinel1Product product_;
  Sentinel1Entry entry_;
  Sentinel1Annotation annotation_;
  Sentinel1ImageOptions options_;
  Sentinel1Window window_;
  std::optional<Sentinel1Calibration> calibration_;
  std::optional<Sentinel1Noise> noise_;
  std::shared_ptr<Sentinel1Measurement> measurement_;
};

}  // namespace gissar::geo
