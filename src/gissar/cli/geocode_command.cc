// `gissar geocode` flags (pipeline/geocode.h holds the request and the work).
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/pipeline/geocode.h"

namespace gissar::cli {

void AddGeocodeCommand(CLI::App& root, CommandRegistry& registry) {
  auto request = std::make_shared<pipeline::GeocodeRequest>();
  auto max_memory = std::make_shared<std::string>();
  CLI::App* cmd = root.add_subcommand(
      "geocode", "Terrain-corrected map-geometry image of a gissar slant-range image (exact back-geocoding on its terrain).");
  cmd->add_option("--image", request->image, "PREFIX.tif of `gissar simulate` (PREFIX.json, PREFIX_mask.tif beside it)")
      ->required();
  cmd->add_option("--dem", request->dem, "DEM whose heights replace the simulation's terrain (default: the sidecar's)");
  cmd->add_option("--vertical-datum", request->vertical_datum, pipeline::SimulateHelp("vertical_datum"));
  cmd->add_option("--crs", request->crs, "Output CRS, e.g. EPSG:32631 (projected; default: UTM zone of the scene centre)");
  cmd->add_option("--pixel-size", request->pixel_size_m, "Output pixel size, m (default: the image's larger spacing)");
  auto resampling = std::make_shared<std::string>(pipeline::kGeocodeResamplings.Name(request->resampling));
  cmd->add_option("--resampling", *resampling, pipeline::kGeocodeResamplings.Alternatives())->capture_default_str();
  cmd->add_option("--max-memory", *max_memory, "Memory budget, e.g. 4G (default: 3/4 of RAM)");
  cmd->add_option("--out", request->out_prefix, "Output prefix: PREFIX.tif (map geometry), PREFIX.json, PREFIX_stac.json")->required();
  registry.Add(cmd, [=](const CommandContext& context) {
    pipeline::GeocodeRequest resolved = *request;
    resolved.resampling = pipeline::kGeocodeResamplings.Parse(*resampling, "--resampling");
    RequirePositiveIfGiven(*cmd, "--pixel-size", resolved.pixel_size_m);
    resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
    const pipeline::GeocodeResult result = pipeline::RunGeocode(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
    // The CRS's name: "EPSG:n" as given, else the first quoted name of its WKT.
    std::string crs = result.crs;
    if (const size_t open = crs.find('"'); crs.rfind("EPSG:", 0) != 0 && open != std::string::npos) {
      crs = crs.substr(open + 1, crs.find('"', open + 1) - open - 1);
    }
    context.out << GeocodeHeadline({{"width", result.width}, {"height", result.height},
                                    {"pixel_size_m", result.geotransform.size() > 1 ? std::abs(result.geotransform[1]) : 0.0},
                                    {"crs", crs}, {"valid_pixels", result.valid_pixels}})
                << "\n";
  });
}

}  // namespace gissar::cli
