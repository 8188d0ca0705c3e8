#include "gissar/pipeline/locate.h"

#include "gissar/geo/sentinel1_safe.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <type_traits>
#include <random>
#include <set>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "gissar/pipeline/simulate.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/image/composite.h"
#include "gissar/image/contact_sheet.h"
#include "gissar/image/impulse_response.h"
#include "gissar/mvg/registration.h"
#include "gissar/nav/matching.h"
#include "gissar/nav/product_locate.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/reference_database.h"
#include "gissar/scene/scene_config.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/number_text.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
namespace {

Eigen::Vector3d Vec3(const nlohmann::json& v, const std::string& key, const std::string& source) {
  if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number()) {
    throw ConfigError("must be an array of 3 numbers", source + ": " + key);
  }
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}

double Num(const nlohmann::json& v, const std::string& key, const std::string& source) {
  if (!v.is_number() || !std::isfinite(v.get<double>())) throw ConfigError("must be a finite number", source + ": " + key);
  return v.get<double>();
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(pos));
  const size_t j = std::min(v.size() - 1, i + 1);
  return v[i] + (pos - i) * (v[j] - v[i]);
}

nlohmann::json PoseJson(const nav::NavPose& pose, sensor::LookSide side, const geo::LocalFrame& frame) {
  const Eigen::Vector3d s = pose.SensorPosition(side);
  const Eigen::Vector3d g = frame.GeodeticFromEnu(s);
  return {{"heading_deg", pose.heading_deg},
          {"depression_deg", pose.depression_deg},
          {"slant_range_m", pose.slant_range_m},
          {"centre_enu_m", {pose.centre_enu.x(), pose.centre_enu.y(), pose.centre_enu.z()}},
          {"sensor_enu_m", {s.x(), s.y(), s.z()}},
          {"sensor_lon_lat_h", {g.x(), g.y(), g.z()}}};
}

// One pass of Laplacian smoothing (weight `lambda`) of the vertex heights,
// leaving building vertices alone: the "slightly different DEM" of the
// observed scene.
scene::TriangleMesh SmoothedTerrain(const scene::TriangleMesh& mesh, double lambda) {
  scene::TriangleMesh out = mesh;
  if (lambda <= 0.0) return out;
  const size_t n = mesh.vertices.size();
  std::vector<double> sum(n, 0.0);
  std::vector<int> count(n, 0);
  std::vector<bool> fixed(n, false);
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Eigen::Vector3i tri = mesh.Triangle(t);
    const bool building = mesh.classes.size() == mesh.triangle_count() && mesh.classes[t] == scene::kClassBuilding;
    for (int k = 0; k < 3; ++k) {
      if (building) fixed[tri[k]] = true;
      for (int j = 0; j < 3; ++j) {
        if (j == k) continue;
        sum[tri[k]] += mesh.vertices[tri[j]].z();
        ++count[tri[k]];
      }
    }
  }
  for (size_t i = 0; i < n; ++i) {
    if (fixed[i] || count[i] == 0) continue;
    out.vertices[i].z() = float((1.0 - lambda) * mesh.vertices[i].z() + lambda * sum[i] / count[i]);
  }
  return out;
}

TerrainRequest TerrainOptions(const std::string& scene, const std::string& dem, const std::string& vertical_datum,
                              const std::string& sea, int64_t max_memory_bytes) {
  TerrainRequest terrain;
  terrain.max_memory_bytes = max_memory_bytes;
  terrain.scene = scene;
  terrain.dem = dem;
  terrain.vertical_datum = vertical_datum;
  terrain.sea = sea;
  terrain.fill_nodata = true;
  return terrain;
}

// --sea auto/off; --reflectors with a product (or an orbit) only.
void CheckSeaAndReflectors(const std::string& sea, const std::string& reflectors, bool track) {
  if (sea != "auto" && sea != "off") throw ConfigError("must be auto or off", "--sea");
  if (!reflectors.empty() && !track) {
    throw ConfigError("point landmarks drive fixes of a --product (or --orbit) only; an --image with a --prior "
                      "does not take them",
                      "--reflectors");
  }
}

void CheckSceneOrDem(const std::string& scene, const std::string& dem, const std::string& vertical_datum) {
  if (scene.empty() == dem.empty()) throw ConfigError("give exactly one of --scene and --dem", "--scene");
  geo::CanonicalVerticalDatum(vertical_datum, "--vertical-datum");
}

// The options of a product fix (LocateRequest/EvaluateRequest::product).
void CheckProductOptions(const std::string& frequency, int looks_range, int looks_azimuth, int dem_oversample,
                         double terrain_horizontal_sigma_m) {
  if (!(terrain_horizontal_sigma_m >= 0 && terrain_horizontal_sigma_m <= 1000)) {
    throw ConfigError("must be in [0, 1000] m", "--terrain-horizontal-sigma");
  }
  if (frequency != "A" && frequency != "B") throw ConfigError("must be A or B", "--frequency");
  if (looks_range < 1 || looks_range > 64 || looks_azimuth < 1 || looks_azimuth > 64) {
    throw ConfigError("must be in [1, 64]", "--looks-range/--looks-azimuth");
  }
  if (dem_oversample < 1 || dem_oversample > 16) throw ConfigError("must be in [1, 16]", "--dem-oversample");
}

// The Sentinel-1 selection goes with a SAFE --product only.
void CheckSentinel1Selection(const std::string& product, const std::string& swath, int burst,
                             const std::optional<std::array<int, 4>>& window) {
  if (!product.empty() && geo::IsSentinel1Path(product)) {
    if (burst < 0) throw ConfigError("must be 1 or more (1-based), got " + std::to_string(burst), "--burst");
    return;
  }
  if (!swath.empty()) throw ConfigError("goes with a Sentinel-1 --product (SAFE)", "--swath");
  if (burst != 0) throw ConfigError("goes with a Sentinel-1 --product (SAFE)", "--burst");
  if (window) throw ConfigError("goes with a Sentinel-1 --product (SAFE)", "--product-window");
}

// Error histogram (position error in resolution cells) as an RGB PNG.
void WriteHistogram(const fs::path& path, const std::vector<double>& cells, double success_cells,
                    const std::string& title) {
  const int w = 640, h = 400, left = 60, bottom = 50, top = 40;
  const int bins = 24;
  const double max_cells = 6.0;
  std::vector<int> counts(bins + 1, 0);
  for (double c : cells) {
    const int b = std::isfinite(c) ? std::min(bins, static_cast<int>(c / (max_cells / bins))) : bins;
    ++counts[b];
  }
  const int peak = std::max(1, *std::max_element(counts.begin(), counts.end()));
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  const double bw = double(w - left - 20) / (bins + 1);
  for (int b = 0; b <= bins; ++b) {
    const int bh = static_cast<int>(double(counts[b]) / peak * (h - top - bottom));
    const cv::Scalar colour = b == bins ? cv::Scalar(60, 60, 200) : cv::Scalar(200, 120, 40);
    cv::rectangle(img, cv::Point(int(left + b * bw) + 1, h - bottom - bh), cv::Point(int(left + (b + 1) * bw) - 1, h - bottom),
                  colour, cv::FILLED);
  }
  const int xs = static_cast<int>(left + success_cells / max_cells * bins * bw);
  cv::line(img, cv::Point(xs, top), cv::Point(xs, h - bottom), cv::Scalar(0, 0, 0), 1);
  cv::line(img, cv::Point(left, h - bottom), cv::Point(w - 20, h - bottom), cv::Scalar(0, 0, 0), 1);
  for (int c = 0; c <= 6; ++c) {
    cv::putText(img, std::to_string(c), cv::Point(int(left + c * bins / max_cells * bw) - 4, h - bottom + 18),
                cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1);
  }
  cv::putText(img, ">6", cv::Point(int(left + bins * bw), h - bottom + 18), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 0), 1);
  cv::putText(img, "position error (resolution cells); line: success bound", cv::Point(left, h - 12),
              cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1);
  cv::putText(img, title, cv::Point(left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1);
  cv::putText(img, "max " + std::to_string(peak), cv::Point(5, top + 10), cv::FONT_HERSHEY_SIMPLEX, 0.4,
              cv::Scalar(0, 0, 0), 1);
  cv::Mat rgb;
  cv::cvtColor(img, rgb, cv::COLOR_BGR2RGB);
  geo::WritePng(path, std::vector<uint8_t>(rgb.data, rgb.data + size_t(w) * h * 3), w, h, 3);
}

}  // namespace

