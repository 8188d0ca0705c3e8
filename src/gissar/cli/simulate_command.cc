// `gissar simulate` flags, bound to SimulateRequest.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddSimulateCommand(CLI::App& root, CommandRegistry& registry) {
  auto options = std::make_shared<SimulateRequest>();
  auto center = std::make_shared<std::string>();
  auto center_map = std::make_shared<std::string>();
  // Enum fields are bound as their names (the default shown in --help) and
  // parsed with their tables when the command runs.
  auto mode = std::make_shared<std::string>(sensor::ToString(options->geometry.mode));
  auto look = std::make_shared<std::string>(sensor::ToString(options->geometry.look_side));
  auto engine = std::make_shared<std::string>(ToString(options->engine));
  CLI::App* cmd = root.add_subcommand(
      "simulate", "Simulate a SAR image (azimuth x slant range) of a DEM by ray tracing.");
  AddSimulateOption(cmd, "dem", options->dem, false);
  AddSimulateOption(cmd, "scene", options->scene, false);
  AddSimulateOption(cmd, "product", options->product, false);
  AddSimulateOption(cmd, "orbit", options->orbit, false);
  AddSimulateOption(cmd, "radar_grid", options->radar_grid, false);
  // Product selection (docs/conventions.md, "Products and sources"); not in
  // the shared help table: they have no meaning for the corridor.
  cmd->add_option("--frequency", options->frequency, "NISAR product: frequency band A or B (default: A)");
  cmd->add_option("--swath", options->swath,
                  "Sentinel-1 product: swath (IW1..IW3, EW1..EW5, S1..S6; default: the product's only swath)");
  cmd->add_option("--burst", options->burst,
                  "Sentinel-1 IW/EW SLC: burst N (1-based, per swath), simulated in its own zero-Doppler grid "
                  "(required for IW/EW SLC; a GRD or stripmap product has none)");
  auto product_window = std::make_shared<std::string>();
  cmd->add_option("--product-window", *product_window,
                  "Render a part of the product's grid: LINE,PIXEL,LINES,PIXELS in its own numbering (a burst's "
                  "lines and samples, a GRD's lines and ground-range pixels)");
  AddSimulateOption(cmd, "dem_oversample", options->dem_oversample);
  AddSimulateOption(cmd, "vertical_units", options->vertical_units, false);
  AddSimulateOption(cmd, "vertical_datum", options->vertical_datum, false);
  AddSimulateOption(cmd, "sea", options->sea);
  AddSimulateOption(cmd, "dem_window", options->dem_window);
  AddSimulateOption(cmd, "sea_level_m", options->sea_level_m);
  AddSimulateSwitch(cmd, "fill_nodata", options->fill_nodata);
  AddSimulateOption(cmd, "heading_deg", options->geometry.heading_deg, false);
  AddSimulateOption(cmd, "depression_deg", options->geometry.depression_deg, false);
  AddSimulateOption(cmd, "look_side", *look);
  AddSimulateOption(cmd, "center_lonlat", *center, false);
  AddSimulateOption(cmd, "center_map", *center_map, false);
  AddSimulateOption(cmd, "slant_range_m", options->geometry.slant_range_m);
  AddSimulateOption(cmd, "range_spacing_m", options->geometry.range_spacing_m, false);
  AddSimulateOption(cmd, "azimuth_spacing_m", options->geometry.azimuth_spacing_m, false);
  AddSimulateOption(cmd, "mode", *mode);
  AddSimulateOption(cmd, "width", options->geometry.width, false);
  AddSimulateOption(cmd, "height", options->geometry.height, false);
  AddSimulateOption(cmd, "engine", *engine);
  AddSimulateOption(cmd, "rays_per_cell", options->rays_per_cell);
  AddSimulateOption(cmd, "bounces", options->bounces);
  AddSimulateSwitch(cmd, "coherent", options->coherent);
  AddSimulateOption(cmd, "wavelength_m", options->wavelength_m);
  AddSimulateOption(cmd, "polarization", options->polarization);
  AddSimulateOption(cmd, "radiometry", options->radiometry);
  AddSimulateSwitch(cmd, "db", options->db);
  AddSimulateSwitch(cmd, "layers", options->layers);
  AddSimulateSwitch(cmd, "overviews", options->overviews);
  AddSimulateSwitch(cmd, "heightfield", options->heightfield);
  AddSimulateSwitch(cmd, "adaptive_sampling", options->adaptive_sampling, "--fixed-sampling");
  AddSimulateOption(cmd, "materials", options->materials, false);
  AddSimulateOption(cmd, "reflectors", options->reflectors, false);
  AddSimulateOption(cmd, "contributions", options->contributions, false);
  AddSimulateOption(cmd, "range_resolution_m", options->range_resolution_m, false);
  AddSimulateOption(cmd, "azimuth_resolution_m", options->azimuth_resolution_m, false);
  AddSimulateOption(cmd, "psf_window", options->psf_window);
  AddSimulateOption(cmd, "speckle_looks", options->speckle_looks);
  AddSimulateOption(cmd, "nesz_db", options->nesz_db, false);
  AddSimulateOption(cmd, "seed", options->seed);
  AddSimulateOption(cmd, "out_prefix", options->out_prefix, false)->required();
  auto max_memory = std::make_shared<std::string>();
  cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);

  registry.Add(cmd, [=](const CommandContext& context) {
    SimulateRequest resolved = *options;
    for (const char* flag : {"--heading", "--depression"}) {
      if (!resolved.UsesProductGeometry() && cmd->count(flag) == 0) throw ConfigError("is required", flag);
      if (resolved.UsesProductGeometry() && cmd->count(flag) > 0) {
        const std::string by = resolved.product.empty() ? "the orbit" : "the product";
        throw ConfigError(by + " fixes the geometry", std::string(resolved.product.empty() ? "--orbit/" : "--product/") + flag);
      }
    }
    RequirePositiveIfGiven(*cmd, "--range-spacing", resolved.geometry.range_spacing_m);
    RequirePositiveIfGiven(*cmd, "--azimuth-spacing", resolved.geometry.azimuth_spacing_m);
    resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
    resolved.geometry.mode = sensor::ParseProjectionMode(*mode);
    resolved.geometry.look_side = sensor::ParseLookSide(*look);
    resolved.engine = kSimulateEngines.Parse(*engine, "--engine");
    if (!product_window->empty()) resolved.product_window_px = ParseProductWindow(*product_window);
    if (!center->empty()) resolved.center_lonlat = ParseNumberPair(*center, "--center");
    if (!center_map->empty()) resolved.center_map = ParseNumberPair(*center_map, "--center-map");
    const SimulateResult result = RunSimulate(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });
}

}  // namespace gissar::cli
