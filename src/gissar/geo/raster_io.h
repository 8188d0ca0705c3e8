// Raster output and input through GDAL: float32/uint8 GeoTIFFs with metadata
// and 8-bit PNGs. Writers write exactly the path they are given (route it
// through AtomicOutputs for all-or-nothing outputs) and throw IoError naming
// the path on failure.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace gissar::geo {

using Metadata = std::map<std::string, std::string>;

// A ground control point in GDAL's convention: (pixel, line) of the raster's
// corner-based grid (the centre of column c is pixel c + 0.5), WGS84
// longitude/latitude in degrees and height above the ellipsoid in metres.
struct GroundControlPoint {
  double pixel = 0.0;
  double line = 0.0;
  double lon_deg = 0.0;
  double lat_deg = 0.0;
  double height_m = 0.0;
};

// Georeferencing of a raster without a geotransform (radar geometry): GCPs
// in WGS84 (EPSG:4326) and GDAL "RPC" metadata-domain items (LINE_OFF, ...,
// SAMP_DEN_COEFF) and GDAL "GEOLOCATION" items (X_BAND, Y_BAND, SRS, ...;
// without X_DATASET the arrays are bands of the raster itself). Any may be
// empty.
struct Georeference {
  std::vector<GroundControlPoint> gcps;
  Metadata rpc;
  Metadata geolocation;
  bool empty() const { return gcps.empty() && rpc.empty() && geolocation.empty(); }
};

// GEOLOCATION items for WGS84 longitude/latitude bands (1-based) of the
// raster itself, one value per pixel.
Metadata LonLatGeolocation(int lon_band, int lat_band);

// A float32 band stack: `bands[b]` holds width*height values, row-major.
struct FloatRaster {
  int width = 0;
  int height = 0;
  std::vector<std::vector<float>> bands;
  std::vector<std::string> band_names;  // one per band (may be empty)
  Metadata metadata;                    // dataset metadata items
  std::string band_unit = {};           // unit of every band (GDAL unit type; may be empty)
  Georeference georeference = {};       // GCPs/RPCs (radar geometry), may be empty
  std::vector<std::string> band_units = {};  // GDAL unit type per band (may be empty)
  // Map-geometry rasters: GDAL geotransform (cell corners) and CRS (any
  // definition OGR accepts, e.g. "EPSG:32631"); both empty for radar geometry.
  std::vector<double> geotransform = {};  // 6 coefficients, or empty
  std::string crs = {};
  // Declares NaN as every band's no-data value (pixels outside the footprint).
  bool nodata_nan = false;
  // A COG (either side over kCogMinSidePx) gets its internal overviews;
  // false: the COG layout without overviews (a third less to write).
  bool overviews = true;
  // The pixels of every band left empty in `bands` (one plane shared by all
  // of them, e.g. a simulation's bounce layers with no return); unused when
  // no band is empty.
  std::vector<float> empty_band_pixels = {};
};

// Every GeoTIFF writer below writes a ZSTD-compressed (level 1), tiled GeoTIFF;
// float32 bands with the floating-point predictor (PREDICTOR=3).
// A raster with either side over kCogMinSidePx pixels is written as a
// Cloud-Optimized GeoTIFF (GDAL COG driver, 512-pixel tiles) with internal
// overviews halving down to 512 pixels or less: AVERAGE for float bands
// (NaN no-data skipped), NEAREST for uint8 masks/class maps and CFloat32;
// `overviews` false (FloatRaster::overviews, the writers' last argument)
// leaves them out.
// Metadata, GCPs, RPC and GEOLOCATION domains, units, band names, no-data,
// colour table and geotransform/CRS are the same in both layouts.
inline constexpr int kCogMinSidePx = 1024;

