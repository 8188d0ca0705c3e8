#include "gissar/geo/raster_io.h"

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <png.h>
#include <zlib.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;
namespace {

// Appends band `b` (1-based) of `ds` to `raster` (a FloatRaster or a
// ComplexRaster of the dataset's size): its values read as `type`
// (`floats_per_pixel` floats each), name and unit; band 1 also says whether
// NaN is the nodata. InputError naming `path` when GDAL cannot read it.
template <class Raster>
void ReadBand(GDALDataset& ds, int b, GDALDataType type, size_t floats_per_pixel, const fs::path& path,
              Raster& raster) {
  GDALRasterBand* band = ds.GetRasterBand(b);
  std::vector<float> values(floats_per_pixel * size_t(raster.width) * raster.height);
  if (band->RasterIO(GF_Read, 0, 0, raster.width, raster.height, values.data(), raster.width, raster.height, type,
                     0, 0, nullptr) != CE_None) {
    throw InputError("cannot read raster band: " + LastGdalMessage(), path.string());
  }
  raster.bands.push_back(std::move(values));
  raster.band_names.emplace_back(band->GetDescription());
  raster.band_units.emplace_back(band->GetUnitType());
  int has_nodata = 0;
  const double nodata = band->GetNoDataValue(&has_nodata);
  if (b == 1) raster.nodata_nan = has_nodata != 0 && std::isnan(nodata);
}

// The dataset's default-domain metadata items into `metadata`.
void ReadDatasetMetadata(GDALDataset& ds, Metadata& metadata) {
  char** items = ds.GetMetadata();
  if (items == nullptr) return;
  for (char** item = items; *item != nullptr; ++item) {
    char* key = nullptr;
    const char* value = CPLParseNameValue(*item, &key);
    if (key != nullptr && value != nullptr) metadata[key] = value;
    CPLFree(key);
  }
}

// Runs a writer of `path`; an IoError it throws on a full disk says so
// (util's WriteError) instead of GDAL's message ("IO error writing tag data",
// "TIFFRewriteDirectory:Error fetching directory count", ...), and any
// IoError names the output, not its temporary (OutputPathOf).
template <typename Write>
void WithSpaceCheck(const fs::path& path, const char* what, Write&& write) {
  errno = 0;  // no stale errno from before the write
  try {
    write();
  } catch (const IoError& e) {
    const int error = errno;
    if (OutOfSpace(error, path)) throw WriteError(what, path, error);
    if (e.where() == path.string()) throw IoError(e.message(), OutputPathOf(path).string());
    throw;
  }
}

GDALDriver* Driver(const char* name) {
  EnsureGdal();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(name);
  if (driver == nullptr) throw IoError(std::string("GDAL driver missing: ") + name, "");
  return driver;
}

void SetMetadata(GDALDataset* ds, const Metadata& metadata) {
  for (const auto& [key, value] : metadata) ds->SetMetadataItem(key.c_str(), value.c_str());
}

void SetGeoreference(GDALDataset* ds, const Georeference& georeference, const fs::path& path) {
  if (!georeference.gcps.empty()) {
    const GdalGcpList gcps(georeference.gcps);
    OGRSpatialReference wgs84;
    wgs84.importFromEPSG(4326);
    wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    if (ds->SetGCPs(static_cast<int>(gcps.list.size()), gcps.list.data(), &wgs84) != CE_None) {
      throw IoError("cannot write GCPs: " + LastGdalMessage(), path.string());
    }
  }
  for (const auto& [key, value] : georeference.rpc) {
    ds->SetMetadataItem(key.c_str(), value.c_str(), "RPC");
  }
  for (const auto& [key, value] : georeference.geolocation) {
    ds->SetMetadataItem(key.c_str(), value.c_str(), "GEOLOCATION");
  }
}

// Closes the dataset and turns a failure during flushing into IoError.
void CloseChecked(DatasetPtr ds, const fs::path& path) {
  CPLErrorReset();
  GDALDataset* raw = ds.release();
  GDALClose(raw);
  if (CPLGetLastErrorType() >= CE_Failure) {
    throw IoError("failed writing raster: " + LastGdalMessage(), path.string());
  }
}

// COG staging. A large raster is viewed through GDAL's MEM driver and copied with
// the COG driver (GDAL 3.6): internal overviews, IFDs and overviews ahead of
// the full-resolution tiles. A small one is created directly as a tiled GTiff.
bool IsCog(int width, int height) { return width > kCogMinSidePx || height > kCogMinSidePx; }

// Creates the dataset the writer fills: a GTiff at `path` (small raster; the
// writer then writes the planes with RasterIO) or, for a COG, an in-memory
// view of the caller's `planes` (one per band, row-major, never written:
// no staging copy) that FinishGeoTiff copies to `path`.
DatasetPtr CreateStaged(const fs::path& path, int width, int height, GDALDataType type,
                        const std::vector<const void*>& planes, const char* const* gtiff_options) {
  const int nbands = static_cast<int>(planes.size());
  if (!IsCog(width, height)) {
    DatasetPtr ds(Driver("GTiff")->Create(path.c_str(), width, height, nbands, type,
                                          const_cast<char**>(gtiff_options)));
    if (!ds) throw IoError("cannot create GeoTIFF: " + LastGdalMessage(), path.string());
    return ds;
  }
  DatasetPtr ds(Driver("MEM")->Create("", width, height, 0, type, nullptr));
  if (!ds) throw IoError("cannot stage the raster in memory: " + LastGdalMessage(), path.string());
  for (const void* plane : planes) {
    char pointer[64] = {};
    pointer[CPLPrintPointer(pointer, const_cast<void*>(plane), sizeof(pointer) - 1)] = '\0';
    const std::string option = std::string("DATAPOINTER=") + pointer;
    const char* options[] = {option.c_str(), nullptr};
    if (ds->AddBand(type, const_cast<char**>(options)) != CE_None) {
      throw IoError("cannot stage the raster in memory: " + LastGdalMessage(), path.string());
    }
  }
  return ds;
}

// GDAL 3.6's GTiff/COG CreateCopy writes only the default metadata domain
// (plus RPC) into the GDAL_METADATA tag; COPY_SRC_MDD arrived in 3.8. A COG's
// GEOLOCATION items therefore travel as a default-domain reserved slot of the
// exact byte length of their XML, which PatchGeolocation overwrites in place
// after the copy (same length: the COG layout is untouched).
constexpr const char* kGeolocationReservedKey = "GISSAR_GEOLOCATION_RESERVED";

std::string GeolocationXml(const Metadata& geolocation) {
  std::string xml;
  for (const auto& [key, value] : geolocation) {
    char* k = CPLEscapeString(key.c_str(), -1, CPLES_XML);
    char* v = CPLEscapeString(value.c_str(), -1, CPLES_XML);
    xml += std::string("<Item name=\"") + k + "\" domain=\"GEOLOCATION\">" + v + "</Item>";
    CPLFree(k);
    CPLFree(v);
  }
  return xml;
}

std::string ReservedSlotXml(size_t length) {
  return std::string("<Item name=\"") + kGeolocationReservedKey + "\">" + std::string(length, 'x') + "</Item>";
}

void PatchGeolocation(const fs::path& path, const Metadata& geolocation) {
  const std::string items = GeolocationXml(geolocation);
  const std::string slot = ReservedSlotXml(items.size());
  std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
  if (!file) throw IoError("cannot reopen COG to write GEOLOCATION metadata", path.string());
  // The GDAL_METADATA tag sits in the COG header, ahead of all tiles.
  std::string head(4u << 20, '\0');
  file.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(file.gcount()));
  const size_t at = head.find(slot);
  if (at == std::string::npos || head.find(slot, at + 1) != std::string::npos) {
    throw IoError("reserved GEOLOCATION slot not found once in the COG header", path.string());
  }
  std::string replacement = items;
  replacement.resize(slot.size(), ' ');  // whitespace between XML elements
  file.clear();
  file.seekp(static_cast<std::streamoff>(at));
  file.write(replacement.data(), static_cast<std::streamsize>(replacement.size()));
  file.close();
  if (!file) throw IoError("cannot write GEOLOCATION metadata into the COG", path.string());
  // Read back: every item present, the reserved slot gone.
  DatasetPtr check(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  bool same = check && check->GetMetadataItem(kGeolocationReservedKey) == nullptr;
  for (const auto& [key, value] : geolocation) {
    const char* back = same ? check->GetMetadataItem(key.c_str(), "GEOLOCATION") : nullptr;
    same = back != nullptr && value == back;
  }
  if (!same) throw IoError("GEOLOCATION metadata did not read back from the COG", path.string());
}

// Tile side of the COGs, and the size their overviews halve down to.
constexpr int kCogBlockPx = 512;
// ZSTD level of the COGs' overview tiles (FinishGeoTiff says why not 1).
constexpr const char* kOverviewZstdLevel = "3";

// One overview level: each 2 x 2 block of the sw x sh level (`counts` the
// base pixels behind each value, or null for the base level: 1 where finite)
// to one pixel of the (sw+1)/2 x (sh+1)/2 level, as the count-weighted mean
// and the summed count (NaN and 0 where no base pixel is finite). Rows in
// parallel (TBB); the base level's full blocks branch-free.
void ReduceLevel(const float* values, const uint32_t* counts, int sw, int sh, float* out_values,
                 uint32_t* out_counts) {
  const int ow = (sw + 1) / 2, oh = (sh + 1) / 2;
  tbb::parallel_for(tbb::blocked_range<int>(0, oh, 16), [&](const tbb::blocked_range<int>& range) {
    for (int r = range.begin(); r < range.end(); ++r) {
      const int rows = std::min(2, sh - 2 * r);
      float* out_v = out_values + size_t(r) * ow;
      uint32_t* out_n = out_counts + size_t(r) * ow;
      int c = 0;
      if (counts == nullptr && rows == 2) {
        const float* a = values + size_t(2 * r) * sw;
        const float* b = a + sw;
        for (; c < sw / 2; ++c) {
          const float p[4] = {a[2 * c], a[2 * c + 1], b[2 * c], b[2 * c + 1]};
          float sum = 0.0f;
          uint32_t n = 0;
          for (float x : p) {
            const bool finite = std::isfinite(x);
            sum += finite ? x : 0.0f;
            n += finite;
          }
          out_v[c] = n > 0 ? sum / float(n) : std::numeric_limits<float>::quiet_NaN();
          out_n[c] = n;
        }
      }
      for (; c < ow; ++c) {
        const int cols = std::min(2, sw - 2 * c);
        double sum = 0.0;
        uint32_t n = 0;
        for (int dr = 0; dr < rows; ++dr) {
          const size_t i0 = size_t(2 * r + dr) * sw + 2 * c;
          for (int dc = 0; dc < cols; ++dc) {
            const float x = values[i0 + dc];
            const uint32_t k = counts != nullptr ? counts[i0 + dc] : uint32_t(std::isfinite(x));
            if (k > 0) sum += double(x) * k, n += k;
          }
        }
        out_v[c] = n > 0 ? static_cast<float>(sum / n) : std::numeric_limits<float>::quiet_NaN();
        out_n[c] = n;
      }
    }
  });
}

// The float overviews of a staged COG, computed here instead of by GDAL 3.6's
// AVERAGE resampler (single-threaded; 2.5-3 s of a 24 Mpx x 5 band write):
// overview factors 2, 4, ... until both sides are at most kCogBlockPx (the
// COG driver's own rule), each pixel the mean of the finite base pixels of
// its block (GDAL's AVERAGE with NaN no-data), NaN where none is finite.
// Each level is reduced from the previous one weighted by its counts, so the
// mean is exact at every level. `planes` are the staged bands' float data.
void WriteFloatAverageOverviews(GDALDataset* ds, const std::vector<const void*>& planes, const fs::path& path) {
  const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
  std::vector<int> factors;
  for (int f = 2, ow = w, oh = h; ow > kCogBlockPx || oh > kCogBlockPx; f *= 2) {
    factors.push_back(f);
    ow = (w + f - 1) / f;
    oh = (h + f - 1) / f;
  }
  if (factors.empty()) return;
  if (GDALBuildOverviews(GDALDataset::ToHandle(ds), "NONE", static_cast<int>(factors.size()), factors.data(), 0,
                         nullptr, nullptr, nullptr) != CE_None) {
    throw IoError("cannot stage overviews: " + LastGdalMessage(), path.string());
  }
  // Two ping-pong buffers of the first level's size, shared by every band
  // and level (fresh pages are expensive: no allocation per band).
  const size_t first_level = size_t((w + 1) / 2) * ((h + 1) / 2);
  // Every element is written before it is read: no zero-filling pass.
  const std::unique_ptr<float[]> value_buffers[2] = {std::make_unique_for_overwrite<float[]>(first_level),
                                                     std::make_unique_for_overwrite<float[]>(first_level)};
  const std::unique_ptr<uint32_t[]> count_buffers[2] = {std::make_unique_for_overwrite<uint32_t[]>(first_level),
                                                        std::make_unique_for_overwrite<uint32_t[]>(first_level)};
  for (int b = 0; b < ds->GetRasterCount(); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b + 1);
    GISSAR_CHECK(band->GetOverviewCount() == static_cast<int>(factors.size()));
    const float* values = static_cast<const float*>(planes[static_cast<size_t>(b)]);
    const uint32_t* counts = nullptr;  // base level: 1 where finite
    int sw = w, sh = h;
    for (size_t level = 0; level < factors.size(); ++level) {
      const int ow = (sw + 1) / 2, oh = (sh + 1) / 2;
      GDALRasterBand* overview = band->GetOverview(static_cast<int>(level));
      GISSAR_CHECK(overview->GetXSize() == ow && overview->GetYSize() == oh);
      float* next_values = value_buffers[level % 2].get();
      uint32_t* next_counts = count_buffers[level % 2].get();
      ReduceLevel(values, counts, sw, sh, next_values, next_counts);
      if (overview->RasterIO(GF_Write, 0, 0, ow, oh, next_values, ow, oh, GDT_Float32, 0, 0, nullptr) != CE_None) {
        throw IoError("cannot stage overviews: " + LastGdalMessage(), path.string());
      }
      values = next_values;
      counts = next_counts;
      sw = ow;
      sh = oh;
    }
  }
}

