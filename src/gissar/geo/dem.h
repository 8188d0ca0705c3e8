// Digital elevation models read through GDAL: any raster format GDAL reads,
// in any CRS PROJ knows (geographic EPSG:4326 or projected). Heights are the
// raster's values in metres as given (SRTM: above the EGM96 geoid).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/local_frame.h"

namespace gissar::geo {

struct DemReadOptions {
  // Fill no-data cells (GDAL FillNodata, inverse-distance interpolation)
  // instead of failing.
  bool fill_nodata = false;
  // Largest distance, in DEM cells, searched for valid values when filling.
  double fill_max_search_cells = 200.0;
  // No-data connected to the raster's border (e.g. the collar of a
  // reprojected DEM) is left out of the scene by the caller rather than
  // filled: it needs no --fill-nodata and is not filled; its posts are marked
  // in nodata_mask and hold the lowest valid height (finite, never meshed).
  // Interior no-data still follows `fill_nodata`.
  bool border_nodata_outside = false;
  // 1-based band index.
  int band = 1;
  // Memory budget of the caller's job (--max-memory) and what the job needs
  // per DEM post (reading it, and the meshes and indices built from it).
  // A raster with width * height * bytes_per_post > max_bytes is refused
  // from its header, before anything is allocated.
  int64_t max_bytes = int64_t{8} << 30;
  int64_t bytes_per_post = 12;
  // Optional window (first column, first row, columns, rows) in raster
  // cells: only that part is read, so large DEMs need not be loaded whole.
  // Posts keep the map coordinates of the whole raster (Dem::lattice_*),
  // and a geographic DEM is checked over the whole raster's extent.
  std::optional<std::array<int, 4>> window;
  // Unit of the stored heights (--vertical-units): "" = from the file (the
  // band's unit type, else the vertical axis of a compound CRS, else metres),
  // "m", "ft" (international foot, 0.3048 m) or "us-ft" (US survey foot,
  // 1200/3937 m). Heights are converted to metres on reading.
  std::string vertical_units;
};

// Metres per unit of a vertical-unit name: the --vertical-units values (m,
// ft, us-ft) and the spellings GDAL and PROJ use ("metre", "meter", "foot",
// "US survey foot", "ftUS", ...); case-insensitive. nullopt for anything
// else.
std::optional<double> MetresPerVerticalUnit(const std::string& name);

// Heights a DEM may hold, metres: Earth's surface lies within about
// -11 km (ocean trenches) and +8.9 km.
inline constexpr double kMinHeightM = -12000.0;
inline constexpr double kMaxHeightM = 10000.0;
// Largest |latitude| of a post of a geographic DEM, degrees.
inline constexpr double kMaxGeographicLatDeg = 89.0;

// A DEM: heights on a grid of posts. Post (col, row) sits at the centre of
// raster cell (col, row); its map coordinates follow the GDAL geotransform.
struct Dem {
  std::string source;                  // file it was read from
  int width = 0;                       // posts per row
  int height = 0;                      // rows
  std::vector<float> heights_m;        // row-major, width*height, all finite
  std::array<double, 6> geotransform;  // GDAL convention (cell corners)
  std::string crs_wkt;                 // CRS of the map coordinates
  int64_t filled_nodata_cells = 0;     // no-data cells filled on reading
  double vertical_unit_m = 1.0;        // metres per stored height unit (converted on reading)
  std::string vertical_unit_source;    // where that unit came from (option, band unit, CRS, default)
  // Vertical datum the file gives its heights (geo::VerticalDatumOfCrs: from
  // a compound or 3-D CRS, or the SRTM .hgt driver); "" when it says nothing.
  // Heights are as stored: ToEllipsoidalHeights (vertical_datum.h) converts.
  std::string file_vertical_datum;
  // 1 where the raster had no data (the height there was filled), row-major
  // like heights_m; empty when the raster had no no-data cell.
  std::vector<uint8_t> nodata_mask;
  // Where this grid lies in the source raster's post lattice, so that a
  // window (DemReadOptions::window) and a refined grid (RefineDem) place
  // every post at exactly the map coordinates (bit for bit) the whole
  // raster read the same way gives it: post (c, r) is source post
  // ((lattice_col0 + c) / lattice_factor, (lattice_row0 + r) / lattice_factor)
  // of source_geotransform. ReadDem sets it; a Dem built by hand leaves
  // lattice_factor 0 and MapFromPost uses `geotransform`.
  std::array<double, 6> source_geotransform{};
  int64_t lattice_col0 = 0, lattice_row0 = 0;
  int lattice_factor = 0;
  int source_width = 0, source_height = 0;  // the whole raster, posts

