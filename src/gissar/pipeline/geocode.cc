#include "gissar/pipeline/geocode.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/pipeline/georeferencing.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/stac.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/number_text.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

std::string Stem(const std::string& tif) {
  const std::string suffix = ".tif";
  if (tif.size() > suffix.size() && tif.compare(tif.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return tif.substr(0, tif.size() - suffix.size());
  }
  return tif;
}

double MetadataNumber(const geo::Metadata& m, const std::string& key, const std::string& source) {
  const auto it = m.find(key);
  if (it == m.end()) throw InputError("not a gissar slant-range image: metadata " + key + " missing", source);
  const std::optional<double> value = util::ParseFiniteNumber(it->second);
  if (!value) throw InputError("metadata " + key + " is not a number: " + it->second, source);
  return *value;
}

std::string MetadataText(const geo::Metadata& m, const std::string& key, const std::string& source) {
  const auto it = m.find(key);
  if (it == m.end()) throw InputError("not a gissar slant-range image: metadata " + key + " missing", source);
  return it->second;
}

// Bilinear sample of a row-major plane at a continuous pixel (centres at
// integers); NaN neighbours are left out and the weights renormalised. NaN
// outside [-0.5, w - 0.5] x [-0.5, h - 0.5] or when every neighbour is NaN.
float Bilinear(const std::vector<float>& plane, int w, int h, double c, double r) {
  if (!(c >= -0.5 && r >= -0.5 && c <= w - 0.5 && r <= h - 0.5)) return kNan;
  const double cc = std::clamp(c, 0.0, double(w - 1)), rr = std::clamp(r, 0.0, double(h - 1));
  const int c0 = std::min(int(cc), std::max(w - 2, 0)), r0 = std::min(int(rr), std::max(h - 2, 0));
  const double fx = cc - c0, fy = rr - r0;
  double sum = 0.0, weight = 0.0;
  for (int dr = 0; dr <= 1; ++dr) {
    for (int dc = 0; dc <= 1; ++dc) {
      const int ci = std::min(c0 + dc, w - 1), ri = std::min(r0 + dr, h - 1);
      const double wgt = (dc ? fx : 1.0 - fx) * (dr ? fy : 1.0 - fy);
      const float v = plane[size_t(ri) * w + ci];
      if (wgt <= 0.0 || std::isnan(v)) continue;
      sum += wgt * v;
      weight += wgt;
    }
  }
  return weight > 0.0 ? float(sum / weight) : kNan;
}

// Loads the terrain the image was simulated from (or request.dem in the
// simulation's frame) from the sidecar's request.
Terrain LoadImageTerrain(const GeocodeRequest& request, const json& sidecar, const std::string& sidecar_path,
                         Reporter& reporter) {
  if (!sidecar.contains("options") || !sidecar.contains("frame") || !sidecar.contains("inputs")) {
    throw InputError("not the sidecar of a `gissar simulate` run (no options/frame/inputs)", sidecar_path);
  }
  SimulateRequest o;
  json options = sidecar["options"];
  for (const char* key : {"materials", "reflectors", "contributions", "out_prefix"}) options.erase(key);
  o.ApplyJson(options, sidecar_path);
  // The terrain's input record: after the product's, or the orbit's and the
  // radar grid's, on a real radar grid.
  const size_t index = !o.product.empty() ? 1 : !o.orbit.empty() ? 2 : 0;
  const std::string input = sidecar["inputs"].at(index).at("path").get<std::string>();
  const double lon0 = sidecar["frame"]["origin_lon_deg"].get<double>();
  const double lat0 = sidecar["frame"]["origin_lat_deg"].get<double>();
  if (!request.dem.empty()) {
    o.dem = request.dem;
    o.vertical_datum = request.vertical_datum;
    o.scene.clear();
    o.dem_oversample = 1;
    o.center_map.reset();
    o.center_lonlat = Eigen::Vector2d(lon0, lat0);  // the simulation's frame
  } else if (!o.scene.empty()) {
    o.scene = input;
  } else {
    o.dem = input;
  }
  o.engine = SimulateEngine::kTrace;  // a triangulated surface, as the simulation's
  o.max_memory_bytes = request.max_memory_bytes;
  Terrain terrain = LoadTerrain(o, reporter);
  if (std::abs(terrain.frame.origin_lon_deg() - lon0) > 1e-9 || std::abs(terrain.frame.origin_lat_deg() - lat0) > 1e-9) {
    throw InputError("the terrain's frame differs from the image's (was the DEM or scene changed?)", sidecar_path);
  }
  return terrain;
}

}  // namespace

