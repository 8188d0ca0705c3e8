// Raster output and input through GDAL: float32/uint8 GeoTIFFs with metadata
// and 8-bit PNGs. Writers write exactly the path they are given (route it
// through AtomicOutputs for all-or-nothing outputs) and throw IoError naming
// the path on failure.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace gissar::geo {

using Metadata = std::map<std::string, std::string>;

// A float32 band stack: `bands[b]` holds width*height values, row-major.
struct FloatRaster {
  int width = 0;
  int height = 0;
  std::vector<std::vector<float>> bands;
  std::vector<std::string> band_names;  // one per band (may be empty)
  Metadata metadata;                    // dataset metadata items
  std::string band_unit = {};           // unit of every band (GDAL unit type; may be empty)
};

// Writes a DEFLATE-compressed, tiled float32 GeoTIFF. Radar-geometry images
// carry no geotransform: their geometry is in `metadata`.
void WriteFloatGeoTiff(const std::filesystem::path& path, const FloatRaster& raster);

// Writes a single-band uint8 GeoTIFF (masks, class maps) with metadata.
void WriteByteGeoTiff(const std::filesystem::path& path, const std::vector<uint8_t>& data,
                      int width, int height, const Metadata& metadata);

// Writes a single-band CFloat32 GeoTIFF (single-look complex image) from
// row-major real and imaginary planes, with metadata and a band unit.
void WriteComplexGeoTiff(const std::filesystem::path& path, const std::vector<float>& real,
                         const std::vector<float>& imag, int width, int height, const Metadata& metadata,
                         const std::string& band_unit = "");

// Writes an 8-bit PNG with 1 (grey), 3 (RGB) or 4 (RGBA) channels,
// interleaved row-major.
void WritePng(const std::filesystem::path& path, const std::vector<uint8_t>& data, int width,
              int height, int channels);

// Reads every band of a raster as float32 with its dataset metadata and
// band descriptions. Throws InputError when missing or unreadable.
FloatRaster ReadFloatRaster(const std::filesystem::path& path);

// Reads band 1 of a raster as uint8 (e.g. a mask). Throws InputError.
std::vector<uint8_t> ReadByteRaster(const std::filesystem::path& path, int* width, int* height);

}  // namespace gissar::geo
