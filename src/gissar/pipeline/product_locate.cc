#include "gissar/pipeline/product_locate.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include <opencv2/imgproc.hpp>

#include "gissar/geo/orbit_file.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/geo/sentinel1_safe.h"
#include "gissar/image/composite.h"
#include "gissar/image/contact_sheet.h"
#include "gissar/image/radiometry.h"
#include "gissar/nav/product_locate.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/product_renderer.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"
#include "gissar/util/utc_time.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
namespace {

// Everything a product fix needs, loaded once per command.
struct ProductFix {
  geo::RslcProduct product;
  nav::ProductObservation observation;
  nav::TrackVectors truth;  // the product's annotated track
  Terrain terrain;
  std::unique_ptr<render::EmbreeScene> embree;
  std::vector<render::SceneReflector> landmarks;  // --reflectors placed on the terrain
  nav::NavScene scene;
};

struct ProductInputs {
  std::string product, frequency, polarization, scene, dem, vertical_datum;
  // A Sentinel-1 SAFE's selection (LocateRequest::swath, burst, product_window_px).
  std::string swath;
  int burst = 0;
  std::optional<std::array<int, 4>> window_px;
  std::string orbit, radar_grid, image;  // instead of the product (LocateRequest::orbit)
  int dem_oversample = 1;
  double rays_per_cell = 4.0;
  int bounces = 1;
  std::string reflectors, sea = "auto";
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();
};

// Throws InputError naming `csv` when no landmark falls in the observed
// image seen from the annotated track (zero-Doppler geo2rdr).
void CheckLandmarksInImage(const ProductFix& fix, const std::string& csv) {
  const sensor::RadarGrid& g = fix.observation.grid;
  const sensor::Orbit orbit = fix.truth.ToOrbit();
  const double t_mid = g.TimeOfRow(0.5 * (g.rows - 1));
  std::string nearest;
  double nearest_px = std::numeric_limits<double>::infinity();
  for (const render::SceneReflector& landmark : fix.landmarks) {
    const Eigen::Vector3d llh = fix.terrain.frame.GeodeticFromEnu(landmark.apex_enu);
    const auto rc = sensor::Geo2Rdr(orbit, geo::LocalFrame::EcefFromGeodetic(llh[0], llh[1], llh[2]), t_mid);
    if (!rc) continue;
    const double row = (rc->time_s - g.t0_s) / g.dt_s, col = (rc->range_m - g.r0_m) / g.dr_m;
    if (row >= 0.0 && row <= g.rows - 1.0 && col >= 0.0 && col <= g.cols - 1.0) return;
    const double outside = std::hypot(std::max({0.0, -col, col - (g.cols - 1.0)}),
                                      std::max({0.0, -row, row - (g.rows - 1.0)}));
    if (outside < nearest_px) {
      nearest_px = outside;
      char text[160];
      std::snprintf(text, sizeof text, "; nearest: row %d at range %.1f, azimuth %.1f px", landmark.row, col, row);
      nearest = text;
    }
  }
  throw InputError("none of its " + std::to_string(fix.landmarks.size()) + " reflectors falls in the image (" +
                       std::to_string(g.cols) + " x " + std::to_string(g.rows) + " px) seen from the annotated track" +
                       nearest,
                   csv);
}

// A Sentinel-1 SLC as an observed product: the selection's zero-Doppler grid
// and orbit (ReadSentinel1Source) with the real image calibrated to beta0 as
// its amplitude (sqrt; 0 where no data). A GRD is refused: the fix needs a
// slant-range grid.
geo::RslcProduct ReadSentinel1Observation(const ProductInputs& in, Reporter& reporter) {
  Sentinel1Selection selection;
  selection.product = in.product;
  selection.swath = in.swath;
  selection.polarization = in.polarization;
  selection.burst = in.burst;
  selection.window_px = in.window_px;
  selection.command = "locate";
  const Sentinel1Source source = ReadSentinel1Source(selection, reporter);
  if (source.ground_range) {
    throw InputError("a GRD is in ground range: a pose fix needs the SLC's slant-range grid",
                     "--product (" + source.product.name + ")");
  }
  geo::RslcProduct product = source.grid;
  product.amplitude = AmplitudeOfPower(ReadSentinel1Beta0(source, in.product));
  return product;
}

std::unique_ptr<ProductFix> LoadProductFix(const ProductInputs& in, Reporter& reporter) {
  auto fix = std::make_unique<ProductFix>();
  geo::RslcReadOptions read;
  read.frequency = in.frequency;
  read.polarization = in.polarization;
  read.read_amplitude = true;
  if (!in.product.empty() && geo::IsSentinel1Path(in.product)) {
    fix->product = ReadSentinel1Observation(in, reporter);
  } else if (!in.product.empty()) {
    fix->product = geo::ReadRslcProduct(in.product, read);
  } else {
    fix->product = geo::ProductFromOrbit(geo::ReadStateVectors(in.orbit), in.orbit, geo::ReadRadarGrid(in.radar_grid),
                                         in.radar_grid);
    const geo::FloatRaster image = geo::ReadFloatRaster(in.image);
    if (image.width != fix->product.cols() || image.height != fix->product.rows()) {
      throw InputError("the image is " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                           ", the radar grid " + std::to_string(fix->product.cols()) + " x " +
                           std::to_string(fix->product.rows()) + " (width x length)",
                       in.image);
    }
    fix->product.amplitude.resize(image.bands.at(0).size());
    for (size_t i = 0; i < image.bands[0].size(); ++i) {
      const float v = image.bands[0][i];
      fix->product.amplitude[i] = std::isfinite(v) && v > 0.0f ? std::sqrt(v) : 0.0f;
    }
  }
  const geo::RslcProduct& p = fix->product;
  fix->observation.grid = RadarGridOf(p);
  fix->observation.intensity.resize(p.amplitude.size());
  for (size_t i = 0; i < p.amplitude.size(); ++i) fix->observation.intensity[i] = p.amplitude[i] * p.amplitude[i];
  fix->truth = {p.orbit.time_s, p.orbit.position_m, p.orbit.velocity_mps};
  reporter.Info("locate: product " + std::to_string(p.rows()) + " lines x " + std::to_string(p.cols()) + " bins, " +
                p.frequency + " " + p.polarization);
  TerrainRequest terrain_options;
  terrain_options.scene = in.scene;
  terrain_options.dem = in.dem;
  terrain_options.vertical_datum = in.vertical_datum;
  terrain_options.dem_oversample = in.dem_oversample;
  terrain_options.sea = in.sea;
  terrain_options.fill_nodata = true;
  terrain_options.max_memory_bytes = in.max_memory_bytes;
  fix->terrain = LoadTerrain(terrain_options, TerrainShape(), reporter);
  fix->embree = std::make_unique<render::EmbreeScene>(fix->terrain.mesh);
  fix->landmarks = fix->terrain.reflectors;  // a scene's own
  if (!in.reflectors.empty()) {
    const auto placed = PlaceReflectors(in.reflectors, fix->terrain, *fix->embree);
    fix->landmarks.insert(fix->landmarks.end(), placed.begin(), placed.end());
    CheckLandmarksInImage(*fix, in.reflectors);
    reporter.Info("locate: " + std::to_string(placed.size()) + " point landmarks from " + in.reflectors);
  }
  fix->scene = {&fix->terrain.mesh, fix->embree.get(), &fix->terrain.materials, in.rays_per_cell, in.bounces,
                fix->landmarks.empty() ? nullptr : &fix->landmarks};
  return fix;
}

nav::ProductLocateOptions LocateOptionsOf(const std::string& matcher, int looks_range, int looks_azimuth,
                                          double sigma_horizontal_m, double sigma_vertical_m,
                                          double sigma_heading_deg, double terrain_horizontal_sigma_m) {
  nav::ProductLocateOptions o;
  o.matcher = nav::ParseShiftMatcher(matcher, "--matcher");
  o.looks_range = looks_range;
  o.looks_azimuth = looks_azimuth;
  o.prior_sigma = {sigma_horizontal_m, sigma_horizontal_m, sigma_vertical_m, sigma_heading_deg};
  o.terrain_horizontal_sigma_m = terrain_horizontal_sigma_m;
  return o;
}

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// The fix's record: the fixed sensor position (ECEF, geodetic, ENU of the
// scene frame) at the fix time, the correction and covariance, and its
// error against the annotated track.
nlohmann::json FixJson(const ProductFix& fix, const nav::ProductLocateResult& r, const nav::TrackVectors& prior) {
  const double epoch = ParseUtcSeconds(fix.product.epoch_utc, fix.product.path + ": epoch");
  const sensor::Orbit truth = fix.truth.ToOrbit();
  const sensor::Orbit prior_orbit = prior.ToOrbit();
  const sensor::Orbit fixed = r.track.ToOrbit();
  const double t = r.fix_time_s;
  const Eigen::Vector3d true_ecef = truth.Interpolate(t).position_m;
  const Eigen::Vector3d prior_ecef = prior_orbit.Interpolate(t).position_m;
  const nav::TrackFrame frame = nav::TrackFrameAt(truth, t);
  const Eigen::Vector3d llh = geo::LocalFrame::GeodeticFromEcef(r.sensor_ecef);
  const Eigen::Vector3d error = r.sensor_ecef - true_ecef;
  const Eigen::Vector3d prior_error = prior_ecef - true_ecef;
  auto heading_error = [&](const sensor::Orbit& o) {
    double d = nav::TrackAngleDeg(o, t) - nav::TrackAngleDeg(truth, t);
    return std::remainder(d, 360.0);
  };
  nlohmann::json covariance = nlohmann::json::array();
  for (int i = 0; i < 4; ++i) {
    covariance.push_back({r.covariance(i, 0), r.covariance(i, 1), r.covariance(i, 2), r.covariance(i, 3)});
  }
  return {
      {"time_utc", FormatUtc(epoch + t)},
      {"frame", {{"sensor_ecef_m", Vec(r.sensor_ecef)},
                 {"sensor_lon_lat_height", Vec(llh)},
                 {"sensor_enu_m", Vec(fix.terrain.frame.EnuFromGeodetic(llh[0], llh[1], llh[2]))},
                 {"enu_origin_lon_lat_height", {fix.terrain.frame.origin_lon_deg(), fix.terrain.frame.origin_lat_deg(),
                                                fix.terrain.frame.origin_height_m()}},
                 {"track_angle_deg", nav::TrackAngleDeg(fixed, t)}}},
      {"correction", {{"along_m", r.correction.along_m}, {"cross_m", r.correction.cross_m},
                      {"up_m", r.correction.up_m}, {"heading_deg", r.correction.heading_deg}}},
      {"covariance_along_cross_up_heading", covariance},
      {"sigma_along_cross_up_heading", {std::sqrt(r.covariance(0, 0)), std::sqrt(r.covariance(1, 1)),
                                        std::sqrt(r.covariance(2, 2)), std::sqrt(r.covariance(3, 3))}},
      {"error_against_annotated_track",
       {{"position_error_m", error.norm()},
        {"along_cross_up_m", Vec(frame.Components(error))},
        {"track_angle_error_deg", heading_error(fixed)},
        {"prior_position_error_m", prior_error.norm()},
        {"prior_along_cross_up_m", Vec(frame.Components(prior_error))},
        {"prior_track_angle_error_deg", heading_error(prior_orbit)}}}};
}

// Which pose components the image constrained and which the prior held.
nlohmann::json PoseComponentsJson(const nav::ProductLocateResult& r) {
  nlohmann::json from_image = nlohmann::json::array(), from_prior = nlohmann::json::array();
  for (int k = 0; k < 4; ++k) (r.from_image[k] ? from_image : from_prior).push_back(nav::kTrackComponents[k]);
  return {{"from_image", from_image}, {"from_prior", from_prior}};
}

nlohmann::json NumberOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json LandmarksJson(const nav::ProductLocateResult& r) {
  nlohmann::json out = nlohmann::json::array();
  auto px = [](const Eigen::Vector2d& v) {
    return v.allFinite() ? nlohmann::json{{"range", v.x()}, {"azimuth", v.y()}} : nlohmann::json(nullptr);
  };
  for (const nav::LandmarkRecord& l : r.landmarks) {
    out.push_back({{"id", l.row},
                   {"in_image", l.in_image},
                   {"used", l.used},
                   {"predicted_px", px(l.predicted_px)},
                   {"peak_px", px(l.peak_px)},
                   {"residual_px", px(l.residual_px)},
                   {"contrast_db", NumberOrNull(l.contrast_db)},
                   {"margin_db", NumberOrNull(l.margin_db)},
                   {"note", l.note.empty() ? nlohmann::json(nullptr) : nlohmann::json(l.note)}});
  }
  return out;
}

nlohmann::json ResultJson(const nav::ProductLocateResult& r) {
  return {{"converged", r.converged},
          {"fix_source", r.source},
          {"pose_components", PoseComponentsJson(r)},
          {"landmarks", LandmarksJson(r)},
          {"reference_contrast_db", NumberOrNull(r.reference_contrast_db)},
          {"reason", r.converged ? nlohmann::json(nullptr) : nlohmann::json(r.failure_reason)},
          {"iterations", r.iterations},
          {"renders", r.renders},
          {"control_points", r.control_points},
          {"peak_margin", NumberOrNull(r.peak_margin)},
          {"resection_rms_px", NumberOrNull(r.rms_px)},
          {"peak_ncc", NumberOrNull(r.peak_ncc)},
          {"first_shift_range_azimuth_px", {r.first_shift_px.x(), r.first_shift_px.y()}},
          {"ncc_shift_at_fix_range_azimuth_px", {r.ncc_shift_px.x(), r.ncc_shift_px.y()}},
          {"similarity_ncc", r.similarity},
          {"prior_similarity_ncc", r.prior_similarity},
          {"cell_m", r.cell_m},
          {"locate_seconds", r.seconds}};
}

// The prior track: the annotated track moved by the offset in its frame at
// the image's centre time.
nav::TrackVectors PriorTrack(const ProductFix& fix, const nav::TrackOffset& offset) {
  const double t = fix.observation.grid.TimeOfRow(0.5 * (fix.observation.grid.rows - 1));
  return nav::DisplaceTrack(fix.truth, nav::TrackFrameAt(fix.truth.ToOrbit(), t), offset);
}

std::vector<float> ReferenceIntensity(const ProductFix& fix, const nav::TrackVectors& track,
                                      const sensor::RadarGrid& grid) {
  render::RenderOptions ro;
  ro.rays_per_cell = fix.scene.rays_per_cell;
  ro.max_bounces = fix.scene.bounces;
  ro.wavelength_m = grid.wavelength_m;
  ro.reflectors = fix.landmarks;
  render::ProductImage img = render::RenderProduct(*fix.embree, fix.terrain.mesh, fix.terrain.materials,
                                                   fix.terrain.frame, track.ToOrbit(), grid, ro);
  if (!img.image.points.empty()) {
    image::SensorEffects psf;  // the landmarks: one pixel's impulse response
    psf.range_resolution_px = psf.azimuth_resolution_px = 1.0;
    image::AddPointIntensities(img.image, psf);
  }
  return img.image.intensity;
}

}  // namespace