void GeocodeRequest::Check() const {
  if (image.empty()) throw ConfigError("an image is required", "--image");
  geo::CanonicalVerticalDatum(vertical_datum, "--vertical-datum");
  if (!vertical_datum.empty() && dem.empty()) {
    throw ConfigError("goes with --dem (the simulation's own terrain keeps its datum)", "--vertical-datum");
  }
  if (out_prefix.empty()) throw ConfigError("an output prefix is required", "--out");
  if (!(pixel_size_m >= 0.0) || !std::isfinite(pixel_size_m)) throw ConfigError("must be >= 0 (0 = automatic)", "--pixel-size");
  const fs::path out_tif = fs::absolute(out_prefix + ".tif").lexically_normal();
  for (const std::string& input : {image, Stem(image) + ".json", Stem(image) + "_mask.tif", dem}) {
    if (input.empty()) continue;
    const fs::path in = fs::absolute(input).lexically_normal();
    if (in == out_tif || in == fs::absolute(out_prefix + ".json").lexically_normal()) {
      throw ConfigError("output would overwrite the input " + input, "--out");
    }
  }
}

sensor::SarGeometry GeometryFromMetadata(const geo::Metadata& m, int width, int height, const std::string& source) {
  sensor::SarGeometryOptions o;
  o.mode = sensor::ParseProjectionMode(MetadataText(m, "GISSAR_PROJECTION_MODE", source), source);
  o.look_side = sensor::ParseLookSide(MetadataText(m, "GISSAR_LOOK_SIDE", source), source);
  o.heading_deg = MetadataNumber(m, "GISSAR_HEADING_DEG", source);
  o.depression_deg = MetadataNumber(m, "GISSAR_DEPRESSION_DEG", source);
  o.slant_range_m = MetadataNumber(m, "GISSAR_SLANT_RANGE_M", source);
  o.range_spacing_m = MetadataNumber(m, "GISSAR_RANGE_SPACING_M", source);
  o.azimuth_spacing_m = MetadataNumber(m, "GISSAR_AZIMUTH_SPACING_M", source);
  std::istringstream centre(MetadataText(m, "GISSAR_SCENE_CENTRE_ENU", source));
  Eigen::Vector3d xc;
  char comma1 = 0, comma2 = 0;
  centre >> xc.x() >> comma1 >> xc.y() >> comma2 >> xc.z();
  if (!centre || comma1 != ',' || comma2 != ',') throw InputError("metadata GISSAR_SCENE_CENTRE_ENU is malformed", source);
  return sensor::SarGeometry(o, xc, MetadataNumber(m, "GISSAR_U0", source), MetadataNumber(m, "GISSAR_V0", source),
                             width, height);
}

// How the image sees a terrain point, and what the outputs record of its
// geometry: an idealised (affine or exact) SarGeometry, or a real radar
// grid (a product's or an orbit's zero-Doppler grid, a Sentinel-1 burst,
// swath or GRD window) through geo2rdr on its orbit.
struct ImageProjection {
  // Pixel (column, row; centres at integers) of an ENU point of the
  // terrain's frame; NaN when the point has none (no zero-Doppler time).
  std::function<Eigen::Vector2d(const Eigen::Vector3d& enu)> project;
  // Unit vector (ENU) from the sensor to the point, for the local incidence.
  std::function<Eigen::Vector3d(const Eigen::Vector3d& enu)> ray_to;
  double range_spacing_m = 0.0, azimuth_spacing_m = 0.0;
  double ground_range_spacing_m = 0.0;  // a range pixel on the ground, m (points per output pixel)
  std::string mode;                     // provenance "projection_mode"
  sensor::LookSide look_side = sensor::LookSide::kRight;
  double incidence_deg = 0.0, off_nadir_deg = 0.0, look_azimuth_deg = 0.0;  // STAC, at the scene centre
  double wavelength_m = 0.0;  // a real grid's (its product's band); 0: the simulation's options say
};

