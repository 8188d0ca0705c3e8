#include "gissar/geo/sentinel1_measurement.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <mutex>
#include <optional>

#include <cpl_vsi.h>
#include <gdal.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

bool VsiExists(const std::string& path) {
  VSIStatBufL st;
  return VSIStatL(path.c_str(), &st) == 0;
}

// Values of the piecewise-linear y(x) (clamped to the end values beyond x) at
// first, first + 1, ..., first + n - 1: the arithmetic of
// Sentinel1LineVectors::At along one vector, walking x once.
void InterpolateRow(const std::vector<int>& x, const std::vector<double>& y, int first, int n, double* out) {
  size_t k = 1;
  for (int i = 0; i < n; ++i) {
    const double at = double(first) + i;
    if (at <= x.front()) {
      out[i] = y.front();
    } else if (at >= x.back()) {
      out[i] = y.back();
    } else {
      while (x[k] <= at) ++k;  // x[k-1] <= at < x[k]
      const double w = (at - x[k - 1]) / double(x[k] - x[k - 1]);
      out[i] = (1.0 - w) * y[k - 1] + w * y[k];
    }
  }
}

double InterpolateAt(const std::vector<int>& x, const std::vector<double>& y, double at) {
  double v = 0.0;
  if (at <= x.front()) return y.front();
  if (at >= x.back()) return y.back();
  const size_t k = static_cast<size_t>(std::upper_bound(x.begin(), x.end(), at) - x.begin());
  const double w = (at - x[k - 1]) / double(x[k] - x[k - 1]);
  v = (1.0 - w) * y[k - 1] + w * y[k];
  return v;
}

void CheckWindow(const Sentinel1Window& outer, const Sentinel1Window& w, const std::string& where) {
  if (w.lines < 0 || w.samples < 0 || !outer.Contains(w)) {
    throw InputError("window of " + std::to_string(w.lines) + " lines x " + std::to_string(w.samples) +
                         " samples at line " + std::to_string(w.first_line) + ", sample " +
                         std::to_string(w.first_sample) + " is outside lines " + std::to_string(outer.first_line) +
                         "-" + std::to_string(outer.first_line + outer.lines - 1) + ", samples " +
                         std::to_string(outer.first_sample) + "-" +
                         std::to_string(outer.first_sample + outer.samples - 1),
                     where);
  }
}

}  // namespace

Sentinel1Radiometry ParseSentinel1Radiometry(const std::string& text, const std::string& option) {
  const std::optional<Sentinel1Radiometry> found = kSentinel1Radiometries.Find(text);
  if (!found) throw ConfigError(kSentinel1Radiometries.UnknownMessage(text) + " (none: the DN)", option);
  return *found;
}

const char* ToString(Sentinel1Radiometry radiometry) {
  // The table's names are string literals: data() is NUL-terminated.
  return kSentinel1Radiometries.Name(radiometry).data();
}

bool Sentinel1Window::Contains(const Sentinel1Window& w) const {
  return w.first_line >= first_line && w.first_sample >= first_sample &&
         int64_t(w.first_line) + w.lines <= int64_t(first_line) + lines &&
         int64_t(w.first_sample) + w.samples <= int64_t(first_sample) + samples;
}

Sentinel1Window Sentinel1SwathWindow(const Sentinel1Annotation& a) {
  return {0, 0, a.number_of_lines, a.number_of_samples};
}

Sentinel1Window Sentinel1BurstWindow(const Sentinel1Annotation& a, int number) {
  const Sentinel1Burst& b = a.Burst(number);
  return {b.first_line, 0, a.lines_per_burst, a.number_of_samples};
}

bool Sentinel1SampleValid(const Sentinel1Annotation& a, int line, int sample) {
  if (a.bursts.empty() || a.lines_per_burst <= 0) return true;
  if (line < 0) return false;
  const size_t b = size_t(line / a.lines_per_burst);
  if (b >= a.bursts.size()) return false;
  const size_t k = size_t(line % a.lines_per_burst);
  const Sentinel1Burst& burst = a.bursts[b];
  const int first = burst.first_valid_sample[k], last = burst.last_valid_sample[k];
  return first >= 0 && sample >= first && sample <= last;
}