PriorPose ParsePriorJson(const nlohmann::json& json, const std::string& source) {
  if (!json.is_object()) throw ConfigError("prior must be a JSON object", source);
  static const std::set<std::string> known = {"heading_deg", "slant_range_m", "sensor_enu_m", "depression_deg",
                                              "centre_enu_m", "centre_lonlat", "sensor_lon_lat_h"};
  for (const auto& [key, value] : json.items()) {
    if (!known.count(key)) {
      throw ConfigError(UnknownKeyMessage(key, std::vector<std::string>(known.begin(), known.end())), source);
    }
  }
  PriorPose p;
  if (!json.contains("heading_deg")) throw ConfigError("missing key 'heading_deg'", source);
  if (!json.contains("slant_range_m")) throw ConfigError("missing key 'slant_range_m'", source);
  p.heading_deg = Num(json["heading_deg"], "heading_deg", source);
  p.slant_range_m = Num(json["slant_range_m"], "slant_range_m", source);
  if (!(p.slant_range_m > 0)) throw ConfigError("must be > 0", source + ": slant_range_m");
  if (json.contains("depression_deg")) p.depression_deg = Num(json["depression_deg"], "depression_deg", source);
  if (json.contains("centre_enu_m")) p.centre_enu = Vec3(json["centre_enu_m"], "centre_enu_m", source);
  if (json.contains("centre_lonlat")) {
    const auto& v = json["centre_lonlat"];
    if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
      throw ConfigError("must be an array of 2 numbers", source + ": centre_lonlat");
    p.centre_lonlat = Eigen::Vector2d(v[0].get<double>(), v[1].get<double>());
  }
  if (json.contains("sensor_enu_m")) p.sensor_enu = Vec3(json["sensor_enu_m"], "sensor_enu_m", source);
  if (!p.sensor_enu && !(p.depression_deg && (p.centre_enu || p.centre_lonlat))) {
    throw ConfigError("give sensor_enu_m, or depression_deg with centre_enu_m or centre_lonlat", source);
  }
  return p;
}

namespace {

// Largest search radius: the matcher's cost surface is (2s+1)^2 floats per
// patch (2048 px: 64 MiB), and no image gissar reads needs more.
constexpr int kMaxSearchPx = 2048;

// Trials of `evaluate --database`: the true pose is a stored pose with its
// heading and depression moved by up to these many degrees and its image
// centre by up to this fraction of the footprint along and across track.
constexpr double kDatabaseTrialHeadingDeg = 2.0;
constexpr double kDatabaseTrialDepressionDeg = 2.0;
constexpr double kDatabaseTrialOffset = 0.15;

// A positive finite number from image metadata `key`; InputError otherwise
// (never the library's "stod" message).
double MetadataNumber(const std::string& text, const std::string& key, const std::string& image) {
  const std::optional<double> value = util::ParseFiniteNumber(text);
  if (!value || !(*value > 0)) throw InputError(key + " is not a positive number: '" + text + "'", image);
  return *value;
}

// The database options of locate and evaluate.
void CheckDatabaseOptions(const std::string& database, const std::string& fallback, double heading_tolerance_deg) {
  if (fallback != "none" && fallback != "render") throw ConfigError("must be none or render", "--database-fallback");
  if (!(heading_tolerance_deg > 0.0 && heading_tolerance_deg <= 180.0)) {
    throw ConfigError("must be in (0, 180] deg", "--database-heading-tolerance");
  }
  (void)database;
}

// A fix from a reference database: the covering stored references, nearest
// first (at most two are tried, until one converges), or, when none covers
// the prior, no fix with the reason (or the on-the-fly fix with fallback
// "render"). `record`: the database part of the result JSON.
struct DatabaseFix {
  nav::LocateResult result;
  nlohmann::json record;
  bool rendered = false;  // the fix rendered its references (fallback)
  int warps = 0;          // stored references warped to a pose
  std::optional<size_t> item;  // the stored reference of `result`
};

DatabaseFix FixFromDatabase(const ReferenceDatabase& db, const std::vector<sensor::SarGeometry>& cameras,
                            const std::function<const nav::StoredReference&(size_t)>& stored,
                            const nav::NavScene& scene, const nav::SensorModel& model,
                            const std::vector<float>& observed, const nav::NavPose& prior,
                            const nav::LocateOptions& lo, double heading_tolerance_deg, const std::string& fallback) {
  DatabaseFix out;
  out.record = {{"catalog", db.path},
                {"terrain_sha256", db.terrain_sha256},
                {"references", db.items.size()},
                {"used", nlohmann::json::array()},
                {"fallback", nullptr},
                {"reason", nullptr}};
  std::string reason;
  const std::vector<ReferenceChoice> choices =
      CoveringReferences(db, cameras, prior, model, heading_tolerance_deg, 2, &reason);
  double seconds = 0.0;
  for (size_t k = 0; k < choices.size(); ++k) {
    const ReferenceChoice& c = choices[k];
    const nav::StoredReference& reference = stored(c.item);
    const nav::LocateResult r = nav::Locate(scene, model, observed, prior, lo, [&](const nav::NavPose& pose) {
      return nav::WarpStoredReference(reference, pose, model);
    });
    seconds += r.seconds;
    out.warps += r.renders;
    out.record["used"].push_back({{"id", db.items[c.item].id},
                                  {"image", db.items[c.item].image},
                                  {"distance_m", c.distance_m},
                                  {"heading_difference_deg", c.heading_difference_deg},
                                  {"converged", r.converged},
                                  {"reason", r.converged ? nlohmann::json(nullptr) : nlohmann::json(r.failure_reason)}});
    if (k == 0 || r.converged) {
      out.result = r;
      out.item = c.item;
    }
    if (r.converged) break;
  }
  out.result.seconds = seconds;
  if (!choices.empty()) return out;
  out.record["reason"] = reason;
  if (fallback == "render") {
    out.record["fallback"] = "render";
    out.result = nav::Locate(scene, model, observed, prior, lo);
    out.rendered = true;
    return out;
  }
  out.result.pose = prior;
  out.result.sensor_enu = prior.SensorPosition(model.look_side);
  out.result.converged = false;
  out.result.failure_reason = reason;
  return out;
}

}  // namespace

void LocateRequest::Check() const {
  CheckSceneOrDem(scene, dem, vertical_datum);
  if (max_memory_bytes <= 0) throw ConfigError("memory limit must be positive", "--max-memory");
  CheckSeaAndReflectors(sea, reflectors, UsesTrack());
  CheckDatabaseOptions(database, database_fallback, database_heading_tolerance_deg);
  if (UsesTrack()) {
    if (!database.empty()) {
      throw ConfigError("a reference database fixes an --image from a --prior, not a product or an orbit",
                        "--database");
    }
    if (!product.empty() && (!orbit.empty() || !radar_grid.empty())) {
      throw ConfigError("give a product or an orbit with a radar grid, not both", "--product/--orbit");
    }
    if (product.empty() && (orbit.empty() || radar_grid.empty())) {
      throw ConfigError("an orbit needs a radar grid and a radar grid an orbit", "--orbit/--radar-grid");
    }
    if (!product.empty() && !image.empty()) throw ConfigError("give --product or --image, not both", "--product/--image");
    if (!orbit.empty() && image.empty()) {
      throw ConfigError("the observed image on the radar grid is required with --orbit", "--image");
    }
    if (!prior.empty()) {
      throw ConfigError("a product's prior is its own track moved by --prior-offset-track and --prior-heading-offset",
                        "--product/--prior");
    }
    CheckProductOptions(frequency, looks_range, looks_azimuth, dem_oversample, terrain_horizontal_sigma_m);
    CheckSentinel1Selection(product, swath, burst, product_window_px);
    if (prior_offset_track.size() != 3 ||
        !std::all_of(prior_offset_track.begin(), prior_offset_track.end(), [](double v) { return std::isfinite(v); })) {
      throw ConfigError("needs ALONG,CROSS,UP in metres", "--prior-offset-track");
    }
    if (!std::isfinite(prior_heading_offset_deg) || std::abs(prior_heading_offset_deg) > 30.0) {
      throw ConfigError("must be in [-30, 30] deg", "--prior-heading-offset");
    }
    if (!(prior_sigma_horizontal_m > 0 && prior_sigma_vertical_m > 0 && prior_sigma_heading_deg > 0)) {
      throw ConfigError("must be > 0", "--prior-sigma-horizontal/--prior-sigma-vertical/--prior-sigma-heading");
    }
    nav::ParseShiftMatcher(matcher, "--matcher");
    if (bounces < 1 || bounces > 16) throw ConfigError("must be in [1, 16]", "--bounces");
    CheckOutputsAreNotInputs({out, composite_png}, {product, orbit, radar_grid, image, scene, dem, reflectors});
    return;
  }
  if (image.empty()) throw ConfigError("required", "--image");
  if (prior.empty()) throw ConfigError("required", "--prior");
  if (out.empty()) throw ConfigError("required", "--out");
  if (!database.empty()) CheckOutputsAreNotInputs({out, composite_png}, {database});
  nav::ParseMatcher(matcher, "--matcher");
  if (!look.empty()) sensor::ParseLookSide(look);
  if (range_spacing_m < 0 || azimuth_spacing_m < 0) throw ConfigError("must be > 0", "--range-spacing/--azimuth-spacing");
  if (dense_renders < 0) throw ConfigError("must be >= 0", "--dense-renders");
  if (polish_evaluations < 0) throw ConfigError("must be >= 0", "--polish");
  if (search_px < 5 || search_px > kMaxSearchPx) throw ConfigError("must be in [5, 2048] px", "--search");
  if (bounces < 1 || bounces > 16) throw ConfigError("must be in [1, 16]", "--bounces");
  CheckOutputsAreNotInputs({out, composite_png}, {image, scene, dem, prior});
}