// Writes a ZSTD-compressed, tiled float32 GeoTIFF (floating-point predictor). Map-geometry rasters
// carry raster.geotransform and raster.crs (an unparsable CRS is an IoError).
// Radar-geometry images
// carry no geotransform: their geometry is in `metadata`, and their
// georeferencing (when given) as WGS84 GCPs and RPC metadata.
void WriteFloatGeoTiff(const std::filesystem::path& path, const FloatRaster& raster);

// Writes a single-band uint8 GeoTIFF (masks, class maps) with metadata.
// Categories of a class raster: names (value = index; written as band
// metadata CATEGORY_<value>) and RGBA colours (a TIFF colour table).
struct ByteCategories {
  std::vector<std::string> names;
  std::vector<std::array<uint8_t, 4>> colours;  // same length as names, or empty
  std::optional<uint8_t> nodata = {};            // declared no-data value (transparent), if any
};

void WriteByteGeoTiff(const std::filesystem::path& path, const std::vector<uint8_t>& data,
                      int width, int height, const Metadata& metadata,
                      const Georeference& georeference = {}, const ByteCategories& categories = {},
                      bool overviews = true);

// Reads the GCPs (as stored, in their own CRS) and the RPC and GEOLOCATION
// domains of a raster.
// Throws InputError when missing or unreadable.
Georeference ReadGeoreference(const std::filesystem::path& path);

// Writes a single-band CFloat32 GeoTIFF (single-look complex image) from
// row-major real and imaginary planes, with metadata and a band unit.
void WriteComplexGeoTiff(const std::filesystem::path& path, const std::vector<float>& real,
                         const std::vector<float>& imag, int width, int height, const Metadata& metadata,
                         const std::string& band_unit = "");

// One band of a complex raster: row-major real and imaginary planes and the
// band's description.
struct ComplexBand {
  const std::vector<float>* real = nullptr;
  const std::vector<float>* imag = nullptr;
  std::string name;
};
// Writes a multi-band CFloat32 GeoTIFF (e.g. a single-look complex image and
// its per-bounce complex parts), every band with `band_unit`, the
// georeference (GCPs/RPCs, may be empty) and, with nodata_nan, NaN declared
// as every band's no-data value. Throws IoError when a plane does not match
// the size or there is no band.
void WriteComplexGeoTiff(const std::filesystem::path& path, const std::vector<ComplexBand>& bands, int width,
                         int height, const Metadata& metadata, const std::string& band_unit = "",
                         const Georeference& georeference = {}, bool nodata_nan = false, bool overviews = true);

// A complex raster as read: per band, interleaved (real, imaginary) row-major
// float pairs, the band descriptions, units and dataset metadata.
struct ComplexRaster {
  int width = 0, height = 0;
  std::vector<std::vector<float>> bands;  // 2 * width * height floats each
  std::vector<std::string> band_names, band_units;
  Metadata metadata;
  bool nodata_nan = false;  // band 1 declares NaN no-data
};
// Reads every band of a raster as CFloat32. Throws InputError when missing
// or unreadable.
ComplexRaster ReadComplexRaster(const std::filesystem::path& path);

// Writes an 8-bit PNG with 1 (grey), 3 (RGB) or 4 (RGBA) channels,
// interleaved row-major.
void WritePng(const std::filesystem::path& path, const std::vector<uint8_t>& data, int width,
              int height, int channels);

// Reads every band of a raster as float32 with its dataset metadata, band
// descriptions and units, geotransform and CRS (WKT) when it has them, and
// nodata_nan when band 1 declares NaN no-data. Throws InputError when missing or unreadable.
FloatRaster ReadFloatRaster(const std::filesystem::path& path);

// Reads band 1 of a raster as uint8 (e.g. a mask). Throws InputError.
std::vector<uint8_t> ReadByteRaster(const std::filesystem::path& path, int* width, int* height);

// A full disk: every writer above (and the scene writers) reports a failed
// write as util's WriteError (atomic_output.h): IoError("<what>: no space
// left on the device holding DIR", OUTPUT), OUTPUT the final output rather
// than its temporary.

}  // namespace gissar::geo
