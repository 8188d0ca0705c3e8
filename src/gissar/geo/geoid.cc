#include "gissar/geo/geoid.h"

#include <gdal_priv.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;

Egm96Geoid::Egm96Geoid(const fs::path& path) {
  fs::path file = path;
  std::string searched;
  if (file.empty()) {
    std::vector<fs::path> dirs;
    for (const char* env : {"PROJ_DATA", "PROJ_LIB"}) {
      if (const char* v = std::getenv(env); v != nullptr && *v != '\0') dirs.emplace_back(v);
    }
    dirs.emplace_back("/usr/share/proj");
    dirs.emplace_back("/usr/local/share/proj");
    for (const fs::path& d : dirs) {
      searched += (searched.empty() ? "" : ", ") + d.string();
      std::error_code ec;
      if (fs::is_regular_file(d / "egm96_15.gtx", ec)) {
        file = d / "egm96_15.gtx";
        break;
      }
    }
    if (file.empty()) {
      throw InputError("EGM96 geoid grid egm96_15.gtx not found (install Debian package proj-data)", searched);
    }
  }
  EnsureGdal();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(file.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds || ds->GetRasterCount() < 1) throw InputError("cannot read geoid grid", file.string());
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None || gt[2] != 0.0 || gt[4] != 0.0) {
    throw InputError("geoid grid has no north-up geotransform", file.string());
  }
  width_ = ds->GetRasterXSize();
  height_ = ds->GetRasterYSize();
  dlon_ = gt[1];
  dlat_ = gt[5];
  lon0_ = gt[0] + 0.5 * gt[1];
  lat0_ = gt[3] + 0.5 * gt[5];
  n_m_.resize(size_t(width_) * height_);
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, width_, height_, n_m_.data(), width_, height_, GDT_Float32, 0,
                                     0) != CE_None) {
    throw InputError("cannot read geoid grid values", file.string());
  }
  source_ = file.string();
}

double Egm96Geoid::UndulationM(double lon_deg, double lat_deg) const {
  lat_deg = std::clamp(lat_deg, -90.0, 90.0);
  double x = (lon_deg - lon0_) / dlon_;
  const double period = 360.0 / std::abs(dlon_);
  x = std::fmod(x, period);
  if (x < 0) x += period;
  double y = std::clamp((lat_deg - lat0_) / dlat_, 0.0, double(height_ - 1));
  const int x0 = static_cast<int>(std::floor(x)), y0 = std::min(static_cast<int>(std::floor(y)), height_ - 2);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int c, int r) {
    c = ((c % width_) + width_) % width_;  // wraps (the grid repeats -180 at +180)
    return double(n_m_[size_t(r) * width_ + c]);
  };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1));
}

}  // namespace gissar::geo

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"

namespace gissar::geo {

void Egm96ToEllipsoidal(Dem& dem, const Egm96Geoid& geoid) {
  const CrsTransform transform(dem.crs_wkt);
  for (int r = 0; r < dem.height; ++r) {
    std::vector<double> x(dem.width), y(dem.width);
    for (int c = 0; c < dem.width; ++c) {
      const Eigen::Vector2d m = dem.MapFromPost(c, r);
      x[c] = m.x();
      y[c] = m.y();
    }
    transform.ToLonLat(x, y);
    for (int c = 0; c < dem.width; ++c) {
      dem.heights_m[size_t(r) * dem.width + c] += static_cast<float>(geoid.UndulationM(x[c], y[c]));
    }
  }
}

}  // namespace gissar::geo