// Small raster: closes the GTiff. Large: copies the staged MEM dataset to a
// COG at `path` (overviews resampled with `resampling`, float AVERAGE ones
// computed from `planes` by WriteFloatAverageOverviews; the COG driver's own
// temporary overview file goes to /vsimem, never next to `path`).
void FinishGeoTiff(DatasetPtr ds, const fs::path& path, const char* resampling, bool overviews,
                   const Metadata& geolocation = {}, const std::vector<const void*>& planes = {}) {
  const bool float_bands = ds->GetRasterCount() > 0 && ds->GetRasterBand(1)->GetRasterDataType() == GDT_Float32;
  if (!IsCog(ds->GetRasterXSize(), ds->GetRasterYSize())) {
    CloseChecked(std::move(ds), path);
    return;
  }
  const bool own_overviews = overviews && float_bands && std::string(resampling) == "AVERAGE" &&
                             planes.size() == static_cast<size_t>(ds->GetRasterCount());
  if (own_overviews) WriteFloatAverageOverviews(ds.get(), planes, path);
  if (!geolocation.empty()) {
    ds->SetMetadataItem(kGeolocationReservedKey,
                        std::string(GeolocationXml(geolocation).size(), 'x').c_str());
  }
  const std::string resampling_option = std::string("RESAMPLING=") + resampling;
  const std::string block_option = "BLOCKSIZE=" + std::to_string(kCogBlockPx);
  std::vector<const char*> options = {"COMPRESS=ZSTD", "LEVEL=1", block_option.c_str(), resampling_option.c_str(),
                                      "NUM_THREADS=ALL_CPUS"};
  if (float_bands) options.push_back("PREDICTOR=FLOATING_POINT");
  if (own_overviews) options.push_back("OVERVIEWS=FORCE_USE_EXISTING");
  if (!overviews) options.push_back("OVERVIEWS=NONE");
  options.push_back(nullptr);
  DatasetPtr cog;
  std::string message;
  {
    const CPLConfigOptionSetter temporary_files_in_memory("CPL_TMPDIR", "/vsimem", false);
    // The COG driver stages the overview tiles in a temporary GeoTIFF, then
    // compresses them again into `path`. LEVEL reaches neither: the staging
    // file took libtiff's default ZSTD level 9 (12 MB of hash tables cleared
    // per tile) and the final overviews level 1. Level 3 for both: at 4000^2
    // the file is 5 % smaller at the same wall time (paired runs, 0.98x).
    // A user's own ZSTD_LEVEL_OVERVIEW wins.
    const CPLConfigOptionSetter overview_level("ZSTD_LEVEL_OVERVIEW", kOverviewZstdLevel, true);
    CPLErrorReset();
    cog.reset(Driver("COG")->CreateCopy(path.c_str(), ds.get(), FALSE, const_cast<char**>(options.data()), nullptr,
                                        nullptr));
    message = LastGdalMessage();
  }
  if (!cog) throw IoError("cannot write Cloud-Optimized GeoTIFF: " + message, path.string());
  CloseChecked(std::move(cog), path);
  if (!geolocation.empty()) PatchGeolocation(path, geolocation);
}

