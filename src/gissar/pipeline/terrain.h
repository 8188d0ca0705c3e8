// The terrain source of the requests: a DEM or a scene, read, meshed and
// centred once (LoadTerrain) into a Terrain (mesh, ENU frame, centre,
// materials, the scene's reflectors), a fixed-size image's DEM window planned
// first (PlanDemWindow). simulate, sequence, ortho, validate and the product
// simulation describe it with their SimulateRequest (TerrainRequestOf,
// TerrainShapeOf and DemWindowNeedsOf, simulate.h); locate and evaluate with
// their own fields, without a simulation request; geocode and pta with the
// request their image's sidecar records.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/material/material.h"
#include "gissar/material/reflector.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/scene_io.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/reporter.h"

namespace gissar::pipeline {

// The terrain a request renders or finds ground points on: a DEM's mesh (bare terrain, one unit
// Lambertian class) or a GIS scene (classes and their materials), with its
// ENU frame, scene centre and default pixel spacing.
struct Terrain {
  scene::TriangleMesh mesh;
  geo::LocalFrame frame{0.0, 0.0};
  geo::GeoPoint centre;
  Eigen::Vector3d centre_enu = Eigen::Vector3d::Zero();
  double post_spacing_m = 30.0;
  // A DEM's grid of posts (mesh.vertices, row-major); 0 x 0 for scenes.
  int grid_width = 0;
  int grid_height = 0;
  // A scene's terrain grid (scene::GridPrefix: its directly split cells at
  // the start of the mesh, the others holes); cells empty: none.
  render::TerrainGrid scene_grid;
  // Raster engine: the class of every triangle of the DEM's grid
  // (scene::MeshFromGrid's order, e.g. the sea); empty = all `default`.
  std::vector<scene::ClassId> grid_classes;
  material::MaterialTable materials;
  // Datum of the source DEM's heights (now ellipsoidal in the mesh) and
  // where it came from: flag, file or assumed (a scene: the datum it was
  // built with).
  std::string vertical_datum = "ellipsoid";
  std::string vertical_datum_source = "assumed";
  nlohmann::json description;  // for provenance
  // Canonical reflectors stored in a scene (`scene build --reflectors`),
  // placed when it was built.
  std::vector<render::SceneReflector> reflectors;
  // The tracer's ray box (render::RenderOptions::ray_box) of a fixed-size
  // image of a DEM: the same whether the window or the whole DEM was read.
  std::optional<Eigen::AlignedBox3d> ray_box;
  // The sidecar's `dem_window` record: what was read and why.
  nlohmann::json dem_window = nullptr;
};

// The DEM window a fixed-size simulation of a DEM needs (PlanDemWindow).
struct DemWindowPlan {
  // A window was computed (width and height set, a DEM, the trace engine):
  // the ray box below is used whatever is read.
  bool applies = false;
  // The window, in the source raster's cells (first column, first row,
  // columns, rows), and whether it is read instead of the whole DEM (else
  // `reason` says why not).
  std::array<int, 4> window{0, 0, 0, 0};
  bool read_window = false;
  std::string reason;
  Eigen::AlignedBox3d ray_box;
  // Bounds used for the halo: ellipsoidal heights (metres) and the image
  // margin (pixels) and post margin.
  double z_low_m = 0.0, z_high_m = 0.0;
  int source_width = 0, source_height = 0;
  // The DEM as the planner opened it (set once it was opened): LoadTerrain
  // reads the window or the whole DEM from it without opening it again.
  std::optional<geo::DemFile> dem_file;
  nlohmann::json ToJson() const;
};
// The margins of a planned window (PlanDemWindow below).
inline constexpr int kDemWindowMarginPx = 4;
inline constexpr int kDemWindowMarginPosts = 4;

// Where the terrain comes from and how its heights are read (the fields of
// the same names in SimulateRequest, simulate.h, say what each means).
struct TerrainRequest {
  std::string dem;             // a DEM raster (any GDAL format and CRS) ...
  std::string scene;           // ... or a scene file of `gissar scene build`
  bool fill_nodata = false;    // fill DEM voids instead of failing
  int dem_oversample = 1;      // cubic refinement of the posts, [1, geo::kMaxDemOversample]
  std::string vertical_units;  // m, ft or us-ft; "" = the file's band unit or vertical CRS, else m
  std::string vertical_datum;  // ellipsoid, egm96, egm2008, EPSG:n; "" = the file's, else ellipsoid (warned)
  std::string sea = "auto";    // auto: DEM posts at or below sea_level_m joined to the border are sea; off
  double sea_level_m = 0.0;
  std::string materials;       // JSON of material overrides per class ("" = none)
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();
};

// How a DEM is meshed and centred for its user (a scene is used as built).
struct TerrainShape {
  // Only the DEM's posts, those outside the scene NaN, the sea as classes
  // of the grid's triangles (the raster engine); else a triangle mesh.
  bool posts_only = false;
  // Traced as a height field: a DEM without a collar keeps its grid's
  // triangles implicit, one with a collar marks its kept cells.
  bool heightfield = true;
  // The scene centre (default: the DEM's centre post), as lon, lat or map
  // coordinates of the DEM's CRS.
  std::optional<Eigen::Vector2d> center_lonlat;
  std::optional<Eigen::Vector2d> center_map;
  // The window a fixed-size image needs (PlanDemWindow); not `applies`: the
  // whole DEM.
  DemWindowPlan window;
};

// What a fixed-size image of a DEM asks of its window (the simulation's
// side of PlanDemWindow; pipeline/simulate.h DemWindowNeedsOf).
struct DemWindowNeeds {
  bool product_grid = false;             // rendered on a product's radar grid: no window
  bool raster_engine = false;            // the raster engine reads the whole grid
  sensor::SarGeometryOptions geometry;   // width and height 0: the image covers the whole DEM
  bool window_off = false;               // --dem-window off
  int bounces = 1;                       // > 1 with a mirror material: mirror paths reach anywhere
  bool reflectors = false;               // --reflectors given (may lie anywhere)
  bool contributions = false;            // --contributions given (returns from anywhere)
};

// Plans the DEM window of a fixed-size image of request.dem. Not `applies`
// without a width and height, for the raster engine, a scene or a product's
// radar grid (`reason` says which).
// The window holds every DEM post whose ENU position can project within
// kDemWindowMarginPx pixels of the image at any height between the DEM's
// bounds (geo::ReadDemInfo: exact lowest and highest heights, widened for
// the vertical datum and DEM refinement), every post that can shadow such
// a point (the line of sight towards the sensor up to the highest height),
// plus kDemWindowMarginPosts posts. The whole DEM is read instead (reason
// given) for --dem-window off, --sea auto on a DEM reaching the sea level
// (the sea is connected to the whole DEM's border), mirror paths (a material
// with a mirror share and --bounces > 1: a mirror ray may reach any
// terrain), reflectors and contributions (both may lie anywhere on the DEM),
// or a window that would be most of the DEM anyway.
// Throws the gissar::Error family (a bad centre: ConfigError naming
// --center or --center-map; the DEM: InputError naming the file).
DemWindowPlan PlanDemWindow(const TerrainRequest& request, const TerrainShape& shape, const DemWindowNeeds& needs);

// The DEM reading options of `request` meshed as `shape`: fill, collar left
// out, memory budget per post, vertical units.
geo::DemReadOptions DemReadOptionsOf(const TerrainRequest& request, const TerrainShape& shape);

// Reads request.dem (voids, datum to ellipsoidal heights, refinement, sea)
// into a mesh of `shape` in the ENU frame of the scene centre, or
// request.scene as built (its frame, centre, classes, materials and stored
// reflectors); then request.materials over the classes. Throws the
// gissar::Error family (InputError naming the file, ConfigError naming the
// flag, a job over the memory budget).
Terrain LoadTerrain(const TerrainRequest& request, const TerrainShape& shape = {},
                    Reporter& reporter = NullReporter());

// request.materials applied over `table` (the --materials rule: a DEM has
// the single class `default`). Throws ConfigError naming the file.
void ApplyMaterialsFile(material::MaterialTable& table, const TerrainRequest& request);

// {"datum": ..., "source": flag|file|assumed|scene (...)}: the sidecars'
// record of the DEM heights' vertical datum.
nlohmann::json VerticalDatumRecord(const Terrain& terrain);

// The reflectors of `reflectors_csv` (none for "") placed on the terrain
// surface in `embree` (apex = surface height at lon, lat + apex_height_m),
// ENU. Throws InputError naming the file and row for a reflector off the
// terrain.
std::vector<render::SceneReflector> PlaceReflectors(const std::string& reflectors_csv, const Terrain& terrain,
                                                    const render::EmbreeScene& embree);

// The surface height below ENU (x, y) (nullopt: off the terrain).
using SurfaceHeightAt = std::function<std::optional<double>(double x_m, double y_m)>;
// The surface of a mesh in `embree`: a vertical ray from above `top_z_m`.
SurfaceHeightAt EmbreeSurface(const render::EmbreeScene& embree, double top_z_m);
// The same with any surface (the raster engine's height field): the rows of
// `reflectors_csv` (none for "") in the ENU of `frame`.
std::vector<render::SceneReflector> PlaceReflectors(const std::string& reflectors_csv, const geo::LocalFrame& frame,
                                                    const SurfaceHeightAt& surface);
// Reflector rows placed on a surface (apex = surface height at lon, lat +
// apex_height_m, ENU of `frame`). Throws InputError naming `source` and the
// row for a reflector off the terrain.
std::vector<render::SceneReflector> PlaceReflectorRows(const std::vector<material::ReflectorSpec>& rows,
                                                       const std::string& source, const geo::LocalFrame& frame,
                                                       const SurfaceHeightAt& surface);
// A scene's stored reflectors as the renderers take them. Throws InputError
// naming `scene_path` for an unknown type.
std::vector<render::SceneReflector> StoredReflectors(const std::vector<scene::StoredReflector>& stored,
                                                     const std::string& scene_path);

}  // namespace gissar::pipeline