PriorErrors FootprintPriorErrors(double along_m, double range_m) {
  const double horizontal = std::min(along_m, range_m) / 8.0;
  return {horizontal, horizontal / 8.0, 0.05};
}

nlohmann::json RunProductLocate(const LocateRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  Stopwatch total;
  AtomicOutputs outputs;  // nothing written without options.out (Python)
  const fs::path out = options.out.empty() ? fs::path() : outputs.Add(options.out);
  const fs::path composite = options.composite_png.empty() ? fs::path() : outputs.Add(options.composite_png);
  const auto fix = LoadProductFix({options.product, options.frequency, options.polarization, options.scene,
                                   options.dem, options.vertical_datum, options.swath, options.burst,
                                   options.product_window_px, options.orbit, options.radar_grid, options.image,
                                   options.dem_oversample, options.rays_per_cell, options.bounces,
                                   options.reflectors, options.sea, options.max_memory_bytes},
                                  reporter);
  const nav::TrackOffset offset{options.prior_offset_track[0], options.prior_offset_track[1],
                                options.prior_offset_track[2], options.prior_heading_offset_deg};
  const nav::TrackVectors prior = PriorTrack(*fix, offset);
  const nav::ProductLocateOptions lo =
      LocateOptionsOf(options.matcher, options.looks_range, options.looks_azimuth, options.prior_sigma_horizontal_m,
                      options.prior_sigma_vertical_m, options.prior_sigma_heading_deg,
                      options.terrain_horizontal_sigma_m);
  const nav::ProductLocateResult r = nav::LocateProduct(fix->scene, fix->terrain.frame, fix->observation, prior, lo);
  reporter.Info(std::string("locate: ") + (r.converged ? "fix" : "no fix (" + r.failure_reason + ")") + ", " +
                std::to_string(r.control_points) + " control points, " + std::to_string(r.renders) + " renders");
  nlohmann::json report = {{"command", "locate"},
                           {"command_line", command_line},
                           {"version", VersionString()},
                           {"created_utc", UtcTimestamp()},
                           {"mode", "product"},
                           {"fix", FixJson(*fix, r, prior)},
                           {"prior_offset_track", {{"along_m", offset.along_m}, {"cross_m", offset.cross_m},
                                                   {"up_m", offset.up_m}, {"heading_deg", offset.heading_deg}}},
                           {"prior_sigma", {{"horizontal_m", options.prior_sigma_horizontal_m},
                                            {"vertical_m", options.prior_sigma_vertical_m},
                                            {"heading_deg", options.prior_sigma_heading_deg}}},
                           {"terrain_horizontal_sigma_m", options.terrain_horizontal_sigma_m},
                           {"looks_range", options.looks_range},
                           {"looks_azimuth", options.looks_azimuth},
                           {"frequency", fix->product.frequency},
                           {"matcher", options.matcher},
                           {"polarization", fix->product.polarization},
                           {"seconds", total.ElapsedSeconds()},
                           {"vertical_datum", VerticalDatumRecord(fix->terrain)},
                           {"inputs", {{"terrain", InputFileRecord(options.scene.empty() ? options.dem : options.scene)}}}};
  if (!options.product.empty()) {
    report["inputs"]["product"] = ProductInputRecord(options.product);
  } else {
    report["inputs"]["orbit"] = InputFileRecord(options.orbit);
    report["inputs"]["radar_grid"] = InputFileRecord(options.radar_grid);
    report["inputs"]["image"] = InputFileRecord(options.image);
  }
  if (!options.reflectors.empty()) report["inputs"]["reflectors"] = InputFileRecord(options.reflectors);
  report.update(ResultJson(r));
  if (!composite.empty()) {
    // Full-resolution grid; the real image box-filtered by the looks (speckle).
    const sensor::RadarGrid& grid = fix->observation.grid;
    cv::Mat observed_mat(grid.rows, grid.cols, CV_32F, const_cast<float*>(fix->observation.intensity.data()));
    cv::Mat smoothed;
    cv::blur(observed_mat, smoothed, cv::Size(options.looks_range, options.looks_azimuth));
    const std::vector<float> observed(smoothed.begin<float>(), smoothed.end<float>());
    const image::RgbImage picture = image::SideBySide(
        {image::IntensityComposite(observed, ReferenceIntensity(*fix, prior, grid), grid.cols, grid.rows),
         image::IntensityComposite(observed, ReferenceIntensity(*fix, r.track, grid), grid.cols, grid.rows)},
        {"at the prior", "at the fix"});  // real green, simulated magenta
    geo::WritePng(composite, picture.rgb, picture.width, picture.height, 3);
    report["pictures"] = {options.composite_png};
  }
  if (!out.empty()) WriteJsonFile(report, out);
  outputs.Commit();
  return report;
}

