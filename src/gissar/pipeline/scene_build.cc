#include "gissar/pipeline/scene_build.h"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>

#include "gissar/geo/dem.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/image/class_map.h"
#include "gissar/image/mesh_view.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/material/material.h"
#include "gissar/material/reflector.h"
#include "gissar/render/embree_scene.h"
#include "gissar/scene/gis_scene.h"
#include "gissar/scene/scene_config.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {

static std::string Num17(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

nlohmann::json MeshCrsRecord(double origin_lon_deg, double origin_lat_deg) {
  const std::string lon = Num17(origin_lon_deg), lat = Num17(origin_lat_deg);
  return {{"crs", "local ENU tangent frame on WGS84 (x east, y north, z up; metres)"},
          {"ellipsoid", "WGS84"},
          {"origin_lon_deg", origin_lon_deg},
          {"origin_lat_deg", origin_lat_deg},
          {"origin_height_m", 0.0},
          {"axes", {"east", "north", "up"}},
          {"unit", "m"},
          {"proj_pipeline_to_wgs84",
           "+proj=pipeline +step +inv +proj=topocentric +ellps=WGS84 +lon_0=" + lon + " +lat_0=" + lat +
               " +h_0=0 +step +inv +proj=cart +ellps=WGS84 +step +proj=unitconvert +xy_in=rad +xy_out=deg"},
          {"note", "apply with: cct <proj_pipeline_to_wgs84> (output: longitude, latitude degrees, ellipsoidal height m)"}};
}
namespace fs = std::filesystem;
using nlohmann::json;

std::array<int, 4> ParseWindow(const std::string& text, const std::string& option) {
  std::array<int, 4> w{};
  char sep[3] = {};
  std::istringstream in(text);
  std::string rest;
  if (!(in >> w[0] >> sep[0] >> w[1] >> sep[1] >> w[2] >> sep[2] >> w[3]) || (in >> rest) ||
      sep[0] != ',' || sep[1] != ',' || sep[2] != ',') {
    throw ConfigError("expected a window 'COL,ROW,COLS,ROWS', got '" + text + "'", option);
  }
  // Bounded so that COL + COLS and ROW + ROWS cannot overflow an int.
  constexpr int kMaxCells = 1000000000;
  for (int v : w) {
    if (v < 0 || v > kMaxCells) throw ConfigError("window values must be in [0, 10^9] cells, got '" + text + "'", option);
  }
  return w;
}

namespace {

// Moves every vertex (ENU of `frame`, heights in `datum`) up the ellipsoid
// normal by the geoid undulation there: ellipsoidal heights.
void RaiseToEllipsoidalHeights(scene::TriangleMesh& mesh, const geo::LocalFrame& frame, const std::string& datum,
                               const std::string& where) {
  if (datum == "ellipsoid" || mesh.vertices.empty()) return;
  std::vector<double> lon(mesh.vertices.size()), lat(lon.size()), h(lon.size());
  for (size_t i = 0; i < lon.size(); ++i) {
    const Eigen::Vector3d g = frame.GeodeticFromEnu(mesh.vertices[i].cast<double>());
    lon[i] = g.x();
    lat[i] = g.y();
    h[i] = g.z();
  }
  const std::vector<double> n = geo::GeoidUndulationsM(datum, lon, lat, where);
  for (size_t i = 0; i < lon.size(); ++i) {
    mesh.vertices[i] = frame.EnuFromGeodetic(lon[i], lat[i], h[i] + n[i]).cast<float>();
  }
}

// The files of a scene build, reserved before any work.
struct SceneBuildOutputs {
  AtomicOutputs files;
  fs::path scene, ply, classes_png, view_png, json, mesh_json, obj, mtl;
};
void ReserveSceneBuildOutputs(const SceneBuildRequest& options, SceneBuildOutputs& o) {
  o.scene = o.files.Add(options.out_prefix + ".gscene");
  o.ply = o.files.Add(options.out_prefix + ".ply");
  o.classes_png = o.files.Add(options.out_prefix + "_classes.png");
  o.view_png = o.files.Add(options.out_prefix + "_3d.png");
  o.json = o.files.Add(options.out_prefix + ".json");
  o.mesh_json = o.files.Add(options.out_prefix + "_mesh.json");
  o.obj = options.export_obj ? o.files.Add(options.out_prefix + ".obj") : fs::path();
  o.mtl = options.export_obj ? o.files.Add(options.out_prefix + ".mtl") : fs::path();
}

// The scene configuration: --config, the --osm or --vectors preset, or none;
// with the sea rule of the request.
scene::SceneConfig SceneConfigOf(const SceneBuildRequest& options, std::vector<std::string>* warnings) {
  scene::SceneConfig config;
  if (!options.config.empty()) {
    config = scene::LoadSceneConfig(options.config);
  } else if (!options.osm.empty()) {
    config = scene::OsmPreset(options.osm);
  } else if (!options.vectors.empty()) {
    config = scene::LayerNamePreset(options.vectors, warnings);
  } else {
    config.source = "no vector data";
  }
  config.sea_auto = options.sea == "auto";
  config.sea_level_m = options.sea_level_m;
  return config;
}

// The DEM (its window), refined by --dem-oversample.
geo::Dem ReadSceneDem(const SceneBuildRequest& options) {
  geo::DemReadOptions read_options;
  read_options.fill_nodata = options.fill_nodata;
  read_options.border_nodata_outside = true;  // a collar is left out of the scene, not filled
  read_options.window = options.window;
  // Constrained triangulation (CGAL vertices and faces with info), GEOS
  // regions and the output mesh, per DEM post; vector constraints add more.
  read_options.bytes_per_post = 512;
  read_options.max_bytes = options.max_memory_bytes;
  read_options.vertical_units = options.vertical_units;
  return geo::RefineDem(geo::ReadDem(options.dem, read_options), options.dem_oversample,
                        options.max_memory_bytes / read_options.bytes_per_post);
}

// The summary's "stats": per class and for the whole build.
json SceneStats(const scene::GisScene& built, const geo::Dem& dem, const geo::VerticalDatumChoice& datum,
                const SceneBuildRequest& options, size_t reflectors) {
  json classes = json::object();
  const auto& names = scene::ClassNames();
  for (int c = 0; c < scene::kClassCount; ++c) {
    classes[names[c]] = {{"triangles", built.stats.triangles[c]},
                         {"mesh_area_m2", built.stats.mesh_area_m2[c]},
                         {"region_area_m2", built.stats.region_area_m2[c]}};
  }
  return {{"classes", classes},
          {"triangles", built.mesh.triangle_count()},
          {"vertices", built.mesh.vertices.size()},
          {"dem_posts", built.stats.dem_posts},
          {"dem_vertical_unit_m", dem.vertical_unit_m},
          {"dem_vertical_unit_source", dem.vertical_unit_source},
          {"dem_vertical_datum", datum.datum},
          {"dem_vertical_datum_source", datum.source},
          {"inserted_vertices", built.stats.inserted_vertices},
          {"constraint_segments", built.stats.constraint_segments},
          {"cdt_cells", built.stats.cdt_cells},
          {"cdt_posts", built.stats.cdt_posts},
          {"grid_cells", built.stats.grid_cells},
          {"terrain_grid_cells", built.grid.cells},
          {"cdt_rebuilds", built.stats.cdt_rebuilds},
          {"features_read", built.stats.features_read},
          {"features_outside", built.stats.features_outside},
          {"repaired_geometries", built.stats.repaired_geometries},
          {"simplified_outlines", built.stats.simplified_outlines},
          {"buildings", built.stats.buildings},
          {"merged_buildings", built.stats.merged_buildings},
          {"step_walls", built.stats.step_walls},
          {"buried_wall_triangles", built.stats.buried_wall_triangles},
          {"coastline_features", built.stats.coastline_features},
          {"coastline_extended_ends", built.stats.coastline_extended_ends},
          {"sea_trimmed_m2", built.stats.sea_trimmed_m2},
          {"sea_level_vertices", built.stats.sea_level_vertices},
          {"sea_from_dem", built.stats.sea_from_dem},
          {"outside_posts", built.stats.outside_posts},
          {"dropped_faces", built.stats.dropped_faces},
          {"needle_faces", built.stats.needle_faces},
          {"sliver_faces", built.stats.sliver_faces},
          {"steep_slivers", built.stats.steep_slivers},
          {"shading_normals", !options.flat_shading},
          {"reflectors", reflectors},
          {"build_seconds", built.stats.seconds}};
}

// The input files' records: the DEM, each vector file once, the config and
// the reflectors.
json SceneInputs(const SceneBuildRequest& options, const scene::SceneConfig& config) {
  json inputs = json::array({InputFileRecord(options.dem)});
  std::vector<std::string> seen;
  for (const scene::LayerSpec& l : config.layers) {
    if (std::find(seen.begin(), seen.end(), l.source.path) != seen.end()) continue;
    seen.push_back(l.source.path);
    if (fs::is_regular_file(l.source.path)) inputs.push_back(InputFileRecord(l.source.path));
  }
  if (!options.config.empty()) inputs.push_back(InputFileRecord(options.config));
  if (!options.reflectors.empty()) inputs.push_back(InputFileRecord(options.reflectors));
  return inputs;
}

// The reflector rows placed on the scene's surface (roofs included), found
// as simulate finds it.
std::vector<scene::StoredReflector> StoredReflectorsOf(const std::vector<material::ReflectorSpec>& reflector_rows,
                                                       const SceneBuildRequest& options, const geo::LocalFrame& frame,
                                                       const scene::TriangleMesh& mesh) {
  const render::EmbreeScene embree(mesh);
  const std::vector<render::SceneReflector> placed =
      PlaceReflectorRows(reflector_rows, options.reflectors, frame, EmbreeSurface(embree, mesh.Bounds().max().z() + 100.0));
  std::vector<scene::StoredReflector> stored;
  for (size_t k = 0; k < placed.size(); ++k) {
    const material::ReflectorSpec& row = reflector_rows[k];
    scene::StoredReflector r;
    r.type = material::ToString(row.type);
    r.lon_deg = row.lon_deg;
    r.lat_deg = row.lat_deg;
    r.apex_height_m = row.apex_height_m;
    r.size_m = row.size_m;
    r.boresight_azimuth_deg = row.boresight_azimuth_deg;
    r.boresight_elevation_deg = row.boresight_elevation_deg;
    r.roll_deg = row.roll_deg;
    r.apex_enu = placed[k].apex_enu;
    r.source = fs::path(options.reflectors).filename().string();
    r.row = row.row;
    stored.push_back(r);
  }
  return stored;
}

// The meshes' files: PREFIX_mesh.json (their georeference, also in the
// header comments), the PLY, the class map and 3-D view PNGs and, with
// --obj, the OBJ and its MTL.
void WriteMeshFiles(const SceneBuildOutputs& o, const scene::SceneFile& file, const SceneBuildRequest& options) {
  const json mesh_crs = MeshCrsRecord(file.origin_lon_deg, file.origin_lat_deg);
  const std::vector<std::string> mesh_comments = {
      "crs " + mesh_crs["crs"].get<std::string>(),
      "origin_lon_deg " + Num17(file.origin_lon_deg) + " origin_lat_deg " + Num17(file.origin_lat_deg) +
          " origin_height_m 0",
      "enu_to_wgs84 " + mesh_crs["proj_pipeline_to_wgs84"].get<std::string>()};
  WriteJsonFile(mesh_crs, o.mesh_json);
  scene::WritePly(o.ply, file.mesh, file.class_names, mesh_comments);
  const image::RgbImage class_map = image::RenderClassMap(file.mesh, file.class_names);
  geo::WritePng(o.classes_png, class_map.rgb, class_map.width, class_map.height, 3);
  const image::RgbImage view = image::RenderMeshView(file.mesh, image::ClassColourList());
  geo::WritePng(o.view_png, view.rgb, view.width, view.height, 3);
  if (options.export_obj) {
    scene::WriteObj(o.obj, o.mtl, fs::path(options.out_prefix + ".mtl").filename().string(), file.mesh,
                    file.class_names, image::ClassColourList(), mesh_comments);
  }
}

// The scene file: the mesh (moved from `built`; shading normals unless
// --flat-shading), the placed reflectors, the frame, centre, classes,
// materials and provenance.
scene::SceneFile SceneFileOf(scene::GisScene& built, const SceneBuildRequest& options,
                             const std::vector<material::ReflectorSpec>& reflector_rows, const geo::LocalFrame& frame,
                             const geo::GeoPoint& centre, const scene::SceneConfig& config,
                             const geo::VerticalDatumChoice& datum, const Eigen::Vector2d& spacing) {
  scene::SceneFile file;
  file.mesh = std::move(built.mesh);
  file.grid = built.grid;
  if (!options.flat_shading) file.mesh.SmoothShadingNormals(scene::kClassBuilding);
  if (!reflector_rows.empty()) file.reflectors = StoredReflectorsOf(reflector_rows, options, frame, file.mesh);
  const auto& names = scene::ClassNames();
  file.origin_lon_deg = frame.origin_lon_deg();
  file.origin_lat_deg = frame.origin_lat_deg();
  file.centre_enu = frame.EnuFromGeodetic(centre.lon_deg, centre.lat_deg, centre.height_m);
  file.centre_lon_deg = centre.lon_deg;
  file.centre_lat_deg = centre.lat_deg;
  file.centre_height_m = centre.height_m;
  file.class_names.assign(names.begin(), names.end());
  file.materials = config.materials;
  file.provenance = {{"version", VersionString()},
                     {"dem", fs::absolute(options.dem).string()},
                     {"post_spacing_m", 0.5 * (spacing.x() + spacing.y())},
                     {"vertical_datum", datum.datum},
                     {"vertical_datum_source", datum.source},
                     {"config", config.ToJson()}};
  return file;
}

// PREFIX.json: the request, config, materials, inputs, frame, extent,
// stats, warnings and resources (outputs are added when committed).
json SceneSummary(const SceneBuildRequest& options, const std::string& command_line, const scene::SceneConfig& config,
                  const material::MaterialTable& materials, const json& inputs, const geo::VerticalDatumChoice& datum,
                  const scene::SceneFile& file, const json& stats, const std::vector<std::string>& warnings,
                  const Stopwatch& total) {
  const Eigen::AlignedBox3d box = file.mesh.Bounds();
  return {{"command", "scene build"},
          {"command_line", command_line},
          {"version", VersionString()},
          {"created_utc", UtcTimestamp()},
          {"options", options.ToJson()},
          {"config", config.ToJson()},
          {"materials", materials.ToJson()},
          {"inputs", inputs},
          {"vertical_datum", {{"datum", datum.datum}, {"source", datum.source}}},
          {"frame", {{"type", "ENU tangent frame, WGS84"},
                     {"origin_lon_deg", file.origin_lon_deg},
                     {"origin_lat_deg", file.origin_lat_deg}}},
          {"extent_enu_m", {{"min", {box.min().x(), box.min().y(), box.min().z()}},
                            {"max", {box.max().x(), box.max().y(), box.max().z()}}}},
          {"stats", stats},
          {"warnings", warnings},
          {"mesh_bytes", file.mesh.MemoryBytes()},
          {"peak_rss_bytes", PeakResidentBytes()},
          {"total_seconds", total.ElapsedSeconds()}};
}

}  // namespace

void SceneBuildRequest::Check() const {
  if (dem.empty()) throw ConfigError("a DEM is required", "--dem");
  if (out_prefix.empty()) throw ConfigError("an output prefix is required", "--out");
  const int sources = !config.empty() + !osm.empty() + !vectors.empty();
  if (sources > 1) throw ConfigError("give one of --config, --osm, --vectors", "--config/--osm/--vectors");
  if (max_memory_bytes <= 0) throw ConfigError("memory limit must be positive", "--max-memory");
  if (sea != "auto" && sea != "off") throw ConfigError("expected auto or off, got '" + sea + "'", "--sea");
  if (!std::isfinite(sea_level_m)) throw ConfigError("sea level must be finite", "--sea-level");
  CheckVerticalUnits(vertical_units);
  geo::CanonicalVerticalDatum(vertical_datum, "--vertical-datum");
  if (dem_oversample < 1 || dem_oversample > geo::kMaxDemOversample) {
    throw ConfigError("DEM oversampling must be in [1, " + std::to_string(geo::kMaxDemOversample) + "], got " +
                          std::to_string(dem_oversample),
                      "--dem-oversample");
  }
  std::vector<std::string> inputs = {dem, osm, config, reflectors};
  inputs.insert(inputs.end(), vectors.begin(), vectors.end());
  std::vector<fs::path> outs;
  for (const char* suffix : {".gscene", ".ply", "_classes.png", "_3d.png", ".json", "_mesh.json", ".obj", ".mtl"}) {
    outs.push_back(out_prefix + suffix);
  }
  CheckOutputsAreNotInputs(outs, inputs);
}

SceneBuildResult RunSceneBuild(const SceneBuildRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  Stopwatch total;
  SceneBuildOutputs outputs;
  ReserveSceneBuildOutputs(options, outputs);

  // Config first: a bad config fails before any heavy work.
  std::vector<std::string> warnings;
  const scene::SceneConfig config = SceneConfigOf(options, &warnings);
  const material::MaterialTable materials = material::SceneMaterials(config.materials, config.source);
  // Reflector rows: a bad row fails before the DEM is read.
  const std::vector<material::ReflectorSpec> reflector_rows =
      options.reflectors.empty() ? std::vector<material::ReflectorSpec>{}
                                 : material::ReadReflectorsCsv(options.reflectors);

  const geo::Dem dem = ReadSceneDem(options);
  const geo::VerticalDatumChoice datum =
      geo::ResolveVerticalDatum(geo::CanonicalVerticalDatum(options.vertical_datum), dem.file_vertical_datum);
  if (datum.source == "assumed") warnings.push_back(geo::AssumedDatumWarning(options.dem));
  geo::GeoPoint centre = geo::ResolveSceneCentre(dem, options.center_lonlat, std::nullopt);
  const geo::LocalFrame frame(centre.lon_deg, centre.lat_deg, 0.0);
  // Built from the heights as given (the sea rule compares orthometric
  // heights with --sea-level), then raised to ellipsoidal heights.
  scene::GisScene built = scene::BuildGisScene(dem, frame, config, reporter);
  RaiseToEllipsoidalHeights(built.mesh, frame, datum.datum, options.dem);
  centre.height_m += geo::GeoidUndulationsM(datum.datum, {centre.lon_deg}, {centre.lat_deg}, options.dem)[0];
  warnings.insert(warnings.end(), built.warnings.begin(), built.warnings.end());
  for (const std::string& w : warnings) reporter.Warn(w);

  const Eigen::Vector2d spacing = geo::DemPostSpacingMetres(dem, frame);
  const json stats = SceneStats(built, dem, datum, options, reflector_rows.size());
  const json inputs = SceneInputs(options, config);

  const scene::SceneFile file = SceneFileOf(built, options, reflector_rows, frame, centre, config, datum, spacing);
  scene::WriteScene(outputs.scene, file);
  WriteMeshFiles(outputs, file, options);

  json summary = SceneSummary(options, command_line, config, materials, inputs, datum, file, stats, warnings, total);
  std::vector<std::string> final_names;
  for (const fs::path& p : outputs.files.final_paths()) final_names.push_back(fs::absolute(p).string());
  summary["outputs"] = final_names;
  WriteJsonFile(summary, outputs.json);
  outputs.files.Commit();
  return {outputs.files.final_paths(), summary};
}

void PrintSceneInfo(const std::string& scene_path, std::ostream& out) {
  const scene::SceneFile file = scene::ReadScene(scene_path);
  const scene::TriangleMesh& mesh = file.mesh;
  std::vector<int64_t> triangles(file.class_names.size(), 0);
  std::vector<double> area(file.class_names.size(), 0.0), plan(file.class_names.size(), 0.0);
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const size_t c = std::min<size_t>(mesh.classes[t], file.class_names.size() - 1);
    const Eigen::Vector3i tri = mesh.Triangle(t);
    const Eigen::Vector3f a = mesh.vertices[tri[0]];
    const Eigen::Vector3f cross = (mesh.vertices[tri[1]] - a).cross(mesh.vertices[tri[2]] - a);
    ++triangles[c];
    area[c] += 0.5 * cross.norm();
    plan[c] += 0.5 * std::abs(cross.z());
  }
  const Eigen::AlignedBox3d box = mesh.Bounds();
  out << std::fixed << std::setprecision(1);
  out << "scene      " << scene_path << "\n";
  out << "frame      ENU, origin lon " << std::setprecision(6) << file.origin_lon_deg << " lat "
      << file.origin_lat_deg << std::setprecision(1) << "\n";
  out << "extent     x " << box.min().x() << " .. " << box.max().x() << " m, y " << box.min().y()
      << " .. " << box.max().y() << " m, z " << box.min().z() << " .. " << box.max().z() << " m\n";
  out << "triangles  " << mesh.triangle_count() << "\nvertices   " << mesh.vertices.size() << "\n";
  out << "memory     " << std::setprecision(2) << mesh.MemoryBytes() / 1048576.0 << " MiB (mesh arrays)\n";
  out << "class        triangles     plan km2  surface km2\n";
  for (size_t c = 0; c < file.class_names.size(); ++c) {
    out << std::left << std::setw(12) << file.class_names[c] << std::right << std::setw(11) << triangles[c]
        << std::setprecision(4) << std::setw(13) << plan[c] / 1e6 << std::setw(13) << area[c] / 1e6 << "\n";
  }
  out << "reflectors " << file.reflectors.size() << "\n";
  if (!file.reflectors.empty()) {
    out << "  type              size_m   lon_deg      lat_deg     apex_enu_m (x, y, z)        boresight az/el deg  source\n";
    for (const scene::StoredReflector& r : file.reflectors) {
      char line[320];
      std::snprintf(line, sizeof(line), "  %-16s %7.3f %11.6f %11.6f  %9.2f %9.2f %8.2f  %7.1f %6.1f  %s row %d\n",
                    r.type.c_str(), r.size_m, r.lon_deg, r.lat_deg, r.apex_enu.x(), r.apex_enu.y(), r.apex_enu.z(),
                    r.boresight_azimuth_deg, r.boresight_elevation_deg, r.source.c_str(), r.row);
      out << line;
    }
  }
}

}  // namespace gissar::pipeline