double Sentinel1LineTime(const Sentinel1Annotation& a, int line) {
  if (a.bursts.empty() || a.lines_per_burst <= 0) return a.first_line_time_s + line * a.azimuth_time_interval_s;
  const int b = std::clamp(line / a.lines_per_burst, 0, int(a.bursts.size()) - 1);
  return a.bursts[size_t(b)].azimuth_time_s + (line - b * a.lines_per_burst) * a.azimuth_time_interval_s;
}

const Sentinel1LineVectors& Sentinel1CalibrationLut(const Sentinel1Calibration& c, Sentinel1Radiometry r,
                                                    const std::string& option) {
  switch (r) {
    case Sentinel1Radiometry::kSigma0: return c.sigma0;
    case Sentinel1Radiometry::kBeta0: return c.beta0;
    case Sentinel1Radiometry::kGamma0: return c.gamma0;
    case Sentinel1Radiometry::kNone: break;
  }
  throw ConfigError("no calibration LUT for radiometry 'none'", option);
}

std::vector<double> Sentinel1LutRow(const Sentinel1LineVectors& lut, double line, int first_sample, int samples) {
  if (lut.line.empty()) throw InputError("empty look-up table", "Sentinel1LineVectors");
  std::vector<double> out(size_t(std::max(samples, 0)));
  if (samples <= 0) return out;
  const size_t n = lut.line.size();
  if (n == 1 || line <= lut.line.front()) {
    InterpolateRow(lut.pixel.front(), lut.values.front(), first_sample, samples, out.data());
    return out;
  }
  if (line >= lut.line.back()) {
    InterpolateRow(lut.pixel.back(), lut.values.back(), first_sample, samples, out.data());
    return out;
  }
  const size_t k = static_cast<size_t>(std::upper_bound(lut.line.begin(), lut.line.end(), line) - lut.line.begin());
  std::vector<double> b(out.size());
  InterpolateRow(lut.pixel[k - 1], lut.values[k - 1], first_sample, samples, out.data());
  InterpolateRow(lut.pixel[k], lut.values[k], first_sample, samples, b.data());
  const double span = double(lut.line[k] - lut.line[k - 1]);
  const double w = span > 0.0 ? (line - lut.line[k - 1]) / span : 1.0;
  for (size_t i = 0; i < out.size(); ++i) out[i] = (1.0 - w) * out[i] + w * b[i];
  return out;
}

std::vector<double> Sentinel1NoiseRow(const Sentinel1Noise& noise, double line, int first_sample, int samples) {
  std::vector<double> out = noise.range.line.empty() ? std::vector<double>(size_t(std::max(samples, 0)), 1.0)
                                                     : Sentinel1LutRow(noise.range, line, first_sample, samples);
  // The first block holding (line, sample) scales it, as Sentinel1Noise::At.
  std::vector<char> done(out.size(), 0);
  for (const Sentinel1NoiseAzimuthBlock& b : noise.azimuth) {
    if (b.line.empty() || line < b.first_azimuth_line || line > b.last_azimuth_line) continue;
    const double factor = InterpolateAt(b.line, b.values, line);
    const int lo = std::max(first_sample, b.first_range_sample);
    const int hi = std::min(first_sample + samples - 1, b.last_range_sample);
    for (int s = lo; s <= hi; ++s) {
      const size_t i = size_t(s - first_sample);
      if (done[i]) continue;
      out[i] *= factor;
      done[i] = 1;
    }
  }
  return out;
}

