#include "gissar/pipeline/terrain.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <utility>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/scene/gis_scene.h"
#include "gissar/util/error.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
namespace {

// Memory estimates for --max-memory (measured, kept on the safe side; peak
// RSS of `simulate` on fractal DEMs, 2026-11-29, docs/robustness.md).
// Per DEM post, traced as a height field or by the raster engine: heights
// as read, map and ENU coordinates, sea mask and classes, and with a
// collar the explicit triangles of the cells kept (measured 28-33 B per
// post without a collar: 8192^2 posts and a small image, 1.9 GB traced,
// 1.2 GB raster).
constexpr double kBytesPerDemPost = 128.0;
// The same with Embree's BVH over the DEM's triangles (--no-heightfield):
// measured about 180 B per post (4096^2: 3.0 GB).
constexpr double kBytesPerDemPostBvh = 256.0;
// Per scene-file byte: the mesh as loaded plus Embree's BVH.
constexpr double kBytesPerSceneFileByte = 5.0;

// Bytes per DEM post of a mesh of `shape` (Embree's BVH over the triangles
// without the height field).
double BytesPerDemPost(const TerrainShape& shape) {
  return !shape.posts_only && !shape.heightfield ? kBytesPerDemPostBvh : kBytesPerDemPost;
}

Terrain TerrainFromDem(const TerrainRequest& options, const TerrainShape& shape, Reporter& reporter) {
  geo::DemReadOptions read_options = DemReadOptionsOf(options, shape);
  DemWindowPlan plan = shape.window;
  if (plan.read_window) read_options.window = plan.window;
  // The file as the window's planner opened it, else opened here: once.
  const geo::DemFile file = plan.dem_file ? *plan.dem_file : geo::DemFile(options.dem);
  geo::Dem dem = file.Read(read_options);
  if (plan.read_window && !dem.nodata_mask.empty()) {
    // GDAL's filling draws on valid cells up to its search distance away:
    // the whole DEM's voids are filled from the whole DEM; and which voids
    // are the border's collar is decided on the whole DEM.
    plan.read_window = false;
    plan.reason = "no-data in the window (filled, or left out, as in the whole DEM)";
    read_options.window.reset();
    dem = file.Read(read_options);
  }
  if (plan.applies) {
    reporter.Info("simulate: DEM window " + std::to_string(plan.window[2]) + " x " + std::to_string(plan.window[3]) +
                  " posts at " + std::to_string(plan.window[0]) + "," + std::to_string(plan.window[1]) + " of " +
                  std::to_string(plan.source_width) + " x " + std::to_string(plan.source_height) +
                  (plan.read_window ? "" : "; reading the whole DEM: " + plan.reason));
  }
  const int source_width = dem.width, source_height = dem.height;
  dem = geo::RefineDem(std::move(dem), options.dem_oversample,
                       static_cast<int64_t>(double(options.max_memory_bytes) / BytesPerDemPost(shape)));
  // Sea from the heights as given (orthometric for SRTM-like DEMs), before
  // any datum change.
  std::vector<uint8_t> sea_posts;
  if (options.sea == "auto") sea_posts = scene::SeaPostMask(dem, options.sea_level_m);
  // The collar and border voids (not sea) are outside the scene.
  const std::vector<uint8_t> outside = scene::OutsidePostMask(dem, sea_posts);
  // No sea post (an inland DEM): no triangle to mark below.
  if (std::find(sea_posts.begin(), sea_posts.end(), uint8_t{1}) == sea_posts.end()) sea_posts.clear();
  const geo::VerticalDatumChoice datum =
      geo::ResolveVerticalDatum(geo::CanonicalVerticalDatum(options.vertical_datum), dem.file_vertical_datum);
  if (datum.source == "assumed") reporter.Warn(geo::AssumedDatumWarning(options.dem));
  geo::ToEllipsoidalHeights(dem, datum.datum);
  if (dem.filled_nodata_cells > 0) {
    reporter.Info("simulate: filled " + std::to_string(dem.filled_nodata_cells) + " no-data cells");
  }
  Terrain t;
  t.vertical_datum = datum.datum;
  t.vertical_datum_source = datum.source;
  // The default centre is the whole raster's, also when a window was read.
  std::optional<Eigen::Vector2d> centre_map = shape.center_map;
  if (!shape.center_lonlat && !centre_map) {
    const Eigen::Vector2d post = dem.SourceCentrePost();
    centre_map = dem.MapFromPost(post.x(), post.y());
  }
  t.centre = geo::ResolveSceneCentre(dem, shape.center_lonlat, centre_map);
  t.frame = geo::LocalFrame(t.centre.lon_deg, t.centre.lat_deg, 0.0);
  t.centre_enu = t.frame.EnuFromGeodetic(t.centre.lon_deg, t.centre.lat_deg, t.centre.height_m);
  if (shape.posts_only) {
    t.mesh.vertices = geo::DemPostsInFrame(dem, t.frame);
    // Posts outside the scene: non-finite, so their cells draw nothing.
    for (size_t i = 0; i < outside.size(); ++i)
      if (outside[i]) t.mesh.vertices[i].z() = std::numeric_limits<float>::quiet_NaN();
  } else if (!outside.empty()) {
    // The cells with no outside post, MeshFromGrid's triangles (traced as a
    // height field with the others as holes, or by Embree).
    const int w = dem.width, h = dem.height;
    scene::TriangleMesh grid = scene::MeshFromGrid(geo::DemPostsInFrame(dem, t.frame), w, h);
    std::vector<uint8_t> cells(size_t(w - 1) * (h - 1), 0);
    t.mesh.vertices = std::move(grid.vertices);
    for (int r = 0; r + 1 < h; ++r)
      for (int c = 0; c + 1 < w; ++c) {
        const size_t i = size_t(r) * w + c, cell = size_t(r) * (w - 1) + c;
        if (outside[i] || outside[i + 1] || outside[i + w] || outside[i + w + 1]) continue;
        cells[cell] = 1;
        for (int k = 0; k < 2; ++k) {
          t.mesh.triangles.push_back(grid.triangles[2 * cell + k]);
          t.mesh.classes.push_back(grid.classes[2 * cell + k]);
        }
      }
    if (t.mesh.triangles.empty()) throw InputError("the DEM has no grid cell with four valid posts", options.dem);
    if (shape.heightfield) t.scene_grid = render::TerrainGrid{w, h, std::move(cells)};
  } else if (shape.heightfield) {
    // Traced as a height field: the grid's triangles stay implicit (no
    // index array: 12 bytes per triangle, 1.6 GB for a 8192^2 DEM).
    t.mesh = scene::GridMesh(geo::DemPostsInFrame(dem, t.frame), dem.width, dem.height);
  } else {
    t.mesh = scene::MeshFromGrid(geo::DemPostsInFrame(dem, t.frame), dem.width, dem.height);
  }
  int64_t sea_triangles = 0;
  if (!sea_posts.empty() && shape.posts_only) {
    // The raster engine's grid has no triangle list: classes per triangle in
    // MeshFromGrid's order (the triangle holding post (c, r), then the one
    // holding (c + 1, r + 1)), sea where all three posts are sea, as
    // MarkSeaTriangles marks the tracer's mesh.
    const int w = dem.width, h = dem.height;
    std::vector<scene::ClassId> classes(size_t(w - 1) * (h - 1) * 2, scene::kClassDefault);
    auto sea = [&](int c, int r) { return sea_posts[size_t(r) * w + c] != 0; };
    for (int r = 0; r + 1 < h; ++r) {
      for (int c = 0; c + 1 < w; ++c) {
        const size_t cell = size_t(r) * (w - 1) + c;
        const bool diagonal = sea(c + 1, r) && sea(c, r + 1);
        if (diagonal && sea(c, r)) classes[2 * cell] = scene::kClassSea;
        if (diagonal && sea(c + 1, r + 1)) classes[2 * cell + 1] = scene::kClassSea;
      }
    }
    sea_triangles = std::count(classes.begin(), classes.end(), scene::kClassSea);
    if (sea_triangles > 0) t.grid_classes = std::move(classes);
  } else if (!sea_posts.empty()) {
    sea_triangles = scene::MarkSeaTriangles(t.mesh, sea_posts);
  }
  // The bare DEM keeps its unit Lambertian material; the sea gets its own.
  if (sea_triangles > 0) t.materials.Set(scene::kClassSea, material::DefaultMaterial(scene::kClassSea));
  t.grid_width = dem.width;
  t.grid_height = dem.height;
  const Eigen::Vector2d spacing = geo::DemPostSpacingMetres(dem, t.frame, /*at_source_centre=*/true);
  // The default pixel spacing stays the source DEM's post spacing.
  t.post_spacing_m = 0.5 * (spacing.x() + spacing.y()) * options.dem_oversample;
  t.description = {{"type", "DEM"},
                   {"width", dem.width},
                   {"height", dem.height},
                   {"filled_nodata_cells", dem.filled_nodata_cells},
                   {"outside_posts", std::count(outside.begin(), outside.end(), uint8_t{1})},
                   {"source_width", source_width},
                   {"source_height", source_height},
                   {"oversample", options.dem_oversample},
                   {"vertical_unit_m", dem.vertical_unit_m},
                   {"vertical_unit_source", dem.vertical_unit_source},
                   {"vertical_datum", datum.datum},
                   {"vertical_datum_source", datum.source},
                   {"sea_triangles", sea_triangles},
                   {"post_spacing_m", {spacing.x(), spacing.y()}},
                   {"crs_wkt", dem.crs_wkt}};
  if (plan.applies) t.ray_box = plan.ray_box;
  t.dem_window = plan.ToJson();
  return t;
}

Terrain TerrainFromScene(const TerrainRequest& options) {
  std::error_code ec;
  const auto file_bytes = fs::file_size(options.scene, ec);
  if (!ec) {
    CheckMemoryBudget(kBytesPerSceneFileByte * double(file_bytes), options.max_memory_bytes,
                      "scene " + options.scene + " of " + FormatBytes(double(file_bytes)),
                      "build it from a window of the DEM (scene build --window)");
  }
  scene::SceneFile file = scene::ReadScene(options.scene);
  Terrain t;
  t.frame = geo::LocalFrame(file.origin_lon_deg, file.origin_lat_deg, 0.0);
  t.centre = {file.centre_lon_deg, file.centre_lat_deg, file.centre_height_m};
  t.centre_enu = file.centre_enu;
  t.materials = material::SceneMaterials(file.materials, options.scene);
  if (file.provenance.is_object() && file.provenance.contains("post_spacing_m")) {
    const nlohmann::json& spacing = file.provenance["post_spacing_m"];
    if (!spacing.is_number() || !(spacing.get<double>() > 0.0) || !std::isfinite(spacing.get<double>())) {
      throw InputError("scene provenance has an invalid post_spacing_m", options.scene);
    }
    t.post_spacing_m = spacing.get<double>();
  }
  // The datum the scene was built with (scenes older than the record:
  // heights used as given, i.e. ellipsoidal).
  if (file.provenance.is_object() && file.provenance.contains("vertical_datum")) {
    const nlohmann::json& d = file.provenance["vertical_datum"];
    if (!d.is_string()) throw InputError("scene provenance has an invalid vertical_datum", options.scene);
    t.vertical_datum = d.get<std::string>();
    t.vertical_datum_source = "scene (" + file.provenance.value("vertical_datum_source", std::string("?")) + ")";
  } else {
    t.vertical_datum_source = "scene (built without a datum record: heights as given)";
  }
  const std::string asked = geo::CanonicalVerticalDatum(options.vertical_datum);
  if (!asked.empty() && asked != t.vertical_datum) {
    throw ConfigError("a scene keeps the datum it was built with (" + t.vertical_datum + "), got " + asked,
                      "--vertical-datum");
  }
  t.description = {{"type", "scene"},
                   {"vertical_datum", t.vertical_datum},
                   {"vertical_datum_source", t.vertical_datum_source},
                   {"triangles", file.mesh.triangle_count()},
                   {"class_names", file.class_names},
                   {"scene_provenance", file.provenance}};
  t.reflectors = StoredReflectors(file.reflectors, options.scene);
  t.description["reflectors"] = file.reflectors.size();
  if (file.grid.cells > 0) {
    // Checked by ReadScene.
    t.scene_grid = render::TerrainGrid{file.grid.width, file.grid.height, *scene::GridPrefixCells(file.mesh, file.grid)};
    t.description["terrain_grid_cells"] = file.grid.cells;
  }
  t.mesh = std::move(file.mesh);
  return t;
}

}  // namespace

