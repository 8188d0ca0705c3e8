// `gissar geocode`: terrain-corrected map-geometry output of a gissar
// slant-range image by exact back-geocoding (docs/georeferencing.md).
//
// Every output pixel centre (x, y in the output CRS) is taken to WGS84
// longitude/latitude, lifted onto the terrain the image was simulated from
// (the simulation's own mesh, reloaded from the sidecar's request, or the
// DEM given with --dem, meshed in the simulation's frame) and projected into
// the image with the image's own model (affine or exact, from the image's
// GISSAR_* metadata; for an image simulated on a real radar grid -- a NISAR
// product, a Sentinel-1 burst, swath or GRD window, an orbit with a radar
// grid -- zero-Doppler geo2rdr on the grid's orbit, the grid read again from
// the sidecar's request). The slant-range bands are sampled there (bilinear), or
// averaged over k x k such points per output pixel ("average", k = output
// pixel / finest ground spacing of the image, at most 8). No interpolation
// in map space is ever involved, so relief is followed exactly.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/geo/raster_io.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/enum_table.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

// How geocode fills an output pixel (--resampling), with its one table of
// names: "bilinear" or "average".
enum class GeocodeResampling { kBilinear, kAverage };
inline constexpr auto kGeocodeResamplings = util::MakeEnumTable<GeocodeResampling>(
    "resampling", {{GeocodeResampling::kBilinear, "bilinear"}, {GeocodeResampling::kAverage, "average"}});

struct GeocodeRequest {
  // PREFIX.tif written by `gissar simulate` (slant-range geometry); its
  // PREFIX.json sidecar and PREFIX_mask.tif must lie beside it.
  std::string image;
  // Optional DEM whose heights replace the simulation's terrain (any GDAL
  // raster).
  std::string dem;
  // Vertical datum of --dem's heights (SimulateRequest::vertical_datum: ""
  // = from the file, else ellipsoid with a warning); only with --dem (the
  // simulation's own terrain keeps its datum).
  std::string vertical_datum;
  // Output CRS, any definition OGR accepts ("EPSG:32631", a PROJ string);
  // must be projected (metres). Empty = the UTM zone of the scene centre.
  std::string crs;
  // Output pixel size in metres of the CRS; 0 = the image's larger pixel
  // spacing (slant range or azimuth).
  double pixel_size_m = 0.0;
  // kBilinear (one back-geocoded point per output pixel) or kAverage (k x k
  // points per output pixel, for outputs coarser than the image).
  GeocodeResampling resampling = GeocodeResampling::kBilinear;
  // Writes PREFIX.tif (map geometry), PREFIX.json and PREFIX_stac.json (STAC Item).
  std::string out_prefix;
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();

  // Throws ConfigError naming the flag for a missing/invalid value, or when
  // an output would overwrite an input.
  void Check() const;
  // {snake_case field: value} of the fields of its table (geocode_fields.h;
  // the sidecar's record, without max_memory_bytes); the keys are the flags'
  // names (FlagOfField).
  nlohmann::json ToJson() const;
  // Sets the fields named by `values` ({field: value}, as ToJson writes;
  // null keeps the field's value). Throws ConfigError naming the key and
  // `source` (an options file, "gissar.geocode keyword") for an unknown key,
  // with "did you mean", or a value of the wrong type or an unknown
  // resampling.
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};

struct GeocodeResult {
  std::vector<std::filesystem::path> outputs;
  int width = 0, height = 0;
  std::vector<double> geotransform;  // GDAL's six coefficients
  std::string crs;
  int64_t valid_pixels = 0;
};

// The image's geometry from its GISSAR_* metadata (SarGeometry::ToMetadata)
// and size. Throws InputError naming `source` when a key is missing or
// malformed.
sensor::SarGeometry GeometryFromMetadata(const geo::Metadata& metadata, int width, int height,
                                         const std::string& source);

// EPSG code ("EPSG:326zz"/"EPSG:327zz") of the UTM zone of a longitude/latitude.
std::string UtmCrsOf(double lon_deg, double lat_deg);

// Writes PREFIX.tif: float32 bands = the image's bands (same names and
// unit; dB images are resampled in linear power), then "local_incidence"
// (degrees, from the terrain's normal and the radar ray) and
// "layover_shadow" (the image's mask code at the sampled pixel, 0 none,
// 1 layover, 2 shadow, 3 both; "average" ORs the codes of its points). NaN
// (declared no-data) where the map pixel's terrain is not imaged or there is
// no terrain. Geotransform and CRS set. Throws the gissar::Error family;
// nothing is left behind on failure.
GeocodeResult RunGeocode(const GeocodeRequest& request, const std::string& command_line,
                         Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