std::vector<nlohmann::json> ProductEvaluateTrials(const EvaluateRequest& options, Reporter& reporter) {
  options.Check();
  const auto fix = LoadProductFix({options.product, options.frequency, options.polarization, options.scene,
                                   options.dem, options.vertical_datum, options.swath, options.burst,
                                   options.product_window_px, "", "", "", options.dem_oversample,
                                   options.rays_per_cell, options.bounces, options.reflectors, options.sea,
                                   options.max_memory_bytes},
                                  reporter);
  // Prior errors: given, or from the footprint of the multilooked image.
  const sensor::RadarGrid& g = fix->observation.grid;
  const sensor::Orbit truth = fix->truth.ToOrbit();
  const double t_mid = g.TimeOfRow(0.5 * (g.rows - 1));
  const double along_m = g.rows * g.dt_s * truth.Interpolate(t_mid).velocity_mps.norm();
  const PriorErrors footprint = FootprintPriorErrors(along_m, g.cols * g.dr_m);
  const double err_h = options.prior_error_horizontal_m >= 0 ? options.prior_error_horizontal_m : footprint.horizontal_m;
  const double err_v = options.prior_error_vertical_m >= 0 ? options.prior_error_vertical_m : footprint.vertical_m;
  const double err_psi = options.prior_error_heading_deg >= 0 ? options.prior_error_heading_deg : footprint.heading_deg;
  const nlohmann::json prior_errors = {{"horizontal_m", err_h}, {"vertical_m", err_v}, {"heading_deg", err_psi},
                                       {"source", options.prior_error_horizontal_m >= 0 ? "options" : "footprint"}};
  // The fix's prior sigmas: those of a uniform +- bound (bound / sqrt 3), never below 1 m / 0.001 deg.
  const nav::ProductLocateOptions lo = LocateOptionsOf(
      options.matcher, options.looks_range, options.looks_azimuth, std::max(1.0, err_h / std::sqrt(3.0)),
      std::max(1.0, err_v / std::sqrt(3.0)), std::max(1e-3, err_psi / std::sqrt(3.0)),
      options.terrain_horizontal_sigma_m);

  const int first = options.trial_first;
  const int count = options.trial_count < 0 ? options.trials - first : options.trial_count;
  std::vector<nlohmann::json> records;
  for (int k = first; k < first + count; ++k) {
    std::mt19937_64 rng(options.seed * 1000003ULL + static_cast<uint64_t>(k));
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    const nav::TrackOffset offset{uni(rng) * err_h, uni(rng) * err_h, uni(rng) * err_v, uni(rng) * err_psi};
    const nav::TrackVectors prior = PriorTrack(*fix, offset);
    const nav::ProductLocateResult r = nav::LocateProduct(fix->scene, fix->terrain.frame, fix->observation, prior, lo);
    const nlohmann::json fj = FixJson(*fix, r, prior);
    const nlohmann::json& e = fj.at("error_against_annotated_track");
    const double error_m = e.at("position_error_m").get<double>();
    const double cells = error_m / r.cell_m;
    const bool success = r.converged && cells <= options.success_cells;
    const auto acu = e.at("along_cross_up_m");
    const double along_cells = std::abs(acu[0].get<double>()) / r.cell_m;
    const double cross_cells = std::abs(acu[1].get<double>()) / r.cell_m;
    char row[512];
    std::snprintf(row, sizeof row, "%d,%d,%d,%.3f,%.4f,%.3f,%.3f,%.3f,%.5f,%.3f,%.3f,%.3f,%.5f,%.4f,%.4f,%.4f,%.3f,", k,
                  int(success), int(r.converged), error_m, cells, acu[0].get<double>(), acu[1].get<double>(),
                  acu[2].get<double>(), e.at("track_angle_error_deg").get<double>(), offset.along_m, offset.cross_m,
                  offset.up_m, offset.heading_deg, r.rms_px, r.peak_ncc, r.peak_margin, r.seconds);
    reporter.Info("evaluate: trial " + std::to_string(k) + (success ? " success" : " failure") + ", error " +
                  std::to_string(error_m) + " m (" + std::to_string(cells) + " cells)" +
                  (r.converged ? "" : ", no fix: " + r.failure_reason));
    nlohmann::json record = {{"trial", k},
                             {"success", success},
                             {"position_error_m", error_m},
                             {"position_error_cells", cells},
                             {"along_cross_error_cells", {along_cells, cross_cells}},
                             {"seconds", r.seconds},
                             {"prior_errors", prior_errors},
                             {"vertical_datum", VerticalDatumRecord(fix->terrain)},
                             {"csv_row", row + std::string("\"") + r.failure_reason + "\""}};
    record.update(ResultJson(r));
    record["fix"] = fj;
    records.push_back(record);
  }
  return records;
}

