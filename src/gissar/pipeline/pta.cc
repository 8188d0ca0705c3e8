#include "gissar/pipeline/pta.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <fstream>
#include <functional>
#include <cstdlib>
#include <map>
#include <memory>
#include <optional>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/geo/sentinel1_measurement.h"
#include "gissar/geo/sentinel1_safe.h"
#include "gissar/image/irf_plot.h"
#include "gissar/image/point_target.h"
#include "gissar/image/radiometry.h"
#include "gissar/material/material.h"
#include "gissar/material/reflector.h"
#include "gissar/material/scattering.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/geocode.h"
#include "gissar/pipeline/georeferencing.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr double kDeg = M_PI / 180.0;

bool IsChannel(const std::string& name) {
  return std::ranges::find(material::kQuadChannelNames, name) != material::kQuadChannelNames.end();
}

std::string Upper(std::string text) {
  for (char& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return text;
}

json Pair(double range, double azimuth) { return {{"range", range}, {"azimuth", azimuth}}; }

// Where a reflector is predicted, how it is seen and how its samples
// convert to beta0.
struct Prediction {
  double col = 0.0, row = 0.0;
  Eigen::Vector3d to_sensor_enu = Eigen::Vector3d::UnitZ();  // unit, from the apex
  double azimuth_spacing_m = 0.0;
  // Products: the apex's zero-Doppler time (s), slant range (m) and the
  // sensor's position then (ECEF, m).
  double zero_doppler_time_s = 0.0, slant_range_m = 0.0;
  Eigen::Vector3d sensor_ecef_m = Eigen::Vector3d::Zero();
  std::optional<double> beta0_factor;  // |s|^2 -> beta0; unset: uncalibrated
  json geometry;                        // what the sidecar records of the prediction
};

// A complex image to measure: the channels on one grid and how to predict.
struct Source {
  int width = 0, height = 0;
  std::string channel;  // the measured one
  std::map<std::string, std::vector<std::complex<float>>> channels;
  double range_spacing_m = 0.0;
  double wavelength_m = 0.0;
  bool polarimetric_expectation = true;  // channel share of ReflectorMatrix (products); simulations: unpolarised
  std::function<Prediction(const material::ReflectorSpec&, const std::string& where)> predict;
  json description;
  json inputs = json::array();
  std::string calibration_note;
  bool calibrated = false;
};

// ENU components of an ECEF vector at (lon, lat).
Eigen::Vector3d EnuOfEcefVector(double lon_deg, double lat_deg, const Eigen::Vector3d& v) {
  const double lo = lon_deg * kDeg, la = lat_deg * kDeg;
  const Eigen::Vector3d e(-std::sin(lo), std::cos(lo), 0.0);
  const Eigen::Vector3d n(-std::sin(la) * std::cos(lo), -std::sin(la) * std::sin(lo), std::cos(la));
  const Eigen::Vector3d u(std::cos(la) * std::cos(lo), std::cos(la) * std::sin(lo), std::sin(la));
  return {e.dot(v), n.dot(v), u.dot(v)};
}

void CheckInside(const Prediction& p, int width, int height, const std::string& grid, const std::string& where) {
  if (!(p.col >= -0.5 && p.col <= width - 0.5 && p.row >= -0.5 && p.row <= height - 0.5)) {
    char text[256];
    std::snprintf(text, sizeof text, "reflector lies outside the %s: predicted at column %.2f, row %.2f of %d x %d",
                  grid.c_str(), p.col, p.row, width, height);
    throw InputError(text, where);
  }
}

// The reflector apex `target` (ECEF, at lon/lat degrees) predicted on the
// product's grid by zero-Doppler geo2rdr on its orbit: pixel, direction to
// the sensor, along-track ground spacing, and the sidecar's geometry record
// (zero-Doppler time, slant range, ground speed, look angles). Throws
// InputError at `where` when the apex has no zero-Doppler time or lies on
// the unlit side of the track.
Prediction PredictOnProduct(const geo::RslcProduct& p, const sensor::Orbit& orbit, const Eigen::Vector3d& target,
                            double lon_deg, double lat_deg, const std::string& where) {
  const double t_mid = 0.5 * (p.zero_doppler_time_s.front() + p.zero_doppler_time_s.back());
  const auto rc = sensor::Geo2Rdr(orbit, target, t_mid);
  if (!rc) throw InputError("reflector has no zero-Doppler time on the product's orbit", where);
  const sensor::LookSide side = p.look_left ? sensor::LookSide::kLeft : sensor::LookSide::kRight;
  if (!sensor::IsOnSide(orbit, target, rc->time_s, side)) {
    throw InputError("reflector lies on the unlit side of the track (the product looks " +
                         sensor::ToString(sensor::LookSideOf(p.look_left)) + ")",
                     where);
  }
  Prediction out;
  out.row = (rc->time_s - p.zero_doppler_time_s.front()) / p.azimuth_spacing_s();
  out.col = (rc->range_m - p.slant_range_m.front()) / p.range_spacing_m();
  const sensor::OrbitState state = orbit.Interpolate(rc->time_s);
  out.to_sensor_enu = EnuOfEcefVector(lon_deg, lat_deg, state.position_m - target).normalized();
  // Along-track pixel spacing on the ground at the reflector: the zero-
  // Doppler point moves at |v| |X| / |P| (geocentric radii).
  const double ground_speed = state.velocity_mps.norm() * target.norm() / state.position_m.norm();
  out.azimuth_spacing_m = ground_speed * p.azimuth_spacing_s();
  out.geometry = {{"zero_doppler_time_s", rc->time_s},
                  {"slant_range_m", rc->range_m},
                  {"ground_speed_mps", ground_speed},
                  {"look_elevation_deg", std::asin(std::clamp(out.to_sensor_enu.z(), -1.0, 1.0)) / kDeg},
                  {"look_azimuth_deg",
                   std::fmod(std::atan2(out.to_sensor_enu.x(), out.to_sensor_enu.y()) / kDeg + 360.0, 360.0)}};
  out.zero_doppler_time_s = rc->time_s;
  out.slant_range_m = rc->range_m;
  out.sensor_ecef_m = state.position_m;
  return out;
}

Source ProductSource(const PtaRequest& request) {
  Source s;
  s.channel = request.polarization.empty() ? "HH" : request.polarization;
  geo::RslcReadOptions options;
  options.frequency = request.frequency;
  options.polarization = s.channel;
  options.read_amplitude = false;
  options.read_complex = true;
  options.read_calibration = true;
  options.max_bytes = request.max_memory_bytes;
  options.bytes_per_pixel = 4 * 8.0;  // up to four complex channels
  auto product = std::make_shared<geo::RslcProduct>(geo::ReadRslcProduct(request.product, options));
  const geo::RslcProduct& p = *product;
  s.width = p.cols();
  s.height = p.rows();
  s.channels[s.channel] = std::move(product->slc);
  const bool quad = std::ranges::all_of(material::kQuadChannelNames, [&](const char* c) {
    return std::find(p.stored_polarizations.begin(), p.stored_polarizations.end(), c) != p.stored_polarizations.end();
  });
  if (quad) {
    for (const char* c : material::kQuadChannelNames) {
      if (s.channels.count(c)) continue;
      geo::RslcReadOptions other = options;
      other.polarization = c;
      other.read_calibration = false;
      s.channels[c] = geo::ReadRslcProduct(request.product, other).slc;
    }
  }
  s.range_spacing_m = p.range_spacing_m();
  s.wavelength_m = p.wavelength_m;
  s.calibrated = p.beta0_lut.has_value();
  s.calibration_note = s.calibrated ? "beta0 = LUT x |DN|^2, LUT " + p.beta0_lut->dataset +
                                          " (bilinear at the reflector's zero-Doppler time and slant range)"
                                    : "uncalibrated: the product states no beta0 LUT (rcs_dbsm in |DN|^2 m^2)";
  s.inputs.push_back(InputFileRecord(request.product));
  s.description = {{"kind", "NISAR RSLC product"},
                   {"file", p.path},
                   {"mission", p.mission},
                   {"frequency", p.frequency},
                   {"polarization", s.channel},
                   {"stored_polarizations", p.stored_polarizations},
                   {"epoch_utc", p.epoch_utc},
                   {"rows", p.rows()},
                   {"cols", p.cols()},
                   {"first_zero_doppler_time_s", p.zero_doppler_time_s.front()},
                   {"zero_doppler_time_spacing_s", p.azimuth_spacing_s()},
                   {"first_slant_range_m", p.slant_range_m.front()},
                   {"slant_range_spacing_m", p.range_spacing_m()},
                   {"center_frequency_hz", p.center_frequency_hz},
                   {"wavelength_m", p.wavelength_m},
                   {"look_side", sensor::ToString(sensor::LookSideOf(p.look_left))},
                   {"ground_height_m", request.ground_height_m},
                   {"prediction", "zero-Doppler geo2rdr on the product's orbit (cubic Hermite state vectors)"}};
  auto orbit = std::make_shared<sensor::Orbit>(p.orbit.time_s, p.orbit.position_m, p.orbit.velocity_mps);
  const double ground_height = request.ground_height_m;
  s.predict = [product, orbit, ground_height](const material::ReflectorSpec& spec, const std::string& where) {
    const geo::RslcProduct& p = *product;
    const double height = ground_height + spec.apex_height_m;
    const Eigen::Vector3d target = geo::LocalFrame::EcefFromGeodetic(spec.lon_deg, spec.lat_deg, height);
    Prediction out = PredictOnProduct(p, *orbit, target, spec.lon_deg, spec.lat_deg, where);
    if (p.beta0_lut) out.beta0_factor = p.beta0_lut->At(out.zero_doppler_time_s, out.slant_range_m);
    out.geometry["apex_height_above_ellipsoid_m"] = height;
    return out;
  };
  return s;
}

// A Sentinel-1 SLC: the reflectors predicted on the whole burst (IW/EW) or
// swath (stripmap) grid, then only the window around them read (search
// radius, chip and a margin of 8 px each side, clipped to the grid): the
// image's DN as stored and, per reflector, beta0 = |DN|^2 / betaNought^2 with
// the calibration LUT at its predicted pixel. A GRD (detected, no phase) is
// refused.
Source Sentinel1PtaSource(const PtaRequest& request, const std::vector<material::ReflectorSpec>& rows,
                          Reporter& reporter) {
  Sentinel1Selection selection;
  selection.product = request.product;
  selection.swath = request.swath;
  selection.burst = request.burst;
  selection.orbit = request.orbit;
  selection.command = "pta";
  selection.polarization = request.polarization;
  if (selection.polarization.empty()) {
    selection.polarization = geo::OpenSentinel1(request.product).Entry(Upper(request.swath), "").polarization;
  }
  const Sentinel1Source whole = ReadSentinel1Source(selection);
  if (whole.ground_range) {
    throw InputError("a GRD is detected (amplitude only, no phase): point-target analysis needs the SLC",
                     "--product (" + whole.product.name + ")");
  }
  const std::string grid_name =
      whole.burst > 0 ? "burst " + std::to_string(whole.burst) + " of " + whole.annotation.swath + " (" +
                            std::to_string(whole.full_size[0]) + " lines)"
                      : "swath " + whole.annotation.swath;
  const double height = request.ground_height_m;
  auto orbit = std::make_shared<sensor::Orbit>(whole.grid.orbit.time_s, whole.grid.orbit.position_m,
                                               whole.grid.orbit.velocity_mps);
  auto target_of = [height](const material::ReflectorSpec& spec) {
    return geo::LocalFrame::EcefFromGeodetic(spec.lon_deg, spec.lat_deg, height + spec.apex_height_m);
  };
  // The window around every prediction on the whole grid.
  const int margin = static_cast<int>(std::ceil(request.search_px)) + request.chip_half_size_px + 8;
  double row_lo = std::numeric_limits<double>::infinity(), row_hi = -row_lo, col_lo = row_lo, col_hi = -row_lo;
  for (const material::ReflectorSpec& spec : rows) {
    const std::string where = request.reflectors + " row " + std::to_string(spec.row);
    const Prediction p = PredictOnProduct(whole.grid, *orbit, target_of(spec), spec.lon_deg, spec.lat_deg, where);
    CheckInside(p, whole.full_size[1], whole.full_size[0], grid_name, where);
    row_lo = std::min(row_lo, p.row), row_hi = std::max(row_hi, p.row);
    col_lo = std::min(col_lo, p.col), col_hi = std::max(col_hi, p.col);
  }
  const int line0 = std::max(0, static_cast<int>(std::floor(row_lo)) - margin);
  const int pixel0 = std::max(0, static_cast<int>(std::floor(col_lo)) - margin);
  const int line1 = std::min(whole.full_size[0], static_cast<int>(std::ceil(row_hi)) + margin + 1);
  const int pixel1 = std::min(whole.full_size[1], static_cast<int>(std::ceil(col_hi)) + margin + 1);
  selection.window_px = std::array<int, 4>{line0, pixel0, line1 - line0, pixel1 - pixel0};
  auto source = std::make_shared<Sentinel1Source>(ReadSentinel1Source(selection, reporter));
  const geo::Sentinel1Annotation& a = source->annotation;
  const std::array<int, 4>& w = source->window;

  // The window in the measurement's numbering (an IW/EW SLC's lines are the
  // bursts' concatenated) and its calibration.
  geo::Sentinel1ImageOptions image_options;
  image_options.swath = a.swath;
  image_options.polarization = a.polarization;
  image_options.burst = source->burst;
  image_options.radiometry = geo::Sentinel1Radiometry::kBeta0;
  const geo::Sentinel1Image image = geo::Sentinel1Image::Open(request.product, image_options);
  if (!image.measurement().is_complex()) {
    throw InputError("the measurement is not complex: point-target analysis needs an SLC", image.measurement().file());
  }
  const int first_line = image.window().first_line + w[0];
  const geo::Sentinel1Window read{first_line, w[1], w[2], w[3]};
  auto lut = std::make_shared<geo::Sentinel1LineVectors>(
      geo::Sentinel1CalibrationLut(*image.calibration(), geo::Sentinel1Radiometry::kBeta0, "pta"));

  Source s;
  s.channel = a.polarization;
  s.width = w[3];
  s.height = w[2];
  s.channels[s.channel] = image.measurement().ReadDn(read);
  s.range_spacing_m = source->grid.range_spacing_m();
  s.wavelength_m = source->grid.wavelength_m;
  s.calibrated = true;
  s.calibration_note = "beta0 = |DN|^2 / betaNought^2, the LUT of " + image.calibration()->file +
                       " bilinear in line and pixel (as ESA specifies) at the reflector's predicted pixel";
  s.inputs.push_back(Sentinel1InputRecord(*source));
  if (!request.orbit.empty()) s.inputs.push_back(InputFileRecord(request.orbit));
  s.description = {{"kind", "Sentinel-1 " + a.product_type},
                   {"file", request.product},
                   {"sentinel1", source->ToJson()},
                   {"polarization", s.channel},
                   {"measurement", image.measurement().file()},
                   {"window_read", {{"first_line", read.first_line},
                                    {"first_sample", read.first_sample},
                                    {"lines", read.lines},
                                    {"samples", read.samples},
                                    {"numbering", "the measurement's lines and samples"}}},
                   {"rows", s.height},
                   {"cols", s.width},
                   {"first_zero_doppler_time_s", source->grid.zero_doppler_time_s.front()},
                   {"zero_doppler_time_spacing_s", source->grid.azimuth_spacing_s()},
                   {"first_slant_range_m", source->grid.slant_range_m.front()},
                   {"slant_range_spacing_m", s.range_spacing_m},
                   {"wavelength_m", s.wavelength_m},
                   {"look_side", sensor::ToString(sensor::LookSideOf(source->grid.look_left))},
                   {"ground_height_m", request.ground_height_m},
                   {"prediction", "zero-Doppler geo2rdr on the product's orbit (" + source->orbit_source + ")"}};
  reporter.Info("pta: read lines " + std::to_string(read.first_line) + "+" + std::to_string(read.lines) +
                ", samples " + std::to_string(read.first_sample) + "+" + std::to_string(read.samples) + " of " +
                image.measurement().file());
  s.predict = [source, orbit, lut, first_line, w, target_of, height](const material::ReflectorSpec& spec,
                                                                     const std::string& where) {
    const geo::RslcProduct& p = source->grid;
    Prediction out = PredictOnProduct(p, *orbit, target_of(spec), spec.lon_deg, spec.lat_deg, where);
    const double a_beta = lut->At(first_line + out.row, w[1] + out.col);
    if (!(a_beta > 0.0)) throw InputError("the betaNought LUT is not positive at the reflector", where);
    out.beta0_factor = 1.0 / (a_beta * a_beta);
    out.geometry["apex_height_above_ellipsoid_m"] = height + spec.apex_height_m;
    out.geometry["measurement_line"] = first_line + out.row;
    out.geometry["measurement_sample"] = w[1] + out.col;
    out.geometry["beta_nought_lut"] = a_beta;
    return out;
  };
  return s;
}

std::string MetadataValue(const geo::Metadata& m, const std::string& key) {
  const auto it = m.find(key);
  return it == m.end() ? "" : it->second;
}

// The sidecar of `gissar simulate`'s PREFIX_slc.tif: PREFIX.json.
std::string SidecarOf(const std::string& image) {
  const std::string suffix = "_slc.tif";
  if (image.size() > suffix.size() && image.compare(image.size() - suffix.size(), suffix.size(), suffix) == 0) {
    return image.substr(0, image.size() - suffix.size()) + ".json";
  }
  const fs::path p(image);
  return (p.parent_path() / p.stem()).string() + ".json";
}

// The terrain of a simulation's sidecar: its input `index` (0 for the
// idealised geometry; a product simulation lists the product, or the orbit
// and radar grid, first), loaded as the simulation loaded it and checked
// against the sidecar's frame.
std::shared_ptr<Terrain> SidecarTerrain(const json& sidecar, const std::string& sidecar_path, size_t index,
                                        SimulateRequest& o, int64_t max_memory_bytes, Reporter& reporter,
                                        std::string* input) {
  *input = sidecar["inputs"].at(index).at("path").get<std::string>();
  if (!o.scene.empty()) o.scene = *input;
  else o.dem = *input;
  o.engine = SimulateEngine::kTrace;
  o.max_memory_bytes = max_memory_bytes;
  auto terrain = std::make_shared<Terrain>(LoadTerrain(o, reporter));
  const double lon0 = sidecar["frame"].value("origin_lon_deg", 0.0), lat0 = sidecar["frame"].value("origin_lat_deg", 0.0);
  if (std::abs(terrain->frame.origin_lon_deg() - lon0) > 1e-9 || std::abs(terrain->frame.origin_lat_deg() - lat0) > 1e-9) {
    throw InputError("the terrain's frame differs from the image's (was the DEM or scene changed?)", sidecar_path);
  }
  return terrain;
}

// `gissar simulate --product --coherent`'s PREFIX_slc.tif: the reflectors
// are placed on the simulation's terrain as the simulation placed them
// (PlaceReflectorRows: the surface height + apex_height_m, ENU of its frame)
// and predicted by zero-Doppler geo2rdr on the product's orbit (the product,
// or orbit and radar grid, the sidecar names), where RenderProduct put
// their phase centres. |z|^2 is `radiometry` per pixel (the ellipsoid
// incidence of the pixel's ground point): beta0 = |z|^2 / (sin or tan of the
// incidence of the reflector's ground point).
void ProductGridPrediction(const PtaRequest& request, const json& sidecar, const std::string& sidecar_path,
                           const geo::ComplexRaster& raster, image::Radiometry radiometry, SimulateRequest o,
                           Source& s, Reporter& reporter) {
  const json& inputs = sidecar["inputs"];
  const bool from_product = !o.product.empty();
  if (inputs.size() < (from_product ? 2u : 3u)) {
    throw InputError("the sidecar lists no product (or orbit and radar grid) and terrain inputs", sidecar_path);
  }
  // The inputs as recorded (absolute paths), not as typed.
  if (from_product) {
    o.product = inputs[0].at("path").get<std::string>();
  } else {
    o.orbit = inputs[0].at("path").get<std::string>();
    o.radar_grid = inputs[1].at("path").get<std::string>();
  }
  o.max_memory_bytes = request.max_memory_bytes;
  auto product = std::make_shared<geo::RslcProduct>(ReadProductGeometry(o, false, reporter));
  const geo::RslcProduct& p = *product;
  if (p.cols() != raster.width || p.rows() != raster.height) {
    throw InputError("the image is " + std::to_string(raster.width) + " x " + std::to_string(raster.height) +
                         ", the product grid its sidecar names " + std::to_string(p.cols()) + " x " +
                         std::to_string(p.rows()) + " (was the product changed?)",
                     request.image);
  }
  const std::string first_range = MetadataValue(raster.metadata, "GISSAR_FIRST_RANGE_M");
  if (!first_range.empty() && std::abs(std::atof(first_range.c_str()) - p.slant_range_m.front()) > 1e-3) {
    throw InputError("the image's first slant range (GISSAR_FIRST_RANGE_M " + first_range +
                         ") is not the product's (was the product changed?)",
                     request.image);
  }
  std::string terrain_input;
  auto terrain = SidecarTerrain(sidecar, sidecar_path, from_product ? 1 : 2, o, request.max_memory_bytes, reporter,
                                &terrain_input);
  auto surface = std::make_shared<TerrainSurface>(*terrain);
  auto orbit = std::make_shared<sensor::Orbit>(p.orbit.time_s, p.orbit.position_m, p.orbit.velocity_mps);
  s.range_spacing_m = p.range_spacing_m();
  s.wavelength_m = p.wavelength_m;
  s.polarimetric_expectation = false;
  s.calibrated = true;
  s.calibration_note = "|z|^2 = " + image::ToString(radiometry) + " (GISSAR_RADIOMETRY), per pixel; beta0 = " +
                       (radiometry == image::Radiometry::kBeta0   ? std::string("|z|^2")
                        : radiometry == image::Radiometry::kSigma0 ? std::string("|z|^2 / sin(incidence)")
                                                 : std::string("|z|^2 cos / sin(incidence)")) +
                       (radiometry == image::Radiometry::kBeta0 ? std::string()
                                              : std::string(", incidence on the ellipsoid at the reflector's ground "
                                                            "point"));
  s.inputs.push_back(InputFileRecord(request.image));
  s.inputs.push_back(InputFileRecord(sidecar_path));
  s.description = {{"kind", "gissar simulate --coherent complex image on a product's radar grid"},
                   {"file", fs::absolute(request.image).string()},
                   {"sidecar", fs::absolute(sidecar_path).string()},
                   {"terrain", terrain_input},
                   {"product", from_product ? o.product : o.orbit},
                   {"polarization", s.channel},
                   {"channels", json::array()},
                   {"radiometry", image::ToString(radiometry)},
                   {"wavelength_m", p.wavelength_m},
                   {"width", raster.width},
                   {"height", raster.height},
                   {"first_zero_doppler_time_s", p.zero_doppler_time_s.front()},
                   {"zero_doppler_time_spacing_s", p.azimuth_spacing_s()},
                   {"first_slant_range_m", p.slant_range_m.front()},
                   {"slant_range_spacing_m", p.range_spacing_m()},
                   {"look_side", sensor::ToString(sensor::LookSideOf(p.look_left))},
                   {"prediction",
                    "the simulation's terrain (sidecar inputs) for the apex, zero-Doppler geo2rdr on the product's "
                    "orbit (cubic Hermite state vectors)"}};
  for (const auto& [name, plane] : s.channels) s.description["channels"].push_back(name);
  const std::string csv = request.reflectors;
  s.predict = [product, orbit, terrain, surface, radiometry, csv](const material::ReflectorSpec& spec,
                                                                  const std::string& where) {
    const geo::RslcProduct& p = *product;
    const TerrainSurface& f = *surface;
    const SurfaceHeightAt height = [&f](double x, double y) -> std::optional<double> {
      const double z = f(x, y);
      return std::isnan(z) ? std::nullopt : std::optional<double>(z);
    };
    const std::vector<render::SceneReflector> placed = PlaceReflectorRows({spec}, csv, terrain->frame, height);
    const Eigen::Vector3d apex_llh = terrain->frame.GeodeticFromEnu(placed.at(0).apex_enu);
    const Eigen::Vector3d target = geo::LocalFrame::EcefFromGeodetic(apex_llh.x(), apex_llh.y(), apex_llh.z());
    Prediction out = PredictOnProduct(p, *orbit, target, apex_llh.x(), apex_llh.y(), where);
    // Ellipsoid incidence at the reflector's ground point (the radiometry
    // of the pixels around it): the geodetic normal there against the line
    // of sight (EnuOfEcefVector's up is that normal).
    const Eigen::Vector3d ground = geo::LocalFrame::EcefFromGeodetic(apex_llh.x(), apex_llh.y(),
                                                                     apex_llh.z() - spec.apex_height_m);
    const double incidence =
        std::acos(std::clamp(EnuOfEcefVector(apex_llh.x(), apex_llh.y(), out.sensor_ecef_m - ground).normalized().z(),
                             -1.0, 1.0));
    out.beta0_factor = radiometry == image::Radiometry::kBeta0    ? 1.0
                       : radiometry == image::Radiometry::kSigma0 ? 1.0 / std::sin(incidence)
                                                : std::cos(incidence) / std::sin(incidence);
    out.geometry["apex_enu_m"] = {placed[0].apex_enu.x(), placed[0].apex_enu.y(), placed[0].apex_enu.z()};
    out.geometry["apex_height_above_ellipsoid_m"] = apex_llh.z();
    out.geometry["incidence_deg"] = incidence / kDeg;
    return out;
  };
}

Source ImageSource(const PtaRequest& request, Reporter& reporter) {
  Source s;
  const geo::ComplexRaster raster = geo::ReadComplexRaster(request.image);
  s.width = raster.width;
  s.height = raster.height;
  CheckMemoryBudget(double(raster.width) * raster.height * 8.0 * double(raster.bands.size()) * 2.0,
                    request.max_memory_bytes, "the complex image (" + request.image + ")", "crop the image");
  // Bands named after channels, else band 1 in the simulation's polarisation.
  std::map<std::string, size_t> named;
  for (size_t b = 0; b < raster.band_names.size(); ++b) {
    const std::string name = Upper(raster.band_names[b]);
    if (IsChannel(name) && !named.count(name)) named[name] = b;
  }
  const std::string sidecar_path = SidecarOf(request.image);
  json sidecar;
  {
    std::ifstream in(sidecar_path);
    if (!in) throw InputError("cannot read the image's sidecar (PREFIX.json of `gissar simulate`)", sidecar_path);
    try {
      in >> sidecar;
    } catch (const json::exception& e) {
      throw InputError(std::string("sidecar is not valid JSON: ") + e.what(), sidecar_path);
    }
  }
  if (!sidecar.contains("options") || !sidecar.contains("frame") || !sidecar.contains("inputs") ||
      sidecar.value("command", std::string()) != "simulate") {
    throw InputError("not the sidecar of a `gissar simulate` run (no command/options/frame/inputs)", sidecar_path);
  }
  SimulateRequest o;
  json options = sidecar["options"];
  for (const char* key : {"materials", "reflectors", "contributions", "out_prefix"}) options.erase(key);
  o.ApplyJson(options, sidecar_path);
  const std::string simulated_pol = o.polarization;
  if (!named.empty()) {
    s.channel = request.polarization.empty() ? (named.count(simulated_pol) ? simulated_pol : named.begin()->first)
                                             : request.polarization;
    if (!named.count(s.channel)) {
      throw InputError("the image has no band named " + s.channel, request.image);
    }
    for (const auto& [name, b] : named) {
      std::vector<std::complex<float>> plane(size_t(s.width) * s.height);
      for (size_t k = 0; k < plane.size(); ++k) plane[k] = {raster.bands[b][2 * k], raster.bands[b][2 * k + 1]};
      s.channels[name] = std::move(plane);
    }
  } else {
    s.channel = simulated_pol;
    if (!request.polarization.empty() && request.polarization != simulated_pol) {
      throw InputError("the image holds the simulation's " + simulated_pol + " channel only, not " +
                           request.polarization,
                       request.image);
    }
    if (raster.bands.empty()) throw InputError("the image has no band", request.image);
    std::vector<std::complex<float>> plane(size_t(s.width) * s.height);
    for (size_t k = 0; k < plane.size(); ++k) plane[k] = {raster.bands[0][2 * k], raster.bands[0][2 * k + 1]};
    s.channels[s.channel] = std::move(plane);
  }
  const std::string units = MetadataValue(raster.metadata, "GISSAR_UNITS");
  if (units.rfind("complex amplitude", 0) != 0) {
    throw InputError("not a gissar complex image: GISSAR_UNITS is '" + units +
                         "' (PREFIX_slc.tif of `gissar simulate --coherent` expected)",
                     request.image);
  }
  const std::string radiometry_text = MetadataValue(raster.metadata, "GISSAR_RADIOMETRY");
  const std::optional<image::Radiometry> found = image::kRadiometries.Find(radiometry_text);
  if (!found) throw InputError("GISSAR_RADIOMETRY: " + image::kRadiometries.UnknownMessage(radiometry_text), request.image);
  const image::Radiometry radiometry = *found;
  if (o.UsesProductGeometry()) {
    ProductGridPrediction(request, sidecar, sidecar_path, raster, radiometry, o, s, reporter);
    return s;
  }
  auto geometry = std::make_shared<sensor::SarGeometry>(
      GeometryFromMetadata(raster.metadata, raster.width, raster.height, request.image));
  // The simulation's terrain, in its own frame.
  std::string input;
  auto terrain = SidecarTerrain(sidecar, sidecar_path, 0, o, request.max_memory_bytes, reporter, &input);
  auto surface = std::make_shared<TerrainSurface>(*terrain);
  s.range_spacing_m = geometry->range_spacing_m();
  s.wavelength_m = o.wavelength_m;
  s.polarimetric_expectation = false;
  s.calibrated = true;
  s.calibration_note = "|z|^2 = " + image::ToString(radiometry) + " (GISSAR_RADIOMETRY); beta0 = " +
                       (radiometry == image::Radiometry::kBeta0   ? std::string("|z|^2")
                        : radiometry == image::Radiometry::kSigma0 ? std::string("|z|^2 / sin(incidence) of the reflector's column")
                                                 : std::string("|z|^2 cos / sin(incidence) of the reflector's column"));
  s.inputs.push_back(InputFileRecord(request.image));
  s.inputs.push_back(InputFileRecord(sidecar_path));
  s.description = {{"kind", "gissar simulate --coherent complex image"},
                   {"file", fs::absolute(request.image).string()},
                   {"sidecar", fs::absolute(sidecar_path).string()},
                   {"terrain", input},
                   {"polarization", s.channel},
                   {"channels", json::array()},
                   {"radiometry", image::ToString(radiometry)},
                   {"wavelength_m", o.wavelength_m},
                   {"width", raster.width},
                   {"height", raster.height},
                   {"range_spacing_m", geometry->range_spacing_m()},
                   {"azimuth_spacing_m", geometry->azimuth_spacing_m()},
                   {"projection_mode", sensor::ToString(geometry->mode())},
                   {"prediction", "the simulation's own geometry (GISSAR_* metadata) and terrain (sidecar options)"}};
  for (const auto& [name, plane] : s.channels) s.description["channels"].push_back(name);
  const std::string csv = request.reflectors;
  s.predict = [geometry, terrain, surface, radiometry, csv](const material::ReflectorSpec& spec,
                                                            const std::string& where) {
    const TerrainSurface& f = *surface;
    const SurfaceHeightAt height = [&f](double x, double y) -> std::optional<double> {
      const double z = f(x, y);
      return std::isnan(z) ? std::nullopt : std::optional<double>(z);
    };
    (void)where;
    const std::vector<render::SceneReflector> placed = PlaceReflectorRows({spec}, csv, terrain->frame, height);
    const Eigen::Vector3d apex = placed.at(0).apex_enu;
    const Eigen::Vector2d q = geometry->Project(apex);
    Prediction out;
    out.col = q.x();
    out.row = q.y();
    out.to_sensor_enu = -geometry->RayDirectionTo(apex);
    out.azimuth_spacing_m = geometry->azimuth_spacing_m();
    const double incidence = geometry->IncidenceDeg(std::clamp(q.x(), 0.0, double(geometry->width() - 1))) * kDeg;
    out.beta0_factor = radiometry == image::Radiometry::kBeta0    ? 1.0
                       : radiometry == image::Radiometry::kSigma0 ? 1.0 / std::sin(incidence)
                                                : std::cos(incidence) / std::sin(incidence);
    out.geometry = {{"apex_enu_m", {apex.x(), apex.y(), apex.z()}},
                    {"incidence_deg", incidence / kDeg},
                    {"look_elevation_deg", std::asin(std::clamp(out.to_sensor_enu.z(), -1.0, 1.0)) / kDeg},
                    {"look_azimuth_deg",
                     std::fmod(std::atan2(out.to_sensor_enu.x(), out.to_sensor_enu.y()) / kDeg + 360.0, 360.0)}};
    return out;
  };
  return s;
}

}  // namespace