geo::DemReadOptions DemReadOptionsOf(const TerrainRequest& options, const TerrainShape& shape) {
  geo::DemReadOptions read_options;
  read_options.fill_nodata = options.fill_nodata;
  // A collar (no-data connected to the border) is left out, as `scene build`
  // leaves it: never filled, no --fill-nodata needed for it.
  read_options.border_nodata_outside = true;
  read_options.max_bytes = options.max_memory_bytes;
  read_options.bytes_per_post = static_cast<int64_t>(BytesPerDemPost(shape));
  read_options.vertical_units = options.vertical_units;
  return read_options;
}

nlohmann::json VerticalDatumRecord(const Terrain& terrain) {
  return {{"datum", terrain.vertical_datum}, {"source", terrain.vertical_datum_source}};
}

void ApplyMaterialsFile(material::MaterialTable& table, const TerrainRequest& options) {
  if (options.materials.empty()) return;
  const nlohmann::json file = material::ReadMaterialsFile(options.materials);
  for (const auto& [name, fields] : file.items()) {
    const auto id = scene::ClassIdFromName(name);
    if (!id || (options.scene.empty() && *id != scene::kClassDefault)) {
      throw ConfigError("unknown class '" + name + "'" +
                            (options.scene.empty() ? " (a DEM has the single class 'default')" : ""),
                        options.materials);
    }
    material::Material m = table.Get(*id);
    m.name = name;
    material::ApplyOverrides(m, fields, name, options.materials);
    table.Set(*id, m);
  }
}