DatasetPtr OpenForReading(const fs::path& path) {
  EnsureGdal();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError("raster file does not exist", path.string());
  DatasetPtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw InputError("not a raster GDAL can read", path.string());
  return ds;
}

}  // namespace

Metadata LonLatGeolocation(int lon_band, int lat_band) {
  EnsureGdal();
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  char* wkt = nullptr;
  wgs84.exportToWkt(&wkt);
  Metadata m{{"SRS", wkt},
             {"X_BAND", std::to_string(lon_band)},
             {"Y_BAND", std::to_string(lat_band)},
             {"PIXEL_OFFSET", "0"},
             {"LINE_OFFSET", "0"},
             {"PIXEL_STEP", "1"},
             {"LINE_STEP", "1"},
             {"GEOREFERENCING_CONVENTION", "PIXEL_CENTER"}};
  CPLFree(wkt);
  return m;
}

static void WriteFloatGeoTiffUnchecked(const fs::path& path, const FloatRaster& raster) {
  const int nbands = static_cast<int>(raster.bands.size());
  if (nbands == 0) throw IoError("no band to write", path.string());
  const char* options[] = {"COMPRESS=ZSTD", "ZSTD_LEVEL=1", "TILED=YES", "PREDICTOR=3", "NUM_THREADS=ALL_CPUS",
                           nullptr};
  std::vector<const void*> planes;
  for (const std::vector<float>& band : raster.bands) {
    const std::vector<float>& b = band.empty() ? raster.empty_band_pixels : band;
    if (b.size() != size_t(raster.width) * raster.height) throw IoError("band size does not match the raster", path.string());
    planes.push_back(b.data());
  }
  DatasetPtr ds = CreateStaged(path, raster.width, raster.height, GDT_Float32, planes, options);
  SetMetadata(ds.get(), raster.metadata);
  SetGeoreference(ds.get(), raster.georeference, path);
  if (raster.geotransform.size() == 6) {
    std::array<double, 6> gt;
    std::copy(raster.geotransform.begin(), raster.geotransform.end(), gt.begin());
    if (ds->SetGeoTransform(gt.data()) != CE_None) throw IoError("cannot set geotransform: " + LastGdalMessage(), path.string());
  }
  if (!raster.crs.empty()) {
    OGRSpatialReference srs;
    if (srs.SetFromUserInput(raster.crs.c_str()) != OGRERR_NONE) throw IoError("cannot parse CRS '" + raster.crs + "'", path.string());
    if (ds->SetSpatialRef(&srs) != CE_None) throw IoError("cannot set CRS: " + LastGdalMessage(), path.string());
  }
  for (int b = 0; b < nbands; ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b + 1);
    if (raster.nodata_nan) band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
    if (b < static_cast<int>(raster.band_names.size())) {
      band->SetDescription(raster.band_names[b].c_str());
    }
    if (b < static_cast<int>(raster.band_units.size())) {
      band->SetUnitType(raster.band_units[b].c_str());
    } else if (!raster.band_unit.empty()) {
      band->SetUnitType(raster.band_unit.c_str());
    }
    if (!IsCog(raster.width, raster.height) &&
        band->RasterIO(GF_Write, 0, 0, raster.width, raster.height,
                       const_cast<void*>(planes[b]), raster.width, raster.height,
                       GDT_Float32, 0, 0, nullptr) != CE_None) {
      throw IoError("cannot write GeoTIFF band: " + LastGdalMessage(), path.string());
    }
  }
  // AVERAGE skips NaN (no-data) samples: an overview pixel is the mean of
  // its valid full-resolution pixels, NaN only where all are NaN.
  FinishGeoTiff(std::move(ds), path, "AVERAGE", raster.overviews, raster.georeference.geolocation, planes);
}