  bool HasLattice() const { return lattice_factor > 0; }
  // Post coordinates, in this grid, of the centre of the whole source
  // raster (refined like this grid); the grid's own centre without a lattice.
  Eigen::Vector2d SourceCentrePost() const;

  bool IsNodata(int col, int row) const {
    return !nodata_mask.empty() && nodata_mask[size_t(row) * width + col] != 0;
  }

  float HeightAt(int col, int row) const { return heights_m[size_t(row) * width + col]; }
  // Map coordinates of a (fractional) post position.
  Eigen::Vector2d MapFromPost(double col, double row) const;
  // Fractional post position of map coordinates; false when the geotransform
  // is singular.
  bool PostFromMap(double x, double y, double* col, double* row) const;
  // Bilinear height at a fractional post position; nullopt outside the grid.
  std::optional<double> InterpolateHeight(double col, double row) const;
};

// What a DEM's header and one streamed pass over its heights tell without
// loading it: size, geotransform, CRS, the vertical datum the file names,
// and the lowest and highest valid height in metres (band scale/offset and
// vertical unit applied as ReadDem applies them; no-data, NaN excluded).
// The heights are exact bounds: GDAL's exact min/max (GDALComputeRasterMinMax
// without approximation, one block at a time: memory of a block, time of a
// full read), not overview or stored statistics, which need not bound.
struct DemInfo {
  int width = 0, height = 0;
  std::array<double, 6> geotransform{};
  std::string crs_wkt;
  std::string file_vertical_datum;
  double vertical_unit_m = 1.0;
  double min_height_m = 0.0, max_height_m = 0.0;
  bool any_valid = false;  // false: every cell is no-data (min/max meaningless)
};
// Throws InputError like ReadDem for a missing or unreadable raster, no
// band, no geotransform/CRS or an unknown vertical unit.
DemInfo ReadDemInfo(const std::filesystem::path& path, const DemReadOptions& options = {});

// A DEM raster opened once and read as often as a job needs: its header and
// height bounds (Info) and windows of posts (Read), so that planning a
// window and reading it open the file once. `path` may be a GDAL virtual
// file. Throws InputError naming the file when it is missing, a directory or
// not a raster GDAL can read. Copies share the open file; one thread at a
// time reads it.
class DemFile {
 public:
  explicit DemFile(const std::filesystem::path& path);
  // ReadDemInfo of this file (same promises and failures).
  DemInfo Info(const DemReadOptions& options = {}) const;
  // ReadDem of this file (same promises and failures).
  Dem Read(const DemReadOptions& options = {}) const;
  const std::string& path() const { return path_; }