ImageProjection IdealisedProjection(const sensor::SarGeometry& geometry) {
  ImageProjection p;
  p.project = [geometry](const Eigen::Vector3d& v) { return geometry.Project(v); };
  p.ray_to = [geometry](const Eigen::Vector3d& v) { return geometry.RayDirectionTo(v); };
  p.range_spacing_m = geometry.range_spacing_m();
  p.azimuth_spacing_m = geometry.azimuth_spacing_m();
  p.ground_range_spacing_m =
      geometry.range_spacing_m() / std::max(std::cos(geometry.options().depression_deg * M_PI / 180.0), 0.05);
  p.mode = sensor::ToString(geometry.mode());
  p.look_side = geometry.options().look_side;
  p.incidence_deg = geometry.IncidenceDeg(geometry.u0());
  p.off_nadir_deg = 90.0 - geometry.options().depression_deg;
  p.look_azimuth_deg = geometry.options().heading_deg + (p.look_side == sensor::LookSide::kRight ? 90.0 : -90.0);
  return p;
}

// The real radar grid a product simulation was rendered on (the request of
// its sidecar, read again as simulate read it): row = (zero-Doppler time -
// first line's) / line interval, column = (slant range - first sample's) /
// spacing, or for a Sentinel-1 GRD the ground-range pixel of that slant
// range (the product's srgr polynomials) minus the window's first pixel.
ImageProjection RadarGridProjection(const SimulateRequest& o, const geo::LocalFrame& frame, Reporter& reporter) {
  std::shared_ptr<const Sentinel1Source> s1;
  geo::RslcProduct grid;
  if (IsSentinel1Request(o)) {
    s1 = std::make_shared<const Sentinel1Source>(ReadSentinel1Source(o, reporter));
    grid = s1->grid;
  } else {
    grid = ReadProductGeometry(o, false, reporter);
  }
  auto orbit = std::make_shared<const sensor::Orbit>(grid.orbit.time_s, grid.orbit.position_m, grid.orbit.velocity_mps);
  const double t0 = grid.zero_doppler_time_s.front(), dt = grid.azimuth_spacing_s();
  const double r0 = grid.slant_range_m.front(), dr = grid.range_spacing_m();
  const double t_mid = 0.5 * (t0 + grid.zero_doppler_time_s.back());
  const bool ground = s1 && s1->ground_range;
  ImageProjection p;
  p.project = [=](const Eigen::Vector3d& enu) -> Eigen::Vector2d {
    const auto rc = sensor::Geo2Rdr(*orbit, frame.EcefFromEnu(enu), t_mid);
    if (!rc) return Eigen::Vector2d::Constant(std::nan(""));
    const double col = ground ? s1->annotation.GroundRangeOfSlantRange(rc->range_m, rc->time_s) / s1->ground_spacing_m -
                                    double(s1->window[1])
                              : (rc->range_m - r0) / dr;
    return {col, (rc->time_s - t0) / dt};
  };
  p.ray_to = [=](const Eigen::Vector3d& enu) -> Eigen::Vector3d {
    const Eigen::Vector3d x = frame.EcefFromEnu(enu);
    const auto rc = sensor::Geo2Rdr(*orbit, x, t_mid);
    if (!rc) return Eigen::Vector3d::Constant(std::nan(""));
    return frame.EnuVectorFromEcef(x - orbit->Interpolate(rc->time_s).position_m).normalized();
  };
  // The scene centre (the frame's origin) sets the figures of the metadata.
  const Eigen::Vector3d centre = frame.EcefFromEnu(Eigen::Vector3d::Zero());
  const auto rc = sensor::Geo2Rdr(*orbit, centre, t_mid);
  if (!rc) throw InputError("the scene centre has no zero-Doppler time on the product's orbit", o.product);
  const sensor::OrbitState state = orbit->Interpolate(rc->time_s);
  const Eigen::Vector3d ray = p.ray_to(Eigen::Vector3d::Zero());
  const double incidence = std::acos(std::clamp(-ray.z(), -1.0, 1.0));
  const Eigen::Vector3d sensor_llh = geo::LocalFrame::GeodeticFromEcef(state.position_m);
  const Eigen::Vector3d nadir =
      (geo::LocalFrame::EcefFromGeodetic(sensor_llh.x(), sensor_llh.y(), sensor_llh.z() - 1.0) - state.position_m)
          .normalized();
  const Eigen::Vector3d los = (centre - state.position_m).normalized();
  p.range_spacing_m = ground ? s1->ground_spacing_m : dr;
  p.azimuth_spacing_m = state.velocity_mps.norm() * centre.norm() / state.position_m.norm() * dt;
  p.ground_range_spacing_m = ground ? s1->ground_spacing_m : dr / std::max(std::sin(incidence), 0.05);
  p.mode = std::string("radar grid (zero-Doppler geo2rdr on the orbit of ") +
           (s1 ? "the Sentinel-1 " + std::string(s1->ground_range ? "GRD" : "SLC") : std::string("the product")) + ")";
  p.look_side = sensor::LookSideOf(grid.look_left);
  p.wavelength_m = grid.wavelength_m;
  p.incidence_deg = incidence * 180.0 / M_PI;
  p.off_nadir_deg = std::acos(std::clamp(nadir.dot(los), -1.0, 1.0)) * 180.0 / M_PI;
  p.look_azimuth_deg = std::fmod(std::atan2(ray.x(), ray.y()) * 180.0 / M_PI + 360.0, 360.0);
  return p;
}