void PtaRequest::Check() const {
  if (product.empty() == image.empty()) throw ConfigError("give one of --product or --image", "--product/--image");
  if (reflectors.empty()) throw ConfigError("a reflectors CSV is required", "--reflectors");
  if (out_prefix.empty()) throw ConfigError("an output prefix is required", "--out");
  if (frequency != "A" && frequency != "B") throw ConfigError("must be A or B, got '" + frequency + "'", "--frequency");
  if (!polarization.empty() && !IsChannel(polarization)) {
    throw ConfigError(material::kPolarizations.UnknownMessage(polarization), "--polarization");
  }
  if (!std::isfinite(ground_height_m) || std::abs(ground_height_m) > 20000.0) {
    throw ConfigError("must be a height in metres within +-20 km of the ellipsoid", "--ground-height");
  }
  const bool sentinel1 = !product.empty() && geo::IsSentinel1Path(product);
  if (!sentinel1) {
    if (!swath.empty()) throw ConfigError("goes with a Sentinel-1 --product (SAFE)", "--swath");
    if (burst != 0) throw ConfigError("goes with a Sentinel-1 --product (SAFE)", "--burst");
    if (!orbit.empty()) throw ConfigError("goes with a Sentinel-1 --product (SAFE)", "--orbit");
  }
  if (burst < 0) throw ConfigError("must be 1 or more (1-based), got " + std::to_string(burst), "--burst");
  if (!image.empty() && ground_height_m != 0.0) {
    throw ConfigError("goes with --product (an --image uses its simulation's terrain)", "--ground-height");
  }
  if (upsampling < 2 || upsampling > 64) {
    throw ConfigError("must be 2 to 64, got " + std::to_string(upsampling), "--upsampling");
  }
  if (!(search_px >= 0.0) || !(search_px <= 1024.0)) throw ConfigError("must be 0 to 1024 px", "--search");
  if (chip_half_size_px < 4 || chip_half_size_px > 256) {
    throw ConfigError("must be 4 to 256 px, got " + std::to_string(chip_half_size_px), "--chip-half-size");
  }
  if (!(detection_threshold_db >= 0.0 && detection_threshold_db <= 100.0)) {
    throw ConfigError("must be 0 to 100 dB", "--detection-threshold");
  }
  if (2 * chip_half_size_px * upsampling > 4096) {
    throw ConfigError("the upsampled chip (2 x chip half-size x upsampling) exceeds 4096 samples a side",
                      "--upsampling");
  }
  std::vector<std::string> inputs{product, image, reflectors, orbit};
  if (!image.empty()) inputs.push_back(SidecarOf(image));
  CheckOutputsAreNotInputs({out_prefix + ".json", out_prefix + "_irf.png"}, inputs);
}

