#include "gissar/pipeline/reference_database.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>

#include "gissar/geo/raster_io.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
namespace {

constexpr double kDeg = M_PI / 180.0;

// Typed access to the catalogue's JSON with errors naming the file and the key path.
struct Node {
  const nlohmann::json& json;
  std::string key;   // path of this node, e.g. gissar:poses[3].reference
  const std::string& file;

  [[noreturn]] void Fail(const std::string& what, const std::string& at) const {
    throw InputError(what + " (key " + at + ")", file);
  }
  std::string Child(const std::string& name) const { return key.empty() ? name : key + "." + name; }
  Node At(const std::string& name) const {
    if (!json.is_object()) Fail("must be a JSON object", key.empty() ? "(top level)" : key);
    const auto it = json.find(name);
    if (it == json.end()) Fail("missing key '" + name + "'", Child(name));
    return Node{*it, Child(name), file};
  }
  bool Has(const std::string& name) const { return json.is_object() && json.contains(name) && !json[name].is_null(); }
  double Number() const {
    if (!json.is_number() || !std::isfinite(json.get<double>())) Fail("must be a finite number", key);
    return json.get<double>();
  }
  double Positive() const {
    const double v = Number();
    if (!(v > 0)) Fail("must be > 0", key);
    return v;
  }
  int Integer(int lo, int hi) const {
    if (!json.is_number_integer() || json.get<int64_t>() < lo || json.get<int64_t>() > hi) {
      Fail("must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]", key);
    }
    return static_cast<int>(json.get<int64_t>());
  }
  std::string String() const {
    if (!json.is_string()) Fail("must be a string", key);
    return json.get<std::string>();
  }
  bool Bool() const {
    if (!json.is_boolean()) Fail("must be true or false", key);
    return json.get<bool>();
  }
  Eigen::Vector3d Vector3() const {
    if (!json.is_array() || json.size() != 3) Fail("must be an array of 3 numbers", key);
    Eigen::Vector3d v;
    for (int k = 0; k < 3; ++k) v[k] = Node{json[k], key + "[" + std::to_string(k) + "]", file}.Number();
    return v;
  }
  Eigen::Vector3d Unit3() const {
    const Eigen::Vector3d v = Vector3();
    if (std::abs(v.norm() - 1.0) > 1e-6) Fail("must be a unit vector", key);
    return v;
  }
};

std::string Hex(const std::string& text) {
  const bool ok = text.size() == 64 && std::all_of(text.begin(), text.end(), [](char c) {
    return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
  });
  return ok ? text : std::string();
}

std::string Fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

}  // namespace

nlohmann::json StoredReferenceItem::ToJson() const { return {{"id", id}, {"image", image}}; }

