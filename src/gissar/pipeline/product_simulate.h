// Simulation in the geometry of a real SAR product (`gissar simulate
// --product`) and its validation against the real image and a peer's
// geolocation (`gissar validate`). See docs/geometry.md ("Real sensor
// geometry") and render/product_renderer.h for the design.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/util/reporter.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/render/product_renderer.h"

namespace gissar::pipeline {

struct Sentinel1Source;  // sentinel1_simulate.h

// The radar geometry a product simulation renders on: options.product (a
// NISAR RSLC of band options.frequency, its amplitude read with
// `read_amplitude`; or a Sentinel-1 SAFE: ReadSentinel1Source's grid, no
// image) or options.orbit with options.radar_grid (geo::ProductFromOrbit,
// polarisation options.polarization), checked against
// options.max_memory_bytes, cut to options.product_window_px when set
// (ConfigError naming --product-window when it leaves the grid; before
// reading a NISAR product, ConfigError naming --product/--orbit, --swath,
// --burst or --frequency for a selection it cannot have). Throws the
// gissar::Error family.
geo::RslcProduct ReadProductGeometry(const SimulateRequest& options, bool read_amplitude,
                                     Reporter& reporter = NullReporter());

// The product's radar grid (times, ranges, look side, wavelength).
sensor::RadarGrid RadarGridOf(const geo::RslcProduct& product);

// The impulse response's 3 dB resolutions of a product simulation (range:
// slant metres; azimuth: metres along the ground at the scene) and where
// each comes from: the request's value when it sets one (source
// "--range-resolution" / "--azimuth-resolution"; 0 = none); else the
// product's processed bandwidth where it states one (RslcProduct::
// processed_range_bandwidth_hz, _azimuth_; source "processedRangeBandwidth" /
// "processedAzimuthBandwidth"): the 3 dB width of the request's spectral
// window over that band, image::UnitHalfPowerWidth(window) c / (2 B_r) and
// image::UnitHalfPowerWidth(window) v_ground / B_az (0.886 c / (2 B_r) with
// no window); else none (0, source "none").
struct ProductResolutions {
  double range_m = 0.0, azimuth_m = 0.0;
  std::string range_source = "none", azimuth_source = "none";
  double range_bandwidth_hz = 0.0, azimuth_bandwidth_hz = 0.0;  // the product's, when used (else 0)
};
ProductResolutions ResolveProductResolutions(const SimulateRequest& options, const geo::RslcProduct& product,
                                             double ground_speed_mps);

// A product simulated in memory: the product (with its real amplitude when
// read), the terrain description and the rendered image and geolocation.
struct ProductSimulation {
  geo::RslcProduct product;
  sensor::RadarGrid grid;
  render::ProductImage image;
  // The channels rendered (SimulateRequest::polarization) in output order:
  // image.image is channels[0], other_channels[i] channels[i + 1] (same
  // grid, mask and ground points). One channel: other_channels is empty.
  std::vector<material::Polarization> channels;
  std::vector<render::SarImage> other_channels;
  nlohmann::json terrain;       // Terrain::description
  nlohmann::json frame;         // local frame origin
  double ground_speed_mps = 0;  // azimuth pixel spacing / line time
  ProductResolutions resolutions;  // of the impulse response applied
  // A Sentinel-1 SAFE's selection and grids (sentinel1_simulate.h); null for
  // NISAR products and orbit files. For a GRD, `image` is the slant-range
  // rendering of sentinel1->grid until ResampleToGroundRange.
  std::shared_ptr<const Sentinel1Source> sentinel1;
};

// The GRD step: resamples a simulation rendered on source.grid (slant range)
// onto the GRD's ground-range pixels of source.window: for line i, pixel j,
// ground range G = (window[1] + j) x ground_spacing_m, slant range R =
// grsr(G) with the record nearest to the line's time, and every band
// (intensity, bounce layers, each further channel, lon/lat/height) taken
// linearly between the two slant samples around R (NaN when either is NaN
// or R lies outside the grid); mask and footprint from the nearer sample;
// reflector returns' columns moved to their ground-range pixels. Linear
// (not dB) values. sim.grid keeps the slant grid rendered.
void ResampleToGroundRange(const Sentinel1Source& source, ProductSimulation& sim);

// Loads options.product and the terrain, renders the product grid and
// applies the sensor effects. Incoherent: the intensity impulse response,
// speckle, the reflectors' intensity responses, then per pixel the
// conversion from beta0 (ellipsoid incidence of the pixel's ground point),
// thermal noise and dB. Coherent (options.coherent): the complex image of
// render::RenderProduct convolved with the amplitude impulse response of
// ResolveProductResolutions (--range-resolution / --azimuth-resolution, or
// the product's processed bandwidths; on the product's pixel spacings), the reflectors added as phasors exp(-j 4 pi R / lambda) (R
// their geo2rdr range) with the same response, no simulated speckle (the
// phasors make it), then per pixel the conversion from beta0 (complex
// planes by the square root of the factor), complex thermal noise on the
// total and detection (image.intensity and bounce_layers the detected power
// of the complex total and layers). Throws the gissar::Error family.
//
// `real` says whether and how the real image is read into
// product.amplitude (the square root of its calibrated power, 0 where
// no-data), before anything is rendered.
struct RealImageOptions {
  bool read = false;
  // A Sentinel-1 SAFE: the LUT the real image is calibrated with
  // (ReadSentinel1Calibrated; "sigma0", "beta0" or "gamma0", ConfigError
  // naming --radiometry otherwise) and whether the thermal noise LUTs are
  // subtracted (InputError naming --noise-removal when no pixel is left).
  // A NISAR RSLC's |s|^2 is read as stored (beta0) whatever these say: its
  // callers refuse other values (ValidateRequest::Check).
  std::string radiometry = "beta0";
  bool remove_noise = false;
};
ProductSimulation SimulateProduct(const SimulateRequest& options, const RealImageOptions& real,
                                  Reporter& reporter = NullReporter());
// The same with the real image in beta0, no noise removal (read_amplitude),
// or none.
ProductSimulation SimulateProduct(const SimulateRequest& options, bool read_amplitude,
                                  Reporter& reporter = NullReporter());

// `gissar simulate --product`: writes PREFIX.tif (bands total, single,
// double, triple, four_or_more, lon_deg, lat_deg, height_m on exactly the
// product's grid), PREFIX_mask.tif, PREFIX.png and PREFIX.json; in coherent
// mode also PREFIX_slc.tif (CFloat32: total, single, double, triple,
// four_or_more, |z|^2 in the output radiometry, linear; GEOLOCATION arrays
// = the longitude and latitude bands of PREFIX.tif by its absolute path, and up to 8 x 8 GCPs),
// which `gissar pta --image`
// measures on the product's own grid. Several channels: PREFIX.tif and
// PREFIX_slc.tif hold each channel's total, then each channel's bounce
// bands (SlcBands), and a coherent run with HH, VV and HV or VH also writes
// PREFIX_pauli.png (WritePauliQuicklook), as `gissar simulate` does. The
// sidecar's impulse_response records the resolutions and their sources.
SimulateResult RunProductSimulate(const SimulateRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

struct ValidateRequest {
  SimulateRequest simulate;                // product, dem/scene, datum, rays, bounces, quiet
  // The quantity compared (--radiometry; simulate.radiometry is not read):
  // the real image calibrated to it and the simulation converted to it from
  // beta0 with each pixel's ellipsoid incidence. "beta0" (the default: a
  // NISAR RSLC's |s|^2 is beta0), "sigma0" or "gamma0" (a Sentinel-1 product
  // only: its sigmaNought or gamma LUT).
  std::string radiometry = "beta0";
  // --noise-removal: a Sentinel-1 product's thermal noise LUTs subtracted
  // from the real image (|DN|^2 - N; NaN where negative).
  bool noise_removal = false;
  // --polarization of a Sentinel-1 product: the channel simulated and
  // compared (with terrain; "" = simulate.polarization), or the one checked
  // against the geolocation grids (without; "" = every one present).
  std::string polarization;
  std::string reference_geolocation;       // directory with x.rdr, y.rdr, z.rdr (optional)
  std::vector<int> looks = {1, 3, 5};      // k of the k x k multilooks
  std::string out_prefix;                  // REPORT.json, .md, _side_by_side.png, _histogram.png

  // Throws ConfigError naming the option (product and terrain required,
  // looks in [1, 64], outputs not overwriting inputs, a radiometry of
  // image::kRadiometries; with a NISAR product --radiometry other than beta0
  // and --noise-removal).
  void Check() const;
  nlohmann::json ToJson() const;
};

struct ValidateResult {
  std::vector<std::filesystem::path> outputs;
  nlohmann::json report;
};

// Pearson correlation of two equally sized images after k x k block
// averaging (non-overlapping blocks, partial edge blocks dropped), over the
// blocks where both block means are finite and `valid` (when non-empty)
// holds for every pixel; with `db_a` / `db_b` that image's block means are
// compared in dB (10 log10; blocks with a non-positive mean are skipped).
// Returns NaN with fewer than 3 blocks or a constant image. `blocks`
// receives the number of blocks used.
double MultilookPearson(const std::vector<float>& a, const std::vector<float>& b, int width, int height, int k,
                        bool db_a, bool db_b, const std::vector<uint8_t>& valid = {}, int64_t* blocks = nullptr);

// `gissar validate`: simulates the product, compares with the real
// image in options.radiometry (and the reference geolocation and peer
// simulation when given) and writes the report files; the report's
// "radiometry" and "real_image" state the quantity, the LUT and the noise
// removal.
ValidateResult RunValidate(const ValidateRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
