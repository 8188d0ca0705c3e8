// `gissar geocode` flags, from the request's field table (pipeline/geocode.h
// holds the request and the work).
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/pipeline/geocode.h"
#include "gissar/pipeline/geocode_fields.h"

namespace gissar::cli {

void AddGeocodeCommand(CLI::App& root, CommandRegistry& registry) {
  auto request = std::make_shared<pipeline::GeocodeRequest>();
  auto max_memory = std::make_shared<std::string>();
  CLI::App* cmd = root.add_subcommand(
      "geocode", "Terrain-corrected map-geometry image of a gissar slant-range image (exact back-geocoding on its terrain).");
  // Every field of the request's table is a flag (pipeline/geocode_fields.cc),
  // in the table's order; --max-memory SIZE is its own.
  auto flags = std::make_shared<RequestFlags<pipeline::GeocodeRequest>>(cmd, pipeline::GeocodeFields(), request.get());
  flags->AddAll({"image", "out_prefix"});
  cmd->add_option("--max-memory", *max_memory, "Memory budget, e.g. 4G (default: 3/4 of RAM)");
  registry.Add(cmd, [=](const CommandContext& context) {
    pipeline::GeocodeRequest resolved = *request;
    flags->Apply(resolved);
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