nlohmann::json DemWindowPlan::ToJson() const {
  if (!applies) return {{"read", "whole"}, {"reason", reason}};
  return {{"read", read_window ? "window" : "whole"},
          {"col", window[0]},
          {"row", window[1]},
          {"cols", window[2]},
          {"rows", window[3]},
          {"source_width", source_width},
          {"source_height", source_height},
          {"reason", read_window ? std::string() : reason},
          {"halo_heights_m", {z_low_m, z_high_m}},
          {"margin_px", kDemWindowMarginPx},
          {"margin_posts", kDemWindowMarginPosts},
          {"ray_box_enu_m",
           {ray_box.min().x(), ray_box.min().y(), ray_box.min().z(), ray_box.max().x(), ray_box.max().y(),
            ray_box.max().z()}}};
}

namespace {

// --- DEM window planning (PlanDemWindow) ---

// geo::ReadDemInfo, remembered per process for a file (path, size,
// modification time, vertical units): a worker rendering many poses of one
// DEM streams its heights once.
geo::DemInfo CachedDemInfo(const geo::DemFile& file, const geo::DemReadOptions& read_options) {
  const fs::path path = file.path();
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  const bool on_disk = !ec;
  const auto mtime = on_disk ? fs::last_write_time(path, ec) : fs::file_time_type();
  if (!on_disk || ec) return file.Info(read_options);
  const std::string key = fs::absolute(path).string() + "|" + std::to_string(size) + "|" +
                          std::to_string(mtime.time_since_epoch().count()) + "|" + read_options.vertical_units;
  static std::mutex mutex;
  static std::map<std::string, geo::DemInfo> cache;
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto found = cache.find(key);
    if (found != cache.end()) return found->second;
  }
  geo::DemInfo info = file.Info(read_options);
  std::lock_guard<std::mutex> lock(mutex);
  if (cache.size() > 64) cache.clear();
  cache[key] = info;
  return info;
}