namespace {

// The complex image the reflectors are measured on: a Sentinel-1 SAFE, a
// simulation's PREFIX_slc.tif or a NISAR product.
Source OpenSource(const PtaRequest& request, const std::vector<material::ReflectorSpec>& rows, Reporter& reporter) {
  return !request.product.empty() && geo::IsSentinel1Path(request.product) ? Sentinel1PtaSource(request, rows, reporter)
         : request.product.empty()                                         ? ImageSource(request, reporter)
                                                                           : ProductSource(request);
}

// Predictions first: a bad row stops the run before anything is measured.
std::vector<Prediction> PredictReflectors(const PtaRequest& request, const Source& source,
                                          const std::vector<material::ReflectorSpec>& rows) {
  std::vector<Prediction> predictions;
  for (const material::ReflectorSpec& spec : rows) {
    const std::string where = request.reflectors + " row " + std::to_string(spec.row);
    Prediction p = source.predict(spec, where);
    CheckInside(p, source.width, source.height, request.product.empty() ? "image" : "product's radar grid", where);
    predictions.push_back(std::move(p));
  }
  return predictions;
}

// Expected RCS: physical optics seen from the sensor, the channel's share.
struct ExpectedRcs {
  double pattern_rcs = 0.0;  // physical optics in the sensor's direction
  double share = 1.0;        // the measured channel's share of the reflector's scattering matrix
  double expected = 0.0;     // pattern_rcs x share
  double peak_rcs = 0.0;     // on boresight
  double off_boresight_deg = 0.0;
};

ExpectedRcs ExpectReflector(const material::ReflectorSpec& spec, const Source& source, const Prediction& p) {
  ExpectedRcs e;
  const Eigen::Vector3d boresight = material::BoresightVector(spec.boresight_azimuth_deg, spec.boresight_elevation_deg);
  e.pattern_rcs = material::ReflectorRcs(spec.type, spec.size_m, source.wavelength_m, boresight, p.to_sensor_enu);
  double share = 1.0;
  if (source.polarimetric_expectation) {
    const material::ScatteringMatrix s = material::ReflectorMatrix(spec.type, spec.size_m, source.wavelength_m, 0.0);
    share = material::ChannelRcs(s, material::ParsePolarization(source.channel, "--polarization")) /
            material::PeakRcs(spec.type, spec.size_m, source.wavelength_m);
  }
  e.share = share;
  e.expected = e.pattern_rcs * share;
  e.peak_rcs = material::PeakRcs(spec.type, spec.size_m, source.wavelength_m);
  e.off_boresight_deg = std::acos(std::clamp(boresight.dot(p.to_sensor_enu), -1.0, 1.0)) / kDeg;
  return e;
}

// The measurement's options for one reflector (its prediction's azimuth
// spacing and beta0 factor).
image::PointTargetOptions MeasurementOptions(const PtaRequest& request, const Source& source, const Prediction& p) {
  image::PointTargetOptions options;
  options.range_spacing_m = source.range_spacing_m;
  options.azimuth_spacing_m = p.azimuth_spacing_m;
  options.search_radius_px = request.search_px;
  options.chip_half_size_px = request.chip_half_size_px;
  options.upsampling = request.upsampling;
  options.beta0_calibration = p.beta0_factor;
  options.min_peak_to_background_db = request.detection_threshold_db;
  return options;
}

// The record of a measured reflector: the measurement, the expectation and
// the calibration offset.
void RecordMeasurement(json& r, const image::PointTargetMeasurement& m, const ExpectedRcs& e, const Source& source,
                       const Prediction& p) {
  r["found"] = true;
  r.update(image::ToJson(m));
  r["rcs_expected_dbsm"] = e.expected > 0.0 ? json(10.0 * std::log10(e.expected)) : json(nullptr);
  r["calibration_offset_db"] = e.expected > 0.0 ? json(m.rcs_dbsm - 10.0 * std::log10(e.expected)) : json(nullptr);
  r["calibrated"] = m.calibrated;
  r["beta0_calibration"] = m.beta0_calibration;
  r["expected"] = {{"peak_rcs_dbsm", 10.0 * std::log10(e.peak_rcs)},
                   {"off_boresight_deg", e.off_boresight_deg},
                   {"pattern_db", e.pattern_rcs > 0.0 ? json(10.0 * std::log10(e.pattern_rcs / e.peak_rcs)) : json(nullptr)},
                   {"channel_share", e.share},
                   {"wavelength_m", source.wavelength_m}};
  r["resolution_px"] = Pair(m.resolution_px.range, m.resolution_px.azimuth);
  r["main_lobe_px"] = Pair(m.main_lobe_px.range, m.main_lobe_px.azimuth);
  r["islr_2d_db"] = m.islr_2d_db;
  r["scr_db"] = m.scr_db;
  r["peak_beta0_db"] = m.peak_beta0_db;
  r["spectrum_centre_cycles_per_px"] =
      Pair(m.spectrum_centre_cycles_per_px.range, m.spectrum_centre_cycles_per_px.azimuth);
  r["azimuth_spacing_m"] = p.azimuth_spacing_m;
  r["range_spacing_m"] = source.range_spacing_m;
}

// Quad-pol: the four channels interpolated at the measured peak, the HH/VV
// ratio and phase and the cross-pol isolation; false (and the reason
// recorded) when the interpolation chip leaves the image.
bool RecordQuadPol(json& r, const image::PointTargetMeasurement& m, const Source& source, const PtaRequest& request) {
  std::map<std::string, std::complex<double>> value;
  json channels = json::object();
  for (const char* c : material::kQuadChannelNames) {
    const auto v = image::InterpolateComplex(source.channels.at(c), source.width, source.height, m.peak_px.range,
                                             m.peak_px.azimuth, m.spectrum_centre_cycles_per_px,
                                             request.chip_half_size_px);
    if (!v) break;  // the chip around the sub-pixel peak leaves the image
    value[c] = *v;
    channels[c] = {{"power_db", 10.0 * std::log10(std::max(std::norm(*v), 1e-300))},
                   {"phase_deg", std::arg(*v) / kDeg}};
  }
  if (value.size() < 4) {
    r["hh_vv_ratio_db"] = r["hh_vv_phase_deg"] = r["cross_pol_isolation_db"] = nullptr;
    r["quad_pol_reason"] = "the interpolation chip around the sub-pixel peak leaves the image";
    return false;
  }
  const double hh = std::norm(value["HH"]), vv = std::norm(value["VV"]);
  const double hv = std::norm(value["HV"]), vh = std::norm(value["VH"]);
  r["hh_vv_ratio_db"] = 10.0 * std::log10(hh / vv);
  r["hh_vv_phase_deg"] = std::arg(value["HH"] * std::conj(value["VV"])) / kDeg;
  r["cross_pol_isolation_db"] = 10.0 * std::log10((hh + vv) / (hv + vh));
  r["channels_at_peak"] = channels;
  return true;
}

// Every reflector's record, the impulse responses to plot, how many were
// measured and why the first was not.
struct Measurements {
  json reflectors = json::array();
  std::vector<image::IrfPlotEntry> plots;
  int measured = 0;
  std::string first_reason;
};

// One reflector: its peak measured near the prediction, compared with the
// expected RCS (and, quad-pol, its polarimetric values at the peak).
void MeasureReflector(const PtaRequest& request, const Source& source, const std::vector<std::complex<float>>& slc,
                      const material::ReflectorSpec& spec, const Prediction& p, bool quad, Reporter& reporter,
                      Measurements& out) {
  const image::PointTargetOptions options = MeasurementOptions(request, source, p);
  std::string why;
  const auto m = image::MeasurePointTarget(slc, source.width, source.height, p.col, p.row, options, &why);
  json r;
  r["id"] = spec.row;
  r["type"] = material::ToString(spec.type);
  r["lon_deg"] = spec.lon_deg;
  r["lat_deg"] = spec.lat_deg;
  r["polarization"] = source.channel;
  r["prediction"] = p.geometry;
  const ExpectedRcs expected = ExpectReflector(spec, source, p);
  if (!m) {
    r["found"] = false;
    r["reason"] = why;
    r["predicted_px"] = Pair(p.col, p.row);
    reporter.Warn("pta: " + request.reflectors + " row " + std::to_string(spec.row) + ": not measured: " + why);
    if (out.first_reason.empty()) out.first_reason = "row " + std::to_string(spec.row) + ": " + why;
    out.reflectors.push_back(r);
    return;
  }
  ++out.measured;
  RecordMeasurement(r, *m, expected, source, p);
  if (quad && !RecordQuadPol(r, *m, source, request)) {
    out.reflectors.push_back(r);
    out.plots.push_back({"row " + std::to_string(spec.row), *m, source.range_spacing_m, p.azimuth_spacing_m});
    return;
  }
  out.reflectors.push_back(r);
  char caption[200];
  std::snprintf(caption, sizeof caption, "row %d %s, %s", spec.row, material::ToString(spec.type).c_str(),
                source.channel.c_str());
  out.plots.push_back({caption, *m, source.range_spacing_m, p.azimuth_spacing_m});
}

Measurements MeasureReflectors(const PtaRequest& request, const Source& source,
                               const std::vector<std::complex<float>>& slc,
                               const std::vector<material::ReflectorSpec>& rows,
                               const std::vector<Prediction>& predictions, bool quad, Reporter& reporter) {
  Measurements out;
  for (size_t k = 0; k < rows.size(); ++k) {
    ThrowIfCancelled(reporter, "pta");
    MeasureReflector(request, source, slc, rows[k], predictions[k], quad, reporter, out);
  }
  return out;
}

// PREFIX.json (but its timings and outputs): the source, the calibration,
// the definitions and every reflector's record.
json PtaReport(const PtaRequest& request, const std::string& command_line, const Source& source, bool quad,
               const Measurements& measurements, int total) {
  json report = ProvenanceHeader("pta", command_line, request.ToJson());
  json inputs = source.inputs;
  inputs.push_back(InputFileRecord(request.reflectors));
  report["inputs"] = inputs;
  report["source"] = source.description;
  report["calibration"] = {{"calibrated", source.calibrated}, {"how", source.calibration_note}};
  report["quad_pol"] = quad;
  report["definitions"] = {
      {"rcs_dbsm", "10 log10(beta0 factor x (sum |s|^2 over the (2h+1)^2 box - background) x range_spacing_m x "
                   "azimuth_spacing_m)"},
      {"rcs_expected_dbsm", source.polarimetric_expectation
                                ? "physical-optics RCS seen from the sensor (material::ReflectorRcs) x the channel's "
                                  "share of the reflector's scattering matrix at roll 0"
                                : "physical-optics RCS seen from the sensor (material::ReflectorRcs), as the "
                                  "simulation renders it"},
      {"calibration_offset_db", "rcs_dbsm - rcs_expected_dbsm"},
      {"location_error", "peak - prediction (columns: slant range, rows: azimuth)"},
      {"hh_vv_ratio_db", "20 log10 |S_HH / S_VV| at the measured peak"},
      {"hh_vv_phase_deg", "arg(S_HH S_VV*) at the measured peak"},
      {"cross_pol_isolation_db",
       "10 log10((|S_HH|^2 + |S_VV|^2) / (|S_HV|^2 + |S_VH|^2)) at the measured peak: co-pol over cross-pol "
       "power at the same position (clutter in the cross-pol channels bounds it from below)"}};
  report["reflectors"] = measurements.reflectors;
  report["measured"] = measurements.measured;
  report["total"] = total;
  report["converged"] = measurements.measured > 0;
  if (measurements.measured == 0) report["reason"] = "no reflector found: " + measurements.first_reason;
  return report;
}

}  // namespace

