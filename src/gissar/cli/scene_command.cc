// `gissar scene build` and `gissar scene info` flags, bound to SceneBuildRequest.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/simulate.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddSceneCommands(CLI::App& root, CommandRegistry& registry) {
  CLI::App* scene = root.add_subcommand("scene", "Build GIS scenes and inspect scene files.");
  scene->require_subcommand(1);

  auto options = std::make_shared<SceneBuildRequest>();
  auto window = std::make_shared<std::string>();
  auto center = std::make_shared<std::string>();
  CLI::App* build = scene->add_subcommand(
      "build", "DEM + vector layers -> classified constrained Delaunay mesh (.gscene, .ply, class map).");
  build->add_option("--dem", options->dem, "DEM raster, any GDAL format and CRS")->required();
  AddSimulateSwitch(build, "fill_nodata", options->fill_nodata);
  build->add_option("--window", *window, "DEM window COL,ROW,COLS,ROWS in cells (default: whole DEM)");
  build->add_option("--vectors", options->vectors,
                    "Vector files whose layer names say the class (water, forest, urban, roads, "
                    "waterways, buildings)");
  build->add_option("--osm", options->osm, "OpenStreetMap file (.osm.pbf, .osm, .osm.gz): built-in preset");
  build->add_option("--config", options->config, "Scene config JSON (layers, classes, widths, materials)");
  build->add_option("--center", *center, "Scene centre LON,LAT (default: DEM centre)");
  build->add_option("--out", options->out_prefix,
                    "Output prefix: PREFIX.gscene, PREFIX.ply, PREFIX_classes.png (class map), PREFIX_3d.png (3-D view), PREFIX.json, PREFIX_mesh.json (the meshes' frame)")
      ->required();
  AddSwitch(build, "obj", options->export_obj, "Also write PREFIX.obj + PREFIX.mtl (class colours) for 3-D viewers");
  build->add_option("--sea", options->sea, "Sea: auto (coastline ways, else DEM at or below --sea-level connected to the border) or off");
  build->add_option("--sea-level", options->sea_level_m, "Sea level for --sea auto without coastline, metres (DEM heights; default 0)");
  build->add_option("--vertical-units", options->vertical_units,
                    "Unit of the DEM heights: m, ft or us-ft (default: the file's band unit or vertical CRS, else m)");
  build->add_option("--vertical-datum", options->vertical_datum, pipeline::SimulateHelp("vertical_datum"));
  build->add_option("--dem-oversample", options->dem_oversample, "Refine the DEM N times (cubic) before meshing (default 1)");
  AddSwitch(build, "flat-shading", options->flat_shading, "No smooth per-vertex shading normals on the terrain");
  build->add_option("--reflectors", options->reflectors,
                    "Canonical reflectors CSV (type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,"
                    "boresight_elevation_deg): placed on the scene's surface and stored in the scene");
  auto max_memory = std::make_shared<std::string>();
  build->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
  registry.Add(build, [=](const CommandContext& context) {
    SceneBuildRequest resolved = *options;
    resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
    if (!window->empty()) resolved.window = ParseWindow(*window, "--window");
    if (!center->empty()) resolved.center_lonlat = ParseNumberPair(*center, "--center");
    const SceneBuildResult result = RunSceneBuild(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });

  auto info_path = std::make_shared<std::string>();
  CLI::App* info = scene->add_subcommand("info", "Counts per class, extent, triangles and memory of a scene.");
  info->add_option("scene", *info_path, "Scene file (.gscene)")->required();
  registry.Add(info, [=](const CommandContext& context) { PrintSceneInfo(*info_path, context.out); });
}

}  // namespace gissar::cli
