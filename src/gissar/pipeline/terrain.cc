#include "gissar/pipeline/terrain.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

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
  dem = geo::RefineDem(dem, options.dem_oversample,
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

std::vector<render::SceneReflector> PlaceReflectors(const std::string& reflectors_csv, const Terrain& terrain,
                                                    const render::EmbreeScene& embree) {
  if (reflectors_csv.empty()) return {};
  return PlaceReflectorRows(material::ReadReflectorsCsv(reflectors_csv), reflectors_csv, terrain.frame,
                            EmbreeSurface(embree, terrain.mesh.Bounds().max().z() + 100.0));
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