static void WriteByteGeoTiffUnchecked(const fs::path& path, const std::vector<uint8_t>& data, int width,
                      int height, const Metadata& metadata, const Georeference& georeference,
                      const ByteCategories& categories, bool overviews) {
  const char* options[] = {"COMPRESS=ZSTD", "ZSTD_LEVEL=1", "TILED=YES", "NUM_THREADS=ALL_CPUS", nullptr};
  if (data.size() != size_t(width) * height) throw IoError("data size does not match the raster", path.string());
  DatasetPtr ds = CreateStaged(path, width, height, GDT_Byte, {data.data()}, options);
  SetMetadata(ds.get(), metadata);
  SetGeoreference(ds.get(), georeference, path);
  if (!categories.names.empty()) {
    // GeoTIFF keeps category names only in a PAM .aux.xml sidecar, which
    // would not follow an atomic rename: they go to band metadata
    // (CATEGORY_<value>=name, in the TIFF's GDAL_METADATA tag) instead.
    for (size_t i = 0; i < categories.names.size(); ++i) {
      ds->GetRasterBand(1)->SetMetadataItem(("CATEGORY_" + std::to_string(i)).c_str(),
                                            categories.names[i].c_str());
    }
  }
  if (!categories.colours.empty()) {
    GDALColorTable table(GPI_RGB);
    for (size_t i = 0; i < categories.colours.size(); ++i) {
      const auto& c = categories.colours[i];
      const GDALColorEntry entry{c[0], c[1], c[2], c[3]};
      table.SetColorEntry(static_cast<int>(i), &entry);
    }
    if (categories.nodata && *categories.nodata >= categories.colours.size()) {
      const GDALColorEntry transparent{0, 0, 0, 0};
      table.SetColorEntry(*categories.nodata, &transparent);
    }
    ds->GetRasterBand(1)->SetColorTable(&table);
    ds->GetRasterBand(1)->SetColorInterpretation(GCI_PaletteIndex);
  }
  if (categories.nodata) ds->GetRasterBand(1)->SetNoDataValue(*categories.nodata);
  if (!IsCog(width, height) &&
      ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, width, height,
                                     const_cast<uint8_t*>(data.data()), width, height, GDT_Byte,
                                     0, 0, nullptr) != CE_None) {
    throw IoError("cannot write GeoTIFF: " + LastGdalMessage(), path.string());
  }
  // NEAREST: an overview pixel of a mask or class map is one of its source
  // pixels' classes, never an average of class numbers.
  FinishGeoTiff(std::move(ds), path, "NEAREST", overviews, georeference.geolocation);
}