// The ground point (ENU) of image pixel (col, row) at ENU height z: in
// exact mode the point of the pixel's range circle (in its zero-Doppler
// plane) nearest the look direction. nullopt when the range circle does not
// reach that height.
std::optional<Eigen::Vector3d> PixelAtHeight(const sensor::SarGeometry& g, double col, double row, double z) {
  const Eigen::Vector3d& l = g.look_direction();
  const Eigen::Vector3d& n = g.range_plane_normal();
  const Eigen::Vector3d& h = g.flight_direction();
  const double a = (row - g.v0()) * g.azimuth_spacing_m();
  const double range = g.slant_range_m() + (col - g.u0()) * g.range_spacing_m();
  if (g.mode() == sensor::ProjectionMode::kAffine) {
    const double s = range - g.slant_range_m();
    const Eigen::Vector3d base = g.scene_centre() + s * l + a * h;
    if (std::abs(n.z()) < 1e-12) return std::nullopt;
    return Eigen::Vector3d(base + (z - base.z()) / n.z() * n);
  }
  if (!(range > 0.0)) return std::nullopt;
  const Eigen::Vector3d sensor = g.SensorPosition(a);
  const double A = range * l.z(), B = range * n.z(), C = z - sensor.z();
  const double m = std::hypot(A, B);
  if (!(m > 0.0) || std::abs(C) > m) return std::nullopt;
  const double phi = std::atan2(B, A), delta = std::acos(C / m);
  auto wrap = [](double t) { return std::remainder(t, 2.0 * M_PI); };
  const double t1 = wrap(phi + delta), t2 = wrap(phi - delta);
  const double theta = std::abs(t1) <= std::abs(t2) ? t1 : t2;
  return Eigen::Vector3d(sensor + range * (std::cos(theta) * l + std::sin(theta) * n));
}

// Where the line of sight from `p` towards the sensor reaches height z_top
// (the farthest terrain that can shadow p); p itself when it does not rise.
Eigen::Vector3d ShadowReach(const sensor::SarGeometry& g, const Eigen::Vector3d& p, double z_top) {
  const Eigen::Vector3d up_sight = -g.RayDirectionTo(p);
  if (!(up_sight.z() > 1e-9) || !(z_top > p.z())) return p;
  return p + (z_top - p.z()) / up_sight.z() * up_sight;
}

// Why a simulation reads the whole DEM without planning a window (nullopt:
// a window is planned).
std::optional<std::string> NoWindowPlanned(const TerrainRequest& request, const DemWindowNeeds& needs) {
  if (request.dem.empty() || needs.product_grid) return "not a DEM";
  if (needs.geometry.width <= 0 || needs.geometry.height <= 0) {
    return "no --width/--height: the image covers the whole DEM";
  }
  if (needs.raster_engine) return "the raster engine spaces its horizon lines from the whole grid";
  return std::nullopt;
}

// Height bounds of the window's halo: exact for the stored heights; cubic
// refinement may overshoot (by less than the height span: Keys' kernel and
// its boundary rule); a geoid adds its undulation (EGM96/EGM2008 lie within
// -107..+86 m). sea_low: the lowest height the sea rule may compare.
struct HaloHeights {
  double lo = 0.0, hi = 0.0, sea_low = 0.0;
};
HaloHeights HaloHeightsOf(const geo::DemInfo& info, int dem_oversample, const std::string& datum) {
  double lo = info.min_height_m, hi = info.max_height_m;
  if (dem_oversample > 1) {
    const double span = hi - lo;
    lo -= span;
    hi += span;
  }
  const double sea_low = lo;
  if (datum != "ellipsoid") {
    lo -= 110.0;
    hi += 90.0;
  }
  lo -= 1.0;
  hi += 1.0;
  return {lo, hi, sea_low};
}