PtaResult RunPta(const PtaRequest& request, const std::string& command_line, Reporter& reporter) {
  request.Check();
  Stopwatch total;
  AtomicOutputs outputs;
  const fs::path out_json = outputs.Add(request.out_prefix + ".json");
  const fs::path out_png = outputs.Add(request.out_prefix + "_irf.png");

  const std::vector<material::ReflectorSpec> rows = material::ReadReflectorsCsv(request.reflectors);
  if (rows.empty()) throw InputError("the reflectors file holds no reflector", request.reflectors);
  Source source = OpenSource(request, rows, reporter);
  ThrowIfCancelled(reporter, "pta");
  const bool quad = std::all_of(std::begin(material::kQuadChannelNames), std::end(material::kQuadChannelNames),
                                [&](const char* c) { return source.channels.count(c) > 0; });
  if (!source.calibrated) {
    reporter.Warn("pta: " + (request.product.empty() ? request.image : request.product) +
                  " states no beta0 calibration: RCS reported uncalibrated (|DN|^2 x m^2)");
  }
  const std::vector<std::complex<float>>& slc = source.channels.at(source.channel);
  const std::vector<Prediction> predictions = PredictReflectors(request, source, rows);
  const Measurements measurements = MeasureReflectors(request, source, slc, rows, predictions, quad, reporter);

  json report = PtaReport(request, command_line, source, quad, measurements, int(rows.size()));
  report["timings_s"] = {{"total", total.ElapsedSeconds()}};
  std::vector<std::string> finals;
  for (const fs::path& path : outputs.final_paths()) finals.push_back(fs::absolute(path).string());
  report["outputs"] = finals;

  const image::RgbImage picture = image::IrfPlot(measurements.plots, -40.0, "pta: no reflector found (see PREFIX.json)");
  geo::WritePng(out_png, picture.rgb, picture.width, picture.height, 3);
  WriteJsonFile(report, out_json);
  outputs.Commit();
  PtaResult result;
  result.outputs = outputs.final_paths();
  result.report = report;
  result.measured = measurements.measured;
  result.total = int(rows.size());
  return result;
}

}  // namespace gissar::pipeline
