// Scene from GIS: DEM posts plus vector layers -> constrained Delaunay
// triangulation (CGAL) with a radar class per triangle, roads buffered into
// strips and buildings extruded (GEOS), in the scene's ENU frame.
//
// The 2-D work (repair, clipping, buffering, union, triangulation, areas)
// happens in a planar metric frame M: DEM cell coordinates mapped by the
// 2x2 Jacobian of (col, row) -> ENU (x, y) at the DEM centre, so DEM posts
// form an exact lattice and widths are in metres (to ~0.2 % over a
// 0.25-degree DEM, from the variation of cos(latitude)). Each vertex is then
// placed exactly: cell coordinates -> map -> WGS84 -> ENU at its height.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/scene/scene_config.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/reporter.h"

namespace gissar::scene {

struct GisSceneStats {
  int64_t features_read = 0;
  int64_t features_outside = 0;     // entirely outside the DEM: dropped
  int64_t repaired_geometries = 0;  // invalid geometries fixed by GEOS MakeValid
  int64_t simplified_outlines = 0;  // over-sampled outlines simplified to 1/1000 of a DEM cell
  int64_t buildings = 0;
  int64_t coastline_features = 0;     // coastline ways and island polygons read
  int64_t coastline_extended_ends = 0;  // chain ends inside the extent, extended to its edge
  double sea_trimmed_m2 = 0.0;        // sea beyond an extension that the DEM says is land, removed
  int64_t sea_level_vertices = 0;     // vertices of sea faces moved to the sea level
  bool sea_from_dem = false;         // the --sea auto fallback (no coastline) was applied
  int64_t outside_posts = 0;          // border-connected no-data posts left out of the scene
  int64_t dropped_faces = 0;          // triangles outside the valid area (and needles)
  int64_t sliver_faces = 0;           // faces narrower than 10 um in plan (rounding), not output
  int64_t steep_slivers = 0;          // terrain slivers < 10 cm wide, steeper than 80 deg: dropped
  int64_t needle_faces = 0;           // degenerate faces along the hull's lattice rows/columns, dropped
  int64_t merged_buildings = 0;       // footprints merged into a touching one of equal height
  int64_t step_walls = 0;             // edges between touching blocks of different roof heights
  int64_t buried_wall_triangles = 0;  // wall sections where the ground is above the roof (pit sides)
  int64_t constraint_segments = 0;
  int64_t dem_posts = 0;
  int64_t inserted_vertices = 0;    // vertices that are not DEM posts
  int64_t cdt_cells = 0;            // DEM cells triangulated by the CDT (those constraints touch)
  int64_t cdt_posts = 0;            // their posts
  int64_t grid_cells = 0;           // valid cells triangulated directly (two triangles each)
  int64_t cdt_rebuilds = 0;         // CDTs rebuilt because a constraint vertex split their border
  // Per class: area of its priority-resolved region (GEOS) and of its mesh
  // triangles, both in M (m^2). Walls have no plan area.
  std::array<double, kClassCount> region_area_m2{};
  std::array<double, kClassCount> mesh_area_m2{};
  std::array<int64_t, kClassCount> triangles{};
  double seconds = 0.0;
};

struct GisScene {
  TriangleMesh mesh;                    // ENU metres, class per triangle
  // The mesh starts with the DEM's posts and the directly split terrain cells
  // (TerrainTriangulation::kConstrainedCellsOnly), a terrain grid with the
  // other cells as holes; cells == 0 when it does not.
  GridPrefix grid;
  std::vector<Eigen::Vector2d> planar;  // M coordinates of each mesh vertex
  Eigen::Matrix2d planar_from_cell;     // M = planar_from_cell * (col, row)
  // Clipped class and building boundaries in M: every one is a union of mesh
  // edges (the constraint property).
  std::vector<std::array<Eigen::Vector2d, 2>> boundary_segments;
  std::vector<std::string> warnings;    // counted problems (repairs, empty layers, ...)
  GisSceneStats stats;
};

// How the terrain's DEM cells are triangulated.
enum class TerrainTriangulation {
  // Cells that a constraint touches go through the constrained Delaunay
  // triangulation (CGAL); every other cell lies inside one class region and
  // is split directly into MeshFromGrid's two triangles, the two parts
  // meeting edge to edge; the directly split terrain cells open the mesh as
  // a terrain grid (GisScene::grid). Time and memory grow with the
  // constraints, not with the DEM.
  kConstrainedCellsOnly,
  // Every post goes through the CDT (the reference for tests: the same
  // regions and areas, up to the diagonals CGAL picks); no terrain grid.
  kEveryPost,
};

// Builds the scene; stage lines go to `reporter` as Info. Throws
// InputError for unreadable vector sources or layers (naming file and layer)
// and ConfigError for invalid widths/heights; an empty layer, features
// outside the DEM and repaired geometries are warnings.
GisScene BuildGisScene(const geo::Dem& dem, const geo::LocalFrame& frame,
                       const SceneConfig& config, Reporter& reporter = NullReporter(),
                       TerrainTriangulation triangulation = TerrainTriangulation::kConstrainedCellsOnly);

// The --sea auto fallback for a DEM without coastline: 1 for posts whose
// height (taken as orthometric, the DEM's own datum) is at or below
// `sea_level_m`, not no-data, and 4-connected to a border post of that kind
// through such posts; a no-data post (dem.nodata_mask) becomes sea only when
// connected to a sea post (so voids on a landlocked DEM's border stay land).
// Row-major like dem.heights_m.
std::vector<uint8_t> SeaPostMask(const geo::Dem& dem, double sea_level_m);

// The posts outside the scene: no-data (dem.nodata_mask) 4-connected to the
// raster's border through no-data posts (the collar of a reprojected DEM,
// voids on its edge), unless they are sea posts (`sea_posts` from
// SeaPostMask, or empty). Row-major like dem.heights_m; empty when there is
// none. A grid cell is in the scene when none of its four posts is outside.
std::vector<uint8_t> OutsidePostMask(const geo::Dem& dem, const std::vector<uint8_t>& sea_posts);

// Sets class `sea` on default-class triangles whose three vertices are sea
// posts, for meshes whose vertex i is DEM post i (MeshFromGrid). Returns the
// number of triangles marked.
int64_t MarkSeaTriangles(TriangleMesh& mesh, const std::vector<uint8_t>& sea_posts);

// Building height from OSM-style tags: `height` (metres, "12", "12 m",
// "12.5m"), else `building:levels` times `level_height_m`, else
// `default_height_m`.
double BuildingHeight(const std::map<std::string, std::string>& tags, double default_height_m,
                      double level_height_m);

// Strip width of a line feature: a `width` tag (metres) wins, then the
// table by `highway` or `waterway` value, then `fallback_m`.
double LineWidth(const std::map<std::string, std::string>& tags,
                 const std::map<std::string, double>& table, double fallback_m);

}  // namespace gissar::scene
