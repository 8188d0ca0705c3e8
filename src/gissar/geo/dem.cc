#include "gissar/geo/dem.h"

#include <gdal_alg.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include "gissar/geo/gdal_env.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"

namespace gissar::geo {
namespace fs = std::filesystem;
namespace {

bool IsVoid(double value, bool has_nodata, double nodata) {
  return !std::isfinite(value) || (has_nodata && value == nodata);
}

// Fills void cells with GDAL's FillNodata on an in-memory copy.
void FillVoids(std::vector<float>& heights, int width, int height, float nodata,
               double max_search_cells, const std::string& where) {
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  DatasetPtr ds(mem ? mem->Create("", width, height, 1, GDT_Float32, nullptr) : nullptr);
  if (!ds) {
    throw IoError("cannot stage the " + std::to_string(width) + " x " + std::to_string(height) +
                      " DEM for no-data filling: " + LastGdalMessage(),
                  where);
  }
  GDALRasterBand* band = ds->GetRasterBand(1);
  band->SetNoDataValue(nodata);
  if (band->RasterIO(GF_Write, 0, 0, width, height, heights.data(), width, height,
                     GDT_Float32, 0, 0, nullptr) != CE_None) {
    throw IoError("cannot stage DEM for no-data filling: " + LastGdalMessage(), where);
  }
  if (GDALFillNodata(band, nullptr, max_search_cells, 0, 0, nullptr, nullptr, nullptr) !=
      CE_None) {
    throw InputError("GDAL FillNodata failed: " + LastGdalMessage(), where);
  }
  if (band->RasterIO(GF_Read, 0, 0, width, height, heights.data(), width, height, GDT_Float32,
                     0, 0, nullptr) != CE_None) {
    throw IoError("cannot read filled DEM: " + LastGdalMessage(), where);
  }
}

// Geographic DEMs: refuses posts near or beyond a pole and longitudes
// outside [-180, 180] (see ReadDem).
void CheckGeographicExtent(const Dem& dem, const OGRSpatialReference& srs) {
  const double to_deg = srs.GetAngularUnits(nullptr) * 180.0 / M_PI;
  double lon_min = 1e300, lon_max = -1e300, lat_max = 0.0;
  // The whole raster's corner posts (also when only a window is read).
  Dem whole;
  whole.geotransform = dem.HasLattice() ? dem.source_geotransform : dem.geotransform;
  const int w = dem.HasLattice() ? dem.source_width : dem.width;
  const int h = dem.HasLattice() ? dem.source_height : dem.height;
  for (const auto& [c, r] : {std::pair{0, 0}, {w - 1, 0}, {0, h - 1}, {w - 1, h - 1}}) {
    const Eigen::Vector2d m = whole.MapFromPost(c, r) * to_deg;
    lon_min = std::min(lon_min, m.x());
    lon_max = std::max(lon_max, m.x());
    lat_max = std::max(lat_max, std::abs(m.y()));
  }
  std::ostringstream text;
  text.precision(10);
  if (lat_max > 90.0) {
    text << "geographic DEM has posts at latitude " << lat_max
         << ", beyond 90 degrees: its geotransform is wrong";
  } else if (lat_max > kMaxGeographicLatDeg) {
    text << "geographic DEM reaches latitude " << lat_max << ", within "
         << 90.0 - kMaxGeographicLatDeg
         << " degree of a pole where longitude/latitude grids degenerate; reproject it to a polar "
            "stereographic CRS (gdalwarp -t_srs EPSG:3413 or EPSG:3031)";
  } else if (lon_min < -180.0 || lon_max > 180.0) {
    text << "geographic DEM spans longitudes " << lon_min << " to " << lon_max
         << ", outside [-180, 180]: it crosses the antimeridian; reproject it to a projected CRS "
            "such as UTM (gdalwarp -t_srs EPSG:326NN)";
  } else {
    return;
  }
  throw InputError(text.str(), dem.source);
}

// The vertical unit of a DEM band: `option` (--vertical-units), else the
// band's unit type, else the vertical axis of a compound CRS, else metres.
// Returns metres per unit and where it came from; InputError for an
// unknown unit.
std::pair<double, std::string> ResolveVerticalUnit(GDALRasterBand& band, const OGRSpatialReference& srs,
                                                   const std::string& option, const std::string& where) {
  std::string unit_name = option;
  std::string source = "--vertical-units";
  if (unit_name.empty()) {
    const char* band_unit = band.GetUnitType();
    if (band_unit != nullptr && band_unit[0] != '\0') {
      unit_name = band_unit;
      source = "band unit type";
    }
  }
  if (unit_name.empty() && srs.IsCompound()) {
    const char* crs_unit = nullptr;
    srs.GetTargetLinearUnits("VERT_CS", &crs_unit);
    if (crs_unit != nullptr && crs_unit[0] != '\0') {
      unit_name = crs_unit;
      source = "vertical CRS";
    }
  }
  if (unit_name.empty()) {
    unit_name = "m";
    source = "default (the file names no unit)";
  }
  const std::optional<double> metres = MetresPerVerticalUnit(unit_name);
  if (!metres) {
    throw InputError("DEM heights are in an unknown unit '" + unit_name + "' (" + source +
                         "); give --vertical-units m, ft or us-ft",
                     where);
  }
  return {*metres, source};
}

}  // namespace

Eigen::Vector2d Dem::MapFromPost(double col, double row) const {
  if (HasLattice()) {
    // Source post (lattice index / factor): the lattice index is an exact
    // integer for every post, whatever the window.
    const double c = (double(lattice_col0) + col) / lattice_factor + 0.5;
    const double r = (double(lattice_row0) + row) / lattice_factor + 0.5;
    const auto& g = source_geotransform;
    return {g[0] + c * g[1] + r * g[2], g[3] + c * g[4] + r * g[5]};
  }
  const double c = col + 0.5, r = row + 0.5;
  const auto& g = geotransform;
  return {g[0] + c * g[1] + r * g[2], g[3] + c * g[4] + r * g[5]};
}

bool Dem::PostFromMap(double x, double y, double* col, double* row) const {
  const auto& g = HasLattice() ? source_geotransform : geotransform;
  const double det = g[1] * g[5] - g[2] * g[4];
  if (det == 0.0) return false;
  const double dx = x - g[0], dy = y - g[3];
  *col = (g[5] * dx - g[2] * dy) / det - 0.5;
  *row = (-g[4] * dx + g[1] * dy) / det - 0.5;
  if (HasLattice()) {
    // Subtracting the integer offset is exact: the same fractional part as
    // in the whole raster.
    *col = *col * lattice_factor - double(lattice_col0);
    *row = *row * lattice_factor - double(lattice_row0);
  }
  return true;
}

Eigen::Vector2d Dem::SourceCentrePost() const {
  if (!HasLattice()) return {(width - 1) / 2.0, (height - 1) / 2.0};
  const double w = double(source_width - 1) * lattice_factor + 1.0;
  const double h = double(source_height - 1) * lattice_factor + 1.0;
  return {(w - 1.0) / 2.0 - double(lattice_col0), (h - 1.0) / 2.0 - double(lattice_row0)};
}

std::optional<double> Dem::InterpolateHeight(double col, double row) const {
  if (!(col >= 0.0 && row >= 0.0 && col <= width - 1 && row <= height - 1)) return std::nullopt;
  const int c0 = std::min(static_cast<int>(col), width - 2);
  const int r0 = std::min(static_cast<int>(row), height - 2);
  const double fc = col - c0, fr = row - r0;
  return (1 - fr) * ((1 - fc) * HeightAt(c0, r0) + fc * HeightAt(c0 + 1, r0)) +
         fr * ((1 - fc) * HeightAt(c0, r0 + 1) + fc * HeightAt(c0 + 1, r0 + 1));
}

namespace {

// The raster at `path`, opened read-only, holding band `band`.
DatasetPtr OpenDemRaster(const fs::path& path, const std::string& where) {
  std::error_code ec;
  // GDAL virtual file systems (/vsimem/, /vsizip/...) are not on disk.
  const bool virtual_path = where.rfind("/vsi", 0) == 0;
  if (!virtual_path && !fs::exists(path, ec)) throw InputError("DEM file does not exist", where);
  if (!virtual_path && fs::is_directory(path, ec)) {
    throw InputError("DEM path is a directory, not a file", where);
  }
  DatasetPtr ds(GDALDataset::Open(where.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw InputError("not a raster GDAL can read", where);
  return ds;
}

void CheckBand(GDALDataset& ds, int band, const std::string& where) {
  if (band < 1 || band > ds.GetRasterCount()) {
    throw InputError("raster has no band " + std::to_string(band), where);
  }
}

// The part of the raster read (options.window, else all of it): sets the
// DEM's width and height, returns the first column and row.
std::pair<int, int> ChooseWindow(GDALDataset& ds, const DemReadOptions& options, const std::string& where,
                                 Dem& dem) {
  dem.width = ds.GetRasterXSize();
  dem.height = ds.GetRasterYSize();
  int col0 = 0, row0 = 0;
  if (options.window) {
    const auto [c, r, w, h] = *options.window;
    if (c < 0 || r < 0 || w < 2 || h < 2 || int64_t{c} + w > dem.width || int64_t{r} + h > dem.height) {
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
  return {col0, row0};
}

// Refuses, from the header, a read over the memory budget: the posts, or
// one GDAL block.
void CheckReadBudget(GDALDataset& ds, const Dem& dem, const DemReadOptions& options, const std::string& where) {
  // In double: width * height * bytes_per_post may overflow 64 bits.
  const double bytes = double(dem.width) * double(dem.height) * double(options.bytes_per_post);
  if (bytes > double(options.max_bytes)) {
    throw InputError("DEM of " + std::to_string(dem.width) + "x" + std::to_string(dem.height) +
                         " posts needs about " + FormatBytes(bytes) + ", over the memory limit of " +
                         FormatBytes(double(options.max_bytes)) +
                         " (--max-memory); use a window of it or resample it to coarser posts",
                     where);
  }
  // GDAL reads a pixel-interleaved block for all bands at once: a tiny
  // file declaring thousands of bands would need gigabytes for one block.
  int block_x = 0, block_y = 0;
  GDALRasterBand* first = ds.GetRasterBand(options.band);
  first->GetBlockSize(&block_x, &block_y);
  const char* interleave = ds.GetMetadataItem("INTERLEAVE", "IMAGE_STRUCTURE");
  const int bands = interleave != nullptr && std::string(interleave) == "PIXEL" ? ds.GetRasterCount() : 1;
  const double block_bytes = double(block_x) * double(block_y) * bands *
                             GDALGetDataTypeSizeBytes(first->GetRasterDataType());
  if (block_bytes > double(options.max_bytes)) {
    throw InputError("raster of " + std::to_string(ds.GetRasterCount()) + " bands of " +
                         std::to_string(block_x) + "x" + std::to_string(block_y) +
                         "-cell blocks needs about " + FormatBytes(block_bytes) +
                         " to read one block, over the memory limit of " +
                         FormatBytes(double(options.max_bytes)) +
                         " (--max-memory); extract the height band (gdal_translate -b N)",
                     where);
  }
}

// The DEM's map geometry: geotransform (moved to the window's first post),
// the whole raster's lattice, CRS and vertical datum; a geographic DEM is
// checked over the whole raster. Returns the CRS (owned by `ds`).
const OGRSpatialReference& ReadMapGeometry(GDALDataset& ds, int col0, int row0, const std::string& where,
                                           Dem& dem) {
  if (ds.GetGeoTransform(dem.geotransform.data()) != CE_None) {
    throw InputError("raster has no geotransform (not georeferenced)", where);
  }
  {
    const auto& g = dem.geotransform;
    const bool finite = std::all_of(g.begin(), g.end(), [](double v) { return std::isfinite(v); });
    if (!finite || g[1] * g[5] - g[2] * g[4] == 0.0) {
      throw InputError("raster geotransform is singular or not finite", where);
    }
  }
  dem.source_geotransform = dem.geotransform;
  dem.source_width = ds.GetRasterXSize();
  dem.source_height = ds.GetRasterYSize();
  dem.lattice_col0 = col0;
  dem.lattice_row0 = row0;
  dem.lattice_factor = 1;
  {
    auto& g = dem.geotransform;
    const double x0 = g[0] + col0 * g[1] + row0 * g[2];
    const double y0 = g[3] + col0 * g[4] + row0 * g[5];
    g[0] = x0;
    g[3] = y0;
  }
  const OGRSpatialReference* srs = ds.GetSpatialRef();
  if (srs == nullptr) throw InputError("raster has no coordinate reference system", where);
  char* wkt = nullptr;
  srs->exportToWkt(&wkt);
  dem.crs_wkt = wkt != nullptr ? wkt : "";
  CPLFree(wkt);
  dem.file_vertical_datum =
      VerticalDatumOfCrs(dem.crs_wkt, ds.GetDriver() != nullptr ? ds.GetDriver()->GetDescription() : "");
  if (srs->IsGeographic()) CheckGeographicExtent(dem, *srs);
  return *srs;
}

// The window's stored values with the band's no-data marking, in float when
// that changes no height (HeightsExactInFloat), else in double.
template <typename T>
struct RawHeights {
  std::vector<T> values;
  bool nodata_marked = false;  // `nodata` marks voids (else only non-finite values do)
  double nodata = 0.0;

  bool IsVoidAt(size_t i) const { return IsVoid(values[i], nodata_marked, nodata); }
};

// Whether the band's scale or offset changes its stored values.
bool ScalesOrOffsets(GDALRasterBand& band) {
  int has_scale = 0, has_offset = 0;
  const double scale = band.GetScale(&has_scale), offset = band.GetOffset(&has_offset);
  return (has_scale && scale != 1.0) || (has_offset && offset != 0.0);
}

// Whether reading the band in float gives the heights of reading it in
// double: every stored value is a float (8- and 16-bit integers, Float32)
// and no scale or offset is applied (a unit conversion rounds once to float
// either way). Reading a 4000^2 Int16 DEM in float touches 64 MB instead of
// 128 MB of double plus the 64 MB of heights (the float values become the
// heights): on this project's benchmark machine fresh pages cost about
// 1.5 ms per MB, serial at the start of the run.
bool HeightsExactInFloat(GDALRasterBand& band) {
  switch (band.GetRasterDataType()) {
    case GDT_Byte:
    case GDT_UInt16:
    case GDT_Int16:
    case GDT_Float32:
      break;
    default:
      return false;
  }
  return !ScalesOrOffsets(band);
}

template <typename T>
RawHeights<T> ReadRawHeights(GDALRasterBand& band, int col0, int row0, const Dem& dem, const std::string& where) {
  RawHeights<T> raw;
  int has_nodata = 0;
  raw.nodata = band.GetNoDataValue(&has_nodata);
  raw.values.resize(size_t(dem.width) * dem.height);
  if (band.RasterIO(GF_Read, col0, row0, dem.width, dem.height, raw.values.data(), dem.width, dem.height,
                    std::is_same_v<T, float> ? GDT_Float32 : GDT_Float64, 0, 0, nullptr) != CE_None) {
    throw InputError("cannot read DEM heights: " + LastGdalMessage(), where);
  }
  raw.nodata_marked = has_nodata != 0;
  return raw;
}

// The band's scale and offset (height = stored * scale + offset, e.g. an
// Int16 DEM in decimetres): applied to every cell that is not no-data (the
// no-data value is a stored value).
template <typename T>
void ApplyScaleAndOffset(GDALRasterBand& band, RawHeights<T>& raw, const std::string& where) {
  int has_scale = 0, has_offset = 0;
  const double scale = band.GetScale(&has_scale), offset = band.GetOffset(&has_offset);
  if ((has_scale && !(std::isfinite(scale) && scale != 0.0)) || (has_offset && !std::isfinite(offset))) {
    throw InputError("DEM band scale/offset must be finite with a non-zero scale", where);
  }
  if (ScalesOrOffsets(band)) {
    const double s = has_scale ? scale : 1.0, o = has_offset ? offset : 0.0;
    for (T& v : raw.values) {
      if (IsVoid(v, raw.nodata_marked, raw.nodata)) {
        v = std::numeric_limits<T>::quiet_NaN();  // stays void after scaling
      } else {
        v = static_cast<T>(v * s + o);
      }
    }
    raw.nodata_marked = false;  // voids are NaN now; a scaled height may equal the stored no-data value
  }
}

// Vertical unit: the option, else the band's unit type, else the vertical
// axis of a compound CRS, else metres. Heights become metres here, before
// the range check (a DEM in feet is not silently read as metres).
template <typename T>
void ConvertToMetres(GDALRasterBand& band, const OGRSpatialReference& srs, const DemReadOptions& options,
                     const std::string& where, RawHeights<T>& raw, Dem& dem) {
  const auto [metres, unit_source] = ResolveVerticalUnit(band, srs, options.vertical_units, where);
  dem.vertical_unit_source = unit_source;
  dem.vertical_unit_m = metres;
  if (metres != 1.0) {
    // In double, rounded once (to float when T is float, as StoreHeights
    // rounds the double values).
    for (T& v : raw.values) {
      if (!IsVoid(v, raw.nodata_marked, raw.nodata)) v = static_cast<T>(double(v) * metres);
      else v = std::numeric_limits<T>::quiet_NaN();
    }
    raw.nodata_marked = false;  // voids are NaN now (a converted height may equal the no-data value)
  }
}

// Counts the voids; refuses heights outside [kMinHeightM, kMaxHeightM] and a
// DEM without any valid height.
template <typename T>
int64_t CheckHeightRange(const RawHeights<T>& raw, const std::string& where) {
  int64_t voids = 0, out_of_range = 0;
  double lowest = kMinHeightM, highest = kMaxHeightM;
  for (const double v : raw.values) {
    if (IsVoid(v, raw.nodata_marked, raw.nodata)) {
      ++voids;
    } else if (v < kMinHeightM || v > kMaxHeightM) {
      ++out_of_range;
      lowest = std::min(lowest, v);
      highest = std::max(highest, v);
    }
  }
  if (out_of_range > 0) {
    std::ostringstream text;
    text << "DEM has " << out_of_range << " heights outside [" << kMinHeightM << ", "
         << kMaxHeightM << "] m (lowest " << lowest << ", highest " << highest
         << "): an unmarked no-data value (set it with gdal_edit -a_nodata) or heights not in metres";
    throw InputError(text.str(), where);
  }
  if (voids == static_cast<int64_t>(raw.values.size())) {
    throw InputError("DEM has no valid height (all " + std::to_string(voids) +
                         " cells are no-data)",
                     where);
  }
  return voids;
}

// Voids 4-connected to the raster border (through voids): 1 per such cell.
struct BorderVoids {
  std::vector<uint8_t> mask;  // empty when not searched
  int64_t count = 0;
};

template <typename T>
BorderVoids FindBorderVoids(const RawHeights<T>& raw, int w, int h) {
  BorderVoids border;
  border.mask.assign(raw.values.size(), 0);
  std::vector<size_t> stack;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const size_t i = size_t(r) * w + c;
      if ((r == 0 || c == 0 || r == h - 1 || c == w - 1) && raw.IsVoidAt(i)) {
        border.mask[i] = 1;
        stack.push_back(i);
      }
    }
  }
  while (!stack.empty()) {
    const size_t i = stack.back();
    stack.pop_back();
    ++border.count;
    const int r = static_cast<int>(i / w), c = static_cast<int>(i % w);
    const std::pair<int, int> next[4] = {{c - 1, r}, {c + 1, r}, {c, r - 1}, {c, r + 1}};
    for (const auto& [nc, nr] : next) {
      if (nc < 0 || nr < 0 || nc >= w || nr >= h) continue;
      const size_t j = size_t(nr) * w + nc;
      if (!border.mask[j] && raw.IsVoidAt(j)) {
        border.mask[j] = 1;
        stack.push_back(j);
      }
    }
  }
  return border;
}

// The heights in float, voids marked in nodata_mask: border voids hold the
// lowest valid height, interior voids are filled (FillVoids).
template <typename T>
void StoreHeights(RawHeights<T>&& raw, int64_t voids, const BorderVoids& border, const DemReadOptions& options,
                  const std::string& where, Dem& dem) {
  constexpr float kVoid = -3.0e38f;
  const size_t count = raw.values.size();
  if constexpr (std::is_same_v<T, float>) {
    if (voids == 0) {
      dem.heights_m = std::move(raw.values);  // every value is a height
      return;
    }
  }
  dem.heights_m.resize(count);
  float lowest_valid = std::numeric_limits<float>::max();
  for (size_t i = 0; i < count; ++i) {
    dem.heights_m[i] = raw.IsVoidAt(i) ? kVoid : static_cast<float>(raw.values[i]);
    if (dem.heights_m[i] != kVoid) lowest_valid = std::min(lowest_valid, dem.heights_m[i]);
  }
  if (voids == 0) return;
  dem.nodata_mask.resize(count);
  for (size_t i = 0; i < count; ++i) dem.nodata_mask[i] = raw.IsVoidAt(i) ? 1 : 0;
  // Border no-data: keeps the lowest valid height so the grid stays finite; the scene leaves these posts out (nodata_mask), never fills them.
  for (size_t i = 0; i < border.mask.size(); ++i) {
    if (border.mask[i]) dem.heights_m[i] = lowest_valid;
  }
  if (voids > border.count) {
    FillVoids(dem.heights_m, dem.width, dem.height, kVoid, options.fill_max_search_cells, where);
  }
  int64_t left = 0;
  for (float v : dem.heights_m) left += (v == kVoid || !std::isfinite(v)) ? 1 : 0;
  if (left > 0) {
    throw InputError(std::to_string(left) + " of " + std::to_string(voids) +
                         " no-data cells are too far from valid heights to fill",
                     where);
  }
  dem.filled_nodata_cells = voids - border.count;
}

// The heights of the window at (col0, row0), read as T, into `dem`.
template <typename T>
void ReadHeights(GDALRasterBand& band, const OGRSpatialReference& srs, int col0, int row0,
                 const DemReadOptions& options, const std::string& where, Dem& dem) {
  RawHeights<T> raw = ReadRawHeights<T>(band, col0, row0, dem, where);
  ApplyScaleAndOffset(band, raw, where);
  ConvertToMetres(band, srs, options, where, raw, dem);
  const int64_t voids = CheckHeightRange(raw, where);
  BorderVoids border;
  if (voids > 0 && options.border_nodata_outside) border = FindBorderVoids(raw, dem.width, dem.height);
  if (voids - border.count > 0 && !options.fill_nodata) {
    throw InputError("DEM has " + std::to_string(voids - border.count) + " no-data cells" +
                         (border.count > 0 ? " inside (" + std::to_string(border.count) +
                                                 " more on its border are left out of the scene)"
                                           : std::string()) +
                         "; use --fill-nodata to interpolate them",
                     where);
  }
  StoreHeights(std::move(raw), voids, border, options, where, dem);
}

}  // namespace

struct DemFile::Dataset {
  DatasetPtr ds;
};

Dem DemFile::Read(const DemReadOptions& options) const {
  const std::string& where = path_;
  GDALDataset* ds = dataset_->ds.get();
  CheckBand(*ds, options.band, where);
  Dem dem;
  dem.source = where;
  const auto [col0, row0] = ChooseWindow(*ds, options, where, dem);
  CheckReadBudget(*ds, dem, options, where);
  const OGRSpatialReference& srs = ReadMapGeometry(*ds, col0, row0, where, dem);

  GDALRasterBand& band = *ds->GetRasterBand(options.band);
  if (HeightsExactInFloat(band)) {
    ReadHeights<float>(band, srs, col0, row0, options, where, dem);
  } else {
    ReadHeights<double>(band, srs, col0, row0, options, where, dem);
  }
  // Give back GDAL's cached blocks of what was read (as closing the file
  // would): the heights are held by `dem` now.
  ds->FlushCache(false);
  return dem;
}


Dem ReadDem(const fs::path& path, const DemReadOptions& options) { return DemFile(path).Read(options); }

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

namespace {

// Posts at most this far apart (metres) are placed by interpolating between
// exactly transformed nodes (DemPostsInFrame).
constexpr double kInterpolationNodeSpacingM = 64.0;

// Every post transformed exactly: map -> WGS84 (PROJ) -> ENU.
std::vector<Eigen::Vector3f> ExactPostsInFrame(const Dem& dem, const LocalFrame& frame) {
  const size_t n = size_t(dem.width) * dem.height;
  std::vector<Eigen::Vector3f> enu(n);
  // Blocks of rows in parallel, each with its own transformation (PROJ's
  // objects are not shared between threads) and row-sized buffers only.
  const int grain = std::max(1, dem.height / 64);
  tbb::parallel_for(tbb::blocked_range<int>(0, dem.height, grain), [&](const tbb::blocked_range<int>& rows) {
    const CrsTransform crs(dem.crs_wkt);
    const size_t count = size_t(rows.size()) * dem.width;
    std::vector<double> x(count), y(count);
    for (int r = rows.begin(); r < rows.end(); ++r) {
      for (int c = 0; c < dem.width; ++c) {
        const Eigen::Vector2d m = dem.MapFromPost(c, r);
        const size_t k = size_t(r - rows.begin()) * dem.width + c;
        x[k] = m.x();
        y[k] = m.y();
      }
    }
    try {
      crs.ToLonLat(x, y);
    } catch (const InputError& e) {
      throw InputError("DEM posts cannot be transformed to WGS84: " + e.message() + " " + e.where(), dem.source);
    }
    const size_t first = size_t(rows.begin()) * dem.width;
    for (size_t k = 0; k < count; ++k) {
      enu[first + k] = frame.EnuFromGeodetic(x[k], y[k], dem.heights_m[first + k]).cast<float>();
    }
  });
  return enu;
}

int64_t FloorDiv(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

}  // namespace

std::vector<Eigen::Vector3f> DemPostsInFrame(const Dem& dem, const LocalFrame& frame) {
  const CrsTransform probe(dem.crs_wkt);  // throws here, on the calling thread, for a bad CRS
  if (dem.width < 2 || dem.height < 2) return ExactPostsInFrame(dem, frame);
  // A post's ENU position is E0(c, r) + h U(c, r): the ellipsoid point below
  // it and the ellipsoid's unit normal, both smooth in the post coordinates.
  // On nodes every S posts (S x spacing <= 64 m) they are computed exactly;
  // between nodes, interpolated bilinearly: off by at most (64 m)^2 / (8 R)
  // = 0.08 mm for the Earth's curvature 1/R (map projections bend less),
  // below a float32 coordinate's rounding (1 mm at 8 km). Nodes sit on the
  // source raster's lattice (Dem::lattice_col0/row0), so a window places its
  // posts bit for bit as the whole raster does.
  // The node step from the spacing at the whole source raster's centre: the
  // same for every window of it.
  double spacing_m = 0.0;
  try {
    spacing_m = DemPostSpacingMetres(dem, frame, /*at_source_centre=*/true).maxCoeff();
  } catch (const InputError&) {
    return ExactPostsInFrame(dem, frame);
  }
  const int step = spacing_m > 0.0 ? static_cast<int>(std::floor(kInterpolationNodeSpacingM / spacing_m)) : 1;
  if (step < 2) return ExactPostsInFrame(dem, frame);

  const int64_t g_col0 = dem.HasLattice() ? dem.lattice_col0 : 0, g_row0 = dem.HasLattice() ? dem.lattice_row0 : 0;
  const int64_t k_col0 = FloorDiv(g_col0, step), k_row0 = FloorDiv(g_row0, step);
  const int nodes_x = static_cast<int>(FloorDiv(g_col0 + dem.width - 1, step) - k_col0 + 2);
  const int nodes_y = static_cast<int>(FloorDiv(g_row0 + dem.height - 1, step) - k_row0 + 2);
  std::vector<Eigen::Vector3d> ground(size_t(nodes_x) * nodes_y), up(ground.size());
  std::atomic<bool> failed{false};
  // About eight blocks of node rows: each makes its own transformation
  // (PROJ's objects stay on their thread), a clone of GDAL's cached one that
  // costs about 0.4 ms, more than transforming its nodes at 1000^2 posts.
  tbb::parallel_for(tbb::blocked_range<int>(0, nodes_y, std::max(4, nodes_y / 8)),
                    [&](const tbb::blocked_range<int>& rows) {
    const CrsTransform crs(dem.crs_wkt);
    const size_t count = size_t(rows.size()) * nodes_x;
    std::vector<double> x(count), y(count);
    for (int j = rows.begin(); j < rows.end(); ++j) {
      for (int i = 0; i < nodes_x; ++i) {
        // Node (i, j) is post ((k_col0 + i) step - g_col0, ...) of this grid.
        const Eigen::Vector2d m = dem.MapFromPost(double((k_col0 + i) * step - g_col0),
                                                  double((k_row0 + j) * step - g_row0));
        const size_t k = size_t(j - rows.begin()) * nodes_x + i;
        x[k] = m.x();
        y[k] = m.y();
      }
    }
    try {
      crs.ToLonLat(x, y);
    } catch (const InputError&) {
      failed = true;  // a node beyond the DEM's edge left the projection's domain
      return;
    }
    const size_t first = size_t(rows.begin()) * nodes_x;
    for (size_t k = 0; k < count; ++k) {
      ground[first + k] = frame.EnuFromGeodetic(x[k], y[k], 0.0);
      up[first + k] = frame.EnuFromGeodetic(x[k], y[k], 1.0) - ground[first + k];
    }
  });
  if (failed) return ExactPostsInFrame(dem, frame);

  std::vector<Eigen::Vector3f> enu(size_t(dem.width) * dem.height);
  const double inv_step = 1.0 / step;
  tbb::parallel_for(tbb::blocked_range<int>(0, dem.height, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r < rows.end(); ++r) {
      const int64_t gr = g_row0 + r;
      const int j = static_cast<int>(FloorDiv(gr, step) - k_row0);
      const double fy = double(gr - (k_row0 + j) * step) * inv_step;
      for (int c = 0; c < dem.width; ++c) {
        const int64_t gc = g_col0 + c;
        const int i = static_cast<int>(FloorDiv(gc, step) - k_col0);
        const double fx = double(gc - (k_col0 + i) * step) * inv_step;
        const size_t n00 = size_t(j) * nodes_x + i, n10 = n00 + 1, n01 = n00 + nodes_x, n11 = n01 + 1;
        auto lerp2 = [&](const std::vector<Eigen::Vector3d>& v) {
          const Eigen::Vector3d bottom = v[n00] + fx * (v[n10] - v[n00]);
          const Eigen::Vector3d top = v[n01] + fx * (v[n11] - v[n01]);
          return Eigen::Vector3d(bottom + fy * (top - bottom));
        };
        const size_t post = size_t(r) * dem.width + c;
        enu[post] = (lerp2(ground) + double(dem.heights_m[post]) * lerp2(up)).cast<float>();
      }
    }
  });
  return enu;
}

Eigen::Vector2d DemPostSpacingMetres(const Dem& dem, const LocalFrame& frame, bool at_source_centre) {
  CrsTransform crs(dem.crs_wkt);
  const Eigen::Vector2d centre =
      at_source_centre ? dem.SourceCentrePost() : Eigen::Vector2d((dem.width - 1) / 2.0, (dem.height - 1) / 2.0);
  const double c = centre.x(), r = centre.y();
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

namespace {

// Refines one line of n samples (stride `stride` in `in`) by `factor`:
// (n - 1) * factor + 1 samples, cubic convolution (Catmull-Rom, Keys
// a = -1/2) with Keys' quadratic boundary rule beyond both ends (linear for
// n == 2).
void RefineLine(const float* in, size_t in_stride, int n, int factor, float* out, size_t out_stride) {
  auto sample = [&](int i) -> double {
    if (i >= 0 && i < n) return in[size_t(i) * in_stride];
    if (n < 3) {  // linear extrapolation
      return i < 0 ? 2.0 * in[0] - in[in_stride] : 2.0 * in[size_t(n - 1) * in_stride] - in[size_t(n - 2) * in_stride];
    }
    if (i < 0) return 3.0 * in[0] - 3.0 * in[in_stride] + in[2 * in_stride];
    return 3.0 * in[size_t(n - 1) * in_stride] - 3.0 * in[size_t(n - 2) * in_stride] + in[size_t(n - 3) * in_stride];
  };
  for (int i = 0; i + 1 < n; ++i) {
    const double p0 = sample(i - 1), p1 = sample(i), p2 = sample(i + 1), p3 = sample(i + 2);
    for (int s = 0; s < factor; ++s) {
      const double t = double(s) / factor;
      const double v = p1 + 0.5 * t * (p2 - p0) + t * t * (p0 - 2.5 * p1 + 2.0 * p2 - 0.5 * p3) +
                       t * t * t * (-0.5 * p0 + 1.5 * p1 - 1.5 * p2 + 0.5 * p3);
      out[(size_t(i) * factor + s) * out_stride] = static_cast<float>(v);
    }
  }
  out[size_t(n - 1) * factor * out_stride] = in[size_t(n - 1) * in_stride];
}

}  // namespace

std::optional<double> MetresPerVerticalUnit(const std::string& name) {
  std::string n;
  for (char ch : name) n += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  while (!n.empty() && n.back() == ' ') n.pop_back();
  while (!n.empty() && n.front() == ' ') n.erase(n.begin());
  for (const char* m : {"m", "metre", "metres", "meter", "meters"}) {
    if (n == m) return 1.0;
  }
  for (const char* ft : {"ft", "foot", "feet", "international foot", "foot (international)", "international feet"}) {
    if (n == ft) return 0.3048;
  }
  for (const char* us : {"us-ft", "us_ft", "ftus", "us survey foot", "us survey feet", "foot_us", "us-foot"}) {
    if (n == us) return 1200.0 / 3937.0;
  }
  return std::nullopt;
}

std::vector<std::vector<PostRing>> LowlandPolygons(const Dem& dem, double level_m) {
  GISSAR_CHECK(dem.width >= 2 && dem.height >= 2 && dem.heights_m.size() == size_t(dem.width) * dem.height);
  const auto [lo, hi] = std::minmax_element(dem.heights_m.begin(), dem.heights_m.end());
  if (*lo > level_m) return {};
  if (*hi <= level_m) {
    const double x1 = dem.width - 0.5, y1 = dem.height - 0.5;
    return {{PostRing{{-0.5, -0.5}, {x1, -0.5}, {x1, y1}, {-0.5, y1}, {-0.5, -0.5}}}};
  }
  EnsureGdal();
  const std::string where = "contour of " + (dem.source.empty() ? std::string("the DEM") : dem.source);
  GDALDriverManager* drivers = GetGDALDriverManager();
  GDALDriver* mem = drivers->GetDriverByName("MEM");
  GDALDriver* memory_vector = drivers->GetDriverByName("Memory");
  DatasetPtr grid(mem ? mem->Create("", dem.width, dem.height, 1, GDT_Float32, nullptr) : nullptr);
  DatasetPtr out(memory_vector ? memory_vector->Create("", 0, 0, 0, GDT_Unknown, nullptr) : nullptr);
  if (!grid || !out) throw IoError("cannot stage the DEM for contouring: " + LastGdalMessage(), where);
  // Post (c, r) at coordinates (c, r): the cell corner is half a post off.
  double transform[6] = {-0.5, 1.0, 0.0, -0.5, 0.0, 1.0};
  grid->SetGeoTransform(transform);
  GDALRasterBand* band = grid->GetRasterBand(1);
  if (band->RasterIO(GF_Write, 0, 0, dem.width, dem.height, const_cast<float*>(dem.heights_m.data()), dem.width,
                     dem.height, GDT_Float32, 0, 0, nullptr) != CE_None) {
    throw IoError("cannot stage the DEM for contouring: " + LastGdalMessage(), where);
  }
  OGRLayer* layer = out->CreateLayer("lowland", nullptr, wkbMultiPolygon, nullptr);
  if (!layer) throw IoError("cannot create the contour layer: " + LastGdalMessage(), where);
  for (const char* name : {"id", "elev_min", "elev_max"}) {
    OGRFieldDefn field(name, std::string(name) == "id" ? OFTInteger : OFTReal);
    layer->CreateField(&field);
  }
  std::ostringstream level_text;
  level_text.precision(17);
  level_text << "FIXED_LEVELS=" << level_m;
  const std::string level = level_text.str();
  const char* options[] = {level.c_str(), "POLYGONIZE=YES", "ID_FIELD=0", "ELEV_FIELD_MIN=1",
                           "ELEV_FIELD_MAX=2", nullptr};
  if (GDALContourGenerateEx(band, OGRLayer::ToHandle(layer), const_cast<char**>(options), nullptr, nullptr) !=
      CE_None) {
    throw IoError("GDAL contour generation failed: " + LastGdalMessage(), where);
  }
  // The polygons of the interval from the lowest height up to the level.
  std::vector<std::vector<PostRing>> polygons;
  layer->ResetReading();
  for (auto& feature : *layer) {
    if (!(feature->GetFieldAsDouble(1) < level_m)) continue;
    const OGRGeometry* g = feature->GetGeometryRef();
    if (!g) continue;
    auto add_polygon = [&](const OGRPolygon* p) {
      std::vector<PostRing> rings;
      for (const OGRLinearRing* ring : *p) {
        PostRing points;
        for (const OGRPoint& q : *ring) points.emplace_back(q.getX(), q.getY());
        if (points.size() >= 4) rings.push_back(std::move(points));
      }
      if (!rings.empty()) polygons.push_back(std::move(rings));
    };
    const OGRwkbGeometryType type = wkbFlatten(g->getGeometryType());
    if (type == wkbPolygon) add_polygon(g->toPolygon());
    if (type == wkbMultiPolygon) {
      for (const OGRPolygon* p : *g->toMultiPolygon()) add_polygon(p);
    }
  }
  return polygons;
}

Dem RefineDem(Dem dem, int factor, int64_t max_posts) {
  if (factor < 1 || factor > kMaxDemOversample) {
    throw ConfigError("DEM oversampling must be in [1, " + std::to_string(kMaxDemOversample) + "], got " +
                          std::to_string(factor),
                      "--dem-oversample");
  }
  GISSAR_CHECK(dem.width >= 2 && dem.height >= 2);
  if (factor == 1) return dem;
  const int w = (dem.width - 1) * factor + 1, h = (dem.height - 1) * factor + 1;
  if (double(w) * double(h) > double(max_posts)) {
    throw InputError("DEM of " + std::to_string(dem.width) + "x" + std::to_string(dem.height) + " posts refined " +
                         std::to_string(factor) + " times has " + std::to_string(w) + "x" + std::to_string(h) +
                         " posts, over the " + std::to_string(max_posts) +
                         " the memory limit allows (--max-memory); lower --dem-oversample, crop the DEM, "
                         "raise --max-memory, or run it anyway with --force",
                     dem.source);
  }
  // Along rows first (width grows), then along columns.
  std::vector<float> rows(size_t(w) * dem.height);
  for (int r = 0; r < dem.height; ++r) {
    RefineLine(dem.heights_m.data() + size_t(r) * dem.width, 1, dem.width, factor, rows.data() + size_t(r) * w, 1);
  }
  Dem out = dem;
  out.width = w;
  out.height = h;
  out.heights_m.assign(size_t(w) * h, 0.0f);
  for (int c = 0; c < w; ++c) RefineLine(rows.data() + c, size_t(w), dem.height, factor, out.heights_m.data() + c, size_t(w));
  if (!dem.nodata_mask.empty()) {
    out.nodata_mask.assign(size_t(w) * h, 0);
    for (int r = 0; r < h; ++r) {
      for (int c = 0; c < w; ++c) {
        const int c0 = c / factor, r0 = r / factor;
        const int c1 = std::min(c0 + (c % factor ? 1 : 0), dem.width - 1);
        const int r1 = std::min(r0 + (r % factor ? 1 : 0), dem.height - 1);
        out.nodata_mask[size_t(r) * w + c] =
            dem.IsNodata(c0, r0) || dem.IsNodata(c1, r0) || dem.IsNodata(c0, r1) || dem.IsNodata(c1, r1);
      }
    }
  }
  // Same post centres: post (i * factor, j * factor) at the old post (i, j).
  auto& g = out.geotransform;
  const auto& g0 = dem.geotransform;
  const double shrink = 1.0 - 1.0 / factor;
  g[0] = g0[0] + 0.5 * (g0[1] + g0[2]) * shrink;
  g[3] = g0[3] + 0.5 * (g0[4] + g0[5]) * shrink;
  g[1] = g0[1] / factor;
  g[2] = g0[2] / factor;
  g[4] = g0[4] / factor;
  g[5] = g0[5] / factor;
  if (dem.HasLattice()) {
    out.lattice_col0 = dem.lattice_col0 * factor;
    out.lattice_row0 = dem.lattice_row0 * factor;
    out.lattice_factor = dem.lattice_factor * factor;
  }
  return out;
}

}  // namespace gissar::geo

namespace gissar::geo {

DemFile::DemFile(const fs::path& path) : path_(path.string()) {
  EnsureGdal();
  dataset_ = std::make_shared<Dataset>(Dataset{OpenDemRaster(path, path_)});
}

DemInfo DemFile::Info(const DemReadOptions& options) const {
  const std::string& where = path_;
  GDALDataset* ds = dataset_->ds.get();
  CheckBand(*ds, options.band, where);
  DemInfo info;
  info.width = ds->GetRasterXSize();
  info.height = ds->GetRasterYSize();
  if (ds->GetGeoTransform(info.geotransform.data()) != CE_None) {
    throw InputError("raster has no geotransform (not georeferenced)", where);
  }
  const OGRSpatialReference* srs = ds->GetSpatialRef();
  if (srs == nullptr) throw InputError("raster has no coordinate reference system", where);
  char* wkt = nullptr;
  srs->exportToWkt(&wkt);
  info.crs_wkt = wkt != nullptr ? wkt : "";
  CPLFree(wkt);
  info.file_vertical_datum =
      VerticalDatumOfCrs(info.crs_wkt, ds->GetDriver() != nullptr ? ds->GetDriver()->GetDescription() : "");
  GDALRasterBand* band = ds->GetRasterBand(options.band);
  info.vertical_unit_m = ResolveVerticalUnit(*band, *srs, options.vertical_units, where).first;
  double min_max[2] = {0.0, 0.0};
  CPLPushErrorHandler(CPLQuietErrorHandler);
  const CPLErr err = band->ComputeRasterMinMax(FALSE, min_max);  // exact: every block, streamed
  CPLPopErrorHandler();
  if (err != CE_None || !std::isfinite(min_max[0]) || !std::isfinite(min_max[1])) return info;
  int has_scale = 0, has_offset = 0;
  const double scale = band->GetScale(&has_scale), offset = band->GetOffset(&has_offset);
  const double s = has_scale ? scale : 1.0, o = has_offset ? offset : 0.0;
  double a = min_max[0] * s + o, b = min_max[1] * s + o;
  if (a > b) std::swap(a, b);
  info.min_height_m = a * info.vertical_unit_m;
  info.max_height_m = b * info.vertical_unit_m;
  info.any_valid = true;
  ds->FlushCache(false);  // the streamed blocks (see Read)
  return info;
}

DemInfo ReadDemInfo(const fs::path& path, const DemReadOptions& options) { return DemFile(path).Info(options); }

}  // namespace gissar::geo