void WriteComplexGeoTiff(const fs::path& path, const std::vector<float>& real, const std::vector<float>& imag,
                         int width, int height, const Metadata& metadata, const std::string& band_unit) {
  WriteComplexGeoTiff(path, {ComplexBand{&real, &imag, "slc"}}, width, height, metadata, band_unit);
}

static void WriteComplexGeoTiffUnchecked(const fs::path& path, const std::vector<ComplexBand>& bands, int width, int height,
                         const Metadata& metadata, const std::string& band_unit, const Georeference& georeference,
                         bool nodata_nan, bool overviews) {
  if (bands.empty()) throw IoError("a complex raster needs at least one band", path.string());
  const size_t n = size_t(width) * height;
  std::vector<std::vector<float>> interleaved(bands.size());
  std::vector<const void*> planes;
  for (size_t b = 0; b < bands.size(); ++b) {
    const ComplexBand& band = bands[b];
    if (band.real == nullptr || band.imag == nullptr || band.real->size() != n || band.imag->size() != n) {
      throw IoError("complex planes do not match the image size", path.string());
    }
    interleaved[b].resize(2 * n);
    for (size_t k = 0; k < n; ++k) {
      interleaved[b][2 * k] = (*band.real)[k];
      interleaved[b][2 * k + 1] = (*band.imag)[k];
    }
    planes.push_back(interleaved[b].data());
  }
  const char* options[] = {"COMPRESS=ZSTD", "ZSTD_LEVEL=1", "TILED=YES", "NUM_THREADS=ALL_CPUS", nullptr};
  DatasetPtr ds = CreateStaged(path, width, height, GDT_CFloat32, planes, options);
  SetMetadata(ds.get(), metadata);
  SetGeoreference(ds.get(), georeference, path);
  for (size_t b = 0; b < bands.size(); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(int(b) + 1);
    band->SetDescription(bands[b].name.c_str());
    if (!band_unit.empty()) band->SetUnitType(band_unit.c_str());
    if (nodata_nan) band->SetNoDataValue(std::numeric_limits<double>::quiet_NaN());
    if (!IsCog(width, height) &&
        band->RasterIO(GF_Write, 0, 0, width, height, interleaved[b].data(), width, height, GDT_CFloat32, 0, 0,
                       nullptr) != CE_None) {
      throw IoError("cannot write GeoTIFF: " + LastGdalMessage(), path.string());
    }
  }
  // NEAREST: each overview sample is a true SLC sample (phase kept, mean
  // intensity unbiased). AVERAGE would sum random speckle phasors coherently
  // and darken distributed scatterers by the decimation factor, point
  // targets not.
  FinishGeoTiff(std::move(ds), path, "NEAREST", overviews, georeference.geolocation);
}