std::string UtmCrsOf(double lon_deg, double lat_deg) {
  const int zone = std::clamp(int(std::floor((lon_deg + 180.0) / 6.0)) + 1, 1, 60);
  return "EPSG:" + std::to_string((lat_deg >= 0.0 ? 32600 : 32700) + zone);
}

namespace {

// The simulation's provenance sidecar beside the image.
json ReadSidecar(const std::string& sidecar_path) {
  json sidecar;
  std::ifstream in(sidecar_path);
  if (!in) throw InputError("cannot read the image's sidecar", sidecar_path);
  try {
    in >> sidecar;
  } catch (const json::exception& e) {
    throw InputError(std::string("sidecar is not valid JSON: ") + e.what(), sidecar_path);
  }
  return sidecar;
}

// The image's layover/shadow mask; it must have the image's size.
std::vector<uint8_t> ReadImageMask(const std::string& mask_path, const geo::FloatRaster& image) {
  int mask_w = 0, mask_h = 0;
  if (!fs::exists(mask_path)) throw InputError("the image's layover/shadow mask is missing", mask_path);
  std::vector<uint8_t> mask = geo::ReadByteRaster(mask_path, &mask_w, &mask_h);
  if (mask_w != image.width || mask_h != image.height) throw InputError("mask size differs from the image's", mask_path);
  return mask;
}

// An idealised geometry (GISSAR_* metadata) or the real radar grid of a
// product simulation (its sidecar's request).
ImageProjection ProjectionOfImage(const GeocodeRequest& request, const geo::FloatRaster& image, json& sidecar,
                                  const std::string& sidecar_path, const geo::LocalFrame& frame, Reporter& reporter) {
  const bool radar_grid = !sidecar["options"].value("product", std::string()).empty() ||
                          !sidecar["options"].value("orbit", std::string()).empty();
  if (radar_grid) {
    SimulateRequest o;
    json options = sidecar["options"];
    for (const char* key : {"materials", "reflectors", "contributions", "out_prefix"}) options.erase(key);
    o.ApplyJson(options, sidecar_path);
    return RadarGridProjection(o, frame, reporter);
  }
  return IdealisedProjection(GeometryFromMetadata(image.metadata, image.width, image.height, request.image));
}

// dB bands are resampled in linear power: converts them; whether they were.
bool ToLinearPower(geo::FloatRaster& image) {
  const bool db = image.metadata.count("GISSAR_UNITS") && image.metadata["GISSAR_UNITS"].find("(dB)") != std::string::npos;
  if (db) {
    for (auto& band : image.bands)
      for (float& v : band) v = std::isnan(v) ? v : float(std::pow(10.0, v / 10.0));
  }
  return db;
}

// The output map grid: in `transform`'s CRS, pixels of px metres, covering
// the terrain the image sees plus a pixel; k x k points per output pixel.
struct MapGrid {
  double px = 0.0, x_min = 0.0, y_max = 0.0;
  int width = 0, height = 0;
  std::vector<double> geotransform;
  int k = 1;
};

MapGrid PlanMapGrid(const GeocodeRequest& request, const Terrain& terrain, const ImageProjection& geometry,
                    const geo::FloatRaster& image, const geo::CrsTransform& transform) {
  MapGrid grid;
  const double px = request.pixel_size_m > 0.0 ? request.pixel_size_m
                                               : std::max(geometry.range_spacing_m, geometry.azimuth_spacing_m);
  // Extent: the terrain the image sees.
  std::vector<double> ex, ey;
  const auto& vertices = terrain.mesh.vertices;
  const size_t stride = std::max<size_t>(1, vertices.size() / 400000);
  for (size_t i = 0; i < vertices.size(); i += stride) {
    const Eigen::Vector3d v = vertices[i].cast<double>();
    if (!v.allFinite()) continue;
    const Eigen::Vector2d p = geometry.project(v);
    if (!p.allFinite() || p.x() < -0.5 || p.y() < -0.5 || p.x() > image.width - 0.5 || p.y() > image.height - 0.5) continue;
    const Eigen::Vector3d g = terrain.frame.GeodeticFromEnu(v);
    ex.push_back(g.x());
    ey.push_back(g.y());
  }
  if (ex.empty()) throw InputError("the image sees none of its terrain", request.image);
  transform.FromLonLat(ex, ey);
  const double x_min = std::floor(*std::min_element(ex.begin(), ex.end()) / px) * px - px;
  const double x_max = std::ceil(*std::max_element(ex.begin(), ex.end()) / px) * px + px;
  const double y_min = std::floor(*std::min_element(ey.begin(), ey.end()) / px) * px - px;
  const double y_max = std::ceil(*std::max_element(ey.begin(), ey.end()) / px) * px + px;
  const int width = int(std::lround((x_max - x_min) / px)), height = int(std::lround((y_max - y_min) / px));
  const int nbands_in = int(image.bands.size());
  const double bytes = double(width) * height * (nbands_in + 2) * 4.0 * 2.0;
  const std::string grid_size = "the map grid of " + std::to_string(width) + " x " + std::to_string(height) + " pixels";
  CheckImagePixels(width, height, request.max_memory_bytes, grid_size, "choose a larger --pixel-size", "--pixel-size");
  CheckMemoryBudget(bytes, request.max_memory_bytes, grid_size, "choose a larger --pixel-size");
  grid.px = px;
  grid.x_min = x_min;
  grid.y_max = y_max;
  grid.width = width;
  grid.height = height;
  grid.geotransform = {x_min, px, 0.0, y_max, 0.0, -px};
  // Points per output pixel.
  grid.k = request.resampling == GeocodeResampling::kAverage
               ? std::clamp(int(std::ceil(px / std::min(geometry.ground_range_spacing_m, geometry.azimuth_spacing_m) -
                                          1e-9)),
                            1, 8)
               : 1;
  return grid;
}

// The terrain point (ENU) under WGS84 lon/lat: the height h at which
// (lon, lat, h) lies on the surface, by fixed-point steps along the local
// vertical (its tilt in the frame is ~1e-3 over tens of km). NaN off the terrain.
Eigen::Vector3d GroundUnder(const geo::LocalFrame& frame, const TerrainSurface& surface, double lon, double lat) {
  const Eigen::Vector3d p0 = frame.EnuFromGeodetic(lon, lat, 0.0);
  const Eigen::Vector3d up = frame.EnuFromGeodetic(lon, lat, 1.0) - p0;
  double h = 0.0;
  Eigen::Vector3d p = p0;
  for (int it = 0; it < 6; ++it) {
    p = p0 + h * up;
    const double z = surface(p.x(), p.y());
    if (std::isnan(z)) return Eigen::Vector3d::Constant(std::nan(""));
    const double step = (z - p.z()) / up.z();
    h += step;
    if (std::abs(step) < 1e-4) break;
  }
  return p0 + h * up;
}

// The map bands: the image's (mean of the k x k points of each pixel that
// see it, bilinear; dB again when the image was), then local incidence and
// the layover/shadow code; NaN where no point sees the image.
class MapResampler {
 public:
  MapResampler(const MapGrid& grid, const geo::FloatRaster& image, const std::vector<uint8_t>& mask, bool db,
               const ImageProjection& geometry, const Terrain& terrain, const TerrainSurface& surface,
               const geo::CrsTransform& transform)
      : grid_(grid), image_(image), mask_(mask), db_(db), geometry_(geometry), frame_(terrain.frame),
        surface_(surface), transform_(transform), nbands_in_(int(image.bands.size())),
        bands_(nbands_in_ + 2, std::vector<float>(size_t(grid.width) * grid.height, kNan)), sums_(nbands_in_),
        counts_(nbands_in_) {}

