#include "gissar/pipeline/sentinel1_simulate.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>

#include "gissar/geo/orbit_file.h"
#include "gissar/geo/sentinel1_measurement.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"
#include "gissar/util/utc_time.h"

namespace gissar::pipeline {

namespace {

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string Join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

}  // namespace

bool IsSentinel1Request(const SimulateRequest& options) {
  return !options.product.empty() && geo::IsSentinel1Path(options.product);
}

std::array<int, 4> ParseProductWindow(const std::string& text) {
  std::array<int, 4> w{};
  std::istringstream in(text);
  char comma = 0;
  std::string rest;
  bool ok = static_cast<bool>(in >> w[0]);
  for (int k = 1; k < 4 && ok; ++k) ok = (in >> comma >> w[k]) && comma == ',';
  if (!ok || (in >> rest) || w[0] < 0 || w[1] < 0 || w[2] < 2 || w[3] < 2) {
    throw ConfigError("expected LINE,PIXEL,LINES,PIXELS (integers; LINE, PIXEL >= 0, at least 2 lines and 2 pixels), "
                      "got '" + text + "'",
                      "--product-window");
  }
  return w;
}

std::vector<float> AmplitudeOfPower(const std::vector<float>& power) {
  std::vector<float> amplitude(power.size());
  for (size_t k = 0; k < power.size(); ++k) {
    amplitude[k] = std::isfinite(power[k]) && power[k] > 0.0f ? std::sqrt(power[k]) : 0.0f;
  }
  return amplitude;
}

nlohmann::json ProductWindowJson(const std::string& text, const std::string&) {
  return nlohmann::json(ParseProductWindow(text));
}

Sentinel1Selection Sentinel1SelectionOf(const SimulateRequest& options) {
  Sentinel1Selection s;
  s.product = options.product;
  s.swath = options.swath;
  s.polarization = options.polarization;
  s.burst = options.burst;
  s.orbit = options.orbit;
  s.window_px = options.product_window_px;
  s.coherent = options.coherent;
  return s;
}

Sentinel1Source ReadSentinel1Source(const SimulateRequest& options, Reporter& reporter) {
  // A SAFE fixes its grid; --orbit replaces its annotation's orbit.
  if (!options.radar_grid.empty()) {
    throw ConfigError("a Sentinel-1 product fixes the radar grid", "--product/--radar-grid");
  }
  if (!options.frequency.empty()) {
    throw ConfigError("a Sentinel-1 product has no frequency band (A/B are NISAR's): choose with --swath and "
                      "--polarization",
                      "--frequency");
  }
  return ReadSentinel1Source(Sentinel1SelectionOf(options), reporter);
}

namespace {

// The swath: --swath, or the product's only one ("" then: Entry finds it).
std::string SelectedSwath(const geo::Sentinel1Product& product, const Sentinel1Selection& options) {
  std::string swath = Upper(options.swath);
  if (swath.empty()) {
    std::vector<std::string> swaths;
    for (const geo::Sentinel1Entry& e : product.entries) {
      if (std::find(swaths.begin(), swaths.end(), e.swath) == swaths.end()) swaths.push_back(e.swath);
    }
    if (swaths.size() > 1) {
      throw InputError(product.name + " has swaths " + Join(swaths) + ": give one with --swath", "--swath");
    }
  }
  return swath;
}

// The first channel's annotation gives the geometry (every polarisation
// of a swath has the same); each channel must be a polarisation of it.
// Throws InputError naming what is present when an annotation is missing.
const geo::Sentinel1Entry& GeometryEntry(const geo::Sentinel1Product& product, const std::string& swath,
                                         const std::vector<material::Polarization>& channels) {
  const geo::Sentinel1Entry& entry = product.Entry(swath, material::ToString(channels.front()));
  for (const material::Polarization c : channels) {
    const geo::Sentinel1Entry& other = product.Entry(entry.swath, material::ToString(c));
    if (&other != &entry && !other.annotation_present) {
      throw InputError("the SAFE lacks the annotation of " + other.swath + "/" + other.polarization + " (" +
                           other.annotation_file + ")",
                       "--polarization");
    }
  }
  if (!entry.annotation_present) {
    std::string present;
    for (const geo::Sentinel1Entry& e : product.entries) {
      if (e.annotation_present) present += (present.empty() ? "" : ", ") + e.swath + "/" + e.polarization;
    }
    throw InputError("the SAFE lacks the annotation of " + entry.swath + "/" + entry.polarization + " (" +
                         entry.annotation_file + "); it has annotations for " +
                         (present.empty() ? std::string("none") : present),
                     "--swath/--polarization (" + product.name + ")");
  }
  return entry;
}

// --orbit's state vectors in place of the annotation's.
void ReplaceOrbit(Sentinel1Source& s, const Sentinel1Selection& options, Reporter& reporter) {
  geo::Sentinel1Annotation& a = s.annotation;
  const geo::StateVectors vectors = geo::ReadStateVectors(options.orbit);
  geo::ReplaceSentinel1Orbit(a, s.product, vectors, options.orbit);
  s.orbit_source = options.orbit;
  reporter.Info(options.command + ": orbit: " + std::to_string(a.orbit.time_s.size()) + " state vectors of " + options.orbit +
                " (" + vectors.format + ") replace the annotation's");
}

// The full grid in the product's own numbering: its first line's time and
// its size.
struct FullGrid {
  double first_time_s = 0.0;
  int lines = 0, pixels = 0;
};

// The burst (IW/EW SLC: --burst, required; sets s.burst) or the whole
// swath / GRD (--burst refused).
FullGrid SelectBurst(Sentinel1Source& s, const Sentinel1Selection& options) {
  const geo::Sentinel1Annotation& a = s.annotation;
  FullGrid full{a.first_line_time_s, a.number_of_lines, a.number_of_samples};
  if (!a.bursts.empty()) {
    if (options.burst == 0) {
      throw InputError("an " + a.mode + " SLC swath is simulated one burst at a time: give --burst N (" + a.swath +
                           " has bursts 1-" + std::to_string(a.bursts.size()) + ")",
                       "--burst (" + a.file + ")");
    }
    const geo::Sentinel1Burst& b = a.Burst(options.burst);
    s.burst = b.number;
    full.first_time_s = b.azimuth_time_s;
    full.lines = a.lines_per_burst;
    full.pixels = a.samples_per_burst > 0 ? a.samples_per_burst : a.number_of_samples;
  } else if (options.burst != 0) {
    a.Burst(options.burst);  // throws: a GRD or stripmap product has no bursts
  }
  return full;
}

// Throws ConfigError naming --product-window when s.window leaves the grid.
void CheckWindow(const Sentinel1Source& s, const FullGrid& full, const std::string& grid_name) {
  const std::array<int, 4>& w = s.window;
  const int lines = full.lines, pixels = full.pixels;
  if (int64_t(w[0]) + w[2] > lines || int64_t(w[1]) + w[3] > pixels) {
    throw ConfigError("window of lines " + std::to_string(w[0]) + "+" + std::to_string(w[2]) + ", pixels " +
                          std::to_string(w[1]) + "+" + std::to_string(w[3]) + " outside " + grid_name + " (" +
                          std::to_string(lines) + " lines x " + std::to_string(pixels) + " pixels, " +
                          s.annotation.file + ")",
                      "--product-window");
  }
}

// The window's slant ranges: an SLC's own samples; a GRD's slant samples
// covering the window's ground-range pixels on every line (grsr increases
// with ground range), two samples of margin each side.
void RangeSamples(Sentinel1Source& s) {
  const geo::Sentinel1Annotation& a = s.annotation;
  const std::array<int, 4>& w = s.window;
  const double dr = a.slant_range_spacing_m();
  geo::RslcProduct& g = s.grid;
  if (!s.ground_range) {
    const double r_first = a.SlantRangeOfTime(a.slant_range_time_s);
    g.slant_range_m.resize(size_t(w[3]));
    for (int j = 0; j < w[3]; ++j) g.slant_range_m[size_t(j)] = r_first + double(w[1] + j) * dr;
    return;
  }
  s.ground_spacing_m = a.range_pixel_spacing_m;
  const double g_first = double(w[1]) * s.ground_spacing_m, g_last = double(w[1] + w[3] - 1) * s.ground_spacing_m;
  double r_lo = std::numeric_limits<double>::infinity(), r_hi = -r_lo;
  for (const double t : g.zero_doppler_time_s) {
    r_lo = std::min(r_lo, a.SlantRangeOfGroundRange(g_first, t));
    r_hi = std::max(r_hi, a.SlantRangeOfGroundRange(g_last, t));
  }
  const double r0 = r_lo - 2.0 * dr;
  const int cols = static_cast<int>(std::ceil((r_hi - r0) / dr)) + 3;
  g.slant_range_m.resize(size_t(cols));
  for (int j = 0; j < cols; ++j) g.slant_range_m[size_t(j)] = r0 + double(j) * dr;
}

// The zero-Doppler slant-range grid rendered (s.grid): the product's
// identity and polarisations, the window's line times and range samples,
// the radar's frequency, look side and orbit.
void FillRadarGrid(Sentinel1Source& s, const Sentinel1Selection& options, const geo::Sentinel1Entry& entry,
                   double first_time_s) {
  const geo::Sentinel1Product& product = s.product;
  const geo::Sentinel1Annotation& a = s.annotation;
  const std::array<int, 4>& w = s.window;
  const double dt = a.azimuth_time_interval_s;
  geo::RslcProduct& g = s.grid;
  g.path = options.product;
  g.mission = a.mission;
  g.product_version = product.name;
  g.epoch_utc = product.epoch_utc.substr(0, 19);
  if (g.epoch_utc.size() > 10) g.epoch_utc[10] = ' ';
  g.frequency = "";
  g.polarization = a.polarization;
  for (const char* pol : {"HH", "HV", "VH", "VV"}) {
    for (const geo::Sentinel1Entry& e : product.entries) {
      if (e.swath != entry.swath || e.polarization != pol) continue;
      g.polarizations.push_back(pol);
      if (e.annotation_present) g.stored_polarizations.push_back(pol);
    }
  }
  g.zero_doppler_time_s.resize(size_t(w[2]));
  for (int i = 0; i < w[2]; ++i) g.zero_doppler_time_s[size_t(i)] = first_time_s + double(w[0] + i) * dt;
  RangeSamples(s);
  g.center_frequency_hz = a.radar_frequency_hz;
  g.wavelength_m = a.wavelength_m;
  g.look_left = a.look_left;
  g.orbit = a.orbit;
  if (s.orbit_source == "annotation") g.orbit.type = "annotation (" + a.file + ")";
}

// The impulse response's bands: an SLC's processing bandwidths, a GRD's
// look bandwidths (one look's band sets the resolution of the multilooked
// image) of its middle swath.
void SetImpulseBandwidths(Sentinel1Source& s) {
  const geo::Sentinel1Annotation& a = s.annotation;
  geo::RslcProduct& g = s.grid;
  if (a.processing.empty()) return;
  if (s.ground_range) {
    const geo::Sentinel1SwathProcessing& p = a.processing[a.processing.size() / 2];
    g.processed_range_bandwidth_hz = p.range_look_bandwidth_hz;
    g.processed_azimuth_bandwidth_hz = p.azimuth_look_bandwidth_hz;
    s.bandwidth_source = "lookBandwidth of " + p.swath + " (the middle swath of the GRD; " +
                         std::to_string(p.range_looks) + " x " + std::to_string(p.azimuth_looks) +
                         " range x azimuth looks)";
  } else {
    const auto it = std::find_if(a.processing.begin(), a.processing.end(),
                                 [&](const geo::Sentinel1SwathProcessing& p) { return p.swath == a.swath; });
    const geo::Sentinel1SwathProcessing& p = it != a.processing.end() ? *it : a.processing.front();
    g.processed_range_bandwidth_hz = p.range_processing_bandwidth_hz;
    g.processed_azimuth_bandwidth_hz = p.azimuth_processing_bandwidth_hz;
    s.bandwidth_source = "processingBandwidth of " + p.swath;
  }
}

}  // namespace

Sentinel1Source ReadSentinel1Source(const Sentinel1Selection& options, Reporter& reporter) {
  Sentinel1Source s;
  s.product = geo::OpenSentinel1(options.product);
  const std::vector<material::Polarization> channels =
      material::ParsePolarizationList(options.polarization, "--polarization");
  const geo::Sentinel1Entry& entry = GeometryEntry(s.product, SelectedSwath(s.product, options), channels);
  s.annotation = geo::ReadSentinel1Annotation(s.product, entry);
  const geo::Sentinel1Annotation& a = s.annotation;
  if (!options.orbit.empty()) ReplaceOrbit(s, options, reporter);
  s.ground_range = a.is_grd();
  if (s.ground_range && options.coherent) {
    throw ConfigError("a GRD is a detected, multilooked product: simulate it without --coherent (or simulate the SLC)",
                      "--coherent");
  }

  // Burst (IW/EW SLC) and the full grid in the product's own numbering; the window of it rendered.
  const FullGrid full = SelectBurst(s, options);
  s.full_size = {full.lines, full.pixels};
  s.window = options.window_px ? *options.window_px : std::array<int, 4>{0, 0, full.lines, full.pixels};
  const std::array<int, 4>& w = s.window;
  const std::string grid_name = s.burst > 0 ? "burst " + std::to_string(s.burst) + " of " + a.swath
                                            : (s.ground_range ? "GRD " : "swath ") + a.swath;
  CheckWindow(s, full, grid_name);

  FillRadarGrid(s, options, entry, full.first_time_s);
  SetImpulseBandwidths(s);
  reporter.Info(options.command + ": " + s.product.name + ": " + grid_name + " " + a.polarization + ", lines " +
                std::to_string(w[0]) + "-" + std::to_string(w[0] + w[2] - 1) + ", pixels " + std::to_string(w[1]) +
                "-" + std::to_string(w[1] + w[3] - 1) +
                (s.ground_range ? " (ground range; rendered on " + std::to_string(s.grid.slant_range_m.size()) +
                                      " slant samples)"
                                : std::string()));
  return s;
}

nlohmann::json Sentinel1Source::ToJson() const {
  const geo::Sentinel1Annotation& a = annotation;
  auto utc = [&](double t) { return FormatUtc(product.epoch_unix_s + t); };
  nlohmann::json j = {{"product", product.name},
                      {"mission", product.mission},
                      {"mode", product.mode},
                      {"product_type", a.product_type},
                      {"swath", a.swath},
                      {"polarization", a.polarization},
                      {"annotation", a.file},
                      {"burst", burst > 0 ? nlohmann::json(burst) : nlohmann::json(nullptr)},
                      {"orbit", {{"source", orbit_source}, {"state_vectors", a.orbit.time_s.size()}}}};
  const double dt = a.azimuth_time_interval_s;
  double first_time_s = a.first_line_time_s;
  if (burst > 0) {
    const geo::Sentinel1Burst& b = a.bursts[size_t(burst - 1)];
    first_time_s = b.azimuth_time_s;
    int first_valid = -1, last_valid = std::numeric_limits<int>::max();
    for (int k = std::max(0, b.first_valid_line); k <= b.last_valid_line; ++k) {
      first_valid = std::max(first_valid, b.first_valid_sample[size_t(k)]);
      last_valid = std::min(last_valid, b.last_valid_sample[size_t(k)]);
    }
    j["burst_azimuth_time_utc"] = utc(b.azimuth_time_s);
    j["burst_first_line_in_measurement"] = b.first_line;
    j["valid_lines"] = b.first_valid_line >= 0 ? nlohmann::json{b.first_valid_line, b.last_valid_line}
                                                : nlohmann::json(nullptr);
    j["valid_samples"] = b.first_valid_line >= 0 ? nlohmann::json{first_valid, last_valid} : nlohmann::json(nullptr);
    j["valid_note"] = "the whole burst grid is simulated; lines and samples outside valid_lines / valid_samples "
                      "(annotation firstValidSample/lastValidSample, the samples valid on every valid line) are "
                      "invalid in the real burst";
  }
  nlohmann::json grid = {
      {"numbering", burst > 0       ? "lines of the burst (0 = its first line) and its range samples"
                    : ground_range ? "lines and ground-range pixels of the GRD"
                                   : "lines and range samples of the swath"},
      {"lines", full_size[0]},
      {"pixels", full_size[1]},
      {"window", {{"first_line", window[0]}, {"first_pixel", window[1]}, {"lines", window[2]}, {"pixels", window[3]}}},
      {"first_line_time_utc", utc(first_time_s + double(window[0]) * dt)},
      {"azimuth_time_interval_s", dt},
      {"slant_range_sample_spacing_m", a.slant_range_spacing_m()}};
  if (ground_range) {
    grid["ground_range_spacing_m"] = ground_spacing_m;
    grid["first_ground_range_m"] = double(window[1]) * ground_spacing_m;
    j["ground_range"] = {
        {"rendered_slant_grid",
         {{"lines", this->grid.rows()},
          {"samples", this->grid.cols()},
          {"first_slant_range_m", this->grid.slant_range_m.front()},
          {"slant_range_spacing_m", a.slant_range_spacing_m()}}},
        {"conversion",
         "pixel p of line i: ground range G = p x rangePixelSpacing, slant range = grsr(G) of the coordinateConversion "
         "record nearest in time to line i (as the annotated geolocation grid: docs/sentinel1.md), every band linear "
         "between the two slant samples around it (mask: the nearer); resampled before dB"},
        {"records", a.range_conversion.size()}};
  } else {
    grid["first_slant_range_m"] = this->grid.slant_range_m.front();
  }
  j["grid"] = grid;
  j["impulse_response_bandwidths"] =
      bandwidth_source.empty() ? nlohmann::json(nullptr) : nlohmann::json(bandwidth_source);
  j["real_image"] = "none: simulate does not read the SAFE's measurement TIFFs; only the simulated image is written";
  return j;
}

nlohmann::json ProductInputRecord(const std::string& product) {
  namespace fs = std::filesystem;
  if (!geo::IsSentinel1Path(product)) return InputFileRecord(product);
  const fs::path path(product);
  std::error_code ec;
  nlohmann::json record;
  if (fs::is_directory(path, ec)) {
    record = InputFileRecord(path / "manifest.safe");
    record["hashed"] = "manifest.safe";
  } else if (path.filename() == "manifest.safe") {
    record = InputFileRecord(path);
    record["hashed"] = "manifest.safe";
  } else {
    record = InputFileRecord(path);
    record["hashed"] = path.filename().string();
  }
  record["path"] = fs::absolute(path).lexically_normal().string();
  record["kind"] = "Sentinel-1 SAFE";
  return record;
}

nlohmann::json Sentinel1InputRecord(const Sentinel1Source& source) {
  nlohmann::json record = ProductInputRecord(source.product.path);
  record["annotation"] = source.annotation.file;
  return record;
}

void AddSentinel1Metadata(const Sentinel1Source& source, std::map<std::string, std::string>& m) {
  const geo::Sentinel1Annotation& a = source.annotation;
  const std::array<int, 4>& w = source.window;
  m["GISSAR_SENTINEL1_PRODUCT"] = source.product.name;
  m["GISSAR_SENTINEL1_SWATH"] = a.swath;
  m["GISSAR_SENTINEL1_POLARIZATION"] = a.polarization;
  if (source.burst > 0) m["GISSAR_SENTINEL1_BURST"] = std::to_string(source.burst);
  m["GISSAR_SENTINEL1_GRID"] =
      std::string(source.burst > 0       ? "burst lines and range samples"
                  : source.ground_range ? "GRD lines and ground-range pixels"
                                        : "swath lines and range samples") +
      "; this image is lines " + std::to_string(w[0]) + "-" + std::to_string(w[0] + w[2] - 1) + ", pixels " +
      std::to_string(w[1]) + "-" + std::to_string(w[1] + w[3] - 1) + " of " + std::to_string(source.full_size[0]) +
      " x " + std::to_string(source.full_size[1]);
  m["GISSAR_REAL_IMAGE"] = "none (the measurement is not read)";
  if (source.ground_range) {
    m["GISSAR_GEOMETRY"] = "Sentinel-1 GRD grid: row = zero-Doppler line, column = ground-range pixel (slant range by "
                           "the annotation's grsr polynomials, record nearest in time)";
    m.erase("GISSAR_FIRST_RANGE_M");
    m.erase("GISSAR_RANGE_SPACING_M");
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.6f", double(w[1]) * source.ground_spacing_m);
    m["GISSAR_FIRST_GROUND_RANGE_M"] = buffer;
    std::snprintf(buffer, sizeof buffer, "%.9g", source.ground_spacing_m);
    m["GISSAR_GROUND_RANGE_SPACING_M"] = buffer;
  }
}

std::vector<float> ReadSentinel1Calibrated(const Sentinel1Source& source, const std::string& product,
                                           geo::Sentinel1Radiometry radiometry, bool remove_noise) {
  if (radiometry == geo::Sentinel1Radiometry::kNone) {
    throw ConfigError("the real image is compared calibrated: give sigma0, beta0 or gamma0", "--radiometry");
  }
  geo::Sentinel1ImageOptions options;
  options.swath = source.annotation.swath;
  options.polarization = source.annotation.polarization;
  options.burst = source.burst;
  options.radiometry = radiometry;
  options.remove_noise = remove_noise;
  const geo::Sentinel1Image image = geo::Sentinel1Image::Open(product, options);
  const std::array<int, 4>& w = source.window;
  std::vector<float> values = image.ReadFloat({image.window().first_line + w[0], w[1], w[2], w[3]});
  if (remove_noise && std::none_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); })) {
    throw InputError("no valid real pixel after noise removal: at every pixel of the window |DN|^2 is below the "
                     "thermal noise power or the DN is no-data (lines " + std::to_string(w[0]) + "-" + std::to_string(w[0] + w[2] - 1) +
                         ", pixels " + std::to_string(w[1]) + "-" + std::to_string(w[1] + w[3] - 1) + " of " +
                         (source.burst > 0 ? "burst " + std::to_string(source.burst) + " of " : std::string()) +
                         source.annotation.swath + " " + source.annotation.polarization + ")",
                     "--noise-removal");
  }
  return values;
}


}  // namespace gissar::pipeline