ComplexRaster ReadComplexRaster(const fs::path& path) {
  DatasetPtr ds = OpenForReading(path);
  ComplexRaster raster;
  raster.width = ds->GetRasterXSize();
  raster.height = ds->GetRasterYSize();
  for (int b = 1; b <= ds->GetRasterCount(); ++b) ReadBand(*ds, b, GDT_CFloat32, 2, path, raster);
  ReadDatasetMetadata(*ds, raster.metadata);
  return raster;
}

// The PNG encoding of `data` (libpng, in memory). Every row is filtered
// with Up (the row above subtracted) and deflated at zlib level 2, grey with
// Z_RLE: on a 1471 x 2007 quicklook 23 ms instead of 65 ms (GDAL's PNG
// driver: libpng's adaptive choice among all five filters per row) and 12 %
// smaller; RGB 2x faster at the same size (docs/performance.md).
static std::vector<uint8_t> EncodePng(const fs::path& path, const std::vector<uint8_t>& data, int width, int height,
                                      int channels) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    throw IoError("cannot write PNG: libpng could not start", path.string());
  }
  std::vector<uint8_t> bytes;
  const auto append = [](png_structp p, png_bytep chunk, png_size_t size) {
    auto* out = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(p));
    out->insert(out->end(), chunk, chunk + size);
  };
  std::vector<png_bytep> rows(static_cast<size_t>(height));
  for (int r = 0; r < height; ++r) {
    rows[size_t(r)] = const_cast<png_bytep>(data.data()) + size_t(r) * width * channels;
  }
  // libpng reports errors by longjmp: nothing with a destructor is created
  // between here and the end of the encoding.
  if (setjmp(png_jmpbuf(png)) != 0) {
    png_destroy_write_struct(&png, &info);
    throw IoError("cannot write PNG: libpng failed to encode it", path.string());
  }
  png_set_write_fn(png, &bytes, append, nullptr);
  const int color = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
  png_set_IHDR(png, info, png_uint_32(width), png_uint_32(height), 8, color, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_set_compression_level(png, 2);
  png_set_compression_strategy(png, channels == 1 ? Z_RLE : Z_DEFAULT_STRATEGY);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return bytes;
}

