#include "gissar/geo/dem.h"

#include <gdal_alg.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <cmath>
#include <memory>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;
namespace {

struct GdalDatasetCloser {
  void operator()(GDALDataset* ds) const { GDALClose(ds); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, GdalDatasetCloser>;

bool IsVoid(double value, bool has_nodata, double nodata) {
  return !std::isfinite(value) || (has_nodata && value == nodata);
}

// Fills void cells with GDAL's FillNodata on an in-memory copy.
void FillVoids(std::vector<float>& heights, int width, int height, float nodata,
               double max_search_cells) {
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  DatasetPtr ds(mem->Create("", width, height, 1, GDT_Float32, nullptr));
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(nodata);
  if (band->RasterIO(GF_Write, 0, 0, width, height, heights.data(), width, height,
                     GDT_Float32, 0, 0, nullptr) != CE_None) {
    throw IoError("cannot stage DEM for no-data filling: " + LastGdalMessage(), "");
  }
  if (GDALFillNodata(band, nullptr, max_search_cells, 0, 0, nullptr, nullptr, nullptr) !=
      CE_None) {
    throw InputError("GDAL FillNodata failed: " + LastGdalMessage(), "");
  }
  if (band->RasterIO(GF_Read, 0, 0, width, height, heights.data(), width, height, GDT_Float32,
                     0, 0, nullptr) != CE_None) {
    throw IoError("cannot read filled DEM: " + LastGdalMessage(), "");
  }
}

}  // namespace

Eigen::Vector2d Dem::MapFromPost(double col, double row) const {
  const double c = col + 0.5, r = row + 0.5;
  const auto& g = geotransform;
  return {g[0] + c * g[1] + r * g[2], g[3] + c * g[4] + r * g[5]};
}

bool Dem::PostFromMap(double x, double y, double* col, double* row) const {
  const auto& g = geotransform;
  const double det = g[1] * g[5] - g[2] * g[4];
  if (det == 0.0) return false;
  const double dx = x - g[0], dy = y - g[3];
  *col = (g[5] * dx - g[2] * dy) / det - 0.5;
  *row = (-g[4] * dx + g[1] * dy) / det - 0.5;
  return true;
}

std::optional<double> Dem::InterpolateHeight(double col, double row) const {
  if (!(col >= 0.0 && row >= 0.0 && col <= width - 1 && row <= height - 1)) return std::nullopt;
  const int c0 = std::min(static_cast<int>(col), width - 2);
  const int r0 = std::min(static_cast<int>(row), height - 2);
  const double fc = col - c0, fr = row - r0;
  return (1 - fr) * ((1 - fc) * HeightAt(c0, r0) + fc * HeightAt(c0 + 1, r0)) +
         fr * ((1 - fc) * HeightAt(c0, r0 + 1) + fc * HeightAt(c0 + 1, r0 + 1));
}

Dem ReadDem(const fs::path& path, const DemReadOptions& options) {
  EnsureGdal();
  const std::string where = path.string();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError("DEM file does not exist", where);
  if (fs::is_directory(path, ec)) throw InputError("DEM path is a directory, not a file", where);
  DatasetPtr ds(GDALDataset::Open(where.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw InputError("not a raster GDAL can read", where);
  if (options.band < 1 || options.band > ds->GetRasterCount()) {
    throw InputError("raster has no band " + std::to_string(options.band), where);
  }
  Dem dem;
  dem.source = where;
  dem.width = ds->GetRasterXSize();
  dem.height = ds->GetRasterYSize();
  int col0 = 0, row0 = 0;
  if (options.window) {
    const auto [c, r, w, h] = *options.window;
    if (c < 0 || r < 0 || w < 2 || h < 2 || c + w > dem.width || r + h > dem.height) {
      throw ConfigError("window " + std::to_string(c) + "," + std::to_string(r) + "," +
                            std::to_string(w) + "," + std::to_string(h) + " is not inside the " +
                            std::to_string(dem.width) + "x" + std::to_string(dem.height) + " DEM",
                        "--window");
    }
    col0 = c;
    row0 = r;
    dem.width = w;
    dem.height = h;
  }
  if (dem.width < 2 || dem.height < 2) {
    throw InputError("DEM must have at least 2x2 posts, has " + std::to_string(dem.width) + "x" +
                         std::to_string(dem.height),
                     where);
  }
  const int64_t bytes = int64_t{dem.width} * dem.height * int64_t{sizeof(float)};
  if (bytes > options.max_bytes) {
    throw InputError("DEM of " + std::to_string(dem.width) + "x" + std::to_string(dem.height) +
                         " posts needs " + std::to_string(bytes >> 20) +
                         " MiB, over the limit; crop it to a window",
                     where);
  }
  if (ds->GetGeoTransform(dem.geotransform.data()) != CE_None) {
    throw InputError("raster has no geotransform (not georeferenced)", where);
  }
  {
    auto& g = dem.geotransform;
    const double x0 = g[0] + col0 * g[1] + row0 * g[2];
    const double y0 = g[3] + col0 * g[4] + row0 * g[5];
    g[0] = x0;
    g[3] = y0;
  }
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (srs == nullptr) throw InputError("raster has no coordinate reference system", where);
  char* wkt = nullptr;
  srs->exportToWkt(&wkt);
  dem.crs_wkt = wkt != nullptr ? wkt : "";
  CPLFree(wkt);

  GDALRasterBand* band = ds->GetRasterBand(options.band);
  int has_nodata = 0;
  const double nodata = band->GetNoDataValue(&has_nodata);
  std::vector<double> raw(size_t(dem.width) * dem.height);
  if (band->RasterIO(GF_Read, col0, row0, dem.width, dem.height, raw.data(), dem.width,
                     dem.height, GDT_Float64, 0, 0, nullptr) != CE_None) {
    throw InputError("cannot read DEM heights: " + LastGdalMessage(), where);
  }
  int64_t voids = 0;
  for (double v : raw) voids += IsVoid(v, has_nodata != 0, nodata) ? 1 : 0;
  if (voids == static_cast<int64_t>(raw.size())) {
    throw InputError("DEM has no valid height (all " + std::to_string(voids) +
                         " cells are no-data)",
                     where);
  }
  if (voids > 0 && !options.fill_nodata) {
    throw InputError("DEM has " + std::to_string(voids) +
                         " no-data cells; use --fill-nodata to interpolate them",
                     where);
  }
  constexpr float kVoid = -3.0e38f;
  dem.heights_m.resize(raw.size());
  for (size_t i = 0; i < raw.size(); ++i) {
    dem.heights_m[i] = IsVoid(raw[i], has_nodata != 0, nodata) ? kVoid : static_cast<float>(raw[i]);
  }
  if (voids > 0) {
    FillVoids(dem.heights_m, dem.width, dem.height, kVoid, options.fill_max_search_cells);
    int64_t left = 0;
    for (float v : dem.heights_m) left += (v == kVoid || !std::isfinite(v)) ? 1 : 0;
    if (left > 0) {
      throw InputError(std::to_string(left) + " of " + std::to_string(voids) +
                           " no-data cells are too far from valid heights to fill",
                       where);
    }
    dem.filled_nodata_cells = voids;
  }
  return dem;
}

void WriteDemGeoTiff(const fs::path& path, const std::vector<float>& heights, int width,
                     int height, const std::array<double, 6>& geotransform, const std::string& crs,
                     double nodata) {
  EnsureGdal();
  OGRSpatialReference srs;
  if (srs.SetFromUserInput(crs.c_str()) != OGRERR_NONE) throw IoError("cannot parse CRS " + crs, path.string());
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  DatasetPtr ds(gtiff->Create(path.c_str(), width, height, 1, GDT_Float32, nullptr));
  if (!ds) throw IoError("cannot create DEM: " + LastGdalMessage(), path.string());
  ds->SetGeoTransform(const_cast<double*>(geotransform.data()));
  ds->SetSpatialRef(&srs);
  if (std::isfinite(nodata)) ds->GetRasterBand(1)->SetNoDataValue(nodata);
  if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, width, height,
                                     const_cast<float*>(heights.data()), width, height,
                                     GDT_Float32, 0, 0, nullptr) != CE_None) {
    throw IoError("cannot write DEM: " + LastGdalMessage(), path.string());
  }
}

GeoPoint ResolveSceneCentre(const Dem& dem, const std::optional<Eigen::Vector2d>& lon_lat,
                            const std::optional<Eigen::Vector2d>& map_xy) {
  CrsTransform crs(dem.crs_wkt);
  std::vector<double> x(1), y(1);
  GeoPoint centre;
  if (lon_lat) {
    centre.lon_deg = lon_lat->x();
    centre.lat_deg = lon_lat->y();
    if (!std::isfinite(centre.lon_deg) || !std::isfinite(centre.lat_deg) ||
        std::abs(centre.lat_deg) > 90.0) {
      throw ConfigError("scene centre is not a valid longitude,latitude", "--center");
    }
    x[0] = centre.lon_deg;
    y[0] = centre.lat_deg;
    crs.FromLonLat(x, y);
  } else {
    const Eigen::Vector2d m =
        map_xy ? *map_xy : dem.MapFromPost((dem.width - 1) / 2.0, (dem.height - 1) / 2.0);
    x[0] = m.x();
    y[0] = m.y();
    std::vector<double> lon = x, lat = y;
    crs.ToLonLat(lon, lat);
    centre.lon_deg = lon[0];
    centre.lat_deg = lat[0];
  }
  double col = 0.0, row = 0.0;
  std::optional<double> h;
  if (dem.PostFromMap(x[0], y[0], &col, &row)) h = dem.InterpolateHeight(col, row);
  if (!h) {
    throw ConfigError("scene centre lies outside the DEM", lon_lat ? "--center" : "--center-map");
  }
  centre.height_m = *h;
  return centre;
}

std::vector<Eigen::Vector3f> DemPostsInFrame(const Dem& dem, const LocalFrame& frame) {
  CrsTransform crs(dem.crs_wkt);
  const size_t n = size_t(dem.width) * dem.height;
  std::vector<double> x(n), y(n);
  for (int r = 0; r < dem.height; ++r) {
    for (int c = 0; c < dem.width; ++c) {
      const Eigen::Vector2d m = dem.MapFromPost(c, r);
      x[size_t(r) * dem.width + c] = m.x();
      y[size_t(r) * dem.width + c] = m.y();
    }
  }
  crs.ToLonLat(x, y);
  std::vector<Eigen::Vector3f> enu(n);
  for (size_t i = 0; i < n; ++i) {
    enu[i] = frame.EnuFromGeodetic(x[i], y[i], dem.heights_m[i]).cast<float>();
  }
  return enu;
}

Eigen::Vector2d DemPostSpacingMetres(const Dem& dem, const LocalFrame& frame) {
  CrsTransform crs(dem.crs_wkt);
  const double c = (dem.width - 1) / 2.0, r = (dem.height - 1) / 2.0;
  std::vector<double> x, y;
  for (const auto& [dc, dr] : {std::pair{0.0, 0.0}, {1.0, 0.0}, {0.0, 1.0}}) {
    const Eigen::Vector2d m = dem.MapFromPost(c + dc, r + dr);
    x.push_back(m.x());
    y.push_back(m.y());
  }
  crs.ToLonLat(x, y);
  const Eigen::Vector3d p0 = frame.EnuFromGeodetic(x[0], y[0], 0.0);
  const Eigen::Vector3d pc = frame.EnuFromGeodetic(x[1], y[1], 0.0);
  const Eigen::Vector3d pr = frame.EnuFromGeodetic(x[2], y[2], 0.0);
  return {(pc - p0).norm(), (pr - p0).norm()};
}

}  // namespace gissar::geo
