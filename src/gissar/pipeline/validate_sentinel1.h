// `gissar validate --product S1.SAFE` without terrain: the geometry proof of
// a Sentinel-1 product on its own annotations. For every point of the
// geolocation grid of every swath and polarisation, gissar's range-Doppler
// solution is compared with what ESA's processor annotated:
//  - geo2rdr (sensor::Geo2Rdr) of the point's (latitude, longitude, height)
//    with the annotation orbit (or an EOF file's) against the point's
//    azimuthTime and slantRangeTime, in pixels: azimuth in lines
//    (azimuthTimeInterval; within a burst for IW/EW SLC, the same thing since
//    a burst's lines are spaced by that interval), range in slant-range
//    samples (c / 2 fs) for SLC and in ground-range pixels for GRD (both
//    slant ranges taken to ground range with the product's srgr polynomials);
//  - rdr2geo (sensor::Rdr2Geo) at the point's azimuthTime, slantRangeTime
//    and height against its latitude and longitude, horizontal metres.
// See docs/sentinel1.md for the measured figures.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/geo/sentinel1_safe.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

// Agreement of one swath/polarisation's geolocation grid. Differences are
// gissar minus annotation: range and azimuth in pixels, ground in metres.
struct GeolocationGridAgreement {
  std::string swath, polarization, product_type;
  std::string orbit_source;      // "annotation" or the orbit file
  int points = 0;                // grid points compared
  int failures = 0;              // points where geo2rdr or rdr2geo found no solution
  double range_rms_px = 0.0, range_max_px = 0.0;    // max of |difference|
  double azimuth_rms_px = 0.0, azimuth_max_px = 0.0;
  double ground_rms_m = 0.0, ground_max_m = 0.0;    // horizontal distance
  double range_mean_px = 0.0, azimuth_mean_px = 0.0;  // signed means (biases)
  // Informative, not part of the pass criteria: gissar's image line and
  // pixel of the point against the grid's `line` and `pixel` numbers (IW/EW
  // SLC: line = first line of the burst holding the grid line + (time -
  // burst azimuthTime) / azimuthTimeInterval; otherwise from the first line;
  // GRD pixel = ground range / rangePixelSpacing). The annotated azimuth
  // times are not on whole lines (up to ~0.14 line off in these products),
  // so these figures mix gissar's error with the grid's own rounding.
  double line_rms_px = 0.0, line_max_px = 0.0, pixel_rms_px = 0.0, pixel_max_px = 0.0;
  // {"points", "failures", "range_px": {"rms", "max", "mean"}, "azimuth_px":
  //  {...}, "ground_m": {"rms", "max"}, "image_px": {"line": {"rms", "max"},
  //  "pixel": {...}}}.
  nlohmann::json ToJson() const;
};

// Runs the comparison on one annotation (its orbit as it stands: replace it
// first with geo::ReplaceSentinel1Orbit to check an EOF). Throws InputError
// naming the annotation file when its orbit cannot be interpolated.
GeolocationGridAgreement CheckGeolocationGrid(const geo::Sentinel1Annotation& annotation,
                                              const std::string& orbit_source = "annotation");

// Pass thresholds of the geometry proof (issue 48).
inline constexpr double kGridRmsMaxPx = 0.1;
inline constexpr double kGridMaxMaxPx = 0.25;
inline constexpr double kGridGroundMaxM = 1.0;

struct Sentinel1ValidateRequest {
  std::string product;       // SAFE directory, its manifest.safe or a .zip
  std::string orbit;         // optional state vectors (EOF, CSV, JSON) replacing the annotations'
  std::string swath;         // "" = every swath present
  std::string polarization;  // "" = every polarisation present
  std::string out_prefix;    // writes PREFIX.json
  // Throws ConfigError naming the option (product and --out required,
  // outputs not overwriting inputs).
  void Check() const;
  nlohmann::json ToJson() const;
};

struct Sentinel1ValidateResult {
  std::vector<std::filesystem::path> outputs;
  nlohmann::json report;
};

// Reads the product, checks every selected swath/polarisation whose
// annotation the SAFE holds (annotations the manifest lists but the SAFE
// lacks are named in "absent_annotations"; selected explicitly with --swath
// and --polarization they are an error) and writes PREFIX.json:
// {"product", "mission", "mode", "product_type", "orbit", "geolocation_grid"
// (all points pooled), "swaths": [{"swath", "polarization", "product_type",
// "geolocation_grid"}], "thresholds", "passed"}. Nothing is written on error.
// Throws the gissar::Error family (InputError for the product and orbit,
// ConfigError for options).
Sentinel1ValidateResult RunSentinel1Validate(const Sentinel1ValidateRequest& request, const std::string& command_line,
                                             Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