static void WritePngUnchecked(const fs::path& path, const std::vector<uint8_t>& data, int width, int height,
                              int channels) {
  GISSAR_CHECK(channels == 1 || channels == 3 || channels == 4);
  GISSAR_CHECK(width > 0 && height > 0 && data.size() >= size_t(width) * height * channels);
  const std::vector<uint8_t> bytes = EncodePng(path, data, width, height, channels);
  // Written here, every failure reported (a PNG cut short by a full disk
  // must not pass as written).
  if (path.string().rfind("/vsi", 0) == 0) {  // a GDAL virtual file
    VSILFILE* file = VSIFOpenL(path.c_str(), "wb");
    const bool written = file != nullptr && VSIFWriteL(bytes.data(), 1, bytes.size(), file) == bytes.size();
    const bool closed = file != nullptr && VSIFCloseL(file) == 0;
    if (!written || !closed) throw IoError("cannot write PNG", path.string());
    return;
  }
  errno = 0;
  std::FILE* file = std::fopen(path.c_str(), "wb");
  int error = file == nullptr ? errno : 0;
  if (file != nullptr) {
    if (std::fwrite(bytes.data(), 1, bytes.size(), file) != bytes.size()) error = errno;
    if (std::fclose(file) != 0 && error == 0) error = errno;
  }
  if (file == nullptr || error != 0) {
    IoError failure(std::string(file == nullptr ? "cannot open PNG for writing: " : "failed writing PNG: ") +
                        std::strerror(error),
                    path.string());
    errno = error;  // for WithSpaceCheck
    throw failure;
  }
}

