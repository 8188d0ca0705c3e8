// `gissar validate` flags, bound to ValidateRequest (the --product flags of
// `gissar simulate` are declared in simulate_command.cc), or, for a
// Sentinel-1 SAFE, to Sentinel1ValidateRequest (the terrain-free geometry
// proof on the product's geolocation grids, pipeline/validate_sentinel1.h).
#include <memory>
#include <sstream>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/validate_fields.h"
#include "gissar/pipeline/validate_sentinel1.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

namespace {

std::string Fixed3(double v) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(3);
  s << v;
  return s.str();
}

// "validate: Sentinel-1 geolocation grid, N points: range rms .. px (max ..), azimuth rms .. px (max ..),
// rdr2geo rms .. m (max ..): within targets | NOT within targets".
std::string Sentinel1Headline(const nlohmann::json& report) {
  const nlohmann::json& g = report.at("geolocation_grid");
  auto px = [&](const char* axis) {
    return "rms " + Fixed3(g.at(axis).at("rms").get<double>()) + " px (max " + Fixed3(g.at(axis).at("max").get<double>()) +
           ")";
  };
  return "validate: Sentinel-1 geolocation grid, " + std::to_string(g.at("points").get<int>()) + " points in " +
         std::to_string(report.at("swaths").size()) + " swath/polarisation(s): range " + px("range_px") + ", azimuth " +
         px("azimuth_px") + ", rdr2geo rms " + Fixed3(g.at("ground_m").at("rms").get<double>()) + " m (max " +
         Fixed3(g.at("ground_m").at("max").get<double>()) + "): " +
         (report.at("passed").get<bool>() ? "within targets" : "NOT within targets (see the JSON per swath)");
}

}  // namespace

void AddProductCommands(CLI::App& root, CommandRegistry& registry) {
  auto options = std::make_shared<ValidateRequest>();
  CLI::App* cmd = root.add_subcommand(
      "validate",
      "Simulate a real SAR product (NISAR RSLC HDF5, Sentinel-1 SAFE) and compare with its image (beta0, or "
      "--radiometry) and a "
      "reference geolocation; for a Sentinel-1 SAFE without --dem/--scene, check gissar's geometry against its "
      "geolocation grids.");
  // Every field of the request's table is a flag (pipeline/validate_fields.cc), in the table's order.
  auto flags = std::make_shared<RequestFlags<ValidateRequest>>(cmd, ValidateFields(), options.get());
  flags->AddAll({"product", "out_prefix"});

  auto max_memory = std::make_shared<std::string>();
  cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);

  registry.Add(cmd, [=](const CommandContext& context) {
    ValidateRequest resolved = *options;
    flags->Apply(resolved);
    resolved.simulate.radiometry = resolved.radiometry;
    const bool terrain = !resolved.simulate.dem.empty() || !resolved.simulate.scene.empty();
    if (geo::IsSentinel1Path(resolved.simulate.product) && !terrain) {
      // Without terrain: the geometry against the product's geolocation grids.
      if (resolved.simulate.burst != 0) throw ConfigError("goes with --dem or --scene (a simulation)", "--burst");
      if (resolved.simulate.product_window_px) {
        throw ConfigError("goes with --dem or --scene (a simulation)", "--product-window");
      }
      if (cmd->count("--radiometry") > 0) throw ConfigError("goes with --dem or --scene (a simulation)", "--radiometry");
      if (resolved.noise_removal) throw ConfigError("goes with --dem or --scene (a simulation)", "--noise-removal");
      Sentinel1ValidateRequest request;
      request.product = resolved.simulate.product;
      request.orbit = resolved.simulate.orbit;
      request.swath = resolved.simulate.swath;
      request.polarization = resolved.polarization;
      request.out_prefix = resolved.out_prefix;
      const Sentinel1ValidateResult result = RunSentinel1Validate(request, context.command_line, context.reporter);
      for (const auto& path : result.outputs) context.out << path.string() << "\n";
      context.out << Sentinel1Headline(result.report) << "\n";
      return;
    }
    if (geo::IsSentinel1Path(resolved.simulate.product)) {
      // With terrain: the selection simulated and compared with the real image.
      if (!resolved.polarization.empty()) resolved.simulate.polarization = resolved.polarization;
    } else {
      for (const auto& [value, flag] : {std::pair{resolved.simulate.orbit, "--orbit"},
                                        {resolved.simulate.swath, "--swath"},
                                        {resolved.polarization, "--polarization"}}) {
        if (!value.empty()) throw ConfigError("only for a Sentinel-1 product", flag);
      }
    }
    resolved.simulate.max_memory_bytes =
        MemoryBudgetBytes(*max_memory, context.force, resolved.simulate.max_memory_bytes);
    const ValidateResult result = RunValidate(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
    context.out << ValidateHeadline(result.report) << "\n";
  });
}

}  // namespace gissar::cli
