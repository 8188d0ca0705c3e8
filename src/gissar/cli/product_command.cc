// `gissar validate` flags, bound to ValidateRequest (the --product flags of
// `gissar simulate` are declared in simulate_command.cc), or, for a
// Sentinel-1 SAFE, to Sentinel1ValidateRequest (the terrain-free geometry
// proof on the product's geolocation grids, pipeline/validate_sentinel1.h).
#include <memory>
#include <sstream>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/image/radiometry.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/product_simulate.h"
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
  auto looks = std::make_shared<std::string>("1,3,5");
  CLI::App* cmd = root.add_subcommand(
      "validate",
      "Simulate a real SAR product (NISAR RSLC HDF5, Sentinel-1 SAFE) and compare with its image (beta0, or "
      "--radiometry) and a "
      "reference geolocation; for a Sentinel-1 SAFE without --dem/--scene, check gissar's geometry against its "
      "geolocation grids.");
  cmd->add_option("--product", options->simulate.product,
                  "NISAR-format RSLC product (HDF5) or Sentinel-1 SAFE (directory, manifest.safe or .zip)")
      ->required();
  auto s1 = std::make_shared<Sentinel1ValidateRequest>();
  cmd->add_option("--orbit", s1->orbit,
                  "Sentinel-1: state vectors (EOF, CSV or JSON) replacing the annotations' orbit");
  cmd->add_option("--swath", s1->swath, "Sentinel-1: swath to check (IW1, ..., S3; default: every swath present)");
  cmd->add_option("--polarization", s1->polarization,
                  "Sentinel-1: polarisation to check (" + material::kPolarizations.List() +
                      "; default: every one present)");
  auto simulate_flags = std::make_shared<RequestFlags<SimulateRequest>>(cmd, SimulateFields(), &options->simulate);
  simulate_flags->Add({"dem", "scene", "fill_nodata", "dem_oversample", "vertical_units", "vertical_datum"});
  cmd->add_option("--reference-geolocation", options->reference_geolocation,
                  "Directory with a peer's per-pixel x.rdr, y.rdr, z.rdr (lon, lat, height; ISCE topo) and simamp.rdr");
  cmd->add_option("--looks", *looks, "Multilook sizes k of the k x k correlations, comma-separated")
      ->capture_default_str();
  simulate_flags->Add({"rays_per_cell", "bounces", "burst", "product_window_px"});
  // validate's default quantity is beta0 (a NISAR RSLC's |s|^2), not
  // simulate's sigma0: the flag's default is set before it is declared.
  options->simulate.radiometry = "beta0";
  simulate_flags->Add("radiometry")
      ->description("Quantity compared: the real image calibrated with a Sentinel-1 product's sigmaNought, "
                    "betaNought or gamma LUT, the simulation converted from beta0 with each pixel's ellipsoid "
                    "incidence: " + image::kRadiometries.Alternatives() + " (a NISAR product: beta0 only, its |s|^2)");
  AddSwitch(cmd, "noise-removal", options->noise_removal,
            "Sentinel-1: subtract the thermal noise power (noiseRangeLut, times noiseAzimuthLut where given) from the real image's "
            "|DN|^2 (negative: no-data)");
  cmd->add_option("--out", options->out_prefix,
                  "Output prefix: PREFIX.json, PREFIX.md, PREFIX_side_by_side.png, PREFIX_histogram.png (Sentinel-1: PREFIX.json)")
      ->required();

  auto max_memory = std::make_shared<std::string>();
  cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);

  registry.Add(cmd, [=](const CommandContext& context) {
    ValidateRequest resolved = *options;
    simulate_flags->Apply(resolved.simulate);
    resolved.radiometry = resolved.simulate.radiometry;  // beta0 unless --radiometry is given
    const bool terrain = !resolved.simulate.dem.empty() || !resolved.simulate.scene.empty();
    if (geo::IsSentinel1Path(resolved.simulate.product) && !terrain) {
      // Without terrain: the geometry against the product's geolocation grids.
      if (resolved.simulate.burst != 0) throw ConfigError("goes with --dem or --scene (a simulation)", "--burst");
      if (resolved.simulate.product_window_px) {
        throw ConfigError("goes with --dem or --scene (a simulation)", "--product-window");
      }
      if (cmd->count("--radiometry") > 0) throw ConfigError("goes with --dem or --scene (a simulation)", "--radiometry");
      if (resolved.noise_removal) throw ConfigError("goes with --dem or --scene (a simulation)", "--noise-removal");
      Sentinel1ValidateRequest request = *s1;
      request.product = options->simulate.product;
      request.out_prefix = options->out_prefix;
      const Sentinel1ValidateResult result = RunSentinel1Validate(request, context.command_line, context.reporter);
      for (const auto& path : result.outputs) context.out << path.string() << "\n";
      context.out << Sentinel1Headline(result.report) << "\n";
      return;
    }
    if (geo::IsSentinel1Path(resolved.simulate.product)) {
      // With terrain: the selection simulated and compared with the real image.
      resolved.simulate.swath = s1->swath;
      if (!s1->polarization.empty()) resolved.simulate.polarization = s1->polarization;
      resolved.simulate.orbit = s1->orbit;
    } else {
      for (const auto& [value, flag] : {std::pair{s1->orbit, "--orbit"}, {s1->swath, "--swath"},
                                        {s1->polarization, "--polarization"}}) {
        if (!value.empty()) throw ConfigError("only for a Sentinel-1 product", flag);
      }
    }
    resolved.simulate.max_memory_bytes =
        MemoryBudgetBytes(*max_memory, context.force, resolved.simulate.max_memory_bytes);
    resolved.looks = ParseIntegerList(*looks, "--looks", "integer multilook sizes");
    const ValidateResult result = RunValidate(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
    context.out << ValidateHeadline(result.report) << "\n";
  });
}

}  // namespace gissar::cli