namespace {

// A reference database, when given: its catalogue, checked to be built from this terrain.
std::optional<ReferenceDatabase> ReadCheckedDatabase(const LocateRequest& options) {
  std::optional<ReferenceDatabase> database;
  if (!options.database.empty()) {
    database = ReadReferenceDatabase(options.database);
    CheckDatabaseTerrain(*database, options.scene, options.dem, options.vertical_datum);
  }
  return database;
}

// The INS prior (a JSON file).
PriorPose ReadPrior(const std::string& path) {
  std::ifstream prior_file(path);
  if (!prior_file) throw IoError("cannot read prior", path);
  nlohmann::json prior_json;
  try {
    prior_json = nlohmann::json::parse(prior_file);
  } catch (const nlohmann::json::exception& e) {
    throw ConfigError(std::string("invalid JSON: ") + e.what(), path);
  }
  return ParsePriorJson(prior_json, path);
}

// The observed image's sensor model: its size, the pixel spacings (the
// options' or the image's metadata) and look side; a prior far from the
// image's own slant range is refused.
nav::SensorModel ImageSensorModel(const geo::FloatRaster& raster, const LocateRequest& options, const PriorPose& prior) {
  auto meta = [&](const std::string& key) -> std::optional<std::string> {
    const auto it = raster.metadata.find(key);
    if (it == raster.metadata.end()) return std::nullopt;
    return it->second;
  };
  nav::SensorModel model;
  model.width = raster.width;
  model.height = raster.height;
  model.range_spacing_m = options.range_spacing_m;
  model.azimuth_spacing_m = options.azimuth_spacing_m;
  if (model.range_spacing_m == 0.0) {
    const auto v = meta("GISSAR_RANGE_SPACING_M");
    if (!v) throw ConfigError("the image has no GISSAR_RANGE_SPACING_M: give --range-spacing", options.image);
    model.range_spacing_m = MetadataNumber(*v, "GISSAR_RANGE_SPACING_M", options.image);
  }
  if (model.azimuth_spacing_m == 0.0) {
    const auto v = meta("GISSAR_AZIMUTH_SPACING_M");
    if (!v) throw ConfigError("the image has no GISSAR_AZIMUTH_SPACING_M: give --azimuth-spacing", options.image);
    model.azimuth_spacing_m = MetadataNumber(*v, "GISSAR_AZIMUTH_SPACING_M", options.image);
  }
  // A prior far from the image's own slant range converges to a wrong fix:
  // refuse it (the image states the range it was made at).
  if (const auto v = meta("GISSAR_SLANT_RANGE_M")) {
    const double image_range_m = MetadataNumber(*v, "GISSAR_SLANT_RANGE_M", options.image);
    if (image_range_m > 0 && std::abs(prior.slant_range_m - image_range_m) > kMaxPriorRangeMismatch * image_range_m) {
      throw ConfigError("the prior's slant range " + std::to_string(int64_t(std::lround(prior.slant_range_m))) +
                            " m disagrees with the image's " + std::to_string(int64_t(std::lround(image_range_m))) +
                            " m by more than 10 %",
                        options.prior + ": slant_range_m");
    }
  }
  if (!options.look.empty()) model.look_side = sensor::ParseLookSide(options.look);
  else if (const auto v = meta("GISSAR_LOOK_SIDE")) model.look_side = sensor::ParseLookSide(*v);
  model.Check();
  return model;
}

// The pose the fix starts from: the prior's sensor position, or its scene
// centre on the surface.
nav::NavPose StartPose(const PriorPose& prior, const nav::NavScene& scene, const Terrain& terrain,
                       const render::EmbreeScene& embree, sensor::LookSide look_side, const std::string& prior_path) {
  std::optional<nav::NavPose> start;
  if (prior.sensor_enu) {
    start = nav::PoseFromSensor(scene, *prior.sensor_enu, prior.heading_deg, prior.slant_range_m,
                                prior.depression_deg.value_or(40.0), look_side);
  } else {
    Eigen::Vector3d c = prior.centre_enu.value_or(Eigen::Vector3d::Zero());
    if (prior.centre_lonlat) c = terrain.frame.EnuFromGeodetic(prior.centre_lonlat->x(), prior.centre_lonlat->y(), 0.0);
    const auto ground = nav::SurfaceBelow(embree, c.x(), c.y());
    if (ground) start = nav::NavPose{prior.heading_deg, *prior.depression_deg, prior.slant_range_m, *ground};
  }
  if (!start) throw InputError("the prior's line of sight does not reach the scene", prior_path);
  return *start;
}

nav::LocateOptions LocateOptionsOf(const LocateRequest& options) {
  nav::LocateOptions lo;
  lo.matcher = nav::ParseMatcher(options.matcher, "--matcher");
  lo.dense_renders = options.dense_renders;
  lo.polish_evaluations = options.polish_evaluations;
  lo.initial_search_px = options.search_px;
  lo.step_px = options.step_px;
  return lo;
}

// A fix of the observed image: from the reference database (stored
// references warped, the ones loaded kept for the composite) or by
// rendering references.
struct SceneFix {
  nav::LocateResult result;
  nlohmann::json database_record = nullptr;
  bool rendered = true;
  int warps = 0;
  std::map<size_t, nav::StoredReference> loaded;
  std::optional<size_t> used_item;
};

void FixPose(const std::optional<ReferenceDatabase>& database, const Terrain& terrain, const nav::NavScene& scene,
             const nav::SensorModel& model, const std::vector<float>& observed, const nav::NavPose& start,
             const nav::LocateOptions& lo, const LocateRequest& options, SceneFix& out) {
  if (!database) {
    out.result = nav::Locate(scene, model, observed, start, lo);
    return;
  }
  std::vector<sensor::SarGeometry> cameras;
  for (const StoredReferenceItem& item : database->items) cameras.push_back(ItemGeometryInFrame(item, terrain.frame));
  auto stored = [&](size_t i) -> const nav::StoredReference& {
    auto it = out.loaded.find(i);
    if (it == out.loaded.end()) it = out.loaded.emplace(i, LoadStoredReference(database->items[i], cameras[i], scene)).first;
    return it->second;
  };
  DatabaseFix fix = FixFromDatabase(*database, cameras, stored, scene, model, observed, start, lo,
                                    options.database_heading_tolerance_deg, options.database_fallback);
  out.result = fix.result;
  out.database_record = fix.record;
  out.rendered = fix.rendered;
  out.warps = fix.warps;
  out.used_item = fix.item;
}

// The fix's JSON: the pose, the prior, how it converged, its error estimate,
// the sensor model and the inputs.
nlohmann::json LocateReport(const LocateRequest& options, const std::string& command_line, const Stopwatch& total,
                            const SceneFix& fix, const nav::NavPose& start, const nav::SensorModel& model,
                            const Terrain& terrain) {
  const nav::LocateResult& r = fix.result;
  nlohmann::json result = PoseJson(r.pose, model.look_side, terrain.frame);
  return {
      {"command", "locate"},
      {"command_line", command_line},
      {"version", VersionString()},
      {"created_utc", UtcTimestamp()},
      {"pose", result},
      {"prior", PoseJson(start, model.look_side, terrain.frame)},
      {"converged", r.converged},
      {"reason", r.converged ? nlohmann::json(nullptr) : nlohmann::json(r.failure_reason)},
      {"iterations", r.iterations},
      {"renders", fix.rendered ? r.renders : 0},
      {"matches", r.matches},
      {"inliers", r.inliers},
      {"resection_rms_px", r.rms_px},
      {"dense_renders", r.dense_renders},
      {"dense_rms_db", r.dense_rms_db},
      {"similarity_ncc", r.similarity},
      {"prior_similarity_ncc", r.prior_similarity},
      {"error_estimate", {{"heading_sigma_deg", r.heading_sigma_deg},
                          {"depression_sigma_deg", r.depression_sigma_deg},
                          {"position_sigma_along_l_h_n_m", {r.position_sigma_lhn_m.x(), r.position_sigma_lhn_m.y(), r.position_sigma_lhn_m.z()}},
                          {"note", "from the resection covariance (matches assumed independent); a lower bound"}}},
      {"seconds", total.ElapsedSeconds()},
      {"locate_seconds", r.seconds},
      {"sensor_model", {{"range_spacing_m", model.range_spacing_m}, {"azimuth_spacing_m", model.azimuth_spacing_m},
                         {"width", model.width}, {"height", model.height}, {"look", sensor::ToString(model.look_side)}}},
      {"matcher", options.matcher},
      {"vertical_datum", VerticalDatumRecord(terrain)},
      {"inputs", {{"image", InputFileRecord(options.image)},
                  {"terrain", InputFileRecord(options.scene.empty() ? options.dem : options.scene)},
                  {"prior", InputFileRecord(options.prior)}}}};
}

// The references the fix saw (the stored one warped, or renders) at the
// prior and at the fix, each over the observed image: observed green,
// simulated magenta.
void WriteFixComposite(const fs::path& path, const SceneFix& fix, const nav::NavScene& scene,
                       const nav::NavPose& start, const nav::SensorModel& model, const std::vector<float>& observed) {
  auto reference_at = [&](const nav::NavPose& pose) {
    return fix.used_item ? nav::WarpStoredReference(fix.loaded.at(*fix.used_item), pose, model)
                         : nav::RenderReference(scene, pose, model);
  };
  const nav::Reference at_prior = reference_at(start);
  const nav::Reference at_fix = reference_at(fix.result.pose);
  const image::RgbImage picture = image::SideBySide(
      {image::IntensityComposite(observed, at_prior.intensity, model.width, model.height),
       image::IntensityComposite(observed, at_fix.intensity, model.width, model.height)},
      {"at the prior", "at the fix"});  // observed green, simulated magenta
  geo::WritePng(path, picture.rgb, picture.width, picture.height, 3);
}

}  // namespace

