#include "gissar/pipeline/scene_build_fields.h"

#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/simulate_fields.h"

namespace gissar::pipeline {
namespace {

using F = Fields<SceneBuildRequest>;
using R = SceneBuildRequest;

nlohmann::json WindowText(const std::string& text, const std::string& flag) {
  return nlohmann::json(ParseWindow(text, flag));
}

}  // namespace

// Fields in the order of `gissar scene build --help` (scene_build.h states what each means).
const FieldTable<SceneBuildRequest>& SceneBuildFields() {
  static const FieldTable<SceneBuildRequest> kTable(
      {
          F::Plain("dem", F::At(&R::dem), "DEM raster, any GDAL format and CRS", false),
          F::Plain("fill_nodata", F::At(&R::fill_nodata), SimulateHelp("fill_nodata")),
          F::OptionalWindow("window", F::At(&R::window), "DEM window COL,ROW,COLS,ROWS in cells (default: whole DEM)",
                            WindowText),
          F::Plain("vectors", F::At(&R::vectors),
                   "Vector files whose layer names say the class (water, forest, urban, roads, waterways, buildings)",
                   false),
          F::Plain("osm", F::At(&R::osm), "OpenStreetMap file (.osm.pbf, .osm, .osm.gz): built-in preset", false),
          F::Plain("config", F::At(&R::config), "Scene config JSON (layers, classes, widths, materials)", false),
          F::OptionalPair("center_lonlat", F::At(&R::center_lonlat), "Scene centre LON,LAT (default: DEM centre)",
                          NumberPairText),
          F::Plain("out_prefix", F::At(&R::out_prefix),
                   "Output prefix: PREFIX.gscene, PREFIX.ply, PREFIX_classes.png (class map), PREFIX_3d.png (3-D "
                   "view), PREFIX.json, PREFIX_mesh.json (the meshes' frame)",
                   false),
          F::Plain("export_obj", F::At(&R::export_obj),
                   "Also write PREFIX.obj + PREFIX.mtl (class colours) for 3-D viewers")
              .WithFlag("--obj"),
          F::Plain("sea", F::At(&R::sea),
                   "Sea: auto (coastline ways, else DEM at or below --sea-level connected to the border) or off",
                   false),
          F::Plain("sea_level_m", F::At(&R::sea_level_m),
                   "Sea level for --sea auto without coastline, metres (DEM heights; default 0)", false),
          F::Plain("vertical_units", F::At(&R::vertical_units),
                   "Unit of the DEM heights: m, ft or us-ft (default: the file's band unit or vertical CRS, else m)",
                   false),
          F::Plain("vertical_datum", F::At(&R::vertical_datum), SimulateHelp("vertical_datum"), false),
          F::Plain("dem_oversample", F::At(&R::dem_oversample),
                   "Refine the DEM N times (cubic) before meshing (default 1)", false),
          F::Plain("flat_shading", F::At(&R::flat_shading), "No smooth per-vertex shading normals on the terrain"),
          F::Plain("reflectors", F::At(&R::reflectors),
                   "Canonical reflectors CSV (type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,"
                   "boresight_elevation_deg): placed on the scene's surface and stored in the scene",
                   false),
          F::Plain("max_memory_bytes", F::At(&R::max_memory_bytes), "", false),
      },
      /*null_keeps_default=*/true);
  return kTable;
}

// The requests' JSON forms are their tables' (the request headers state the promises).
nlohmann::json SceneBuildRequest::ToJson() const { return SceneBuildFields().ToJson(*this); }

void SceneBuildRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  SceneBuildFields().ApplyJson(*this, values, source);
}

}  // namespace gissar::pipeline