nlohmann::json ProductSummariseTrials(const EvaluateRequest& options, std::vector<nlohmann::json> records) {
  if (records.empty()) throw ConfigError("no trial records to summarise", "evaluate trial records");
  std::sort(records.begin(), records.end(),
            [](const nlohmann::json& a, const nlohmann::json& b) { return a.at("trial").get<int>() < b.at("trial").get<int>(); });
  for (size_t i = 1; i < records.size(); ++i) {
    if (records[i].at("trial") == records[i - 1].at("trial")) {
      throw ConfigError("trial " + records[i].at("trial").dump() + " appears twice", "evaluate trial records");
    }
  }
  std::vector<double> errors_m, errors_cells, seconds;
  int successes = 0, converged = 0, within_one_cell = 0, by_landmarks = 0;
  for (const nlohmann::json& r : records) {
    successes += r.at("success").get<bool>();
    converged += r.at("converged").get<bool>();
    if (r.at("converged").get<bool>() && r.contains("along_cross_error_cells")) {
      const auto& ac = r.at("along_cross_error_cells");
      within_one_cell += ac[0].get<double>() <= 1.0 && ac[1].get<double>() <= 1.0;
    }
    by_landmarks += r.value("fix_source", std::string()) == "landmarks";
    errors_m.push_back(r.at("position_error_m").get<double>());
    errors_cells.push_back(r.at("position_error_cells").get<double>());
    seconds.push_back(r.at("seconds").get<double>());
  }
  auto percentile = [](std::vector<double> v, double q) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<size_t>(std::floor(q * (v.size() - 1) + 0.5)))];
  };
  const int n = static_cast<int>(records.size());
  // The covariance checked against the Monte-Carlo spread (converged fixes):
  // per axis the median one-sigma the fix states, the standard deviation of
  // the errors and their RMS about the truth (which includes any bias).
  nlohmann::json spread = nlohmann::json::object();
  const char* axes[] = {"along_m", "cross_m", "up_m"};
  for (int a = 0; a < 3; ++a) {
    std::vector<double> sigmas, errors;
    for (const nlohmann::json& r : records) {
      if (!r.at("converged").get<bool>()) continue;
      sigmas.push_back(r.at("fix").at("sigma_along_cross_up_heading")[a].get<double>());
      errors.push_back(r.at("fix").at("error_against_annotated_track").at("along_cross_up_m")[a].get<double>());
    }
    double mean = 0.0, rms = 0.0, var = 0.0;
    for (double e : errors) mean += e / errors.size(), rms += e * e / errors.size();
    for (double e : errors) var += (e - mean) * (e - mean) / errors.size();
    if (errors.empty()) {
      spread[axes[a]] = nullptr;  // no converged fix
      continue;
    }
    spread[axes[a]] = {{"stated_sigma_median", percentile(sigmas, 0.5)}, {"error_mean", mean},
                       {"error_sd", std::sqrt(var)}, {"error_rms", std::sqrt(rms)}};
  }
  // How often the truth lies inside the fix's own 95 % region (converged
  // fixes): the horizontal (along, cross) ellipse, chi-square 2 dof 5.991,
  // and the (along, cross, up) ellipsoid, 3 dof 7.815. An honest covariance
  // gives about 0.95; a bias it does not state gives less.
  int inside_2d = 0, inside_3d = 0, fixes = 0;
  for (const nlohmann::json& r : records) {
    if (!r.at("converged").get<bool>()) continue;
    const nlohmann::json& c = r.at("fix").at("covariance_along_cross_up_heading");
    const nlohmann::json& e = r.at("fix").at("error_against_annotated_track").at("along_cross_up_m");
    Eigen::Matrix3d cov;
    Eigen::Vector3d err;
    for (int i = 0; i < 3; ++i) {
      err(i) = e[i].get<double>();
      for (int j = 0; j < 3; ++j) cov(i, j) = c[i][j].get<double>();
    }
    ++fixes;
    inside_2d += err.head<2>().dot(cov.topLeftCorner<2, 2>().ldlt().solve(err.head<2>())) <= 5.991;
    inside_3d += err.dot(cov.ldlt().solve(err)) <= 7.815;
  }
  spread["inside_95_region"] =
      fixes == 0 ? nlohmann::json(nullptr)
                 : nlohmann::json{{"fixes", fixes},
                                  {"along_cross_rate", double(inside_2d) / fixes},
                                  {"along_cross_up_rate", double(inside_3d) / fixes}};
  return {{"mode", "product"},
          {"trials", n},
          {"seed", options.seed},
          {"success_definition", "converged and 3-D sensor position error at the fix time <= success_cells cells "
                                 "(cell = the larger pixel spacing after multilook; zero-Doppler product: position only)"},
          {"success_cells", options.success_cells},
          {"resolution_cell_m", records.front().at("cell_m")},
          {"success_rate", double(successes) / n},
          {"converged_rate", double(converged) / n},
          {"refused", n - converged},
          // Converged with along- and cross-track errors both within one cell
          // (the landmark fix's measure: up and heading are the prior's).
          {"within_one_cell_along_cross_rate", double(within_one_cell) / n},
          {"fixes_by_landmarks", by_landmarks},
          {"position_error_m", {{"median", percentile(errors_m, 0.5)}, {"p95", percentile(errors_m, 0.95)}}},
          {"position_error_cells", {{"median", percentile(errors_cells, 0.5)}, {"p95", percentile(errors_cells, 0.95)}}},
          {"seconds_per_fix", {{"median", percentile(seconds, 0.5)}, {"p95", percentile(seconds, 0.95)}}},
          {"covariance_check", spread},
          {"prior_errors", records.front().at("prior_errors")},
          {"looks_range", options.looks_range},
          {"looks_azimuth", options.looks_azimuth},
          {"matcher", options.matcher},
          {"frequency", options.frequency},
          {"polarization", options.polarization},
          {"trial_records", records}};
}

