// Flags of `gissar locate`, `gissar evaluate` and `gissar matchpair`.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/material/material.h"
#include "gissar/nav/matching.h"
#include "gissar/nav/product_locate.h"
#include "gissar/pipeline/evaluate_fields.h"
#include "gissar/pipeline/locate.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

namespace {

// The help of a flag `locate` shares with `evaluate` (a product's terrain
// and multilook, the matcher, the database): the evaluate table's text.
const std::string& SharedHelp(const std::string& field) { return EvaluateFields().at(field).help; }

// The flags `locate` and `evaluate` share for a product's terrain and
// multilook (LocateRequest and EvaluateRequest spell these fields alike).
void AddProductTerrainFlags(CLI::App* cmd, LocateRequest& o) {
  cmd->add_option("--looks-range", o.looks_range, SharedHelp("looks_range"))->capture_default_str();
  cmd->add_option("--looks-azimuth", o.looks_azimuth, SharedHelp("looks_azimuth"))->capture_default_str();
  cmd->add_option("--dem-oversample", o.dem_oversample, SharedHelp("dem_oversample"))->capture_default_str();
  cmd->add_option("--reflectors", o.reflectors, SharedHelp("reflectors"));
  cmd->add_option("--terrain-horizontal-sigma", o.terrain_horizontal_sigma_m,
                  SharedHelp("terrain_horizontal_sigma_m"))->capture_default_str();
  cmd->add_option("--sea", o.sea, SharedHelp("sea"))->capture_default_str();
}

}  // namespace

