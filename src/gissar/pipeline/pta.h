// `gissar pta`: point-target analysis of the reflectors of a reflectors CSV
// in a complex image (docs/radiometry.md, "Point-target analysis" and "A
// real quad-pol corner reflector").
//
// For each CSV row: the apex (phase centre) is predicted in the image --
// a NISAR RSLC product (--product) through its orbit by zero-Doppler geo2rdr
// (row = zero-Doppler time on the product grid, column = slant range), a
// Sentinel-1 SLC the same way on its burst's (IW/EW) or swath's (stripmap)
// zero-Doppler grid, beta0 = |DN|^2 / betaNought^2 with ESA's LUT at the
// predicted pixel (only the window around the predictions is read), or
// the complex GeoTIFF of `gissar simulate --coherent` (--image PREFIX_slc.tif)
// through the simulation's own geometry (its GISSAR_* metadata) and terrain
// (its sidecar PREFIX.json) -- for a simulation on a real radar grid
// (`simulate --product/--orbit --coherent`) the apex is placed on that
// terrain and predicted by zero-Doppler geo2rdr on the orbit of the product
// (or orbit and radar grid) the sidecar names, and sigma0/gamma0 convert
// back to beta0 with the ellipsoid incidence at the reflector's ground
// point; the target is measured with
// image::MeasurePointTarget (peak, -3 dB widths, PSLR/ISLR, background-
// corrected energy -> RCS with the beta0 calibration the input states);
// the expected RCS is the physical-optics RCS of the reflector seen from
// the sensor at the radar wavelength (material::ReflectorRcs times the
// channel's share of material::ReflectorMatrix at roll 0). On a quad-pol
// input every channel is read at the measured channel's sub-pixel peak
// (image::InterpolateComplex) for the HH/VV ratio and phase and the
// cross-polarisation isolation.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/util/memory_limit.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

struct PtaRequest {
  // NISAR RSLC HDF5, or a Sentinel-1 SLC (SAFE directory, manifest.safe or
  // .zip; geo::IsSentinel1Path): an IW/EW burst or a stripmap swath, of
  // which only the window around the predicted reflectors is read.
  std::string product;
  std::string image;       // or PREFIX_slc.tif of `gissar simulate --coherent`
  std::string reflectors;  // reflectors CSV (material::ReadReflectorsCsv)
  std::string frequency = "A";  // product band (NISAR)
  // Sentinel-1 (pipeline/sentinel1_simulate.h, Sentinel1Selection): the
  // swath ("" = the only one), the burst (1-based; required for an IW/EW
  // SLC, refused otherwise) and state vectors replacing the annotation's.
  std::string swath;
  int burst = 0;
  std::string orbit;
  // Channel measured: HH, HV, VH or VV. "" = HH for a NISAR product, the
  // swath's first polarisation for a SAFE; for --image the band named so,
  // else the simulation's own polarisation (band 1).
  std::string polarization;
  // --product: ellipsoidal height (m) of the ground under the reflectors
  // (the apex lies apex_height_m above it); --image uses the simulation's
  // terrain instead.
  double ground_height_m = 0.0;
  int upsampling = 32;           // image::PointTargetOptions::upsampling
  double search_px = 8.0;        // search radius around the prediction, px
  int chip_half_size_px = 16;    // upsampled chip 2h x 2h; h = energy box half-size
  // A target is found when its brightest sample stands at least this far
  // above the background (mean |s|^2 of the energy box's corner boxes);
  // single-look clutter exceeds 10 dB above its mean in 1 sample of 22 000
  // and 15 dB in none of 10^13, but real clutter is not uniform: 30 lines
  // from the ALOS chip's reflector a clutter sample stands 10.6 dB above
  // its surroundings.
  double detection_threshold_db = 15.0;
  // PREFIX.json (the measurements) and PREFIX_irf.png (the cuts).
  std::string out_prefix;
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();

  // Throws ConfigError naming the flag for a missing or bad value (one of
  // --product / --image, --reflectors, --out, channel, upsampling 2..64,
  // search >= 0, chip half-size 4..256, detection threshold 0..100 dB,
  // --swath/--burst/--orbit only with a Sentinel-1 --product, burst >= 0,
  // outputs not overwriting inputs).
  void Check() const;
  nlohmann::json ToJson() const;
  // Keys of ToJson (the table of pipeline/pta_fields.cc; null keeps the
  // default); ConfigError naming the key and `source` otherwise.
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};

struct PtaResult {
  std::vector<std::filesystem::path> outputs;
  nlohmann::json report;  // what PREFIX.json holds
  int measured = 0;       // reflectors found and measured
  int total = 0;          // rows of the CSV
};

// Writes PREFIX.json and PREFIX_irf.png (all or nothing). A reflector that
// is predicted inside the image but not found (no peak above the
// background, edge, ...) is reported with "found": false and the reason, and
// a warning; when no reflector is found the report says "converged": false
// with the reason (the CLI's exit status 3). Throws InputError naming the
// CSV and row for a bad row or a reflector predicted outside the image (or
// off the simulation's terrain), InputError naming the input for an unknown
// or missing channel, a product without orbit, an image that is not a
// gissar complex image; ConfigError from Check().
PtaResult RunPta(const PtaRequest& request, const std::string& command_line, Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
