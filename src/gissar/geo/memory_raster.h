// A georeferenced raster held in memory and visible to every reader of this
// library under a GDAL virtual path (/vsimem/...): how a request takes an
// array (the Python door's NumPy DEM) where it takes a path. The file lives
// as long as the object.
#pragma once

#include <array>
#include <string>
#include <vector>

namespace gissar::geo {

class MemoryRaster {
 public:
  // `values`: height x width, row-major, top row first; `geotransform`:
  // GDAL's six coefficients (x0, dx, rx, y0, ry, dy) in the units of `crs`;
  // `crs`: anything PROJ reads ("EPSG:32631", "32631", WKT, PROJJSON);
  // `nodata`: the no-data value, or NaN for none besides NaN itself.
  // Throws ConfigError for a bad shape, transform or CRS (naming
  // `what`), IoError when GDAL cannot create the file.
  MemoryRaster(const std::vector<float>& values, int width, int height,
               const std::array<double, 6>& geotransform, const std::string& crs, double nodata,
               const std::string& what);
  ~MemoryRaster();
  MemoryRaster(const MemoryRaster&) = delete;
  MemoryRaster& operator=(const MemoryRaster&) = delete;

  // The virtual path to put in a request's raster field.
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace gissar::geo