 private:
  struct Dataset;  // the GDAL dataset (dem.cc)
  std::string path_;
  std::shared_ptr<Dataset> dataset_;
};

// Reads band `options.band` of a raster as a DEM. `path` may be a GDAL
// virtual file (/vsimem/..., /vsizip/archive.zip/file.hgt). Throws InputError naming
// the file when it is missing, not a raster, has no geotransform or CRS (or
// a singular or non-finite one), is smaller than 2x2 posts, would need more
// memory than options.max_bytes (the message gives the amount; a
// pixel-interleaved block of all bands counts too), holds
// heights outside [kMinHeightM, kMaxHeightM] (unmarked no-data values or
// wrong units), or holds no-data cells (value equal to the band's no-data
// value, NaN or infinite) and `fill_nodata` is false: the message gives
// their count. With `fill_nodata`, cells that cannot be filled within the
// search distance are also an InputError. A geographic (longitude/latitude)
// DEM is refused when a post lies beyond kMaxGeographicLatDeg of latitude
// (longitude/latitude grids degenerate at the poles: reproject it to a
// polar stereographic CRS) or outside longitudes [-180, 180] (it crosses
// the antimeridian: reproject it to a projected CRS such as UTM).
Dem ReadDem(const std::filesystem::path& path, const DemReadOptions& options = {});

// A DEM refined by `factor` (>= 1): (width - 1) * factor + 1 by
// (height - 1) * factor + 1 posts spanning the same post centres, post (i * factor,
// j * factor) at the original post (i, j) with its height unchanged, the
// posts between interpolated by separable cubic convolution (Keys 1981,
// a = -1/2, GDAL's "cubic"; Keys' boundary rule 3 f0 - 3 f1 + f2 beyond the
// edges). It reproduces quadratic surfaces exactly and has a continuous
// slope, so the facets of a meshed coarse DEM (one plane per half cell,
// i.e. streaks of constant brightness several radar pixels long when the
// posts are coarser than the pixels) become smoothly varying normals.
// factor 1 returns the DEM unchanged (moved: pass an rvalue to avoid a copy). A refined post is no-data when one of
// the original posts around it (the cell it lies in) is. Throws ConfigError (--dem-oversample)
// when factor is outside [1, kMaxDemOversample] and InputError naming the
// DEM when the refined grid would exceed max_posts.
inline constexpr int kMaxDemOversample = 16;
Dem RefineDem(Dem dem, int factor, int64_t max_posts);

// The lowland of a DEM: the region where the height is at most `level_m`,
// outlined by the `level_m` contour (GDAL's contour generator: linear
// interpolation along the edges between posts, so the outline follows the
// terrain, not the post grid) and closed by the raster's outer edge (half a
// post beyond the outer posts). One entry per polygon: its shell first, then
// its holes; points in post coordinates (col, row). Every post counts,
// no-data posts with the height they hold. Empty when no post is that low.
// Throws IoError when GDAL cannot stage the grid or trace the contours.
using PostRing = std::vector<Eigen::Vector2d>;
std::vector<std::vector<PostRing>> LowlandPolygons(const Dem& dem, double level_m);

// WGS84 longitude/latitude (degrees) and DEM height of the scene centre.
struct GeoPoint {
  double lon_deg = 0.0;
  double lat_deg = 0.0;
  double height_m = 0.0;
};

// The scene centre: `lon_lat` if given, else `map_xy` (DEM CRS) if given,
// else the centre of the DEM extent; its height is the DEM's bilinear height
// there. Throws ConfigError when the point lies outside the DEM.
GeoPoint ResolveSceneCentre(const Dem& dem, const std::optional<Eigen::Vector2d>& lon_lat,
                            const std::optional<Eigen::Vector2d>& map_xy);

// Writes `heights` (row-major, width x height) as a float32 GeoTIFF with the
// given geotransform and CRS (any definition OGR accepts, e.g. "EPSG:32631"
// or a PROJ string); `nodata` is set when finite. For synthetic scenes and
// tests. Throws IoError on failure.
void WriteDemGeoTiff(const std::filesystem::path& path, const std::vector<float>& heights,
                     int width, int height, const std::array<double, 6>& geotransform,
                     const std::string& crs, double nodata = std::numeric_limits<double>::quiet_NaN());

// ENU positions (metres, `frame`) of every DEM post, row-major like
// heights_m. Heights are used as ellipsoidal heights (see local_frame.h).
// Throws InputError naming the DEM when a post cannot be transformed to
// WGS84 (outside its projection's domain).
std::vector<Eigen::Vector3f> DemPostsInFrame(const Dem& dem, const LocalFrame& frame);

// Mean post spacing in metres along columns and rows, measured in `frame`
// at the DEM centre (with `at_source_centre`, at the centre of the whole
// source raster, Dem::SourceCentrePost: the same for every window of it).
Eigen::Vector2d DemPostSpacingMetres(const Dem& dem, const LocalFrame& frame, bool at_source_centre = false);

}  // namespace gissar::geo