// The source raster's header only: map coordinates of its posts.
geo::Dem PostLattice(const geo::DemInfo& info) {
  geo::Dem lattice;
  lattice.geotransform = info.geotransform;
  lattice.source_geotransform = info.geotransform;
  lattice.lattice_factor = 1;
  lattice.width = lattice.source_width = info.width;
  lattice.height = lattice.source_height = info.height;
  return lattice;
}

// The scene centre (--center, --center-map or the DEM's centre) in source
// posts (column, row). Throws ConfigError for a centre that is not a
// longitude,latitude or lies outside the DEM.
Eigen::Vector2d SceneCentrePost(const TerrainShape& shape, const geo::DemInfo& info, const geo::Dem& lattice,
                                const geo::CrsTransform& crs) {
  Eigen::Vector2d centre_map;
  if (shape.center_lonlat) {
    std::vector<double> x{shape.center_lonlat->x()}, y{shape.center_lonlat->y()};
    if (!std::isfinite(x[0]) || !std::isfinite(y[0]) || std::abs(y[0]) > 90.0) {
      throw ConfigError("scene centre is not a valid longitude,latitude", "--center");
    }
    crs.FromLonLat(x, y);
    centre_map = {x[0], y[0]};
  } else if (shape.center_map) {
    centre_map = *shape.center_map;
  } else {
    centre_map = lattice.MapFromPost((info.width - 1) / 2.0, (info.height - 1) / 2.0);
  }
  double centre_col = 0.0, centre_row = 0.0;
  lattice.PostFromMap(centre_map.x(), centre_map.y(), &centre_col, &centre_row);
  if (!(centre_col >= 0.0 && centre_row >= 0.0 && centre_col <= info.width - 1 && centre_row <= info.height - 1)) {
    throw ConfigError("scene centre lies outside the DEM", shape.center_map ? "--center-map" : "--center");
  }
  return {centre_col, centre_row};
}

// The frame, scene centre (ENU), post spacing and image geometry exactly as
// the whole DEM gives them.
struct CentredGeometry {
  geo::LocalFrame frame;
  Eigen::Vector3d xc;
  double post_spacing_m;
  sensor::SarGeometry geometry;
};

// CentredGeometry from the posts around the scene centre; nullopt (and the
// reason) when voids next to it are filled from the whole DEM.
std::optional<CentredGeometry> GeometryAtCentre(const TerrainRequest& request, const TerrainShape& shape,
                                                const sensor::SarGeometryOptions& image, const geo::DemFile& file,
                                                const geo::DemReadOptions& read_options,
                                                const geo::DemInfo& info, const std::string& datum,
                                                const Eigen::Vector2d& centre_post, std::string* reason) {
  const int c = static_cast<int>(std::floor(centre_post.x())), r = static_cast<int>(std::floor(centre_post.y()));
  const int c0 = std::max(0, c - 3), r0 = std::max(0, r - 3);
  const int c1 = std::min(info.width - 1, c + 4), r1 = std::min(info.height - 1, r + 4);
  geo::DemReadOptions small_options = read_options;
  small_options.window = std::array<int, 4>{c0, r0, c1 - c0 + 1, r1 - r0 + 1};
  geo::Dem small = file.Read(small_options);
  if (small.filled_nodata_cells > 0) {
    *reason = "--fill-nodata with voids next to the scene centre (filled from the whole DEM)";
    return std::nullopt;
  }
  small = geo::RefineDem(std::move(small), request.dem_oversample, int64_t{1} << 40);
  geo::ToEllipsoidalHeights(small, datum);
  std::optional<Eigen::Vector2d> small_map = shape.center_map;
  if (!shape.center_lonlat && !small_map) {
    const Eigen::Vector2d post = small.SourceCentrePost();
    small_map = small.MapFromPost(post.x(), post.y());
  }
  const geo::GeoPoint centre = geo::ResolveSceneCentre(small, shape.center_lonlat, small_map);
  const geo::LocalFrame frame(centre.lon_deg, centre.lat_deg, 0.0);
  const Eigen::Vector3d xc = frame.EnuFromGeodetic(centre.lon_deg, centre.lat_deg, centre.height_m);
  sensor::SarGeometryOptions g = image;
  const Eigen::Vector2d spacing = geo::DemPostSpacingMetres(small, frame, /*at_source_centre=*/true);
  const double post_spacing_m = 0.5 * (spacing.x() + spacing.y()) * request.dem_oversample;
  if (g.range_spacing_m == 0.0) g.range_spacing_m = post_spacing_m;
  if (g.azimuth_spacing_m == 0.0) g.azimuth_spacing_m = post_spacing_m;
  return CentredGeometry{frame, xc, post_spacing_m, sensor::SarGeometry::Covering(g, xc, {})};
}

