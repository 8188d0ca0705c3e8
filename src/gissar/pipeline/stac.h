// STAC Items (SpatioTemporal Asset Catalog, stacspec.org, version 1.0.0)
// for gissar products, with the sar (v1.3.0), view (v1.1.0), projection
// (v2.0.0) and processing (v1.2.0) extensions, so that a catalogue can
// ingest them (docs/georeferencing.md; the schemas are in
// tests/data/stac_schemas/).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace gissar::pipeline {

// The STAC URIs of the extensions an Item declares.
extern const char* const kStacSarExtension;
extern const char* const kStacViewExtension;
extern const char* const kStacProjectionExtension;
extern const char* const kStacProcessingExtension;

struct StacAsset {
  std::string key;    // e.g. "image"
  std::filesystem::path path;  // written as an href relative to the Item's directory
  std::string type;   // media type
  std::string title;
  std::vector<std::string> roles;  // "data", "overview", "thumbnail", "metadata", ...
};

struct StacProduct {
  std::string id;
  std::string datetime_utc;  // ISO 8601, the product's creation (a simulation has no acquisition time)
  // Footprint: WGS84 longitude/latitude points on the imaged terrain; the
  // Item's geometry is their convex hull, bbox their extent.
  std::vector<Eigen::Vector2d> footprint_lonlat;
  double wavelength_m = 0.031;
  std::string polarization = "VV";
  std::string instrument_mode = "simulated";
  std::string product_type;       // "DETECTED_SLANT_RANGE", "SLC", "GEOCODED"
  std::string observation_direction = "right";
  double range_spacing_m = 0.0, azimuth_spacing_m = 0.0;
  double range_resolution_m = 0.0, azimuth_resolution_m = 0.0;  // 0 = not stated
  double looks_equivalent_number = 0.0;                          // 0 = not stated
  double incidence_deg = 0.0;   // ellipsoid incidence at the scene centre
  double off_nadir_deg = 0.0;   // at the sensor
  double look_azimuth_deg = 0.0;  // bearing from the sensor's nadir to the scene centre
  // Projection: an "EPSG:n" code (else null: radar geometry or another
  // CRS, then proj:wkt2 when crs_wkt is set), raster shape and, in map
  // geometry, the geotransform.
  std::string proj_code;
  std::string crs_wkt;
  int width = 0, height = 0;
  std::vector<double> geotransform;
  std::string lineage;
  std::string processing_level = "L1";
  std::vector<StacAsset> assets;
};

// SAR frequency band letter (IEEE 521) of a wavelength: P, L, S, C, X, Ku,
// K or Ka; throws ConfigError outside 0.75 cm .. 1.2 m.
std::string FrequencyBandOf(double wavelength_m);

// The Item. Asset hrefs are relative to `item_directory`.
nlohmann::json StacItem(const StacProduct& product, const std::filesystem::path& item_directory);

}  // namespace gissar::pipeline