ReferenceDatabase ReadReferenceDatabase(const std::string& path) {
  if (!fs::exists(path)) throw InputError("reference database catalogue does not exist", path);
  std::ifstream in(path);
  if (!in) throw IoError("cannot read the reference database catalogue", path);
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    std::string what = e.what();
    what = what.substr(what.find(']') + 1);
    what.erase(0, what.find_first_not_of(' '));
    throw InputError("the reference database catalogue is not JSON: " + what, path);
  }
  const Node root{json, "", path};
  ReferenceDatabase db;
  db.path = path;
  if (!root.Has("gissar:database")) {
    root.Fail("missing key 'gissar:database': not a reference database (a gissar corridor catalogue written "
              "since database format 1; re-run the corridor to add it)", "gissar:database");
  }
  const Node d = root.At("gissar:database");
  const int format = d.At("format").Integer(1, 1000000);
  if (format != 1) d.Fail("unsupported database format " + std::to_string(format) + " (this gissar reads 1)", d.Child("format"));
  db.terrain = d.At("terrain").String();
  if (db.terrain != "dem" && db.terrain != "scene") d.Fail("must be dem or scene", d.Child("terrain"));
  const Node hash = d.At("terrain_sha256");
  if (hash.json.is_null()) {
    hash.Fail("no content hash of the terrain: the database cannot be checked against --dem/--scene (a GDAL virtual "
              "path?); rebuild it from a local file", hash.key);
  }
  db.terrain_sha256 = Hex(hash.String());
  if (db.terrain_sha256.empty()) hash.Fail("must be 64 lowercase hex digits (SHA-256)", hash.key);
  if (d.Has("vertical_datum")) db.vertical_datum = d.At("vertical_datum").String();
  const Node poses = root.At("gissar:poses");
  if (!poses.json.is_array()) poses.Fail("must be an array", poses.key);
  const fs::path directory = fs::absolute(fs::path(path)).parent_path();
  db.poses = static_cast<int>(poses.json.size());
  for (size_t i = 0; i < poses.json.size(); ++i) {
    const Node pose{poses.json[i], "gissar:poses[" + std::to_string(i) + "]", path};
    const std::string status = pose.At("status").String();
    if (status != "done" || !pose.Has("reference")) continue;
    const Node r = pose.At("reference");
    StoredReferenceItem item;
    item.id = pose.At("id").String();
    auto file = [&](const std::string& name) {
      const std::string rel = r.At(name).String();
      if (rel.empty()) r.Fail("must name a file", r.Child(name));
      const fs::path p(rel);
      return (p.is_absolute() ? p : directory / p).lexically_normal().string();
    };
    item.image = file("image");
    if (r.Has("mask")) item.mask = file("mask");
    if (r.Has("band")) item.band = r.At("band").Integer(1, 65535);
    if (r.Has("db")) item.db = r.At("db").Bool();
    item.heading_deg = r.At("heading_deg").Number();
    item.depression_deg = r.At("depression_deg").Number();
    if (!(item.depression_deg > 1.0 && item.depression_deg < 89.0)) r.Fail("must be in (1, 89) deg", r.Child("depression_deg"));
    item.slant_range_m = r.At("slant_range_m").Positive();
    const std::string look = r.At("look_side").String();
    const std::optional<sensor::LookSide> side = sensor::kLookSides.Find(look);
    if (!side) r.Fail(sensor::kLookSides.UnknownMessage(look), r.Child("look_side"));
    item.look_side = *side;
    const std::string affine = sensor::ToString(sensor::ProjectionMode::kAffine);
    const std::string mode = r.Has("projection_mode") ? r.At("projection_mode").String() : affine;
    if (mode != affine) {
      r.Fail("stored references must be affine images (projection mode '" + mode + "')", r.Child("projection_mode"));
    }
    item.frame_origin = r.At("frame_origin_lon_lat_h").Vector3();
    if (!(std::abs(item.frame_origin.y()) <= 90.0)) r.Fail("latitude out of range", r.Child("frame_origin_lon_lat_h"));
    item.centre_enu = r.At("centre_enu_m").Vector3();
    item.look_direction = r.At("look_direction_enu").Unit3();
    item.flight_direction = r.At("flight_direction_enu").Unit3();
    item.u0 = r.At("u0").Number();
    item.v0 = r.At("v0").Number();
    item.width = r.At("width").Integer(48, 1 << 15);
    item.height = r.At("height").Integer(48, 1 << 15);
    item.range_spacing_m = r.At("range_spacing_m").Positive();
    item.azimuth_spacing_m = r.At("azimuth_spacing_m").Positive();
    if (std::abs(item.look_direction.dot(item.flight_direction)) > 1e-3) {
      r.Fail("look and flight directions must be perpendicular", r.Child("look_direction_enu"));
    }
    db.items.push_back(std::move(item));
  }
  if (db.items.empty()) {
    throw InputError("the reference database holds no stored reference (no done pose with a 'reference' entry among " +
                         std::to_string(db.poses) + " poses)",
                     path);
  }
  return db;
}

void CheckDatabaseTerrain(const ReferenceDatabase& database, const std::string& scene, const std::string& dem,
                          const std::string& vertical_datum) {
  const std::string kind = scene.empty() ? "dem" : "scene";
  const std::string given = scene.empty() ? dem : scene;
  if (kind != database.terrain) {
    throw InputError("the reference database was built from a " + std::string(database.terrain == "dem" ? "DEM" : "scene") +
                         ", not a " + (kind == "dem" ? "DEM" : "scene") + ": give --" + database.terrain,
                     database.path);
  }
  const std::string hash = Sha256OfFile(given);
  if (hash != database.terrain_sha256) {
    throw InputError("the reference database was built from another " + std::string(kind == "dem" ? "DEM" : "scene") +
                         ": its catalogue records SHA-256 " + database.terrain_sha256 + ", --" + kind + " " + given +
                         " has SHA-256 " + hash,
                     database.path);
  }
  if (!vertical_datum.empty() && !database.vertical_datum.empty() &&
      geo::CanonicalVerticalDatum(vertical_datum) != geo::CanonicalVerticalDatum(database.vertical_datum)) {
    throw ConfigError("the reference database was built with vertical datum " + database.vertical_datum + ", not " +
                          vertical_datum,
                      "--vertical-datum");
  }
}

sensor::SarGeometry ItemGeometryInFrame(const StoredReferenceItem& item, const geo::LocalFrame& frame) {
  const geo::LocalFrame source(item.frame_origin.x(), item.frame_origin.y(), item.frame_origin.z());
  auto carry = [&](const Eigen::Vector3d& enu) {
    const Eigen::Vector3d g = source.GeodeticFromEnu(enu);
    return frame.EnuFromGeodetic(g.x(), g.y(), g.z());
  };
  const Eigen::Vector3d centre = carry(item.centre_enu);
  const Eigen::Vector3d l = (carry(item.centre_enu + 1000.0 * item.look_direction) - centre).normalized();
  const Eigen::Vector3d h = (carry(item.centre_enu + 1000.0 * item.flight_direction) - centre).normalized();
  nav::NavPose pose;
  pose.heading_deg = std::atan2(h.x(), h.y()) / kDeg;
  if (pose.heading_deg < 0) pose.heading_deg += 360.0;
  pose.depression_deg = std::asin(std::clamp(-l.z(), -1.0, 1.0)) / kDeg;
  pose.slant_range_m = item.slant_range_m;
  pose.centre_enu = centre;
  nav::SensorModel model;
  model.range_spacing_m = item.range_spacing_m;
  model.azimuth_spacing_m = item.azimuth_spacing_m;
  model.width = item.width;
  model.height = item.height;
  model.look_side = item.look_side;
  return sensor::SarGeometry(nav::AffineGeometryOptions(pose, model), centre, item.u0, item.v0, item.width,
                             item.height);
}