// Points along the image's border (and the window's) per side.
constexpr int kWindowBorderSteps = 64;

// The ground the image can see (ENU): its border (plus the margin) at the
// lowest and highest ENU heights, and where its lines of sight reach the
// highest. ENU heights drop with distance d from the origin (about
// d^2 / 2R): the lowest bound (z_low) is lowered by the drop at the
// farthest point found.
struct ImageReach {
  std::vector<Eigen::Vector3d> points;
  double z_low = 0.0;
};
ImageReach ImageReachOf(const sensor::SarGeometry& geometry, const HaloHeights& heights) {
  const double lo = heights.lo, hi = heights.hi;
  const double m = kDemWindowMarginPx;
  const double c_lo = -m, c_hi = geometry.width() - 1 + m, r_lo = -m, r_hi = geometry.height() - 1 + m;
  std::vector<Eigen::Vector2d> border;
  const int steps = kWindowBorderSteps;
  for (int k = 0; k <= steps; ++k) {
    const double f = double(k) / steps;
    border.emplace_back(c_lo + f * (c_hi - c_lo), r_lo);
    border.emplace_back(c_lo + f * (c_hi - c_lo), r_hi);
    border.emplace_back(c_lo, r_lo + f * (r_hi - r_lo));
    border.emplace_back(c_hi, r_lo + f * (r_hi - r_lo));
  }
  ImageReach reach;
  std::vector<Eigen::Vector3d>& points = reach.points;
  double z_low = lo;
  for (int pass = 0; pass < 2; ++pass) {
    points.clear();
    double farthest = 0.0;
    for (const Eigen::Vector2d& px : border) {
      for (const double z : {z_low, hi}) {
        const auto p = PixelAtHeight(geometry, px.x(), px.y(), z);
        if (!p) continue;
        points.push_back(*p);
        points.push_back(ShadowReach(geometry, *p, hi));
        farthest = std::max({farthest, p->head<2>().norm(), points.back().head<2>().norm()});
      }
    }
    const double drop = 1.2 * farthest * farthest / (2.0 * 6.35e6) + 1.0;
    if (lo - drop >= z_low) break;
    z_low = lo - drop;
  }
  reach.z_low = z_low;
  return reach;
}

// The window of source posts (first column, first row, columns, rows)
// holding `points` plus kDemWindowMarginPosts; nullopt (and the reason)
// when the footprint leaves the CRS's domain or the DEM.
std::optional<std::array<int, 4>> WindowOfPoints(const std::vector<Eigen::Vector3d>& points,
                                                 const geo::LocalFrame& frame, const geo::CrsTransform& crs,
                                                 const geo::Dem& lattice, const geo::DemInfo& info,
                                                 std::string* reason) {
  // Source posts of those points.
  std::vector<double> x, y;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d geodetic = frame.GeodeticFromEnu(p);
    x.push_back(geodetic.x());
    y.push_back(geodetic.y());
  }
  try {
    crs.FromLonLat(x, y);
  } catch (const InputError&) {  // a footprint beyond the domain of the DEM's CRS: read the whole DEM
    *reason = "the image's footprint reaches outside the domain of the DEM's CRS";
    return std::nullopt;
  }
  double col_min = 1e300, col_max = -1e300, row_min = 1e300, row_max = -1e300;
  for (size_t i = 0; i < x.size(); ++i) {
    double c = 0.0, r = 0.0;
    lattice.PostFromMap(x[i], y[i], &c, &r);
    if (!std::isfinite(c) || !std::isfinite(r)) continue;
    col_min = std::min(col_min, c);
    col_max = std::max(col_max, c);
    row_min = std::min(row_min, r);
    row_max = std::max(row_max, r);
  }
  auto clamp_post = [](double v, int size) {
    return static_cast<int>(std::clamp(v, 0.0, double(size - 1)));
  };
  const int wc0 = clamp_post(std::floor(col_min) - kDemWindowMarginPosts, info.width);
  const int wc1 = clamp_post(std::ceil(col_max) + kDemWindowMarginPosts, info.width);
  const int wr0 = clamp_post(std::floor(row_min) - kDemWindowMarginPosts, info.height);
  const int wr1 = clamp_post(std::ceil(row_max) + kDemWindowMarginPosts, info.height);
  if (wc1 - wc0 < 1 || wr1 - wr0 < 1) {
    *reason = "the image's footprint lies outside the DEM";
    return std::nullopt;
  }
  return std::array<int, 4>{wc0, wr0, wc1 - wc0 + 1, wr1 - wr0 + 1};
}