  // One map row; the first and last valid pixel's centres go to the footprint.
  void Row(int row) {
    RowPoints(row);
    const size_t per_pixel = size_t(grid_.k) * grid_.k + 1;
    int first_valid = -1, last_valid = -1;
    for (int col = 0; col < grid_.width; ++col) {
      if (!Pixel(row, col, per_pixel)) continue;
      if (first_valid < 0) first_valid = col;
      last_valid = col;
      LocalIncidence(size_t(row) * grid_.width + col, col * per_pixel + per_pixel - 1);
    }
    for (int col : {first_valid, last_valid}) {
      if (col >= 0) footprint_.emplace_back(sx_[col * per_pixel + per_pixel - 1], sy_[col * per_pixel + per_pixel - 1]);
    }
  }

  int64_t valid() const { return valid_; }
  // lon/lat of each row's first and last valid pixel
  const std::vector<Eigen::Vector2d>& footprint() const { return footprint_; }
  std::vector<std::vector<float>>& bands() { return bands_; }

 private:
  // Every point of the row, in WGS84 lon/lat: k x k per pixel, then the
  // pixel centre.
  void RowPoints(int row) {
    const int k = grid_.k;
    const double px = grid_.px;
    sx_.clear();
    sy_.clear();
    for (int col = 0; col < grid_.width; ++col) {
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          sx_.push_back(grid_.x_min + (col + (i + 0.5) / k) * px);
          sy_.push_back(grid_.y_max - (row + (j + 0.5) / k) * px);
        }
      sx_.push_back(grid_.x_min + (col + 0.5) * px);
      sy_.push_back(grid_.y_max - (row + 0.5) * px);
    }
    transform_.ToLonLat(sx_, sy_);
  }

