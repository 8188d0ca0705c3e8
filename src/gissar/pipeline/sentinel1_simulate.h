// `gissar simulate --product S1.SAFE`: simulation in the geometry of a
// Sentinel-1 Level-1 product (geo/sentinel1_safe.h), through the same path
// as a NISAR product (pipeline/product_simulate.h): the SAFE's annotation is
// turned into a zero-Doppler radar grid with its orbit (a geo::RslcProduct
// without image), which render::RenderProduct renders like any product grid.
//
//  - IW/EW SLC: one burst (--burst N, 1-based per swath; required: a swath is
//    never simulated as one image, its bursts overlap in time) in its own grid:
//    line k at the burst's azimuthTime + k x azimuthTimeInterval, sample j at
//    slant range c/2 x slantRangeTime + j x c / (2 x rangeSamplingRate),
//    linesPerBurst x samplesPerBurst (the whole burst, invalid margins
//    included: they are recorded, not cut).
//  - SM SLC: the whole swath grid (productFirstLineUtcTime, numberOfLines x
//    numberOfSamples).
//  - GRD: rendered on a slant-range grid with the GRD's own lines (same
//    azimuth times) and slant samples of c / (2 fs) covering its ground-range
//    pixels, then resampled to those pixels (product_simulate.h,
//    ResampleToGroundRange) with the
//    product's grsr polynomials: the record nearest in time of each line, as
//    geo::Sentinel1Annotation::SlantRangeOfGroundRange (docs/sentinel1.md
//    says why not interpolated), linear in slant range.
// --product-window LINE,PIXEL,LINES,PIXELS renders a part of that grid (in
// the product's own numbering: the burst's lines, the GRD's lines and ground
// pixels); --orbit FILE replaces the annotation's orbit
// (geo::ReplaceSentinel1Orbit). No real image is read or written: the
// measurement TIFFs are not opened here.
#pragma once

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/geo/rslc_product.h"
#include "gissar/geo/sentinel1_measurement.h"
#include "gissar/geo/sentinel1_safe.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

struct SimulateRequest;

// True when options.product names a Sentinel-1 SAFE (geo::IsSentinel1Path).
bool IsSentinel1Request(const SimulateRequest& options);

// The Sentinel-1 geometry a simulation renders on and writes.
struct Sentinel1Source {
  geo::Sentinel1Product product;        // the manifest
  geo::Sentinel1Annotation annotation;  // the swath/polarisation read (orbit replaced with --orbit)
  std::string orbit_source = "annotation";  // or the --orbit file
  int burst = 0;  // 1-based; 0 for a SM SLC or a GRD
  // The output grid: first line, first pixel, lines, pixels, in the
  // product's own numbering (IW/EW SLC: lines of the burst, 0 = its first
  // line, and its range samples; SM SLC: the swath's; GRD: its lines and
  // ground-range pixels), i.e. --product-window or the whole burst/swath/GRD.
  std::array<int, 4> window{0, 0, 0, 0};
  std::array<int, 2> full_size{0, 0};  // lines, pixels of the whole burst / swath / GRD
  bool ground_range = false;           // GRD: output in ground range
  double ground_spacing_m = 0.0;       // GRD: rangePixelSpacing
  // The zero-Doppler slant-range grid rendered, with the orbit: for an SLC
  // exactly the output grid; for a GRD the window's lines and the slant
  // samples that cover its pixels.
  geo::RslcProduct grid;
  // Where the impulse response's bandwidths came from ("processingBandwidth
  // of IW1", "lookBandwidth of IW2 (the middle swath of the GRD)", or "").
  std::string bandwidth_source;

  // The sidecar's "sentinel1" record: product id, mission, mode, product
  // type, swath, polarisation, burst (and its azimuth time, valid lines and
  // samples), the output grid and window, the orbit source, the range
  // conversion rule of a GRD and the note that no real image is written.
  nlohmann::json ToJson() const;
};

// What of a SAFE a command reads: the request fields a Sentinel-1 source
// takes (simulate's, pta's, ...), named as their flags.
struct Sentinel1Selection {
  std::string product;       // --product: the SAFE (directory, manifest.safe or .zip)
  std::string swath;         // --swath: "" = the product's only swath
  std::string polarization;  // --polarization: a channel list (material::ParsePolarizationList)
  int burst = 0;             // --burst: 1-based; required for an IW/EW SLC, refused otherwise
  std::string orbit;         // --orbit: state vectors replacing the annotation's ("" = keep them)
  std::optional<std::array<int, 4>> window_px;  // --product-window LINE,PIXEL,LINES,PIXELS
  bool coherent = false;     // --coherent: refused for a GRD
  std::string command = "simulate";  // what the progress lines start with
};
Sentinel1Selection Sentinel1SelectionOf(const SimulateRequest& options);