nlohmann::json RunTerrainLocate(const LocateRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  if (options.UsesTrack()) {
    throw ConfigError("a product or an orbit is fixed by RunProductLocate (product_locate.h)",
                      options.product.empty() ? "--orbit" : "--product");
  }
  Stopwatch total;
  AtomicOutputs outputs;
  const fs::path out = outputs.Add(options.out);
  const fs::path composite = options.composite_png.empty() ? fs::path() : outputs.Add(options.composite_png);
  // A reference database is checked first: its catalogue, and that it was built from this terrain.
  const std::optional<ReferenceDatabase> database = ReadCheckedDatabase(options);
  const PriorPose prior = ReadPrior(options.prior);
  const geo::FloatRaster raster = geo::ReadFloatRaster(options.image);
  const nav::SensorModel model = ImageSensorModel(raster, options, prior);
  std::vector<float> observed = raster.bands.at(0);
  for (float& v : observed) if (!std::isfinite(v)) v = 0.0f;

  Terrain terrain = LoadTerrain(TerrainOptions(options.scene, options.dem, options.vertical_datum, options.sea, options.max_memory_bytes),
                              TerrainShape(), reporter);
  const render::EmbreeScene embree(terrain.mesh);
  nav::NavScene scene{&terrain.mesh, &embree, &terrain.materials, options.rays_per_cell, options.bounces};
  const nav::NavPose start = StartPose(prior, scene, terrain, embree, model.look_side, options.prior);
  SceneFix fix;
  FixPose(database, terrain, scene, model, observed, start, LocateOptionsOf(options), options, fix);

  nlohmann::json report = LocateReport(options, command_line, total, fix, start, model, terrain);
  if (database) {
    fix.database_record["stored_reference_warps"] = fix.warps;
    report["database"] = fix.database_record;
    report["inputs"]["database"] = InputFileRecord(options.database);
  }
  if (!composite.empty()) {
    WriteFixComposite(composite, fix, scene, start, model, observed);
    report["pictures"] = {options.composite_png};
  }
  WriteJsonFile(report, out);
  outputs.Commit();
  return report;
}

void EvaluateRequest::Check() const {
  CheckSceneOrDem(scene, dem, vertical_datum);
  if (max_memory_bytes <= 0) throw ConfigError("memory limit must be positive", "--max-memory");
  CheckSeaAndReflectors(sea, reflectors, !product.empty());
  if (trials < 1 || trials > kMaxTrials) throw ConfigError("must be in [1, 100000]", "--trials");
  if (out_prefix.empty() && product.empty()) throw ConfigError("required", "--out");
  if (!(spacing_m > 0)) throw ConfigError("must be > 0", "--spacing");
  if (size_px < 48) throw ConfigError("must be >= 48", "--size");
  if (!(slant_range_m > 0)) throw ConfigError("must be > 0", "--slant-range");
  if (!(depression_min_deg > 1 && depression_max_deg < 89 && depression_min_deg <= depression_max_deg))
    throw ConfigError("need 1 < min <= max < 89", "--depression-min/--depression-max");
  if (!(speckle_looks == 0 || (speckle_looks >= 1 && std::isfinite(speckle_looks)))) {
    throw ConfigError("must be 0 (off) or a finite number >= 1", "--looks");
  }
  if (!std::isnan(nesz_db) && !(nesz_db >= kMinNeszDb && nesz_db <= kMaxNeszDb)) {
    throw ConfigError("must be in [-100, 60] dB", "--nesz");
  }
  if (!(material_db >= 0)) throw ConfigError("must be >= 0", "--material-db");
  if (!(dem_smoothing >= 0 && dem_smoothing <= 1)) throw ConfigError("must be in [0, 1]", "--dem-smoothing");
  if (!(success_cells > 0)) throw ConfigError("must be > 0", "--success-cells");
  if (!(success_heading_deg > 0)) throw ConfigError("must be > 0", "--success-heading-deg");
  for (double v : {prior_error_horizontal_m, prior_error_vertical_m, prior_error_heading_deg}) {
    if (!std::isfinite(v)) {
      throw ConfigError("must be finite (negative: automatic)",
                        "--prior-error-horizontal/--prior-error-vertical/--prior-error-heading");
    }
  }
  if (!product.empty()) {
    CheckProductOptions(frequency, looks_range, looks_azimuth, dem_oversample, terrain_horizontal_sigma_m);
    CheckSentinel1Selection(product, swath, burst, product_window_px);
    nav::ParseShiftMatcher(matcher, "--matcher");
  } else {
    nav::ParseMatcher(matcher, "--matcher");
  }
  if (search_px != 0 && (search_px < 5 || search_px > kMaxSearchPx)) {
    throw ConfigError("must be 0 (automatic) or in [5, 2048] px", "--search");
  }
  if (dense_renders < 0) throw ConfigError("must be >= 0", "--dense-renders");
  if (polish_evaluations < 0) throw ConfigError("must be >= 0", "--polish");
  if (bounces < 1 || bounces > 16) throw ConfigError("must be in [1, 16]", "--bounces");
  CheckDatabaseOptions(database, database_fallback, database_heading_tolerance_deg);
  if (database_fixes != "stored" && database_fixes != "render") throw ConfigError("must be stored or render", "--database-fixes");
  if (!database.empty() && !product.empty()) {
    throw ConfigError("a reference database's trials are simulated images, not a product's", "--database");
  }
  if (trial_first < 0 || trial_first >= trials) throw ConfigError("must be in [0, trials)", "--trial-first");
  if (!(trial_count == -1 || (trial_count >= 1 && int64_t{trial_first} + trial_count <= trials))) {
    throw ConfigError("must be -1 (the rest) or in [1, trials - trial_first]", "--trial-count");
  }
}

EvaluateRequest EvaluateRequest::Resolved() const {
  EvaluateRequest r = *this;
  if (!product.empty()) return r;
  if (r.prior_error_horizontal_m < 0) r.prior_error_horizontal_m = 200.0;
  if (r.prior_error_vertical_m < 0) r.prior_error_vertical_m = 50.0;
  if (r.prior_error_heading_deg < 0) r.prior_error_heading_deg = 3.0;
  if (!database.empty()) {
    // The observed images take the database's sensor (its first stored reference).
    const ReferenceDatabase db = ReadReferenceDatabase(database);
    const StoredReferenceItem& item = db.items.front();
    if (item.width != item.height || std::abs(item.range_spacing_m - item.azimuth_spacing_m) > 1e-9) {
      throw ConfigError("evaluate --database needs square images with equal range and azimuth spacings (this "
                        "database: " + std::to_string(item.width) + " x " + std::to_string(item.height) + " px)",
                        database);
    }
    r.spacing_m = item.range_spacing_m;
    r.size_px = item.width;
    r.slant_range_m = item.slant_range_m;
    r.depression_min_deg = item.depression_deg - kDatabaseTrialDepressionDeg;
    r.depression_max_deg = item.depression_deg + kDatabaseTrialDepressionDeg;
  }
  return r;
}

