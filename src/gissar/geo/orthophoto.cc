#include "gissar/geo/orthophoto.h"

#include <gdal_priv.h>

#include <cmath>
#include <filesystem>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"

namespace gissar::geo {

Orthophoto::Orthophoto(const std::string& path, int64_t max_bytes) {
  EnsureGdal();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError("orthophoto does not exist", path);
  std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(
      GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY),
      [](GDALDataset* d) { GDALClose(d); });
  if (!ds) throw InputError("not a raster GDAL can read", path);
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None) throw InputError("orthophoto has no geotransform", path);
  if (!GDALInvGeoTransform(gt, inverse_.data())) throw InputError("orthophoto geotransform is singular", path);
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (srs == nullptr) throw InputError("orthophoto has no coordinate reference system", path);
  char* wkt = nullptr;
  srs->exportToWkt(&wkt);
  crs_ = std::make_unique<CrsTransform>(wkt);
  CPLFree(wkt);
  width_ = ds->GetRasterXSize();
  height_ = ds->GetRasterYSize();
  if (int64_t{width_} * height_ > (int64_t{1} << 30)) throw InputError("orthophoto is too large", path);
  CheckMemoryBudget(3.0 * double(width_) * double(height_), max_bytes,
                    "orthophoto " + path + " of " + std::to_string(width_) + " x " + std::to_string(height_) +
                        " pixels",
                    "crop or downsample it (gdal_translate -projwin / -outsize)");
  rgb_.resize(size_t(width_) * height_ * 3);
  const int bands = ds->GetRasterCount();
  for (int c = 0; c < 3; ++c) {
    GDALRasterBand* band = ds->GetRasterBand(std::min(c + 1, bands));
    if (band->RasterIO(GF_Read, 0, 0, width_, height_, rgb_.data() + c, width_, height_, GDT_Byte, 3,
                       3 * static_cast<GSpacing>(width_), nullptr) != CE_None) {
      throw InputError("cannot read orthophoto: " + LastGdalMessage(), path);
    }
  }
}

std::optional<std::array<uint8_t, 3>> Orthophoto::Sample(double lon_deg, double lat_deg) const {
  std::vector<double> x{lon_deg}, y{lat_deg};
  try {
    crs_->FromLonLat(x, y);
  } catch (const InputError&) {
    return std::nullopt;
  }
  const auto& g = inverse_;
  const double col = g[0] + x[0] * g[1] + y[0] * g[2], row = g[3] + x[0] * g[4] + y[0] * g[5];
  const int c = static_cast<int>(std::floor(col)), r = static_cast<int>(std::floor(row));
  if (c < 0 || r < 0 || c >= width_ || r >= height_) return std::nullopt;
  const uint8_t* p = &rgb_[(size_t(r) * width_ + c) * 3];
  return std::array<uint8_t, 3>{p[0], p[1], p[2]};
}

}  // namespace gissar::geo