// The ray box: the window's posts at both height bounds (its border,
// densely, and its centre; ENU heights are lowest at the border), the scene
// centre, a post of slack (the window's plan is curved in ENU) and the ENU
// drop below heights.lo.
Eigen::AlignedBox3d WindowRayBox(const std::array<int, 4>& window, const geo::Dem& lattice,
                                 const geo::CrsTransform& crs, const CentredGeometry& centred,
                                 const HaloHeights& heights, double z_low) {
  const double lo = heights.lo, hi = heights.hi;
  const int wc0 = window[0], wr0 = window[1], wc1 = window[0] + window[2] - 1, wr1 = window[1] + window[3] - 1;
  const int steps = kWindowBorderSteps;
  std::vector<double> bx, by;
  for (int k = 0; k <= steps; ++k) {
    const double f = double(k) / steps;
    const double cc = wc0 + f * (wc1 - wc0), rr = wr0 + f * (wr1 - wr0);
    for (const auto& [pc, pr] : {std::pair{cc, double(wr0)}, {cc, double(wr1)}, {double(wc0), rr}, {double(wc1), rr}}) {
      const Eigen::Vector2d mp = lattice.MapFromPost(pc, pr);
      bx.push_back(mp.x());
      by.push_back(mp.y());
    }
  }
  const Eigen::Vector2d mid = lattice.MapFromPost(0.5 * (wc0 + wc1), 0.5 * (wr0 + wr1));
  bx.push_back(mid.x());
  by.push_back(mid.y());
  crs.ToLonLat(bx, by);
  Eigen::AlignedBox3d box;
  for (size_t i = 0; i < bx.size(); ++i) {
    for (const double z : {lo, hi}) box.extend(centred.frame.EnuFromGeodetic(bx[i], by[i], z));
  }
  box.extend(centred.xc);
  const double slack = 2.0 * centred.post_spacing_m + 1.0;
  box.min() -= Eigen::Vector3d(slack, slack, slack + (z_low < lo ? lo - z_low : 0.0));
  box.max() += Eigen::Vector3d(slack, slack, slack);
  return box;
}

// Why the whole DEM is read anyway although a window was planned ("": the
// window is read).
std::string WhyWholeDem(const TerrainRequest& request, const DemWindowNeeds& needs, const std::array<int, 4>& window,
                        const geo::DemInfo& info, double sea_low) {
  material::MaterialTable materials;
  ApplyMaterialsFile(materials, request);
  const bool mirror_paths = needs.bounces > 1 && materials.Get(scene::kClassDefault).mirror > 0.0;
  const double window_posts = double(window[2]) * window[3];
  if (needs.window_off) return "--dem-window off";
  if (request.sea == "auto" && sea_low <= request.sea_level_m) {
    return "--sea auto on a DEM reaching the sea level (the sea is what connects to the whole DEM's border; "
           "--sea off reads a window)";
  }
  if (mirror_paths) return "mirror paths (--materials with a mirror share and --bounces > 1) may reach any terrain";
  if (needs.reflectors) return "--reflectors may lie anywhere on the DEM";
  if (needs.contributions) return "--contributions records returns from anywhere on the DEM";
  if (window_posts >= 0.8 * double(info.width) * double(info.height)) return "the window is most of the DEM";
  return "";
}

}  // namespace

DemWindowPlan PlanDemWindow(const TerrainRequest& request, const TerrainShape& shape, const DemWindowNeeds& needs) {
  DemWindowPlan plan;
  if (const std::optional<std::string> why = NoWindowPlanned(request, needs)) {
    plan.reason = *why;
    return plan;
  }
  const geo::DemReadOptions read_options = DemReadOptionsOf(request, shape);
  // Opened once: its header and bounds, the posts at the centre, then the
  // window or the whole DEM (LoadTerrain reads plan.dem_file).
  plan.dem_file.emplace(request.dem);
  const geo::DemInfo info = CachedDemInfo(*plan.dem_file, read_options);
  if (!info.any_valid) {
    plan.reason = "the DEM has no valid height";
    return plan;
  }
  plan.source_width = info.width;
  plan.source_height = info.height;
  const geo::VerticalDatumChoice datum =
      geo::ResolveVerticalDatum(geo::CanonicalVerticalDatum(request.vertical_datum), info.file_vertical_datum);
  const HaloHeights heights = HaloHeightsOf(info, request.dem_oversample, datum.datum);

  // The scene centre, frame and geometry exactly as the whole DEM gives
  // them: the centre's height from the posts around it.
  const geo::Dem lattice = PostLattice(info);
  const geo::CrsTransform crs(info.crs_wkt);
  const Eigen::Vector2d centre_post = SceneCentrePost(shape, info, lattice, crs);
  const std::optional<CentredGeometry> centred = GeometryAtCentre(
      request, shape, needs.geometry, *plan.dem_file, read_options, info, datum.datum, centre_post, &plan.reason);
  if (!centred) return plan;

  // The posts the image can see or be shadowed from, and the rays' box.
  const ImageReach reach = ImageReachOf(centred->geometry, heights);
  if (reach.points.empty()) {
    plan.reason = "the image's lines of sight do not reach the DEM's heights";
    return plan;
  }
  plan.z_low_m = reach.z_low;
  plan.z_high_m = heights.hi;
  const std::optional<std::array<int, 4>> window =
      WindowOfPoints(reach.points, centred->frame, crs, lattice, info, &plan.reason);
  if (!window) return plan;
  plan.window = *window;
  plan.ray_box = WindowRayBox(plan.window, lattice, crs, *centred, heights, reach.z_low);
  plan.applies = true;

  // When the whole DEM is read anyway.
  plan.reason = WhyWholeDem(request, needs, plan.window, info, heights.sea_low);
  plan.read_window = plan.reason.empty();
  return plan;
}

