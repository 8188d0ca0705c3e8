// `gissar scene build` and `gissar scene info`: a GIS scene (DEM + vector
// layers -> classified constrained triangulation) written to disk, and a
// summary of a scene file.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/util/reporter.h"
#include "gissar/util/memory_limit.h"

namespace gissar::pipeline {

struct SceneBuildRequest {
  std::string dem;                               // DEM raster
  bool fill_nodata = false;
  std::optional<std::array<int, 4>> window;      // col, row, cols, rows of the DEM
  std::vector<std::string> vectors;              // files whose layer names give classes
  std::string osm;                               // OSM file, built-in preset
  std::string config;                            // JSON scene config
  std::optional<Eigen::Vector2d> center_lonlat;  // scene centre (default DEM centre)
  std::string out_prefix;  // PREFIX.gscene, PREFIX.ply, PREFIX_classes.png, PREFIX_3d.png, PREFIX.json
  // Also PREFIX.obj + PREFIX.mtl (Wavefront, one material per class in the
  // class-map colours) for any 3-D viewer.
  bool export_obj = false;
  // Sea (--sea auto|off, --sea-level M): coastline layers, else DEM posts at
  // or below the sea level connected to the border (scene::SeaPostMask).
  std::string sea = "auto";
  double sea_level_m = 0.0;
  // DEM refinement before meshing (--dem-oversample, geo::RefineDem).
  int dem_oversample = 1;
  // Unit of the DEM's heights (--vertical-units): "" = from the file, m, ft or us-ft.
  std::string vertical_units;
  // Vertical datum of the DEM's heights (--vertical-datum, SimulateRequest's
  // rule): "" = from the file, else ellipsoid with a warning. The sea rule
  // uses the heights as given (orthometric); the mesh is then raised to
  // ellipsoidal heights, and the scene records the datum.
  std::string vertical_datum;
  // --flat-shading: no per-vertex shading normals (smooth terrain) in the scene.
  bool flat_shading = false;
  // Canonical reflectors (--reflectors FILE.csv, material/reflector.h):
  // placed on the scene's surface (apex = surface height at lon, lat +
  // apex_height_m, as `simulate --reflectors`) and stored in the .gscene,
  // so that `simulate --scene` renders them.
  std::string reflectors;
  // Memory budget (--max-memory), bytes: the DEM (window) is checked against
  // it before it is read.
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();

  // Throws ConfigError naming the option: DEM and output required, at most
  // one of --config / --osm / --vectors, a positive memory budget, and no
  // output (PREFIX.*) that would overwrite an input.
  void Check() const;
  // {snake_case field: value} of every field (scene_build_fields.h): the
  // sidecar's record; the keys are the flags' names (FlagOfField; export_obj
  // is --obj).
  nlohmann::json ToJson() const;
  // Sets the fields named by `values` ({field: value}, as ToJson writes; null
  // is "not set" for window and center_lonlat, else keeps the field's value).
  // Throws ConfigError naming the key and `source` (an options file,
  // "gissar.Scene.build keyword") for an unknown key, with "did you mean", or
  // a value of the wrong type or shape.
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};

struct SceneBuildResult {
  std::vector<std::filesystem::path> outputs;
  nlohmann::json summary;  // stats, warnings, timings, peak memory
};

// Builds and writes the scene (all outputs or none). Warnings (repaired
// geometries, empty layers, features outside the DEM) are printed as
// "gissar: warning: ..." lines on stderr and recorded in the JSON. Throws the
// gissar::Error family on failure.
// The georeference of a scene's PLY/OBJ meshes (PREFIX_mesh.json): the
// local ENU tangent frame on WGS84 at (lon0, lat0, height 0), x east, y
// north, z up, metres, and the PROJ pipeline taking mesh coordinates to
// WGS84 longitude/latitude (degrees) and ellipsoidal height (cct, or
// geo::ApplyProjPipeline).
nlohmann::json MeshCrsRecord(double origin_lon_deg, double origin_lat_deg);

SceneBuildResult RunSceneBuild(const SceneBuildRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

// Prints counts per class, extent, triangle count, memory and the stored
// reflectors of a scene file. Throws InputError for unreadable or invalid files.
void PrintSceneInfo(const std::string& scene_path, std::ostream& out);

// Parses "C,R,W,H" (integers); throws ConfigError naming `option`.
std::array<int, 4> ParseWindow(const std::string& text, const std::string& option);

}  // namespace gissar::pipeline