// Reads the SAFE of options.product for options.swath / burst /
// polarization (the first channel of the list; every channel must have an
// annotation in the swath), replaces the orbit with options.orbit when set
// and builds the grids of options.product_window_px (or the whole
// burst/swath/GRD). Throws InputError naming --swath, --burst or
// --polarization (and the annotation file) for a swath, burst or
// polarisation the product lacks, a burst asked of a GRD or stripmap
// product, or an IW/EW SLC without --burst (listing its bursts); ConfigError
// naming --product-window for a window outside the grid or --coherent for a
// GRD (a detected product).
Sentinel1Source ReadSentinel1Source(const Sentinel1Selection& options, Reporter& reporter = NullReporter());
// The selection of a simulation request; also ConfigError naming
// --product/--radar-grid or --frequency (a SAFE fixes its grid and has no
// frequency band), before anything is read.
Sentinel1Source ReadSentinel1Source(const SimulateRequest& options, Reporter& reporter = NullReporter());

// The real image of source.window, calibrated to `radiometry` (sigma0,
// beta0 or gamma0: linear power (|DN|^2 - N) / A^2, A the sigmaNought,
// betaNought or gamma LUT, N = 0, or with `remove_noise` the thermal noise
// power (noiseRangeLut, times noiseAzimuthLut where the noise annotation has
// one); both bilinear in line and pixel as
// ESA specifies; geo::Sentinel1Image): window lines x pixels, row-major, in
// the product's own numbering (an IW/EW burst's lines, a GRD's ground-range
// pixels); NaN where the DN is 0, in a burst outside its valid samples, and
// with noise removal where |DN|^2 < N. Throws what
// geo::Sentinel1Image::Open throws (a missing measurement, calibration or
// noise file, named); ConfigError naming --radiometry for kNone; with
// `remove_noise`, InputError naming --noise-removal when no pixel of the
// window is left valid (the noise power above |DN|^2 everywhere).
std::vector<float> ReadSentinel1Calibrated(const Sentinel1Source& source, const std::string& product,
                                           geo::Sentinel1Radiometry radiometry, bool remove_noise);
// An RslcProduct amplitude layer from linear power: sqrt, 0 where the power
// is NaN or not positive (the amplitude's no-data).
std::vector<float> AmplitudeOfPower(const std::vector<float>& power);
// ReadSentinel1Calibrated in beta0 without noise removal (the observed image
// of locate/evaluate, the real image of a Python simulate_product).
inline std::vector<float> ReadSentinel1Beta0(const Sentinel1Source& source, const std::string& product) {
  return ReadSentinel1Calibrated(source, product, geo::Sentinel1Radiometry::kBeta0, false);
}

// The sidecar's input record of the SAFE: "path" (absolute, what --product
// takes again), the bytes and SHA-256 of the .zip, or of manifest.safe for a
// directory ("hashed": which file), and the annotation read.
nlohmann::json Sentinel1InputRecord(const Sentinel1Source& source);
// The input record of a --product: ProductInputRecord's SAFE record (without
// the annotation) for a SAFE, InputFileRecord for a file (a NISAR HDF5).
nlohmann::json ProductInputRecord(const std::string& product);

// GeoTIFF metadata of a Sentinel-1 simulation: GISSAR_SENTINEL1_PRODUCT,
// _SWATH, _BURST, _POLARIZATION, _GRID (numbering and window) and
// GISSAR_REAL_IMAGE (none); for a GRD, GISSAR_GEOMETRY describes the
// ground-range grid, GISSAR_FIRST_GROUND_RANGE_M and
// GISSAR_GROUND_RANGE_SPACING_M replace the slant-range keys.
void AddSentinel1Metadata(const Sentinel1Source& source, std::map<std::string, std::string>& metadata);

// Parses --product-window "LINE,PIXEL,LINES,PIXELS" (integers; first line and
// pixel >= 0, at least 2 lines and 2 pixels). Throws ConfigError naming the
// flag.
std::array<int, 4> ParseProductWindow(const std::string& text);
// ParseProductWindow as a request field's JSON value (request_fields.h's
// TextReader of the product_window_px rows).
nlohmann::json ProductWindowJson(const std::string& text, const std::string& flag);

}  // namespace gissar::pipeline