std::vector<float> CalibrateSentinel1(const std::vector<std::complex<float>>& dn, const Sentinel1Window& window,
                                      const Sentinel1LineVectors& lut, const Sentinel1Noise* noise) {
  if (int64_t(dn.size()) != window.pixels()) {
    throw InputError(std::to_string(dn.size()) + " values for a window of " + std::to_string(window.pixels()) +
                         " pixels",
                     "CalibrateSentinel1");
  }
  if (lut.line.empty()) throw InputError("empty look-up table", "CalibrateSentinel1");
  std::vector<float> out(dn.size());
  const int grain = std::max(1, 65536 / std::max(1, window.samples));
  tbb::parallel_for(tbb::blocked_range<int>(0, window.lines, grain), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r != rows.end(); ++r) {
      const double line = double(window.first_line) + r;
      const std::vector<double> a = Sentinel1LutRow(lut, line, window.first_sample, window.samples);
      std::vector<double> n;
      if (noise != nullptr) n = Sentinel1NoiseRow(*noise, line, window.first_sample, window.samples);
      const size_t row = size_t(r) * size_t(window.samples);
      for (size_t c = 0; c < size_t(window.samples); ++c) {
        const std::complex<float> v = dn[row + c];
        const double power = double(v.real()) * v.real() + double(v.imag()) * v.imag();
        const double signal = noise != nullptr ? power - n[c] : power;
        out[row + c] = signal < 0.0 ? kNaN : static_cast<float>(signal / (a[c] * a[c]));
      }
    }
  });
  return out;
}

// ------------------------------------------------------------ the TIFF

struct Sentinel1Measurement::Impl {
  std::string file;
  GDALDatasetH dataset = nullptr;
  bool complex = false;
  int lines = 0, samples = 0;
  std::mutex mutex;
  ~Impl() {
    if (dataset != nullptr) GDALClose(dataset);
  }
};

Sentinel1Measurement::Sentinel1Measurement(const Sentinel1Product& product, const Sentinel1Entry& entry,
                                           const Sentinel1Annotation& annotation)
    : impl_(std::make_unique<Impl>()) {
  EnsureGdal();
  if (entry.measurement_file.empty()) {
    throw InputError("the manifest lists no measurement for " + entry.swath + "/" + entry.polarization,
                     product.name + "/manifest.safe: dataObjectSection");
  }
  impl_->file = product.name + "/" + entry.measurement_file;
  const std::string path = product.root + "/" + entry.measurement_file;
  if (!VsiExists(path)) {
    throw InputError("measurement file does not exist (the manifest lists it; this SAFE lacks it)", impl_->file);
  }
  impl_->dataset = GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr);
  if (impl_->dataset == nullptr) {
    throw InputError("GDAL cannot open the measurement: " + LastGdalMessage(), impl_->file);
  }
  if (GDALGetRasterCount(impl_->dataset) < 1) throw InputError("the measurement has no band", impl_->file);
  const GDALDataType type = GDALGetRasterDataType(GDALGetRasterBand(impl_->dataset, 1));
  impl_->complex = !annotation.is_grd();
  const GDALDataType expected = impl_->complex ? GDT_CInt16 : GDT_UInt16;
  if (type != expected) {
    throw InputError(std::string("data type ") + GDALGetDataTypeName(type) + ", expected " +
                         GDALGetDataTypeName(expected) + " for a" + (impl_->complex ? "n SLC" : " GRD"),
                     impl_->file);
  }
  impl_->samples = GDALGetRasterXSize(impl_->dataset);
  impl_->lines = GDALGetRasterYSize(impl_->dataset);
  if (impl_->samples != annotation.number_of_samples || impl_->lines != annotation.number_of_lines) {
    throw InputError("the measurement is " + std::to_string(impl_->samples) + " x " + std::to_string(impl_->lines) +
                         " samples x lines, the annotation states " + std::to_string(annotation.number_of_samples) +
                         " x " + std::to_string(annotation.number_of_lines),
                     impl_->file + " (" + annotation.file +
                         ": imageAnnotation/imageInformation/numberOfSamples, numberOfLines)");
  }
}

Sentinel1Measurement::~Sentinel1Measurement() = default;
Sentinel1Measurement::Sentinel1Measurement(Sentinel1Measurement&&) noexcept = default;
Sentinel1Measurement& Sentinel1Measurement::operator=(Sentinel1Measurement&&) noexcept = default;

const std::string& Sentinel1Measurement::file() const { return impl_->file; }
bool Sentinel1Measurement::is_complex() const { return impl_->complex; }
int Sentinel1Measurement::lines() const { return impl_->lines; }
int Sentinel1Measurement::samples() const { return impl_->samples; }