namespace {

// The locate options an evaluation derives from its request: the first
// search radius (from the prior errors when --search is 0: sqrt(2)
// horizontal + R sin(heading) + vertical / tan(min depression), over the
// spacing, + 4 px; never below the refinement radius) and the reference's
// noise floor (the observed image's NESZ, a property of the sensor: shadow
// and calm sea then read the same in both).
void ResolveSearchAndFloor(const EvaluateRequest& options, nav::LocateOptions& lo) {
  lo.initial_search_px = options.search_px > 0
      ? options.search_px
      : static_cast<int>(std::ceil((std::sqrt(2.0) * options.prior_error_horizontal_m +
                                    options.slant_range_m * std::sin(options.prior_error_heading_deg * M_PI / 180.0) +
                                    options.prior_error_vertical_m / std::tan(options.depression_min_deg * M_PI / 180.0)) /
                                   options.spacing_m)) + 4;
  lo.initial_search_px = std::max(lo.initial_search_px, lo.refine_search_px);
  if (std::isfinite(options.nesz_db) && options.reference_floor) {
    lo.reference_floor = std::max(lo.reference_floor, std::pow(10.0, options.nesz_db / 10.0));
  }
}

// What every trial of an evaluation shares: the terrain, its BVH, the
// observed (smoothed) terrain, the sensor model, the locate options and the
// region true centres are drawn from.
struct EvaluateSetup {
  Terrain terrain;
  std::unique_ptr<render::EmbreeScene> embree;
  scene::TriangleMesh observed_mesh;
  std::unique_ptr<render::EmbreeScene> observed_embree;
  nav::SensorModel model;
  nav::LocateOptions lo;
  Eigen::Vector2d lo_xy, hi_xy;
  // With a reference database: its catalogue, every stored reference's
  // camera in the terrain's frame and (database_fixes "stored") the stored
  // references, loaded once as a navigation computer would hold them.
  std::optional<ReferenceDatabase> database;
  std::vector<sensor::SarGeometry> cameras;
  std::vector<nav::StoredReference> stored;
};

const std::vector<nav::Matcher>& ComparedMatchers() {
  static const std::vector<nav::Matcher> matchers = {nav::Matcher::kNcc, nav::Matcher::kChamfer,
                                                     nav::Matcher::kFeatures};
  return matchers;
}

EvaluateSetup PrepareEvaluation(const EvaluateRequest& options, Reporter& reporter) {
  EvaluateSetup s;
  s.terrain = LoadTerrain(TerrainOptions(options.scene, options.dem, options.vertical_datum, options.sea, options.max_memory_bytes),
                              TerrainShape(), reporter);
  s.embree = std::make_unique<render::EmbreeScene>(s.terrain.mesh);
  s.observed_mesh = SmoothedTerrain(s.terrain.mesh, options.dem_smoothing);
  s.observed_embree = std::make_unique<render::EmbreeScene>(s.observed_mesh);
  s.model.range_spacing_m = s.model.azimuth_spacing_m = options.spacing_m;
  s.model.width = s.model.height = options.size_px;
  s.model.look_side = sensor::LookSide::kRight;
  nav::LocateOptions& lo = s.lo;
  lo.matcher = nav::ParseMatcher(options.matcher, "--matcher");
  lo.dense_renders = options.dense_renders;
  lo.polish_evaluations = options.polish_evaluations;
  ResolveSearchAndFloor(options, lo);
  lo.step_px = options.step_px;
  // True image centres are drawn where the whole image (and the prior's)
  // stays on the scene.
  const Eigen::AlignedBox3d box = s.terrain.mesh.Bounds();
  const double extent = 0.5 * options.size_px * options.spacing_m /
                            std::cos(options.depression_max_deg * M_PI / 180.0) * std::sqrt(2.0) +
                        options.slant_range_m * std::sin(options.prior_error_heading_deg * M_PI / 180.0) +
                        options.prior_error_horizontal_m + 100.0;
  s.lo_xy = Eigen::Vector2d(box.min().x() + extent, box.min().y() + extent);
  s.hi_xy = Eigen::Vector2d(box.max().x() - extent, box.max().y() - extent);
  if (!options.database.empty()) {
    s.database = ReadReferenceDatabase(options.database);
    CheckDatabaseTerrain(*s.database, options.scene, options.dem, options.vertical_datum);
    for (const StoredReferenceItem& item : s.database->items) {
      s.cameras.push_back(ItemGeometryInFrame(item, s.terrain.frame));
    }
    if (options.database_fixes == "stored") {
      const nav::NavScene scene{&s.terrain.mesh, s.embree.get(), &s.terrain.materials, options.rays_per_cell,
                                options.bounces};
      for (size_t i = 0; i < s.cameras.size(); ++i) {
        s.stored.push_back(LoadStoredReference(s.database->items[i], s.cameras[i], scene));
      }
    }
    return s;  // true poses come from the stored poses, not the region below
  }
  if (!(s.lo_xy.x() < s.hi_xy.x() && s.lo_xy.y() < s.hi_xy.y())) {
    throw ConfigError("the scene is too small for images of this size and the prior errors", "--size/--spacing");
  }
  return s;
}

nlohmann::json NumberOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
double NumberOf(const nlohmann::json& v) {
  return v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN();
}

// A trial's random numbers: std::mt19937_64 seeded with seed * 1000003 +
// trial, drawn uniform in [a, b) in the order the trial's phases ask.
struct TrialRandom {
  explicit TrialRandom(uint64_t seed) : rng(seed) {}
  double Uniform(double a, double b) { return a + (b - a) * u01(rng); }
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> u01{0.0, 1.0};
};

// The true pose of a trial, and (with a database) the stored reference it
// was drawn around.
struct TruePose {
  nav::NavPose pose;
  nlohmann::json near_item = nullptr;
};

// With a database: around a stored pose (kDatabaseTrial*); else uniform in
// heading, depression and centre over the region. 100 attempts to land on
// the scene surface.
TruePose DrawTruePose(const EvaluateSetup& s, const EvaluateRequest& options, TrialRandom& random) {
  auto uni = [&](double a, double b) { return random.Uniform(a, b); };
  TruePose out;
  nav::NavPose& truth = out.pose;
  bool ok = false;
  if (s.database) {
    // Around a stored pose (kDatabaseTrial*).
    const size_t n = s.cameras.size();
    for (int attempt = 0; attempt < 100 && !ok; ++attempt) {
      const size_t k = std::min(n - 1, static_cast<size_t>(uni(0.0, double(n))));
      const sensor::SarGeometry& g = s.cameras[k];
      truth.heading_deg = g.options().heading_deg + uni(-1, 1) * kDatabaseTrialHeadingDeg;
      truth.depression_deg = g.options().depression_deg + uni(-1, 1) * kDatabaseTrialDepressionDeg;
      truth.slant_range_m = options.slant_range_m;
      const Eigen::Vector3d across = Eigen::Vector3d(g.look_direction().x(), g.look_direction().y(), 0.0).normalized();
      const double a = uni(-1, 1) * kDatabaseTrialOffset * g.width() * g.range_spacing_m() /
                       std::cos(g.options().depression_deg * M_PI / 180.0);
      const double b = uni(-1, 1) * kDatabaseTrialOffset * g.height() * g.azimuth_spacing_m();
      const Eigen::Vector3d c = g.scene_centre() + a * across + b * g.flight_direction();
      const auto ground = nav::SurfaceBelow(*s.embree, c.x(), c.y());
      if (ground) {
        truth.centre_enu = *ground;
        out.near_item = s.database->items[k].id;
        ok = true;
      }
    }
  }
  for (int attempt = 0; attempt < 100 && !ok && !s.database; ++attempt) {
    truth.heading_deg = uni(0.0, 360.0);
    truth.depression_deg = uni(options.depression_min_deg, options.depression_max_deg);
    truth.slant_range_m = options.slant_range_m;
    const auto g = nav::SurfaceBelow(*s.embree, uni(s.lo_xy.x(), s.hi_xy.x()), uni(s.lo_xy.y(), s.hi_xy.y()));
    if (g) { truth.centre_enu = *g; ok = true; }
  }
  if (!ok) throw InputError("no true pose found on the scene surface", options.scene);
  return out;
}

// Observed image: smoothed terrain, materials off by +-material_db per class, speckle, noise.
render::SarImage RenderObservedImage(const EvaluateSetup& s, const EvaluateRequest& options, int trial,
                                     const nav::NavPose& truth, TrialRandom& random) {
  auto uni = [&](double a, double b) { return random.Uniform(a, b); };
  material::MaterialTable materials = s.terrain.materials;
  for (int c = 0; c < std::max<int>(scene::kClassCount, int(s.terrain.materials.size())); ++c) {
    material::Material m = s.terrain.materials.Get(static_cast<scene::ClassId>(c));
    m.gain_db += uni(-options.material_db, options.material_db);
    materials.Set(static_cast<scene::ClassId>(c), m);
  }
  render::RenderOptions ro;
  ro.rays_per_cell = options.rays_per_cell;
  ro.max_bounces = options.bounces;
  ro.seed = options.seed + trial;
  render::SarImage obs = render::RenderSar(*s.observed_embree, s.observed_mesh, materials, nav::GeometryOf(truth, s.model), ro);
  if (options.speckle_looks >= 1) image::ApplyMultiplicativeSpeckle(obs.intensity, options.speckle_looks, options.seed * 7919 + trial);
  if (std::isfinite(options.nesz_db)) image::AddThermalNoise(obs.intensity, options.nesz_db, options.seed * 104729 + trial);
  return obs;
}

// The INS prior after drift: the true sensor position moved by the prior
// errors, the heading turned.
struct TrialPrior {
  Eigen::Vector3d sensor_true;
  double heading_deg = 0.0;
  nav::NavPose pose;
};

TrialPrior DrawPrior(const nav::NavScene& scene, const EvaluateRequest& options, int trial, const nav::NavPose& truth,
                     sensor::LookSide look, TrialRandom& random) {
  auto uni = [&](double a, double b) { return random.Uniform(a, b); };
  TrialPrior out;
  const Eigen::Vector3d sensor_true = out.sensor_true = truth.SensorPosition(look);
  const Eigen::Vector3d sensor_prior = sensor_true + Eigen::Vector3d(uni(-1, 1) * options.prior_error_horizontal_m,
                                                                     uni(-1, 1) * options.prior_error_horizontal_m,
                                                                     uni(-1, 1) * options.prior_error_vertical_m);
  const double heading_prior = out.heading_deg = truth.heading_deg + uni(-1, 1) * options.prior_error_heading_deg;
  const auto prior = nav::PoseFromSensor(scene, sensor_prior, heading_prior, truth.slant_range_m, truth.depression_deg, look);
  if (!prior) throw InputError("prior beam leaves the scene (trial " + std::to_string(trial) + ")", options.scene);
  out.pose = *prior;
  return out;
}

// --compare-matchers: each compared matcher at the prior, its matches
// against the truth (raw, inliers, good (< 1 px), median error) as JSON rows
// and as the CSV's numbers.
struct MatcherComparison {
  nlohmann::json rows = nlohmann::json::array();
  std::vector<std::array<double, 4>> numbers;
};

MatcherComparison CompareMatchers(const EvaluateSetup& s, const nav::NavScene& scene, const render::SarImage& obs,
                                  const nav::NavPose& prior, const nav::NavPose& truth) {
  const nav::LocateOptions& lo = s.lo;
  const nav::SensorModel& model = s.model;
  MatcherComparison out;
  const nav::Reference ref = nav::RenderReference(scene, prior, model);
  const cv::Mat obs_log = nav::LogIntensity(obs.intensity, model.width, model.height, lo.filter_px);
  const sensor::SarGeometry true_geometry = nav::GeometryOf(truth, model);
  nav::MatchOptions mo;
  mo.patch_px = lo.patch_px;
  mo.step_px = lo.step_px;
  mo.search_px = lo.initial_search_px;
  for (const nav::Matcher matcher : ComparedMatchers()) {
    const nav::ControlMatches cm = nav::MatchReference(ref, obs_log, matcher, mo, lo.filter_px, lo.ransac_threshold_px,
                                                       lo.reference_floor);
    std::vector<double> errs;
    for (size_t i = 0; i < cm.world.size(); ++i) errs.push_back((cm.observed[i] - true_geometry.Project(cm.world[i])).norm());
    const double good = double(std::count_if(errs.begin(), errs.end(), [](double e) { return e < 1.0; }));
    const double med = Percentile(errs, 0.5);
    out.numbers.push_back({double(cm.raw), double(cm.world.size()), good, med});
    out.rows.push_back({{"matcher", nav::ToString(matcher)},
                        {"raw", cm.raw},
                        {"inliers", cm.world.size()},
                        {"good", good},
                        {"median_error_px", NumberOrNull(med)}});
  }
  return out;
}

// The trial's fix: from the stored references (database_fixes "stored"; the
// choice of the references timed with it) or by rendering; with a database
// its record, and the stored pose the truth was drawn around.
nav::LocateResult FixTrial(const EvaluateSetup& s, const EvaluateRequest& options, const nav::NavScene& scene,
                           const render::SarImage& obs, const nav::NavPose& prior, const TruePose& truth,
                           nlohmann::json& database_record) {
  const nav::LocateOptions& lo = s.lo;
  const nav::SensorModel& model = s.model;
  nav::LocateResult r;
  if (s.database && options.database_fixes == "stored") {
    const Stopwatch clock;
    DatabaseFix fix = FixFromDatabase(
        *s.database, s.cameras, [&](size_t i) -> const nav::StoredReference& { return s.stored.at(i); }, scene, model,
        obs.intensity, prior, lo, options.database_heading_tolerance_deg, options.database_fallback);
    r = fix.result;
    r.seconds = clock.ElapsedSeconds();  // the choice of the references included
    database_record = fix.record;
    database_record.erase("catalog");
    database_record.erase("terrain_sha256");
    database_record["stored_reference_warps"] = fix.warps;
  } else {
    r = nav::Locate(scene, model, obs.intensity, prior, lo);
  }
  if (s.database) {
    if (database_record.is_null()) database_record = nlohmann::json::object();
    database_record["truth_near"] = truth.near_item;
  }
  return r;
}

// The trial's errors against the truth and whether it succeeded
// (docs/conventions.md).
struct TrialErrors {
  Eigen::Vector3d d;  // fixed minus true sensor position
  double e3 = 0.0, eh = 0.0, e_heading = 0.0, e_dep = 0.0, cells = 0.0;
  bool success = false;
};

TrialErrors ErrorsOf(const nav::LocateResult& r, const nav::NavPose& truth, const Eigen::Vector3d& sensor_true,
                     const EvaluateRequest& options) {
  TrialErrors e;
  const Eigen::Vector3d d = e.d = r.sensor_enu - sensor_true;
  e.e3 = d.norm();
  e.eh = d.head<2>().norm();
  e.e_heading = std::abs(std::remainder(r.pose.heading_deg - truth.heading_deg, 360.0));
  e.e_dep = r.pose.depression_deg - truth.depression_deg;
  e.cells = e.e3 / options.spacing_m;
  e.success = r.converged && e.cells <= options.success_cells && e.e_heading <= options.success_heading_deg;
  return e;
}

// The trial's row of PREFIX_trials.csv (TrialsCsvHeader).
std::string TrialCsvRow(int trial, const nav::NavPose& truth, const TrialPrior& prior, const nav::LocateResult& r,
                        const TrialErrors& e, const MatcherComparison& matchers, sensor::LookSide look) {
  const Eigen::Vector3d& sensor_true = prior.sensor_true;
  const Eigen::Vector3d& d = e.d;
  char row[1024];
  int n = std::snprintf(row, sizeof(row), "%d,%.4f,%.4f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.4f,%d,%d,%d,%.4f,%.3f,%.3f,%.3f,%.4f,%.5f,%.5f,%.5f,%.4f,%.4f,%.3f,%d",
               trial, truth.heading_deg, truth.depression_deg, truth.centre_enu.x(), truth.centre_enu.y(),
               sensor_true.x(), sensor_true.y(), sensor_true.z(), (prior.pose.SensorPosition(look) - sensor_true).norm(),
               std::remainder(prior.heading_deg - truth.heading_deg, 360.0), r.converged ? 1 : 0, r.iterations, r.inliers,
               r.rms_px, e.e3, e.eh, d.z(), e.cells, e.e_heading, e.e_dep, r.heading_sigma_deg, r.similarity, r.prior_similarity,
               r.seconds, e.success ? 1 : 0);
  const Eigen::Vector3d prior_offset = prior.pose.SensorPosition(look) - sensor_true;
  n += std::snprintf(row + n, sizeof(row) - n, ",%d,%.5f,%.2f,%.2f,%.2f", r.matches, r.depression_sigma_deg,
                     prior_offset.x(), prior_offset.y(), prior_offset.z());
  for (const auto& m : matchers.numbers) {
    n += std::snprintf(row + n, sizeof(row) - n, ",%.0f,%.0f,%.0f,%.4f", m[0], m[1], m[2], m[3]);
  }
  return row;
}

// One progress line per trial.
void ReportTrial(int trial, const EvaluateRequest& options, const TrialPrior& prior, const nav::LocateResult& r,
                 const TrialErrors& e, sensor::LookSide look, Reporter& reporter) {
  const Eigen::Vector3d prior_offset = prior.pose.SensorPosition(look) - prior.sensor_true;
  char line[320];
  std::snprintf(line, sizeof(line),
                "evaluate: trial %d/%d: prior offset %.0f m; %d matches, %d inliers, rms %.2f px; position error "
                "%.1f m (%.2f cells), heading %.3f deg, depression %+.3f deg, %s, %.2f s",
                trial + 1, options.trials, prior_offset.norm(), r.matches, r.inliers, r.rms_px, e.e3, e.cells,
                e.e_heading, e.e_dep, e.success ? "ok" : "FAIL", r.seconds);
  reporter.Info(line);
  ThrowIfCancelled(reporter, "evaluate");
}

// One Monte-Carlo trial: its randomness depends on (options.seed, trial)
// only (the true pose, materials, prior: std::mt19937_64 seeded with
// seed * 1000003 + trial; render, speckle and noise seeds from seed and
// trial), so any subset of trials, in any order or process, gives the same
// records.
nlohmann::json RunTrial(const EvaluateSetup& s, const EvaluateRequest& options, int trial, Reporter& reporter) {
  const sensor::LookSide look = s.model.look_side;
  nav::NavScene scene{&s.terrain.mesh, s.embree.get(), &s.terrain.materials, options.rays_per_cell, options.bounces};
  TrialRandom random(options.seed * 1000003ULL + trial);
  const TruePose truth = DrawTruePose(s, options, random);
  const render::SarImage obs = RenderObservedImage(s, options, trial, truth.pose, random);
  const TrialPrior prior = DrawPrior(scene, options, trial, truth.pose, look, random);
  const MatcherComparison matchers =
      options.compare_matchers ? CompareMatchers(s, scene, obs, prior.pose, truth.pose) : MatcherComparison();
  nlohmann::json database_record = nullptr;
  const nav::LocateResult r = FixTrial(s, options, scene, obs, prior.pose, truth, database_record);
  const TrialErrors e = ErrorsOf(r, truth.pose, prior.sensor_true, options);
  const std::string row = TrialCsvRow(trial, truth.pose, prior, r, e, matchers, look);
  ReportTrial(trial, options, prior, r, e, look, reporter);
  return {{"trial", trial},
          {"success", e.success},
          {"converged", r.converged},
          {"position_error_m", NumberOrNull(e.e3)},
          {"position_error_cells", NumberOrNull(e.cells)},
          {"horizontal_error_m", NumberOrNull(e.eh)},
          {"heading_error_deg", NumberOrNull(e.e_heading)},
          {"depression_error_deg", NumberOrNull(std::abs(e.e_dep))},
          {"seconds", r.seconds},
          {"database", database_record},
          {"matchers", matchers.rows},
          {"csv_row", row}};
}

std::string TrialsCsvHeader(const EvaluateRequest& options) {
  std::string h =
      "trial,heading_deg,depression_deg,centre_x_m,centre_y_m,sensor_x_m,sensor_y_m,sensor_z_m,"
      "prior_position_error_m,prior_heading_error_deg,converged,iterations,inliers,rms_px,"
      "position_error_m,horizontal_error_m,vertical_error_m,position_error_cells,heading_error_deg,"
      "depression_error_deg,sigma_heading_deg,similarity,prior_similarity,seconds,success,matches,"
      "sigma_depression_deg,prior_east_m,prior_north_m,prior_up_m";
  if (options.compare_matchers) {
    for (nav::Matcher m : ComparedMatchers()) {
      const std::string n = nav::ToString(m);
      h += "," + n + "_raw," + n + "_inliers," + n + "_good," + n + "_median_err_px";
    }
  }
  return h;
}

// Records sorted by trial; ConfigError for a repeated trial.
std::vector<nlohmann::json> SortedRecords(const std::vector<nlohmann::json>& records) {
  std::vector<nlohmann::json> sorted = records;
  std::sort(sorted.begin(), sorted.end(),
            [](const nlohmann::json& a, const nlohmann::json& b) { return a.at("trial").get<int>() < b.at("trial").get<int>(); });
  for (size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i]["trial"] == sorted[i - 1]["trial"]) {
      throw ConfigError("trial " + sorted[i]["trial"].dump() + " appears twice", "evaluate trial records");
    }
  }
  return sorted;
}

}  // namespace

