// `gissar validate` flags, bound to ValidateRequest (the --product flags of
// `gissar simulate` are declared in simulate_command.cc).
#include <memory>
#include <sstream>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/pipeline/product_simulate.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddProductCommands(CLI::App& root, CommandRegistry& registry) {
  auto options = std::make_shared<ValidateRequest>();
  auto looks = std::make_shared<std::string>("1,3,5");
  CLI::App* cmd = root.add_subcommand(
      "validate",
      "Simulate a real SAR product (NISAR RSLC HDF5) and compare with its image and a reference geolocation.");
  cmd->add_option("--product", options->simulate.product, "NISAR-format RSLC product (HDF5)")->required();
  AddSimulateOption(cmd, "dem", options->simulate.dem, false);
  AddSimulateOption(cmd, "scene", options->simulate.scene, false);
  AddSimulateSwitch(cmd, "fill_nodata", options->simulate.fill_nodata);
  AddSimulateOption(cmd, "dem_oversample", options->simulate.dem_oversample);
  AddSimulateOption(cmd, "vertical_units", options->simulate.vertical_units, false);
  AddSimulateOption(cmd, "vertical_datum", options->simulate.vertical_datum, false);
  cmd->add_option("--reference-geolocation", options->reference_geolocation,
                  "Directory with a peer's per-pixel x.rdr, y.rdr, z.rdr (lon, lat, height; ISCE topo) and simamp.rdr");
  cmd->add_option("--looks", *looks, "Multilook sizes k of the k x k correlations, comma-separated")
      ->capture_default_str();
  AddSimulateOption(cmd, "rays_per_cell", options->simulate.rays_per_cell);
  AddSimulateOption(cmd, "bounces", options->simulate.bounces);
  cmd->add_option("--out", options->out_prefix,
                  "Output prefix: PREFIX.json, PREFIX.md, PREFIX_side_by_side.png, PREFIX_histogram.png")
      ->required();

  auto max_memory = std::make_shared<std::string>();
  cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);

  registry.Add(cmd, [=](const CommandContext& context) {
    ValidateRequest resolved = *options;
    resolved.simulate.max_memory_bytes =
        MemoryBudgetBytes(*max_memory, context.force, resolved.simulate.max_memory_bytes);
    resolved.looks = ParseIntegerList(*looks, "--looks", "integer multilook sizes");
    const ValidateResult result = RunValidate(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
    context.out << ValidateHeadline(result.report) << "\n";
  });
}

}  // namespace gissar::cli