  // The image bands and mask code of pixel (row, col); false when none of
  // its points sees the image.
  bool Pixel(int row, int col, size_t per_pixel) {
    std::fill(sums_.begin(), sums_.end(), 0.0);
    std::fill(counts_.begin(), counts_.end(), 0);
    int code = 0, seen = 0;
    for (size_t s = 0; s < per_pixel - 1; ++s) {
      const size_t at = col * per_pixel + s;
      const Eigen::Vector3d p = GroundUnder(frame_, surface_, sx_[at], sy_[at]);
      if (!p.allFinite()) continue;
      const Eigen::Vector2d q = geometry_.project(p);
      if (!q.allFinite() || q.x() < -0.5 || q.y() < -0.5 || q.x() > image_.width - 0.5 || q.y() > image_.height - 0.5) continue;
      ++seen;
      for (int b = 0; b < nbands_in_; ++b) {
        const float v = Bilinear(image_.bands[b], image_.width, image_.height, q.x(), q.y());
        if (std::isnan(v)) continue;
        sums_[b] += v;
        ++counts_[b];
      }
      const int mc = std::clamp(int(std::lround(q.x())), 0, image_.width - 1);
      const int mr = std::clamp(int(std::lround(q.y())), 0, image_.height - 1);
      const uint8_t m = mask_[size_t(mr) * image_.width + mc];
      if (m != render::kMaskOutside) code |= m & 3;
    }
    if (seen == 0) return false;
    const size_t o = size_t(row) * grid_.width + col;
    for (int b = 0; b < nbands_in_; ++b) {
      if (counts_[b] == 0) continue;
      const double mean = sums_[b] / counts_[b];
      bands_[b][o] = db_ ? float(mean > 0.0 ? 10.0 * std::log10(mean) : -std::numeric_limits<float>::infinity())
                         : float(mean);
    }
    bands_[nbands_in_ + 1][o] = float(code);
    ++valid_;
    return true;
  }

  // Local incidence at the pixel centre (point `centre_at` of the row): the
  // surface normal from central differences over half a pixel, against the
  // radar ray.
  void LocalIncidence(size_t o, size_t centre_at) {
    const Eigen::Vector3d p = GroundUnder(frame_, surface_, sx_[centre_at], sy_[centre_at]);
    if (!p.allFinite()) return;
    const double d = 0.5 * grid_.px;
    const double zx = (surface_(p.x() + d, p.y()) - surface_(p.x() - d, p.y())) / (2.0 * d);
    const double zy = (surface_(p.x(), p.y() + d) - surface_(p.x(), p.y() - d)) / (2.0 * d);
    if (!std::isfinite(zx) || !std::isfinite(zy)) return;
    const Eigen::Vector3d normal = Eigen::Vector3d(-zx, -zy, 1.0).normalized();
    const double c = std::clamp(-geometry_.ray_to(p).dot(normal), -1.0, 1.0);
    bands_[nbands_in_][o] = float(std::acos(c) * 180.0 / M_PI);
  }

  const MapGrid& grid_;
  const geo::FloatRaster& image_;
  const std::vector<uint8_t>& mask_;
  const bool db_;
  const ImageProjection& geometry_;
  const geo::LocalFrame& frame_;
  const TerrainSurface& surface_;
  const geo::CrsTransform& transform_;
  const int nbands_in_;
  std::vector<std::vector<float>> bands_;
  int64_t valid_ = 0;
  std::vector<Eigen::Vector2d> footprint_;
  std::vector<double> sx_, sy_;
  std::vector<double> sums_;
  std::vector<int> counts_;
};

