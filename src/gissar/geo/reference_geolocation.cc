#include "gissar/geo/reference_geolocation.h"

#include <gdal_priv.h>

#include <memory>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;

namespace {

template <typename T>
std::vector<T> ReadBand(const fs::path& path, GDALDataType type, int* width, int* height) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError("reference geolocation layer not found", path.string());
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds || ds->GetRasterCount() < 1) throw InputError("cannot read reference layer", path.string());
  *width = ds->GetRasterXSize();
  *height = ds->GetRasterYSize();
  std::vector<T> v(size_t(*width) * *height);
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, *width, *height, v.data(), *width, *height, type, 0, 0) !=
      CE_None) {
    throw InputError("cannot read reference layer values", path.string());
  }
  return v;
}

}  // namespace

ReferenceGeolocation ReadReferenceGeolocation(const fs::path& dir) {
  EnsureGdal();
  ReferenceGeolocation ref;
  int w[3], h[3];
  ref.lon_deg = ReadBand<double>(dir / "x.rdr", GDT_Float64, &w[0], &h[0]);
  ref.lat_deg = ReadBand<double>(dir / "y.rdr", GDT_Float64, &w[1], &h[1]);
  ref.height_m = ReadBand<double>(dir / "z.rdr", GDT_Float64, &w[2], &h[2]);
  if (w[0] != w[1] || w[0] != w[2] || h[0] != h[1] || h[0] != h[2]) {
    throw InputError("x.rdr, y.rdr and z.rdr differ in size", dir.string());
  }
  ref.width = w[0];
  ref.height = h[0];
  std::error_code ec;
  if (fs::is_regular_file(dir / "simamp.rdr", ec)) {
    int sw = 0, sh = 0;
    ref.simamp = ReadBand<float>(dir / "simamp.rdr", GDT_Float32, &sw, &sh);
    if (sw != ref.width || sh != ref.height) throw InputError("simamp.rdr differs in size from x.rdr", dir.string());
  }
  return ref;
}

}  // namespace gissar::geo