Terrain LoadTerrain(const TerrainRequest& request, const TerrainShape& shape, Reporter& reporter) {
  Terrain t = request.scene.empty() ? TerrainFromDem(request, shape, reporter) : TerrainFromScene(request);
  ApplyMaterialsFile(t.materials, request);
  return t;
}

SurfaceHeightAt EmbreeSurface(const render::EmbreeScene& embree, double top_z_m) {
  return [&embree, top_z_m](double x, double y) -> std::optional<double> {
    // A vertical ray exactly through a mesh vertex or edge may slip between
    // its triangles (Embree's fast, non-watertight test): then a few
    // millimetres beside it.
    constexpr double kNudge[5][2] = {{0, 0}, {2e-3, 1e-3}, {-1e-3, 2e-3}, {-2e-3, -1e-3}, {1e-3, -2e-3}};
    for (const auto& d : kNudge) {
      const auto hit = embree.Intersect(Eigen::Vector3f(float(x + d[0]), float(y + d[1]), float(top_z_m)),
                                        Eigen::Vector3f(0, 0, -1), 0.0f, std::numeric_limits<float>::infinity());
      if (hit) return top_z_m - hit->t;
    }
    return std::nullopt;
  };
}

std::vector<render::SceneReflector> PlaceReflectorRows(const std::vector<material::ReflectorSpec>& rows,
                                                       const std::string& source, const geo::LocalFrame& frame,
                                                       const SurfaceHeightAt& surface) {
  std::vector<render::SceneReflector> out;
  for (const material::ReflectorSpec& spec : rows) {
    // The ground point of (lon, lat): on the ellipsoid normal there, at the
    // surface's height (ENU verticals lean from it away from the origin:
    // the plan position is taken at the height found, then the surface
    // read again there).
    const std::string where = source + " row " + std::to_string(spec.row);
    Eigen::Vector3d at = frame.EnuFromGeodetic(spec.lon_deg, spec.lat_deg, 0.0);
    std::optional<double> z = surface(at.x(), at.y());
    if (z) {
      const double h = frame.GeodeticFromEnu(Eigen::Vector3d(at.x(), at.y(), *z)).z();
      at = frame.EnuFromGeodetic(spec.lon_deg, spec.lat_deg, h);
      z = surface(at.x(), at.y());
    }
    if (!z) throw InputError("reflector lies outside the terrain", where);
    render::SceneReflector r;
    r.type = spec.type;
    r.size_m = spec.size_m;
    r.apex_enu = Eigen::Vector3d(at.x(), at.y(), *z + spec.apex_height_m);
    r.boresight_enu = material::BoresightVector(spec.boresight_azimuth_deg, spec.boresight_elevation_deg);
    r.roll_rad = spec.roll_deg * M_PI / 180.0;
    r.row = spec.row;
    out.push_back(r);
  }
  return out;
}

std::vector<render::SceneReflector> PlaceReflectors(const std::string& reflectors_csv, const geo::LocalFrame& frame,
                                                    const SurfaceHeightAt& surface) {
  if (reflectors_csv.empty()) return {};
  return PlaceReflectorRows(material::ReadReflectorsCsv(reflectors_csv), reflectors_csv, frame, surface);
}

std::vector<render::SceneReflector> PlaceReflectors(const std::string& reflectors_csv, const Terrain& terrain,
                                                    const render::EmbreeScene& embree) {
  return PlaceReflectors(reflectors_csv, terrain.frame, EmbreeSurface(embree, terrain.mesh.Bounds().max().z() + 100.0));
}

std::vector<render::SceneReflector> StoredReflectors(const std::vector<scene::StoredReflector>& stored,
                                                     const std::string& scene_path) {
  std::vector<render::SceneReflector> out;
  for (size_t k = 0; k < stored.size(); ++k) {
    const scene::StoredReflector& s = stored[k];
    render::SceneReflector r;
    r.type = material::ParseReflectorType(s.type, scene_path + " reflector " + std::to_string(k + 1));
    r.size_m = s.size_m;
    r.apex_enu = s.apex_enu;
    r.boresight_enu = material::BoresightVector(s.boresight_azimuth_deg, s.boresight_elevation_deg);
    r.roll_rad = s.roll_deg * M_PI / 180.0;
    r.row = s.row;
    out.push_back(r);
  }
  return out;
}

}  // namespace gissar::pipeline