std::vector<ReferenceChoice> CoveringReferences(const ReferenceDatabase& database,
                                                const std::vector<sensor::SarGeometry>& cameras,
                                                const nav::NavPose& prior, const nav::SensorModel& model,
                                                double heading_tolerance_deg, size_t max_choices,
                                                std::string* reason) {
  std::vector<ReferenceChoice> covering;
  std::optional<ReferenceChoice> nearest;
  std::string nearest_where;
  int other_sensor = 0;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const sensor::SarGeometry& g = cameras[i];
    const double ratio_r = g.range_spacing_m() / model.range_spacing_m;
    const double ratio_a = g.azimuth_spacing_m() / model.azimuth_spacing_m;
    if (g.options().look_side != model.look_side || ratio_r < 2.0 / 3.0 || ratio_r > 1.5 || ratio_a < 2.0 / 3.0 ||
        ratio_a > 1.5) {
      ++other_sensor;
      continue;
    }
    ReferenceChoice c;
    c.item = i;
    c.distance_m = (prior.centre_enu - g.scene_centre()).head<2>().norm();
    c.heading_difference_deg = std::abs(std::remainder(prior.heading_deg - g.options().heading_deg, 360.0));
    const Eigen::Vector2d px = g.Project(prior.centre_enu);
    const double w = g.width() - 1, h = g.height() - 1;
    const bool inside = px.x() >= 0.25 * w && px.x() <= 0.75 * w && px.y() >= 0.25 * h && px.y() <= 0.75 * h;
    if (inside && c.heading_difference_deg <= heading_tolerance_deg) covering.push_back(c);
    if (!nearest || c.distance_m < nearest->distance_m) {
      nearest = c;
      nearest_where = "(" + Fixed(px.x(), 0) + ", " + Fixed(px.y(), 0) + ") of its " + std::to_string(g.width()) +
                      " x " + std::to_string(g.height()) + " px image";
    }
  }
  std::sort(covering.begin(), covering.end(),
            [](const ReferenceChoice& a, const ReferenceChoice& b) { return a.distance_m < b.distance_m; });
  if (covering.size() > max_choices) covering.resize(max_choices);
  if (covering.empty() && reason != nullptr) {
    if (!nearest) {
      *reason = "no stored reference of the database matches the image's sensor (look side, or pixel spacing within "
                "a factor 1.5 of " + Fixed(model.range_spacing_m, 1) + " x " + Fixed(model.azimuth_spacing_m, 1) +
                " m): " + std::to_string(other_sensor) + " references differ";
    } else {
      *reason = "no stored reference covers the prior (its image centre in the central half of a reference, heading "
                "within " + Fixed(heading_tolerance_deg, 1) + " deg): the nearest, " +
                database.items[nearest->item].id + ", is " + Fixed(nearest->distance_m, 0) + " m away, heading " +
                Fixed(nearest->heading_difference_deg, 1) + " deg off, the prior's centre at pixel " + nearest_where;
    }
  }
  return covering;
}

nav::StoredReference LoadStoredReference(const StoredReferenceItem& item, const sensor::SarGeometry& geometry,
                                         const nav::NavScene& scene) {
  if (!fs::exists(item.image)) throw InputError("stored reference image of " + item.id + " does not exist", item.image);
  geo::FloatRaster raster = geo::ReadFloatRaster(item.image);
  if (raster.width != item.width || raster.height != item.height) {
    throw InputError("stored reference image is " + std::to_string(raster.width) + " x " +
                         std::to_string(raster.height) + " px, its catalogue entry says " + std::to_string(item.width) +
                         " x " + std::to_string(item.height),
                     item.image);
  }
  if (item.band > static_cast<int>(raster.bands.size())) {
    throw InputError("stored reference image has no band " + std::to_string(item.band), item.image);
  }
  std::vector<float> intensity = std::move(raster.bands[item.band - 1]);
  if (item.db) {
    for (float& v : intensity) v = std::isfinite(v) ? static_cast<float>(std::pow(10.0, v / 10.0)) : 0.0f;
  }
  std::vector<uint8_t> mask;
  if (!item.mask.empty()) {
    if (!fs::exists(item.mask)) throw InputError("stored reference mask of " + item.id + " does not exist", item.mask);
    int w = 0, h = 0;
    mask = geo::ReadByteRaster(item.mask, &w, &h);
    if (w != item.width || h != item.height) throw InputError("stored reference mask is not the image's size", item.mask);
  }
  return nav::MakeStoredReference(scene, geometry, std::move(intensity), mask);
}

}  // namespace gissar::pipeline