void AddNavCommands(CLI::App& root, CommandRegistry& registry) {
  {
    auto o = std::make_shared<LocateRequest>();
    CLI::App* cmd = root.add_subcommand(
        "locate", "Pose fix from one SAR image: match to simulated SAR at the INS prior, resect, iterate.");
    cmd->add_option("--image", o->image, "Observed image (GeoTIFF, band 1 linear intensity, GISSAR_* metadata)");
    cmd->add_option("--product", o->product,
                    "Or a real RSLC product (HDF5): fix its own track from a displaced prior (docs/navigation.md)");
    cmd->add_option("--orbit", o->orbit,
                    "Or any sensor's state vectors (CSV, JSON, ESA .EOF) of the --image, fixed like a product");
    cmd->add_option("--radar-grid", o->radar_grid, "Radar grid JSON of the --image (with --orbit)");
    cmd->add_option("--frequency", o->frequency, SharedHelp("frequency"))->capture_default_str();
    cmd->add_option("--polarization", o->polarization, SharedHelp("polarization"))->capture_default_str();
    cmd->add_option("--prior-offset-track", o->prior_offset_track,
                    "With --product: prior = annotated track moved ALONG,CROSS,UP metres (mid-scene velocity frame)")
        ->delimiter(',')->expected(3)->capture_default_str();
    cmd->add_option("--prior-heading-offset", o->prior_heading_offset_deg,
                    "With --product: and turned by this many degrees (clockwise)")->capture_default_str();
    cmd->add_option("--prior-sigma-horizontal", o->prior_sigma_horizontal_m,
                    "With --product: INS one-sigma horizontal error, m")->capture_default_str();
    cmd->add_option("--prior-sigma-vertical", o->prior_sigma_vertical_m,
                    "With --product: INS one-sigma vertical error, m")->capture_default_str();
    cmd->add_option("--prior-sigma-heading", o->prior_sigma_heading_deg,
                    "With --product: INS one-sigma track-angle error, deg")->capture_default_str();
    AddProductTerrainFlags(cmd, *o);
    cmd->add_option("--scene", o->scene, "Scene built by `gissar scene build`");
    cmd->add_option("--dem", o->dem, "Or a DEM (bare terrain)");
    cmd->add_option("--vertical-datum", o->vertical_datum, SharedHelp("vertical_datum"));
    cmd->add_option("--prior", o->prior, "Prior pose JSON (docs/navigation.md; with --image)");
    cmd->add_option("--out", o->out, "Output prefix: PREFIX.json (the fix)")->required();
    cmd->add_option("--composite", o->composite_png,
                    "PNG: observed (green) over simulated (magenta) at the prior and at the fix");
    cmd->add_option("--range-spacing", o->range_spacing_m, "Slant-range pixel spacing, m (default: image metadata)");
    cmd->add_option("--azimuth-spacing", o->azimuth_spacing_m, "Azimuth pixel spacing, m (default: image metadata)");
    cmd->add_option("--look", o->look,
                    sensor::kLookSides.Alternatives() + " (default: image metadata, else " +
                        sensor::ToString(sensor::LookSide::kRight) + ")");
    cmd->add_option("--matcher", o->matcher, SharedHelp("matcher"))->capture_default_str();
    cmd->add_option("--search", o->search_px, "First-iteration search radius, px (prior uncertainty)")->capture_default_str();
    cmd->add_option("--step", o->step_px, SharedHelp("step_px"))->capture_default_str();
    cmd->add_option("--dense-renders", o->dense_renders, SharedHelp("dense_renders"))->capture_default_str();
    cmd->add_option("--polish", o->polish_evaluations, SharedHelp("polish_evaluations"))->capture_default_str();
    cmd->add_option("--bounces", o->bounces, "Reflections per ray in the reference renders")->capture_default_str();
    cmd->add_option("--rays-per-cell", o->rays_per_cell, "Rays per cell in the reference renders")->capture_default_str();
    cmd->add_option("--database", o->database,
                    "Reference database PREFIX_catalog.json (gissar corridor, same --dem/--scene): match the stored "
                    "reference covering the prior, no rendering (docs/navigation.md)");
    cmd->add_option("--database-fallback", o->database_fallback,
                    "No stored reference covers the prior: none (no fix, exit 3) or render (on the fly)")
        ->capture_default_str();
    cmd->add_option("--database-heading-tolerance", o->database_heading_tolerance_deg,
                    SharedHelp("database_heading_tolerance_deg"))->capture_default_str();
    auto max_memory = std::make_shared<std::string>();
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    registry.Add(cmd, [=](const CommandContext& context) {
      LocateRequest resolved = *o;
      resolved.out = PrefixedOutput(o->out, ".json");
      resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
      const auto report = RunLocate(resolved, context.command_line, context.reporter);
      context.out << resolved.out << "\n";
      if (!resolved.composite_png.empty()) context.out << resolved.composite_png << "\n";
      context.out << LocateHeadline(report) << "\n";
      if (!report.at("converged").get<bool>()) context.no_result = report.at("reason").get<std::string>();
    });
  }
  {
    auto o = std::make_shared<EvaluateRequest>();
    CLI::App* cmd = root.add_subcommand(
        "evaluate", "Monte-Carlo evaluation of `locate`: success rate, position/heading errors, time per fix.");
    // Every field of the request's table that has a help text is a flag
    // (pipeline/evaluate_fields.cc), in the table's order.
    auto flags = std::make_shared<RequestFlags<EvaluateRequest>>(cmd, EvaluateFields(), o.get());
    for (const RequestField<EvaluateRequest>& field : EvaluateFields().fields()) {
      if (field.help.empty()) continue;
      CLI::Option* option = flags->Add(field.name);
      if (field.name == "out_prefix") option->required();
    }
    auto max_memory = std::make_shared<std::string>();
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    registry.Add(cmd, [=](const CommandContext& context) {
      EvaluateRequest r = *o;
      flags->Apply(r);
      r.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, r.max_memory_bytes);
      const auto summary = RunEvaluate(r, context.command_line, context.reporter);
      context.out << r.out_prefix << ".json\n" << r.out_prefix << "_trials.csv\n";
      if (r.product.empty()) context.out << r.out_prefix << "_hist.png\n";
      context.out << EvaluateHeadline(summary) << "\n";
    });
  }
  {
    auto o = std::make_shared<MatchPairRequest>();
    CLI::App* cmd = root.add_subcommand(
        "matchpair", "Recover a known affine warp between two real images with every matcher (RMS error, px).");
    cmd->add_option("--fixed", o->fixed, "Fixed image")->required();
    cmd->add_option("--moving", o->moving, "Moving image (same grid, another date)")->required();
    cmd->add_option("--warp", o->warp, "Known warp ROT_DEG,SCALE,TX,TY applied to the moving image")->delimiter(',')->expected(4)->capture_default_str();
    cmd->add_option("--patch", o->patch_px, "Patch side, px (odd)")->capture_default_str();
    cmd->add_option("--step", o->step_px, "Grid step, px")->capture_default_str();
    cmd->add_option("--search", o->search_px, "Search radius, px")->capture_default_str();
    cmd->add_option("--filter", o->filter_px, "Speckle box filter, px")->capture_default_str();
    cmd->add_option("--out", o->out, "Output prefix: PREFIX.json (errors per matcher)")->required();
    registry.Add(cmd, [=](const CommandContext& context) {
      MatchPairRequest resolved = *o;
      resolved.out = PrefixedOutput(o->out, ".json");
      RunMatchPair(resolved, context.command_line, context.reporter);
      context.out << resolved.out << "\n";
    });
  }
}

}  // namespace gissar::cli