std::vector<nlohmann::json> TerrainEvaluateTrials(const EvaluateRequest& requested, Reporter& reporter) {
  requested.Check();
  if (!requested.product.empty()) {
    throw ConfigError("a product's trials are run by the product path (product_locate.h)", "--product");
  }
  const EvaluateRequest options = requested.Resolved();
  const EvaluateSetup setup = PrepareEvaluation(options, reporter);
  std::vector<nlohmann::json> records;
  const int last = options.trial_count < 0 ? options.trials : options.trial_first + options.trial_count;
  for (int trial = options.trial_first; trial < last; ++trial) records.push_back(RunTrial(setup, options, trial, reporter));
  return records;
}

nlohmann::json TerrainSummariseTrials(const EvaluateRequest& requested, const std::vector<nlohmann::json>& unsorted) {
  if (!requested.product.empty()) {
    throw ConfigError("a product's trials are run by the product path (product_locate.h)", "--product");
  }
  // A database sets the cell size (EvaluateRequest::Resolved).
  const EvaluateRequest options = requested.database.empty() ? requested : requested.Resolved();
  const std::vector<nlohmann::json> records = SortedRecords(unsorted);
  if (records.empty()) throw ConfigError("no trial records to summarise", "evaluate trial records");
  std::vector<double> pos_err, pos_cells, horiz_err, head_err, dep_err, seconds;
  int successes = 0, converged = 0;
  struct MatcherStats { std::vector<double> raw, inliers, good, median; };
  const auto& matchers = ComparedMatchers();
  std::vector<MatcherStats> mstats(matchers.size());
  for (const nlohmann::json& r : records) {
    successes += r.at("success").get<bool>();
    converged += r.at("converged").get<bool>();
    pos_err.push_back(NumberOf(r.at("position_error_m")));
    pos_cells.push_back(NumberOf(r.at("position_error_cells")));
    horiz_err.push_back(NumberOf(r.at("horizontal_error_m")));
    head_err.push_back(NumberOf(r.at("heading_error_deg")));
    dep_err.push_back(NumberOf(r.at("depression_error_deg")));
    seconds.push_back(NumberOf(r.at("seconds")));
    const nlohmann::json& rows = r.at("matchers");
    for (size_t k = 0; k < rows.size() && k < matchers.size(); ++k) {
      mstats[k].raw.push_back(NumberOf(rows[k].at("raw")));
      mstats[k].inliers.push_back(NumberOf(rows[k].at("inliers")));
      mstats[k].good.push_back(NumberOf(rows[k].at("good")));
      const double med = NumberOf(rows[k].at("median_error_px"));
      if (std::isfinite(med)) mstats[k].median.push_back(med);
    }
  }
  const int n = static_cast<int>(records.size());
  nlohmann::json matcher_json = nlohmann::json::object();
  if (options.compare_matchers) {
    for (size_t k = 0; k < matchers.size(); ++k) {
      matcher_json[nav::ToString(matchers[k])] = {
          {"median_raw_matches", Percentile(mstats[k].raw, 0.5)},
          {"median_inliers_after_ransac", Percentile(mstats[k].inliers, 0.5)},
          {"median_inliers_within_1px_of_truth", Percentile(mstats[k].good, 0.5)},
          {"median_of_trial_median_error_px", Percentile(mstats[k].median, 0.5)},
          {"trials_with_8_or_more_good", std::count_if(mstats[k].good.begin(), mstats[k].good.end(), [](double g) { return g >= 8; })}};
    }
  }
  nlohmann::json database = nullptr;
  if (!options.database.empty()) {
    int uncovered = 0, fallbacks = 0;
    for (const nlohmann::json& r : records) {
      const auto it = r.find("database");
      if (it == r.end() || !it->is_object()) continue;
      if (it->contains("reason") && !(*it)["reason"].is_null()) ++uncovered;
      if (it->contains("fallback") && !(*it)["fallback"].is_null()) ++fallbacks;
    }
    database = {{"catalog", options.database},
                {"fixes", options.database_fixes},
                {"fallback", options.database_fallback},
                {"heading_tolerance_deg", options.database_heading_tolerance_deg},
                {"trials_without_covering_reference", uncovered},
                {"trials_fixed_by_fallback", fallbacks}};
  }
  return {{"trials", n},
          {"seed", options.seed},
          {"database", database},
          {"success_definition", "converged, 3-D sensor position error <= success_cells resolution cells and "
                                 "heading error <= success_heading_deg"},
          {"success_cells", options.success_cells},
          {"success_heading_deg", options.success_heading_deg},
          {"resolution_cell_m", options.spacing_m},
          {"success_rate", double(successes) / n},
          {"converged_rate", double(converged) / n},
          {"position_error_m", {{"median", Percentile(pos_err, 0.5)}, {"p95", Percentile(pos_err, 0.95)}}},
          {"position_error_cells", {{"median", Percentile(pos_cells, 0.5)}, {"p95", Percentile(pos_cells, 0.95)}}},
          {"horizontal_error_m", {{"median", Percentile(horiz_err, 0.5)}, {"p95", Percentile(horiz_err, 0.95)}}},
          {"heading_error_deg", {{"median", Percentile(head_err, 0.5)}, {"p95", Percentile(head_err, 0.95)}}},
          {"depression_error_deg", {{"median", Percentile(dep_err, 0.5)}, {"p95", Percentile(dep_err, 0.95)}}},
          {"seconds_per_fix", {{"median", Percentile(seconds, 0.5)}, {"p95", Percentile(seconds, 0.95)}}},
          {"matcher_comparison_first_iteration", matcher_json}};
}