// PREFIX.tif's raster: the map bands named and described.
geo::FloatRaster MapRaster(const GeocodeRequest& request, const MapGrid& grid, const std::string& crs,
                           std::vector<std::vector<float>>&& bands, const geo::FloatRaster& image, const json& sidecar,
                           const std::string& resampling) {
  const int nbands_in = int(image.bands.size());
  const int k = grid.k;
  geo::FloatRaster out;
  out.width = grid.width;
  out.height = grid.height;
  out.geotransform = grid.geotransform;
  out.crs = crs;
  out.nodata_nan = true;
  out.bands = std::move(bands);
  std::string unit = sidecar.contains("radiometry") ? sidecar["radiometry"].value("unit", "") : "";
  for (int b = 0; b < nbands_in; ++b) {
    out.band_names.push_back(b < int(image.band_names.size()) && !image.band_names[b].empty() ? image.band_names[b]
                                                                                               : "band_" + std::to_string(b + 1));
    out.band_units.push_back(unit);
  }
  out.band_names.push_back("local_incidence");
  out.band_units.push_back("deg");
  out.band_names.push_back("layover_shadow");
  out.band_units.push_back("code");
  out.metadata = image.metadata;
  out.metadata.erase("GISSAR_PIXEL_CONVENTION");
  out.metadata["GISSAR_GEOMETRY"] = "map (terrain-corrected by gissar geocode)";
  out.metadata["GISSAR_GEOCODE_SOURCE"] = fs::absolute(request.image).string();
  out.metadata["GISSAR_GEOCODE_RESAMPLING"] = resampling + (k > 1 ? " (" + std::to_string(k) + "x" + std::to_string(k) + " points per pixel)" : "");
  out.metadata["GISSAR_MASK_CODES"] = "0 none, 1 layover, 2 shadow, 3 layover and shadow";
  {
    std::string names;
    for (size_t b = 0; b < out.band_names.size(); ++b) names += (b ? ", " : "") + std::to_string(b + 1) + " " + out.band_names[b];
    out.metadata["GISSAR_BANDS"] = names;
  }
  return out;
}

// The STAC Item (stac.h) of the map image, dated as its provenance.
void WriteGeocodeStac(const fs::path& out_stac, const GeocodeRequest& request, const MapGrid& grid,
                      const std::string& crs, const ImageProjection& geometry, json& sidecar,
                      const std::vector<Eigen::Vector2d>& footprint, const std::string& resampling,
                      const std::string& created_utc) {
  StacProduct p;
  p.id = fs::path(request.out_prefix).filename().string();
  p.datetime_utc = created_utc;
  p.footprint_lonlat = footprint;
  const json& sim_options = sidecar["options"];
  p.wavelength_m = geometry.wavelength_m > 0.0 ? geometry.wavelength_m : sim_options.value("wavelength_m", 0.031);
  p.polarization = sim_options.value("polarization", std::string("VV"));
  p.product_type = "GEOCODED";
  p.observation_direction = sensor::ToString(geometry.look_side);
  p.range_spacing_m = geometry.range_spacing_m;
  p.azimuth_spacing_m = geometry.azimuth_spacing_m;
  // null: not set (SimulateRequest: none on an idealised geometry).
  for (const auto& [key, field] : {std::pair{"range_resolution_m", &p.range_resolution_m},
                                   std::pair{"azimuth_resolution_m", &p.azimuth_resolution_m}}) {
    if (sim_options.contains(key) && sim_options[key].is_number() && sim_options[key].get<double>() > 0) {
      *field = sim_options[key].get<double>();
    }
  }
  p.incidence_deg = geometry.incidence_deg;
  p.off_nadir_deg = geometry.off_nadir_deg;
  p.look_azimuth_deg = geometry.look_azimuth_deg;
  if (crs.rfind("EPSG:", 0) == 0) p.proj_code = crs;
  p.width = grid.width;
  p.height = grid.height;
  p.geotransform = grid.geotransform;
  p.processing_level = "L2";
  p.lineage = "terrain-corrected by gissar geocode (" + resampling + ") from " + fs::path(request.image).filename().string();
  const std::string tiff = "image/tiff; application=geotiff";
  p.assets = {{"image", request.out_prefix + ".tif", tiff,
               "Map-geometry bands: image bands, local incidence (deg), layover/shadow code", {"data"}},
              {"provenance", request.out_prefix + ".json", "application/json", "gissar provenance sidecar", {"metadata"}}};
  WriteJsonFile(StacItem(p, fs::path(request.out_prefix).parent_path()), out_stac);
}

}  // namespace