Georeference ReadGeoreference(const fs::path& path) {
  DatasetPtr ds = OpenForReading(path);
  Georeference georeference;
  const GDAL_GCP* gcps = ds->GetGCPs();
  for (int i = 0; i < ds->GetGCPCount(); ++i) {
    georeference.gcps.push_back(
        {gcps[i].dfGCPPixel, gcps[i].dfGCPLine, gcps[i].dfGCPX, gcps[i].dfGCPY, gcps[i].dfGCPZ});
  }
  for (auto [domain, items] : {std::pair{"RPC", &georeference.rpc}, std::pair{"GEOLOCATION", &georeference.geolocation}}) {
    char** entries = ds->GetMetadata(domain);
    for (int i = 0; entries != nullptr && entries[i] != nullptr; ++i) {
      char* key = nullptr;
      const char* value = CPLParseNameValue(entries[i], &key);
      if (key != nullptr && value != nullptr) (*items)[key] = value;
      CPLFree(key);
    }
  }
  return georeference;
}

FloatRaster ReadFloatRaster(const fs::path& path) {
  DatasetPtr ds = OpenForReading(path);
  FloatRaster raster;
  raster.width = ds->GetRasterXSize();
  raster.height = ds->GetRasterYSize();
  for (int b = 1; b <= ds->GetRasterCount(); ++b) ReadBand(*ds, b, GDT_Float32, 1, path, raster);
  double gt[6];
  if (ds->GetGeoTransform(gt) == CE_None) raster.geotransform.assign(gt, gt + 6);
  if (const OGRSpatialReference* srs = ds->GetSpatialRef()) {
    char* wkt = nullptr;
    if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt != nullptr) raster.crs = wkt;
    CPLFree(wkt);
  }
  ReadDatasetMetadata(*ds, raster.metadata);
  return raster;
}

std::vector<uint8_t> ReadByteRaster(const fs::path& path, int* width, int* height) {
  DatasetPtr ds = OpenForReading(path);
  *width = ds->GetRasterXSize();
  *height = ds->GetRasterYSize();
  std::vector<uint8_t> values(size_t(*width) * *height);
  if (ds->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, *width, *height, values.data(), *width,
                                     *height, GDT_Byte, 0, 0, nullptr) != CE_None) {
    throw InputError("cannot read raster: " + LastGdalMessage(), path.string());
  }
  return values;
}

// The writers: a failure on a full disk says so (WithSpaceCheck).
void WriteFloatGeoTiff(const fs::path& path, const FloatRaster& raster) {
  WithSpaceCheck(path, "failed writing raster", [&] { WriteFloatGeoTiffUnchecked(path, raster); });
}

void WriteByteGeoTiff(const fs::path& path, const std::vector<uint8_t>& data, int width, int height,
                      const Metadata& metadata, const Georeference& georeference, const ByteCategories& categories,
                      bool overviews) {
  WithSpaceCheck(path, "failed writing raster", [&] {
    WriteByteGeoTiffUnchecked(path, data, width, height, metadata, georeference, categories, overviews);
  });
}

void WriteComplexGeoTiff(const fs::path& path, const std::vector<ComplexBand>& bands, int width, int height,
                         const Metadata& metadata, const std::string& band_unit, const Georeference& georeference,
                         bool nodata_nan, bool overviews) {
  WithSpaceCheck(path, "failed writing raster", [&] {
    WriteComplexGeoTiffUnchecked(path, bands, width, height, metadata, band_unit, georeference, nodata_nan,
                                 overviews);
  });
}

void WritePng(const fs::path& path, const std::vector<uint8_t>& data, int width, int height, int channels) {
  WithSpaceCheck(path, "failed writing PNG", [&] { WritePngUnchecked(path, data, width, height, channels); });
}

}  // namespace gissar::geo