nlohmann::json WriteTerrainEvaluation(const EvaluateRequest& requested, const std::vector<nlohmann::json>& unsorted,
                                      const std::string& command_line, double seconds,
                                      const nlohmann::json& vertical_datum) {
  requested.Check();
  if (!requested.product.empty()) {
    throw ConfigError("a product's trials are run by the product path (product_locate.h)", "--product");
  }
  const EvaluateRequest options = requested.Resolved();
  AtomicOutputs outputs;
  const fs::path json_path = outputs.Add(options.out_prefix + ".json");
  const fs::path csv_path = outputs.Add(options.out_prefix + "_trials.csv");
  const fs::path png_path = outputs.Add(options.out_prefix + "_hist.png");
  CheckOutputsAreNotInputs({options.out_prefix + ".json", options.out_prefix + "_trials.csv"},
                           {options.scene, options.dem, options.database});
  const std::vector<nlohmann::json> records = SortedRecords(unsorted);
  nlohmann::json stats = TerrainSummariseTrials(options, records);
  std::FILE* csv = std::fopen(csv_path.c_str(), "w");
  if (csv == nullptr) throw WriteError("cannot write the trials CSV", csv_path, errno);
  std::fprintf(csv, "%s\n", TrialsCsvHeader(options).c_str());
  std::vector<double> pos_cells;
  int successes = 0;
  for (const nlohmann::json& r : records) {
    std::fprintf(csv, "%s\n", r.at("csv_row").get<std::string>().c_str());
    pos_cells.push_back(NumberOf(r.at("position_error_cells")));
    successes += r.at("success").get<bool>();
  }
  const int write_error = std::ferror(csv) != 0 ? errno : 0;
  if (std::fclose(csv) != 0 || write_error != 0) {
    throw WriteError("failed writing the trials CSV", csv_path, write_error != 0 ? write_error : errno);
  }
  const std::string title = fs::path(options.scene.empty() ? options.dem : options.scene).stem().string() + ": " +
                            std::to_string(records.size()) + " trials, " + std::to_string(successes) + " successes";
  WriteHistogram(png_path, pos_cells, options.success_cells, title);
  // The options as the serial run records them (search_px and the floor as resolved).
  nav::LocateOptions lo;
  ResolveSearchAndFloor(options, lo);
  nlohmann::json summary = {{"command", "evaluate"},
                            {"command_line", command_line},
                            {"version", VersionString()},
                            {"created_utc", UtcTimestamp()}};
  for (auto& [key, value] : stats.items()) summary[key] = value;
  summary["options"] = {{"spacing_m", options.spacing_m}, {"size_px", options.size_px}, {"slant_range_m", options.slant_range_m},
                        {"depression_range_deg", {options.depression_min_deg, options.depression_max_deg}},
                        {"speckle_looks", options.speckle_looks}, {"nesz_db", options.nesz_db},
                        {"material_db", options.material_db}, {"dem_smoothing", options.dem_smoothing},
                        {"prior_error_horizontal_m", options.prior_error_horizontal_m}, {"prior_error_vertical_m", options.prior_error_vertical_m},
                        {"prior_error_heading_deg", options.prior_error_heading_deg}, {"matcher", options.matcher},
                        {"dense_renders", options.dense_renders},
                        {"polish_evaluations", options.polish_evaluations}, {"search_px", lo.initial_search_px}, {"step_px", options.step_px}, {"bounces", options.bounces},
                        {"reference_floor", lo.reference_floor},
                        {"rays_per_cell", options.rays_per_cell}, {"database", options.database},
                        {"database_fixes", options.database_fixes}, {"database_fallback", options.database_fallback},
                        {"database_heading_tolerance_deg", options.database_heading_tolerance_deg}};
  summary["vertical_datum"] = vertical_datum.is_null()
                                  ? nlohmann::json{{"datum", geo::CanonicalVerticalDatum(options.vertical_datum)}}
                                  : vertical_datum;
  summary["inputs"] = {{"terrain", InputFileRecord(options.scene.empty() ? options.dem : options.scene)}};
  if (!options.database.empty()) summary["inputs"]["database"] = InputFileRecord(options.database);
  summary["seconds"] = seconds;
  WriteJsonFile(summary, json_path);
  outputs.Commit();
  return summary;
}