GeocodeResult RunGeocode(const GeocodeRequest& request, const std::string& command_line, Reporter& reporter) {
  request.Check();
  Stopwatch total;
  const std::string stem = Stem(request.image);
  const std::string sidecar_path = stem + ".json", mask_path = stem + "_mask.tif";
  AtomicOutputs outputs;
  const fs::path out_tif = outputs.Add(request.out_prefix + ".tif");
  const fs::path out_json = outputs.Add(request.out_prefix + ".json");
  const fs::path out_stac = outputs.Add(request.out_prefix + "_stac.json");

  // The image, its mask, terrain, geometry and sidecar.
  geo::FloatRaster image = geo::ReadFloatRaster(request.image);
  const std::vector<uint8_t> mask = ReadImageMask(mask_path, image);
  json sidecar = ReadSidecar(sidecar_path);
  const Terrain terrain = LoadImageTerrain(request, sidecar, sidecar_path, reporter);
  const geo::LocalFrame& frame = terrain.frame;
  const TerrainSurface surface(terrain);
  const ImageProjection geometry = ProjectionOfImage(request, image, sidecar, sidecar_path, frame, reporter);
  ThrowIfCancelled(reporter, "geocode");
  const bool db = ToLinearPower(image);

  // Output CRS and grid.
  const std::string crs = request.crs.empty() ? UtmCrsOf(frame.origin_lon_deg(), frame.origin_lat_deg()) : request.crs;
  const geo::CrsTransform transform(crs);
  if (transform.source_is_geographic()) throw ConfigError("the output CRS must be projected (metres): " + crs, "--crs");
  const MapGrid grid = PlanMapGrid(request, terrain, geometry, image, transform);
  const std::string resampling(kGeocodeResamplings.Name(request.resampling));

  // Every map pixel's image values, local incidence and mask code.
  MapResampler resampler(grid, image, mask, db, geometry, terrain, surface, transform);
  Progress progress("geocode", grid.height, reporter);
  for (int row = 0; row < grid.height; ++row) {
    ThrowIfCancelled(reporter, "geocode");
    resampler.Row(row);
    progress.Advance(1);
  }
  progress.Done();
  const int64_t valid = resampler.valid();
  if (valid == 0) throw InputError("no map pixel sees the image's terrain", request.image);
  const geo::FloatRaster out =
      MapRaster(request, grid, crs, std::move(resampler.bands()), image, sidecar, resampling);
  geo::WriteFloatGeoTiff(out_tif, out);

  json provenance = ProvenanceHeader("geocode", command_line, request.ToJson());
  json inputs = json::array({InputFileRecord(request.image), InputFileRecord(mask_path), InputFileRecord(sidecar_path)});
  if (!request.dem.empty()) inputs.push_back(InputFileRecord(request.dem));
  provenance["inputs"] = inputs;
  provenance["grid"] = {{"crs", crs}, {"geotransform", grid.geotransform}, {"width", grid.width},
                        {"height", grid.height}, {"pixel_size_m", grid.px}, {"points_per_pixel", grid.k * grid.k}};
  provenance["vertical_datum"] = VerticalDatumRecord(terrain);
  provenance["terrain"] = request.dem.empty() ? "the simulation's own terrain (sidecar options)" : "--dem, in the simulation's frame";
  provenance["projection_mode"] = geometry.mode;
  provenance["bands"] = out.band_names;
  provenance["band_units"] = out.band_units;
  provenance["nodata"] = "NaN";
  provenance["valid_pixels"] = valid;
  provenance["timings_s"] = {{"total", total.ElapsedSeconds()}};
  std::vector<std::string> final_names;
  for (const fs::path& p : outputs.final_paths()) final_names.push_back(fs::absolute(p).string());
  provenance["outputs"] = final_names;
  WriteJsonFile(provenance, out_json);
  WriteGeocodeStac(out_stac, request, grid, crs, geometry, sidecar, resampler.footprint(), resampling,
                   provenance["created_utc"].get<std::string>());
  outputs.Commit();

  GeocodeResult result;
  result.outputs = outputs.final_paths();
  result.width = grid.width;
  result.height = grid.height;
  result.geotransform = grid.geotransform;
  result.crs = crs;
  result.valid_pixels = valid;
  return result;
}

}  // namespace gissar::pipeline
