#include "gissar/geo/memory_raster.h"

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <atomic>
#include <cmath>
#include <cstdint>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {

MemoryRaster::MemoryRaster(const std::vector<float>& values, int width, int height,
                           const std::array<double, 6>& geotransform, const std::string& crs, double nodata,
                           const std::string& what) {
  EnsureGdal();
  if (width < 2 || height < 2 || values.size() != size_t(width) * size_t(height)) {
    throw ConfigError("needs a 2-D array of at least 2 x 2 values", what);
  }
  for (double c : geotransform) {
    if (!std::isfinite(c)) throw ConfigError("the transform has a non-finite coefficient", what);
  }
  if (geotransform[1] * geotransform[5] - geotransform[2] * geotransform[4] == 0.0) {
    throw ConfigError("the transform is singular (zero pixel size)", what);
  }
  OGRSpatialReference srs;
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::string crs_text = crs;
  if (!crs_text.empty() && crs_text.find_first_not_of("0123456789") == std::string::npos) {
    crs_text = "EPSG:" + crs_text;
  }
  if (crs_text.empty() || srs.SetFromUserInput(crs_text.c_str()) != OGRERR_NONE) {
    throw ConfigError("not a CRS PROJ knows: '" + crs + "'", what);
  }
  char* wkt = nullptr;
  srs.exportToWkt(&wkt);
  const std::string crs_wkt = wkt != nullptr ? wkt : "";
  CPLFree(wkt);

  static std::atomic<uint64_t> counter{0};
  path_ = "/vsimem/gissar_memory_raster_" + std::to_string(counter.fetch_add(1)) + ".tif";
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (driver == nullptr) throw IoError("GDAL driver missing: GTiff", what);
  GDALDataset* ds = driver->Create(path_.c_str(), width, height, 1, GDT_Float32, nullptr);
  if (ds == nullptr) throw IoError("cannot create an in-memory raster: " + LastGdalMessage(), what);
  double transform[6];
  std::copy(geotransform.begin(), geotransform.end(), transform);
  ds->SetGeoTransform(transform);
  ds->SetProjection(crs_wkt.c_str());
  GDALRasterBand* band = ds->GetRasterBand(1);
  if (!std::isnan(nodata)) band->SetNoDataValue(nodata);
  const CPLErr err = band->RasterIO(GF_Write, 0, 0, width, height, const_cast<float*>(values.data()), width,
                                    height, GDT_Float32, 0, 0);
  GDALClose(ds);
  if (err != CE_None) {
    VSIUnlink(path_.c_str());
    throw IoError("cannot write an in-memory raster: " + LastGdalMessage(), what);
  }
}

MemoryRaster::~MemoryRaster() { VSIUnlink(path_.c_str()); }

}  // namespace gissar::geo
