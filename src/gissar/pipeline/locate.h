// `gissar locate`, `gissar evaluate` and `gissar matchpair`: automatic
// positioning from one SAR image (issue 7), its Monte-Carlo evaluation, and
// the matcher's warp recovery on real image pairs. The algorithms live in
// gissar/nav; these functions load the inputs and write the outputs (all
// through AtomicOutputs, with provenance). Errors: the gissar::Error family.
// Here: the requests and the path of a scene or DEM terrain (simulated or
// given images over the terrain). Callers go through the door (locate_door.h),
// which sends a request with a product or a track to product_locate.h.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/util/memory_limit.h"
#include "gissar/util/reporter.h"
#include "gissar/nav/locate.h"

namespace gissar::pipeline {

// locate refuses a prior whose slant range differs from the image's
// GISSAR_SLANT_RANGE_M by more than this fraction of it.
inline constexpr double kMaxPriorRangeMismatch = 0.10;

// Prior/result pose JSON (keys; any other key is a ConfigError naming the
// key and the file):
//   "heading_deg"      flight direction, degrees clockwise from north (required)
//   "slant_range_m"    measured slant range to the image centre (required)
//   and either "sensor_enu_m": [x, y, z]   INS sensor position (depression and
//                                           centre derived on the scene surface)
//   or "depression_deg" plus "centre_enu_m": [x, y, z] or "centre_lonlat": [lon, lat]
// A result written by `locate` also holds these keys (sensor_enu_m and the
// centre), so it can be fed back as a prior.
struct PriorPose {
  double heading_deg = 0.0;
  double slant_range_m = 0.0;
  std::optional<Eigen::Vector3d> sensor_enu;
  std::optional<double> depression_deg;
  std::optional<Eigen::Vector3d> centre_enu;
  std::optional<Eigen::Vector2d> centre_lonlat;
};
PriorPose ParsePriorJson(const nlohmann::json& json, const std::string& source);

// The fields locate and evaluate share (each request's table gives their
// flags and help): the real product fixed, its looks, the terrain's options
// and the reference database.
struct ProductFixFields {
  // A real product instead of --image/--prior (docs/navigation.md "Real
  // images"): the observed image is the RSLC's detected layer (frequency,
  // polarization), multilooked looks_azimuth x looks_range.
  std::string product;
  std::string frequency = "A";
  std::string polarization = "HH";
  // A Sentinel-1 SLC --product (a SAFE; pipeline/sentinel1_simulate.h): the
  // swath ("" = the only one), the burst (1-based; required for an IW/EW
  // SLC) and the window of the burst or swath fixed (LINE, PIXEL, LINES,
  // PIXELS in its own numbering; unset = all of it). The observed image is
  // beta0 = |DN|^2 / betaNought^2. Refused with another product.
  std::string swath;
  int burst = 0;
  std::optional<std::array<int, 4>> product_window_px;
  int looks_range = 3;
  int looks_azimuth = 3;
  int dem_oversample = 1;
  // Point landmarks (docs/navigation.md "Landmarks where the terrain is
  // flat"): a reflectors CSV (docs/conventions.md "Reflectors"), placed on
  // the terrain as `simulate --reflectors` places them, rendered in the
  // references; where one falls in the image it drives the fix (along and
  // cross track; up and heading from the prior). With a product or an orbit
  // only; none of them in the image (on the annotated track) is an
  // InputError naming the file.
  std::string reflectors;
  // The terrain's sea (docs/conventions.md): "auto" or "off" (a flat DEM
  // at the ellipsoid below the geoid would otherwise be sea).
  std::string sea = "auto";
  // The terrain's absolute horizontal error, one sigma per axis, metres
  // (nav::ProductLocateOptions::terrain_horizontal_sigma_m): added to a
  // relief fix's along/cross variance. Default: SRTM-class 1" DEMs, whose
  // absolute geolocation error is 7.2-12.6 m at 90 % by continent
  // (Rodriguez et al. 2006), i.e. about 6 m per axis at the worst.
  double terrain_horizontal_sigma_m = 6.0;
  // Memory budget of the terrain (DEM posts, scene file), bytes
  // (SimulateRequest::max_memory_bytes; the CLI's --max-memory/--force).
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();
  // A reference database (docs/navigation.md "Fixes from a reference
  // database"): a corridor's PREFIX_catalog.json built from the same
  // --dem/--scene (SHA-256 checked). The fix matches the observed image
  // against the stored reference that covers the prior (warped to the pose,
  // no rendering) and resects with its geometry. No covering reference:
  // database_fallback "none" = no fix (exit 3 with the reason), "render" =
  // the fix renders its references on the fly. locate: with --image/--prior
  // only; evaluate: see EvaluateRequest::database_fixes.
  std::string database;
  std::string database_fallback = "none";
  double database_heading_tolerance_deg = 10.0;  // largest prior-to-reference heading difference
};

struct LocateRequest : ProductFixFields {
  std::string image;   // observed image: GeoTIFF (band 1 linear intensity) with GISSAR_* metadata
  std::string scene;   // .gscene (or a DEM with --dem)
  std::string dem;
  std::string vertical_datum;  // of --dem's heights ("" = from the file; SimulateRequest::vertical_datum)
  std::string prior;   // prior pose JSON
  std::string out;     // result JSON
  // Optional picture: the observed image (green) over the simulation
  // (magenta) at the prior (left) and at the fix (right).
  std::string composite_png;
  // Pixel spacings (0: the image's GISSAR_*_SPACING_M metadata).
  double range_spacing_m = 0.0;
  double azimuth_spacing_m = 0.0;
  std::string look = "";  // "" = metadata, else right/left
  std::string matcher = "ncc";
  int search_px = 28;  // first-iteration search radius: the prior's uncertainty in pixels
  int step_px = 12;    // grid step of the matched patches
  // Renders of the dense photometric stage after the patch iterations
  // (nav::LocateOptions::dense_renders; 0 = off).
  int dense_renders = 2;
  int polish_evaluations = 0;
  int bounces = 1;
  double rays_per_cell = 4.0;
  // Or, instead of a product (ProductFixFields::product), any sensor's track
  // (geo/orbit_file.h): state vectors (--orbit) and the radar grid
  // (--radar-grid) of the observed detected image given as --image (band 1
  // linear intensity, exactly width x length of the grid); fixed like a
  // product (the state vectors are the annotated truth).
  std::string orbit;
  std::string radar_grid;
  // With a product or a track: the prior is the annotated track moved by
  // prior_offset_track (along, cross, up; metres, in the frame of the
  // mid-scene velocity) and prior_heading_offset_deg; the references are
  // simulated on the product's zero-Doppler grid; the fix is the track
  // offset (nav/product_locate.h). prior_sigma_*: the INS's one-sigma errors
  // (regularisation and search).
  std::vector<double> prior_offset_track = {0.0, 0.0, 0.0};
  double prior_heading_offset_deg = 0.0;
  double prior_sigma_horizontal_m = 60.0;
  double prior_sigma_vertical_m = 10.0;
  double prior_sigma_heading_deg = 0.05;
  bool UsesTrack() const { return !product.empty() || !orbit.empty() || !radar_grid.empty(); }
  void Check() const;
  // The request as {snake_case field: value} (pipeline/locate_fields.cc).
  nlohmann::json ToJson() const;
  // Sets the fields named by `values` ({snake_case field: value}: the Python
  // keywords of gissar.locate_product; null keeps the default); an unknown key
  // or a wrong type is a ConfigError naming `source`.
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};
// A fix of --image from --prior over the terrain (--scene or --dem; with
// --database from its stored references): Check(), then writes options.out
// (the fix JSON: pose, errors in metres and degrees, matches, `seconds`) and
// the composite picture when asked, atomically; returns the JSON. A request
// with a product or a track (UsesTrack) goes through the door in
// locate_door.h (here: ConfigError).
nlohmann::json RunTerrainLocate(const LocateRequest& options, const std::string& command_line,
                                Reporter& reporter = NullReporter());

// Most Monte-Carlo trials one `evaluate` runs (each is a whole pose fix).
constexpr int kMaxTrials = 100000;

struct EvaluateRequest : ProductFixFields {
  std::string scene;
  std::string dem;
  std::string vertical_datum;  // of --dem's heights ("" = from the file; SimulateRequest::vertical_datum)
  int trials = 20;
  uint64_t seed = 1;
  std::string out_prefix;  // PREFIX.json, PREFIX_trials.csv, PREFIX_hist.png
  double spacing_m = 30.0;      // range and azimuth pixel spacing
  int size_px = 160;            // square image side
  double slant_range_m = 10000.0;
  double depression_min_deg = 35.0, depression_max_deg = 45.0;
  double speckle_looks = 4.0;
  double nesz_db = -25.0;
  double material_db = 3.0;     // +- per class diffuse/specular scale of the observed scene
  double dem_smoothing = 0.5;   // Laplacian weight on terrain vertex heights of the observed scene
  // INS prior errors, uniform +-: per horizontal axis, vertical, heading.
  // Negative = automatic: 200 m, 50 m, 3 deg on a scene; on a product
  // (FootprintPriorErrors, product_locate.h) scaled to its footprint.
  double prior_error_horizontal_m = -1.0, prior_error_vertical_m = -1.0, prior_error_heading_deg = -1.0;
  // Success (docs/conventions.md): converged, 3-D position error <= success_cells x cell and heading
  // error <= success_heading_deg.
  double success_cells = 2.0;
  double success_heading_deg = 0.2;
  std::string matcher = "ncc";
  bool compare_matchers = true;
  // First-iteration search radius in pixels; 0 = from the prior errors:
  // (sqrt(2) horizontal + R sin(heading) + vertical / tan(min depression)) / spacing + 4.
  int search_px = 0;
  int step_px = 12;  // grid step of the matched patches (more matches: better depression)
  // Renders of the dense photometric stage after the patch iterations
  // (nav::LocateOptions::dense_renders; 0 = off).
  int dense_renders = 2;
  int polish_evaluations = 0;
  int bounces = 1;
  double rays_per_cell = 4.0;
  // The reference images carry the observed image's noise floor (NESZ) as
  // nav::LocateOptions::reference_floor (--no-reference-floor: 1e-4).
  bool reference_floor = true;
  // A subset of the trials (EvaluateTrials, locate_door.h: for spreading them over
  // workers): trials trial_first .. trial_first + trial_count - 1 of the
  // `trials`; trial_count -1 = the rest (by default: all of them).
  int trial_first = 0;
  int trial_count = -1;
  // With a product (ProductFixFields::product) instead of simulated
  // observations, each trial displaces the product's annotated track by a
  // seeded prior error and fixes it (RunProductEvaluate). The image-shape
  // options (spacing, size, slant range, depression, looks, nesz, material,
  // smoothing) do not apply.
  // With a database (ProductFixFields::database), the trials' true poses are
  // drawn around its stored poses (a stored pose, heading and depression
  // +- 2 deg, image centre +- 15 % of the footprint along and across) with
  // its image size, pixel spacing, slant range and depression (Resolved()
  // takes them from the catalogue); database_fixes "stored" fixes them from
  // the stored references, "render" renders on the fly (the same observed
  // images and priors: the comparison of docs/navigation.md).
  std::string database_fixes = "stored";
  void Check() const;
  // The request with automatic (negative) prior errors replaced by the
  // scene defaults (200 m, 50 m, 3 deg); product requests are returned as
  // they are (RunProductEvaluate resolves them from the footprint). With a
  // database: spacing_m, size_px, slant_range_m and the depression range
  // from its catalogue (InputError naming the catalogue when unreadable).
  EvaluateRequest Resolved() const;
  // {snake_case field: value} and back (the Python keywords; unknown key or
  // wrong type: ConfigError naming `source`; pipeline/evaluate_fields.cc).
  // ApplyJson(ToJson()) is the identity.
  nlohmann::json ToJson() const;
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};
// The Monte-Carlo evaluation over a scene or DEM terrain: each trial renders
// an observed image at a seeded true pose and fixes it from a prior drawn
// around it. A request with a product goes through the door in
// locate_door.h (here: ConfigError).
//
// The whole run: Check(), TerrainEvaluateTrials (every trial unless
// trial_first/trial_count pick some), then WriteTerrainEvaluation; returns
// the summary JSON (also written to PREFIX.json).
nlohmann::json RunTerrainEvaluate(const EvaluateRequest& options, const std::string& command_line,
                                  Reporter& reporter = NullReporter());

// The per-trial records of trials trial_first .. (see EvaluateRequest),
// nothing written; Check() first. Trial k's randomness depends only on
// (seed, k): any split of the trials over processes gives the records of the
// serial run (up to `seconds`, the time a fix took). A record: trial,
// success, converged, position_error_m, position_error_cells,
// horizontal_error_m, heading_error_deg, depression_error_deg (absolute),
// seconds, matchers (per compared matcher: raw, inliers, good,
// median_error_px), csv_row (the PREFIX_trials.csv line).
std::vector<nlohmann::json> TerrainEvaluateTrials(const EvaluateRequest& options, Reporter& reporter = NullReporter());
// The summary statistics of a set of trial records (any order; a repeated
// trial is a ConfigError): the keys of RunTerrainEvaluate's summary from
// "trials" to "matcher_comparison_first_iteration" (success_rate,
// position_error_m median/p95, ...), identical to the serial run's for the
// same records.
nlohmann::json TerrainSummariseTrials(const EvaluateRequest& options, const std::vector<nlohmann::json>& records);
// Check(), then writes PREFIX.json (TerrainSummariseTrials plus command,
// options, inputs, `seconds`), PREFIX_trials.csv (rows by trial) and
// PREFIX_hist.png from records, atomically; returns the summary.
// `vertical_datum`: the record of the DEM's datum (null: the option as given).
nlohmann::json WriteTerrainEvaluation(const EvaluateRequest& options, const std::vector<nlohmann::json>& records,
                                      const std::string& command_line, double seconds,
                                      const nlohmann::json& vertical_datum = nullptr);

struct MatchPairRequest {
  std::string fixed, moving;  // two co-registered images (GDAL), band 1 linear intensity
  std::vector<double> warp = {1.5, 1.02, 3.3, -2.7};  // rotation deg, scale, tx px, ty px (about the centre)
  std::string out;            // JSON
  int patch_px = 21, step_px = 6, search_px = 12, filter_px = 3;
  void Check() const;
};
// Warps `moving` by the known affine map, matches `fixed` to it with every
// matcher, fits an affine map (RANSAC) and reports the RMS difference to the
// known warp over all pixels. Returns the JSON written to `out`.
nlohmann::json RunMatchPair(const MatchPairRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
