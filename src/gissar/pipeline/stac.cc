#include "gissar/pipeline/stac.h"

#include <algorithm>
#include <cmath>

#include "gissar/material/material.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {

namespace {

// sar:polarizations from a request's channels ("VV", "HH,VV", "quad").
nlohmann::json StacPolarizations(const std::string& channels) {
  nlohmann::json list = nlohmann::json::array();
  for (const material::Polarization c : material::ParsePolarizationList(channels, "polarization")) {
    list.push_back(material::ToString(c));
  }
  return list;
}

}  // namespace
namespace fs = std::filesystem;
using json = nlohmann::json;

const char* const kStacSarExtension = "https://stac-extensions.github.io/sar/v1.3.0/schema.json";
const char* const kStacViewExtension = "https://stac-extensions.github.io/view/v1.1.0/schema.json";
const char* const kStacProjectionExtension = "https://stac-extensions.github.io/projection/v2.0.0/schema.json";
const char* const kStacProcessingExtension = "https://stac-extensions.github.io/processing/v1.2.0/schema.json";

namespace {

// Andrew's monotone chain; returns the hull counter-clockwise, closed
// (first point repeated), as GeoJSON wants.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> p) {
  std::sort(p.begin(), p.end(), [](const auto& a, const auto& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  std::vector<Eigen::Vector2d> h(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k);  // last == first
  return h;
}

}  // namespace

std::string FrequencyBandOf(double wavelength_m) {
  const double f_ghz = 0.299792458 / wavelength_m;
  if (!(wavelength_m >= 0.0075 && wavelength_m <= 1.2)) {
    throw ConfigError("wavelength outside the SAR bands P..Ka (0.75 cm to 1.2 m)", "--wavelength");
  }
  if (f_ghz < 1.0) return "P";
  if (f_ghz < 2.0) return "L";
  if (f_ghz < 4.0) return "S";
  if (f_ghz < 8.0) return "C";
  if (f_ghz < 12.0) return "X";
  if (f_ghz < 18.0) return "Ku";
  if (f_ghz < 27.0) return "K";
  return "Ka";
}

json StacItem(const StacProduct& product, const fs::path& item_directory) {
  if (product.footprint_lonlat.empty()) throw ConfigError("a STAC Item needs a footprint", product.id);
  Eigen::Vector2d lo = product.footprint_lonlat[0], hi = lo;
  for (const auto& p : product.footprint_lonlat) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  std::vector<Eigen::Vector2d> hull = ConvexHull(product.footprint_lonlat);
  if (hull.size() < 4) {  // degenerate footprint: its bounding box
    hull = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}, lo};
  }
  json ring = json::array();
  for (const auto& p : hull) ring.push_back({p.x(), p.y()});

  json properties = {
      {"datetime", product.datetime_utc},
      {"created", product.datetime_utc},
      {"sar:instrument_mode", product.instrument_mode},
      {"sar:frequency_band", FrequencyBandOf(product.wavelength_m)},
      {"sar:center_frequency", 0.299792458 / product.wavelength_m},
      {"sar:polarizations", StacPolarizations(product.polarization)},
      {"sar:product_type", product.product_type},
      {"sar:observation_direction", product.observation_direction},
      {"sar:pixel_spacing_range", product.range_spacing_m},
      {"sar:pixel_spacing_azimuth", product.azimuth_spacing_m},
      {"view:incidence_angle", product.incidence_deg},
      {"view:off_nadir", product.off_nadir_deg},
      {"view:azimuth", std::fmod(std::fmod(product.look_azimuth_deg, 360.0) + 360.0, 360.0)},
      {"proj:code", product.proj_code.empty() ? json(nullptr) : json(product.proj_code)},
      {"proj:shape", {product.height, product.width}},
      {"processing:level", product.processing_level},
      {"processing:lineage", product.lineage},
      {"processing:software", {{"gissar", VersionString()}}},
      {"processing:datetime", product.datetime_utc},
  };
  if (product.range_resolution_m > 0) properties["sar:resolution_range"] = product.range_resolution_m;
  if (product.azimuth_resolution_m > 0) properties["sar:resolution_azimuth"] = product.azimuth_resolution_m;
  if (product.looks_equivalent_number > 0) properties["sar:looks_equivalent_number"] = product.looks_equivalent_number;
  if (product.proj_code.empty() && !product.crs_wkt.empty()) properties["proj:wkt2"] = product.crs_wkt;
  if (product.geotransform.size() == 6) {
    const auto& g = product.geotransform;
    properties["proj:transform"] = {g[1], g[2], g[0], g[4], g[5], g[3]};
    const double x0 = g[0], x1 = g[0] + g[1] * product.width, y0 = g[3] + g[5] * product.height, y1 = g[3];
    properties["proj:bbox"] = {std::min(x0, x1), std::min(y0, y1), std::max(x0, x1), std::max(y0, y1)};
  }
  json assets = json::object();
  // An output prefix without a directory ("--out sim") puts the Item in the
  // working directory: its parent path is empty.
  const fs::path base = fs::absolute(item_directory.empty() ? fs::path(".") : item_directory).lexically_normal();
  for (const StacAsset& a : product.assets) {
    assets[a.key] = {{"href", fs::absolute(a.path).lexically_normal().lexically_relative(base).generic_string()},
                     {"type", a.type},
                     {"title", a.title},
                     {"roles", a.roles}};
  }
  return {{"type", "Feature"},
          {"stac_version", "1.0.0"},
          {"stac_extensions", {kStacSarExtension, kStacViewExtension, kStacProjectionExtension, kStacProcessingExtension}},
          {"id", product.id},
          {"geometry", {{"type", "Polygon"}, {"coordinates", {ring}}}},
          {"bbox", {lo.x(), lo.y(), hi.x(), hi.y()}},
          {"properties", properties},
          {"links", json::array()},
          {"assets", assets}};
}

}  // namespace gissar::pipeline