std::vector<std::complex<float>> Sentinel1Measurement::ReadDn(const Sentinel1Window& w) const {
  CheckWindow({0, 0, impl_->lines, impl_->samples}, w, impl_->file);
  std::vector<std::complex<float>> out(size_t(w.pixels()));
  if (out.empty()) return out;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const CPLErr err = GDALRasterIO(GDALGetRasterBand(impl_->dataset, 1), GF_Read, w.first_sample, w.first_line,
                                  w.samples, w.lines, out.data(), w.samples, w.lines, GDT_CFloat32, 0, 0);
  if (err != CE_None) throw IoError("cannot read the measurement: " + LastGdalMessage(), impl_->file);
  return out;
}

// ------------------------------------------------------------ the image

Sentinel1Image Sentinel1Image::Open(const fs::path& path, const Sentinel1ImageOptions& options) {
  EnsureGdal();
  if (path.empty() || !VsiExists(path.string())) throw InputError("product does not exist", path.string());
  Sentinel1Image image;
  image.options_ = options;
  image.product_ = OpenSentinel1(path);
  image.entry_ = image.product_.Entry(options.swath, options.polarization);
  image.annotation_ = ReadSentinel1Annotation(image.product_, image.entry_);
  image.window_ = options.burst != 0 ? Sentinel1BurstWindow(image.annotation_, options.burst)
                                     : Sentinel1SwathWindow(image.annotation_);
  if (options.remove_noise && options.radiometry == Sentinel1Radiometry::kNone) {
    throw ConfigError("thermal noise removal needs a radiometry (sigma0, beta0 or gamma0)", "--noise-removal");
  }
  image.measurement_ = std::make_shared<Sentinel1Measurement>(image.product_, image.entry_, image.annotation_);
  const auto require = [&](const std::string& file, const char* what) {
    if (file.empty()) {
      throw InputError(std::string("the manifest lists no ") + what + " for " + image.entry_.swath + "/" +
                           image.entry_.polarization,
                       image.product_.name + "/manifest.safe: dataObjectSection");
    }
    if (!VsiExists(image.product_.root + "/" + file)) {
      throw InputError(std::string(what) + " does not exist (the manifest lists it; this SAFE lacks it)",
                       image.product_.name + "/" + file);
    }
  };
  if (options.radiometry != Sentinel1Radiometry::kNone) {
    require(image.entry_.calibration_file, "calibration annotation");
    image.calibration_ = ReadSentinel1Calibration(image.product_, image.entry_);
  }
  if (options.remove_noise) {
    require(image.entry_.noise_file, "noise annotation");
    image.noise_ = ReadSentinel1Noise(image.product_, image.entry_);
  }
  return image;
}

std::vector<std::complex<float>> Sentinel1Image::ReadDn(const Sentinel1Window& w) const {
  CheckWindow(window_, w, measurement_->file());
  std::vector<std::complex<float>> dn = measurement_->ReadDn(w);
  const std::complex<float> nodata(kNaN, kNaN);
  const bool bursts = !annotation_.bursts.empty();
  for (int r = 0; r < w.lines; ++r) {
    std::complex<float>* row = dn.data() + size_t(r) * size_t(w.samples);
    const int line = w.first_line + r;
    for (int c = 0; c < w.samples; ++c) {
      if (row[c] == std::complex<float>(0.0f, 0.0f) ||
          (bursts && !Sentinel1SampleValid(annotation_, line, w.first_sample + c))) {
        row[c] = nodata;
      }
    }
  }
  return dn;
}

std::vector<float> Sentinel1Image::ReadFloat(const Sentinel1Window& w) const {
  const std::vector<std::complex<float>> dn = ReadDn(w);
  if (options_.radiometry == Sentinel1Radiometry::kNone) {
    std::vector<float> out(dn.size());
    for (size_t i = 0; i < dn.size(); ++i) out[i] = std::isnan(dn[i].real()) ? kNaN : std::abs(dn[i]);
    return out;
  }
  return CalibrateSentinel1(dn, w, Sentinel1CalibrationLut(*calibration_, options_.radiometry, "--radiometry"),
                            noise());
}

}  // namespace gissar::geo