nlohmann::json RunTerrainEvaluate(const EvaluateRequest& requested, const std::string& command_line,
                                  Reporter& reporter) {
  requested.Check();
  if (!requested.product.empty()) {
    throw ConfigError("a product's trials are run by the product path (product_locate.h)", "--product");
  }
  const EvaluateRequest options = requested.Resolved();
  Stopwatch total;
  {
    // Fail on a missing or read-only output directory before any trial.
    AtomicOutputs probe;
    probe.Add(options.out_prefix + ".json");
  }
  const EvaluateSetup setup = PrepareEvaluation(options, reporter);
  std::vector<nlohmann::json> records;
  const int last = options.trial_count < 0 ? options.trials : options.trial_first + options.trial_count;
  for (int trial = options.trial_first; trial < last; ++trial) records.push_back(RunTrial(setup, options, trial, reporter));
  return WriteTerrainEvaluation(options, records, command_line, total.ElapsedSeconds(),
                                VerticalDatumRecord(setup.terrain));
}

void MatchPairRequest::Check() const {
  if (fixed.empty() || moving.empty()) throw ConfigError("required", "--fixed/--moving");
  if (out.empty()) throw ConfigError("required", "--out");
  if (warp.size() != 4) throw ConfigError("needs ROT_DEG,SCALE,TX,TY", "--warp");
  for (double v : warp) if (!std::isfinite(v)) throw ConfigError("must be finite", "--warp");
  if (!(warp[1] > 0)) throw ConfigError("scale must be > 0", "--warp");
  if (search_px < 1 || search_px > kMaxSearchPx) throw ConfigError("must be in [1, 2048] px", "--search");
  nav::MatchOptions m;
  m.patch_px = patch_px;
  m.step_px = step_px;
  m.search_px = search_px;
  m.Check();
  if (filter_px < 1) throw ConfigError("must be >= 1", "--filter");
  CheckOutputsAreNotInputs({out}, {fixed, moving});
}

nlohmann::json RunMatchPair(const MatchPairRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  AtomicOutputs outputs;
  const fs::path out = outputs.Add(options.out);
  auto load = [](const std::string& path, int& w, int& h) {
    geo::FloatRaster r = geo::ReadFloatRaster(path);
    w = r.width;
    h = r.height;
    std::vector<float> v = r.bands.at(0);
    for (float& x : v) if (!std::isfinite(x) || x < 0) x = 0.0f;
    return v;
  };
  int w1, h1, w2, h2;
  const std::vector<float> a = load(options.fixed, w1, h1);
  std::vector<float> b = load(options.moving, w2, h2);
  if (w1 != w2 || h1 != h2) throw InputError("the two images differ in size", options.moving);
  // Known warp T (moving -> warped): rotation and scale about the centre, then a shift.
  const double th = options.warp[0] * M_PI / 180.0, s = options.warp[1];
  const Eigen::Vector2d c((w1 - 1) / 2.0, (h1 - 1) / 2.0);
  Eigen::Matrix2d A;
  A << s * std::cos(th), -s * std::sin(th), s * std::sin(th), s * std::cos(th);
  const Eigen::Vector2d t = c - A * c + Eigen::Vector2d(options.warp[2], options.warp[3]);
  cv::Mat M = (cv::Mat_<double>(2, 3) << A(0, 0), A(0, 1), t.x(), A(1, 0), A(1, 1), t.y());
  cv::Mat moving(h2, w2, CV_32F, b.data()), warped;
  cv::warpAffine(moving, warped, M, moving.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  std::vector<float> wv(warped.begin<float>(), warped.end<float>());
  const cv::Mat fixed_log = nav::LogIntensity(a, w1, h1, options.filter_px);
  const cv::Mat warped_log = nav::LogIntensity(wv, w1, h1, options.filter_px);
  nlohmann::json results = nlohmann::json::object();
  for (nav::Matcher m : {nav::Matcher::kNcc, nav::Matcher::kChamfer, nav::Matcher::kFeatures}) {
    nav::MatchOptions mo;
    mo.patch_px = options.patch_px;
    mo.step_px = options.step_px;
    mo.search_px = options.search_px;
    mo.min_contrast_db = 0.0;
    Stopwatch clock;
    // Reference = fixed image, observed = warped moving image.
    const auto corr = nav::Match(m, fixed_log, warped_log, mo);
    nlohmann::json r = {{"correspondences", corr.size()}};
    if (corr.size() >= 4) {
      std::vector<mvg::PointMatch> pairs;
      for (const auto& k : corr) pairs.push_back({k.observed, k.reference});
      mvg::RegistrationOptions ro;
      ro.threshold_px = 1.5;
      const auto reg = mvg::RegisterControlPoints(pairs, ro);
      if (reg) {
        double sum = 0;
        int n = 0;
        for (int y = 0; y < h1; ++y)
          for (int x = 0; x < w1; ++x) {
            const Eigen::Vector2d p(x, y);
            sum += (reg->moving_to_fixed.Apply(p) - (A * p + t)).squaredNorm();
            ++n;
          }
        r["inliers"] = reg->inliers.size();
        r["fit_rms_px"] = reg->rms_px;
        r["warp_rms_error_px"] = std::sqrt(sum / n);
      }
    }
    r["seconds"] = clock.ElapsedSeconds();
    results[nav::ToString(m)] = r;
  }
  nlohmann::json report = {{"command", "matchpair"},
                           {"command_line", command_line},
                           {"version", VersionString()},
                           {"created_utc", UtcTimestamp()},
                           {"warp", {{"rotation_deg", options.warp[0]}, {"scale", options.warp[1]},
                                     {"tx_px", options.warp[2]}, {"ty_px", options.warp[3]}}},
                           {"image_size", {w1, h1}},
                           {"matchers", results},
                           {"inputs", {{"fixed", InputFileRecord(options.fixed)}, {"moving", InputFileRecord(options.moving)}}}};
  WriteJsonFile(report, out);
  outputs.Commit();
  return report;
}

}  // namespace gissar::pipeline