nlohmann::json WriteProductEvaluation(const EvaluateRequest& options, const std::vector<nlohmann::json>& records,
                                      const std::string& command_line, double seconds) {
  options.Check();
  if (options.out_prefix.empty()) throw ConfigError("required", "--out");
  CheckOutputsAreNotInputs({options.out_prefix + ".json", options.out_prefix + "_trials.csv"},
                           {options.product, options.scene, options.dem, options.reflectors});
  AtomicOutputs outputs;
  const fs::path json_path = outputs.Add(options.out_prefix + ".json");
  const fs::path csv_path = outputs.Add(options.out_prefix + "_trials.csv");
  nlohmann::json summary = ProductSummariseTrials(options, records);
  summary["command"] = "evaluate";
  summary["command_line"] = command_line;
  summary["version"] = VersionString();
  summary["created_utc"] = UtcTimestamp();
  summary["seconds"] = seconds;
  summary["inputs"] = {{"product", ProductInputRecord(options.product)},
                       {"terrain", InputFileRecord(options.scene.empty() ? options.dem : options.scene)}};
  if (!options.reflectors.empty()) summary["inputs"]["reflectors"] = InputFileRecord(options.reflectors);
  summary["options"] = options.ToJson();
  summary["vertical_datum"] = records.front().at("vertical_datum");
  std::string csv = "trial,success,converged,position_error_m,position_error_cells,along_error_m,cross_error_m,"
                    "up_error_m,track_angle_error_deg,prior_along_m,prior_cross_m,prior_up_m,prior_heading_deg,"
                    "rms_px,peak_ncc,peak_margin,seconds,reason\n";
  for (const nlohmann::json& r : summary.at("trial_records")) csv += r.at("csv_row").get<std::string>() + "\n";
  WriteJsonFile(summary, json_path);
  std::FILE* f = std::fopen(csv_path.c_str(), "w");
  if (f == nullptr) throw WriteError("cannot write the trials CSV", csv_path, errno);
  const bool ok = std::fputs(csv.c_str(), f) >= 0;
  const int write_error = ok ? 0 : errno;
  if (std::fclose(f) != 0 || !ok) {
    throw WriteError("failed writing the trials CSV", csv_path, write_error != 0 ? write_error : errno);
  }
  outputs.Commit();
  return summary;
}

nlohmann::json RunProductEvaluate(const EvaluateRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  Stopwatch total;
  if (!options.out_prefix.empty()) {
    AtomicOutputs probe;  // a missing or read-only output directory fails before any trial
    probe.Add(options.out_prefix + ".json");
  }
  const std::vector<nlohmann::json> records = ProductEvaluateTrials(options, reporter);
  if (options.out_prefix.empty()) return ProductSummariseTrials(options, records);
  return WriteProductEvaluation(options, records, command_line, total.ElapsedSeconds());
}

}  // namespace gissar::pipeline
