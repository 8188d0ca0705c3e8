// A peer's per-pixel geolocation of a radar image: ISCE "topo" layers
// x.rdr, y.rdr, z.rdr (longitude, latitude in WGS84 degrees, height in
// metres, float64, one value per radar pixel) in one directory, read
// through GDAL (ENVI .hdr or ISCE .xml headers), and the peer's simulated
// amplitude simamp.rdr when present.
#pragma once

#include <filesystem>
#include <vector>

namespace gissar::geo {

struct ReferenceGeolocation {
  int width = 0;   // columns (slant range)
  int height = 0;  // rows (azimuth)
  std::vector<double> lon_deg, lat_deg, height_m;  // row-major
  std::vector<float> simamp;                       // empty when absent
};

// Reads DIR/x.rdr, DIR/y.rdr, DIR/z.rdr (and DIR/simamp.rdr if present).
// Throws InputError naming the file when one is missing or unreadable or
// the layers differ in size.
ReferenceGeolocation ReadReferenceGeolocation(const std::filesystem::path& dir);

}  // namespace gissar::geo
