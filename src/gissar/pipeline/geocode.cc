#include "gissar/pipeline/geocode.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/pipeline/geocode_fields.h"
#include "gissar/pipeline/georeferencing.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/stac.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"
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
  try {
    size_t used = 0;
    const double v = std::stod(it->second, &used);
    if (used != it->second.size() || !std::isfinite(v)) throw std::invalid_argument("");
    return v;
  } catch (const std::exception&) {
    throw InputError("metadata " + key + " is not a number: " + it->second, source);
  }
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

json GeocodeRequest::ToJson() const { return GeocodeFields().ToJson(*this); }

void GeocodeRequest::ApplyJson(const json& values, const std::string& source) {
  GeocodeFields().ApplyJson(*this, values, source);
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

GeocodeResult RunGeocode(const GeocodeRequest& request, const std::string& command_line, Reporter& reporter) {
  request.Check();
  Stopwatch total;
  const std::string stem = Stem(request.image);
  const std::string sidecar_path = stem + ".json", mask_path = stem + "_mask.tif";
  AtomicOutputs outputs;
  const fs::path out_tif = outputs.Add(request.out_prefix + ".tif");
  const fs::path out_json = outputs.Add(request.out_prefix + ".json");
  const fs::path out_stac = outputs.Add(request.out_prefix + "_stac.json");

  // The image, its mask, geometry and sidecar.
  geo::FloatRaster image = geo::ReadFloatRaster(request.image);
  int mask_w = 0, mask_h = 0;
  if (!fs::exists(mask_path)) throw InputError("the image's layover/shadow mask is missing", mask_path);
  const std::vector<uint8_t> mask = geo::ReadByteRaster(mask_path, &mask_w, &mask_h);
  if (mask_w != image.width || mask_h != image.height) throw InputError("mask size differs from the image's", mask_path);
  json sidecar;
  {
    std::ifstream in(sidecar_path);
    if (!in) throw InputError("cannot read the image's sidecar", sidecar_path);
    try {
      in >> sidecar;
    } catch (const json::exception& e) {
      throw InputError(std::string("sidecar is not valid JSON: ") + e.what(), sidecar_path);
    }
  }
  const Terrain terrain = LoadImageTerrain(request, sidecar, sidecar_path, reporter);
  const geo::LocalFrame& frame = terrain.frame;
  const TerrainSurface surface(terrain);
  // An idealised geometry (GISSAR_* metadata) or the real radar grid of a
  // product simulation (its sidecar's request).
  const bool radar_grid = !sidecar["options"].value("product", std::string()).empty() ||
                          !sidecar["options"].value("orbit", std::string()).empty();
  ImageProjection geometry;
  if (radar_grid) {
    SimulateRequest o;
    json options = sidecar["options"];
    for (const char* key : {"materials", "reflectors", "contributions", "out_prefix"}) options.erase(key);
    o.ApplyJson(options, sidecar_path);
    geometry = RadarGridProjection(o, frame, reporter);
  } else {
    geometry = IdealisedProjection(GeometryFromMetadata(image.metadata, image.width, image.height, request.image));
  }
  ThrowIfCancelled(reporter, "geocode");

  // dB bands are resampled in linear power.
  const bool db = image.metadata.count("GISSAR_UNITS") && image.metadata["GISSAR_UNITS"].find("(dB)") != std::string::npos;
  if (db) {
    for (auto& band : image.bands)
      for (float& v : band) v = std::isnan(v) ? v : float(std::pow(10.0, v / 10.0));
  }

  // Output CRS and pixel size.
  const std::string crs = request.crs.empty() ? UtmCrsOf(frame.origin_lon_deg(), frame.origin_lat_deg()) : request.crs;
  const geo::CrsTransform transform(crs);
  if (transform.source_is_geographic()) throw ConfigError("the output CRS must be projected (metres): " + crs, "--crs");
  const double px = request.pixel_size_m > 0.0 ? request.pixel_size_m
                                               : std::max(geometry.range_spacing_m, geometry.azimuth_spacing_m);

  // Extent: the terrain the image sees.
  std::vector<double> ex, ey;
  {
    const auto& vertices = terrain.mesh.vertices;
    const size_t stride = std::max<size_t>(1, vertices.size() / 400000);
    for (size_t i = 0; i < vertices.size(); i += stride) {
      const Eigen::Vector3d v = vertices[i].cast<double>();
      if (!v.allFinite()) continue;
      const Eigen::Vector2d p = geometry.project(v);
      if (!p.allFinite() || p.x() < -0.5 || p.y() < -0.5 || p.x() > image.width - 0.5 || p.y() > image.height - 0.5) continue;
      const Eigen::Vector3d g = frame.GeodeticFromEnu(v);
      ex.push_back(g.x());
      ey.push_back(g.y());
    }
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
  const std::vector<double> geotransform{x_min, px, 0.0, y_max, 0.0, -px};

  // Points per output pixel.
  const std::string resampling(kGeocodeResamplings.Name(request.resampling));
  const int k = request.resampling == GeocodeResampling::kAverage
                    ? std::clamp(int(std::ceil(px / std::min(geometry.ground_range_spacing_m, geometry.azimuth_spacing_m) -
                                               1e-9)),
                                 1, 8)
                    : 1;

  // The terrain point (ENU) under WGS84 lon/lat: the height h at which
  // (lon, lat, h) lies on the surface, by fixed-point steps along the local
  // vertical (its tilt in the frame is ~1e-3 over tens of km). NaN off the terrain.
  auto ground = [&](double lon, double lat) -> Eigen::Vector3d {
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
  };

  std::vector<std::vector<float>> bands(nbands_in + 2, std::vector<float>(size_t(width) * height, kNan));
  std::vector<float>& incidence = bands[nbands_in];
  std::vector<float>& mask_band = bands[nbands_in + 1];
  Progress progress("geocode", height, reporter);
  int64_t valid = 0;
  std::vector<Eigen::Vector2d> footprint;  // lon/lat of each row's first and last valid pixel
  std::vector<double> sx, sy;
  std::vector<double> sums(nbands_in);
  std::vector<int> counts(nbands_in);
  for (int row = 0; row < height; ++row) {
    ThrowIfCancelled(reporter, "geocode");
    // Every point of the row: k x k per pixel, then the pixel centre.
    sx.clear();
    sy.clear();
    for (int col = 0; col < width; ++col) {
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          sx.push_back(x_min + (col + (i + 0.5) / k) * px);
          sy.push_back(y_max - (row + (j + 0.5) / k) * px);
        }
      sx.push_back(x_min + (col + 0.5) * px);
      sy.push_back(y_max - (row + 0.5) * px);
    }
    transform.ToLonLat(sx, sy);
    const size_t per_pixel = size_t(k) * k + 1;
    int first_valid = -1, last_valid = -1;
    for (int col = 0; col < width; ++col) {
      std::fill(sums.begin(), sums.end(), 0.0);
      std::fill(counts.begin(), counts.end(), 0);
      int code = 0, seen = 0;
      for (size_t s = 0; s < per_pixel - 1; ++s) {
        const size_t at = col * per_pixel + s;
        const Eigen::Vector3d p = ground(sx[at], sy[at]);
        if (!p.allFinite()) continue;
        const Eigen::Vector2d q = geometry.project(p);
        if (!q.allFinite() || q.x() < -0.5 || q.y() < -0.5 || q.x() > image.width - 0.5 || q.y() > image.height - 0.5) continue;
        ++seen;
        for (int b = 0; b < nbands_in; ++b) {
          const float v = Bilinear(image.bands[b], image.width, image.height, q.x(), q.y());
          if (std::isnan(v)) continue;
          sums[b] += v;
          ++counts[b];
        }
        const int mc = std::clamp(int(std::lround(q.x())), 0, image.width - 1);
        const int mr = std::clamp(int(std::lround(q.y())), 0, image.height - 1);
        const uint8_t m = mask[size_t(mr) * image.width + mc];
        if (m != render::kMaskOutside) code |= m & 3;
      }
      if (seen == 0) continue;
      const size_t o = size_t(row) * width + col;
      for (int b = 0; b < nbands_in; ++b) {
        if (counts[b] == 0) continue;
        const double mean = sums[b] / counts[b];
        bands[b][o] = db ? float(mean > 0.0 ? 10.0 * std::log10(mean) : -std::numeric_limits<float>::infinity())
                         : float(mean);
      }
      mask_band[o] = float(code);
      ++valid;
      if (first_valid < 0) first_valid = col;
      last_valid = col;
      // Local incidence at the pixel centre: the surface normal from
      // central differences over half a pixel, against the radar ray.
      const size_t centre_at = col * per_pixel + per_pixel - 1;
      const Eigen::Vector3d p = ground(sx[centre_at], sy[centre_at]);
      if (!p.allFinite()) continue;
      const double d = 0.5 * px;
      const double zx = (surface(p.x() + d, p.y()) - surface(p.x() - d, p.y())) / (2.0 * d);
      const double zy = (surface(p.x(), p.y() + d) - surface(p.x(), p.y() - d)) / (2.0 * d);
      if (!std::isfinite(zx) || !std::isfinite(zy)) continue;
      const Eigen::Vector3d normal = Eigen::Vector3d(-zx, -zy, 1.0).normalized();
      const double c = std::clamp(-geometry.ray_to(p).dot(normal), -1.0, 1.0);
      incidence[o] = float(std::acos(c) * 180.0 / M_PI);
    }
    for (int col : {first_valid, last_valid}) {
      if (col >= 0) footprint.emplace_back(sx[col * per_pixel + per_pixel - 1], sy[col * per_pixel + per_pixel - 1]);
    }
    progress.Advance(1);
  }
  progress.Done();
  if (valid == 0) throw InputError("no map pixel sees the image's terrain", request.image);

  geo::FloatRaster out;
  out.width = width;
  out.height = height;
  out.geotransform = geotransform;
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
  geo::WriteFloatGeoTiff(out_tif, out);

  json provenance = ProvenanceHeader("geocode", command_line, request.ToJson());
  json inputs = json::array({InputFileRecord(request.image), InputFileRecord(mask_path), InputFileRecord(sidecar_path)});
  if (!request.dem.empty()) inputs.push_back(InputFileRecord(request.dem));
  provenance["inputs"] = inputs;
  provenance["grid"] = {{"crs", crs}, {"geotransform", geotransform}, {"width", width}, {"height", height},
                        {"pixel_size_m", px}, {"points_per_pixel", k * k}};
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

  // The STAC Item (stac.h).
  StacProduct p;
  p.id = fs::path(request.out_prefix).filename().string();
  p.datetime_utc = provenance["created_utc"].get<std::string>();
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
  p.width = width;
  p.height = height;
  p.geotransform = geotransform;
  p.processing_level = "L2";
  p.lineage = "terrain-corrected by gissar geocode (" + resampling + ") from " + fs::path(request.image).filename().string();
  const std::string tiff = "image/tiff; application=geotiff";
  p.assets = {{"image", request.out_prefix + ".tif", tiff,
               "Map-geometry bands: image bands, local incidence (deg), layover/shadow code", {"data"}},
              {"provenance", request.out_prefix + ".json", "application/json", "gissar provenance sidecar", {"metadata"}}};
  WriteJsonFile(StacItem(p, fs::path(request.out_prefix).parent_path()), out_stac);
  outputs.Commit();

  GeocodeResult result;
  result.outputs = outputs.final_paths();
  result.width = width;
  result.height = height;
  result.geotransform = geotransform;
  result.crs = crs;
  result.valid_pixels = valid;
  return result;
}

}  // namespace gissar::pipeline
