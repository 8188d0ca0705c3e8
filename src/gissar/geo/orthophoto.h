// An RGB raster (orthophoto, any GDAL format and CRS) sampled at WGS84
// positions, for draping over a scene.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gissar/geo/local_frame.h"

namespace gissar::geo {

class Orthophoto {
 public:
  // Reads bands 1-3 (a single band is used as grey) into memory, 3 bytes per
  // pixel. Throws InputError when the file is missing, not a raster, or has
  // no geotransform or CRS, and ConfigError (--max-memory) when the pixels
  // would need more than `max_bytes`, before anything is read.
  Orthophoto(const std::string& path, int64_t max_bytes);

  // Nearest-pixel colour at WGS84 (lon, lat); nullopt outside the raster.
  std::optional<std::array<uint8_t, 3>> Sample(double lon_deg, double lat_deg) const;

 private:
  int width_ = 0, height_ = 0;
  std::vector<uint8_t> rgb_;
  std::array<double, 6> inverse_;  // map -> pixel
  std::unique_ptr<CrsTransform> crs_;
};

}  // namespace gissar::geo
