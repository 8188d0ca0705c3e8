// `gissar simulate` flags, bound to SimulateRequest.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/simulate_door.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddSimulateCommand(CLI::App& root, CommandRegistry& registry) {
  auto options = std::make_shared<SimulateRequest>();
  CLI::App* cmd = root.add_subcommand(
      "simulate", "Simulate a SAR image (azimuth x slant range) of a DEM by ray tracing.");
  // Every field of the request's table that has a help text is a flag
  // (pipeline/simulate_fields.cc), in the table's order.
  auto flags = std::make_shared<RequestFlags<SimulateRequest>>(cmd, SimulateFields(), options.get());
  flags->AddAll({"out_prefix"});
  auto max_memory = std::make_shared<std::string>();
  cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);

  registry.Add(cmd, [=](const CommandContext& context) {
    SimulateRequest resolved = *options;
    flags->Apply(resolved);
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
    const SimulateResult result = RunSimulate(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });
}

}  // namespace gissar::cli
