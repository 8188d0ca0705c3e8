// Flags of `gissar locate`, `gissar evaluate` and `gissar matchpair`.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/material/material.h"
#include "gissar/nav/matching.h"
#include "gissar/nav/product_locate.h"
#include "gissar/pipeline/locate.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

namespace {

// The help of --matcher: the scene matchers, then a product's.
std::string MatcherHelp() {
  return nav::kMatchers.Alternatives() + " (--product: " + nav::kShiftMatchers.Alternatives() + ")";
}
std::string ProductLayerHelp() { return "Product layer (" + material::kPolarizations.List() + ")"; }

// The flags `locate` and `evaluate` share for a product's terrain and
// multilook (LocateRequest and EvaluateRequest spell these fields alike).
template <class Request>
void AddProductTerrainFlags(CLI::App* cmd, Request& o) {
  cmd->add_option("--looks-range", o.looks_range, "With --product: range looks of the multilook")->capture_default_str();
  cmd->add_option("--looks-azimuth", o.looks_azimuth, "With --product: azimuth looks of the multilook")
      ->capture_default_str();
  cmd->add_option("--dem-oversample", o.dem_oversample, "Refine the DEM N x by cubic interpolation")->capture_default_str();
  cmd->add_option("--reflectors", o.reflectors,
                  "With --product: point landmarks, a reflectors CSV (type,lon,lat,apex_height_m,size_m,"
                  "boresight_azimuth_deg,boresight_elevation_deg): rendered in the references; one in the image "
                  "fixes along and cross track where the terrain is flat (up and heading from the prior)");
  cmd->add_option("--terrain-horizontal-sigma", o.terrain_horizontal_sigma_m,
                  "With --product: the DEM's/scene's absolute horizontal error, one sigma per axis, m; added to a "
                  "relief fix's along/cross variance (default: SRTM-class 1\" DEMs)")->capture_default_str();
  cmd->add_option("--sea", o.sea, "auto or off: the terrain's sea (auto: DEM cells at or below sea level "
                                  "connected to its border)")->capture_default_str();
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
    cmd->add_option("--frequency", o->frequency, "Product band, A or B")->capture_default_str();
    cmd->add_option("--polarization", o->polarization, ProductLayerHelp())->capture_default_str();
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
    cmd->add_option("--vertical-datum", o->vertical_datum, kVerticalDatumHelp);
    cmd->add_option("--prior", o->prior, "Prior pose JSON (docs/navigation.md; with --image)");
    cmd->add_option("--out", o->out, "Output prefix: PREFIX.json (the fix)")->required();
    cmd->add_option("--composite", o->composite_png,
                    "PNG: observed (green) over simulated (magenta) at the prior and at the fix");
    cmd->add_option("--range-spacing", o->range_spacing_m, "Slant-range pixel spacing, m (default: image metadata)");
    cmd->add_option("--azimuth-spacing", o->azimuth_spacing_m, "Azimuth pixel spacing, m (default: image metadata)");
    cmd->add_option("--look", o->look,
                    sensor::kLookSides.Alternatives() + " (default: image metadata, else " +
                        sensor::ToString(sensor::LookSide::kRight) + ")");
    cmd->add_option("--matcher", o->matcher, MatcherHelp())->capture_default_str();
    cmd->add_option("--search", o->search_px, "First-iteration search radius, px (prior uncertainty)")->capture_default_str();
    cmd->add_option("--step", o->step_px, "Grid step of the matched patches, px")->capture_default_str();
    cmd->add_option("--dense-renders", o->dense_renders,
                    "Renders of the dense stage (all-pixel fit with one gain per class; 0 = off)")->capture_default_str();
    cmd->add_option("--polish", o->polish_evaluations, "Nelder-Mead renders after convergence (0 = off)")->capture_default_str();
    cmd->add_option("--bounces", o->bounces, "Reflections per ray in the reference renders")->capture_default_str();
    cmd->add_option("--rays-per-cell", o->rays_per_cell, "Rays per cell in the reference renders")->capture_default_str();
    cmd->add_option("--database", o->database,
                    "Reference database PREFIX_catalog.json (gissar corridor, same --dem/--scene): match the stored "
                    "reference covering the prior, no rendering (docs/navigation.md)");
    cmd->add_option("--database-fallback", o->database_fallback,
                    "No stored reference covers the prior: none (no fix, exit 3) or render (on the fly)")
        ->capture_default_str();
    cmd->add_option("--database-heading-tolerance", o->database_heading_tolerance_deg,
                    "Largest heading difference between the prior and a stored reference, deg")->capture_default_str();
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
    auto compare = std::make_shared<bool>(true);
    CLI::App* cmd = root.add_subcommand(
        "evaluate", "Monte-Carlo evaluation of `locate`: success rate, position/heading errors, time per fix.");
    cmd->add_option("--scene", o->scene, "Scene built by `gissar scene build`");
    cmd->add_option("--dem", o->dem, "Or a DEM (bare terrain)");
    cmd->add_option("--vertical-datum", o->vertical_datum, kVerticalDatumHelp);
    cmd->add_option("--product", o->product,
                    "A real RSLC product (HDF5): trials displace its annotated track (docs/navigation.md)");
    cmd->add_option("--frequency", o->frequency, "Product band, A or B")->capture_default_str();
    cmd->add_option("--polarization", o->polarization, ProductLayerHelp())->capture_default_str();
    AddProductTerrainFlags(cmd, *o);
    cmd->add_option("--trials", o->trials, "Trials")->capture_default_str();
    cmd->add_option("--seed", o->seed, "Seed")->capture_default_str();
    cmd->add_option("--trial-first", o->trial_first,
                    "Run trials from this index (trial k depends only on the seed and k)")->capture_default_str();
    cmd->add_option("--trial-count", o->trial_count, "Run this many trials (-1: the rest)")->capture_default_str();
    cmd->add_option("--out", o->out_prefix, "Output prefix: PREFIX.json, PREFIX_trials.csv, PREFIX_hist.png")->required();
    cmd->add_option("--spacing", o->spacing_m, "Pixel spacing (range = azimuth), m: the resolution cell")->capture_default_str();
    cmd->add_option("--size", o->size_px, "Image side, pixels")->capture_default_str();
    cmd->add_option("--slant-range", o->slant_range_m, "Slant range to the image centre, m")->capture_default_str();
    cmd->add_option("--depression-min", o->depression_min_deg, "Smallest true depression, deg")->capture_default_str();
    cmd->add_option("--depression-max", o->depression_max_deg, "Largest true depression, deg")->capture_default_str();
    cmd->add_option("--looks", o->speckle_looks, "Speckle looks of the observed image (0 = none)")->capture_default_str();
    cmd->add_option("--nesz", o->nesz_db, "Thermal noise of the observed image, dB")->capture_default_str();
    cmd->add_option("--material-db", o->material_db, "Material mismatch, +- dB per class")->capture_default_str();
    cmd->add_option("--dem-smoothing", o->dem_smoothing, "Laplacian weight of the observed terrain heights")->capture_default_str();
    cmd->add_option("--prior-error-horizontal", o->prior_error_horizontal_m, "INS drift, +- m per horizontal axis (negative: 200, or the product footprint / 8)")->capture_default_str();
    cmd->add_option("--prior-error-vertical", o->prior_error_vertical_m, "INS drift, +- m vertical (negative: 50, or the horizontal / 8)")->capture_default_str();
    cmd->add_option("--prior-error-heading", o->prior_error_heading_deg, "INS heading drift, +- deg (negative: 3, or 0.05 on a product)")->capture_default_str();
    cmd->add_option("--success-cells", o->success_cells, "Success: position error at most this many cells")->capture_default_str();
    cmd->add_option("--success-heading-deg", o->success_heading_deg, "Success: and heading error at most this, deg")->capture_default_str();
    cmd->add_option("--matcher", o->matcher, MatcherHelp())->capture_default_str();
    AddSwitch(cmd, "compare", *compare, "Per-trial matcher comparison (--no-compare: skip it)");
    cmd->add_option("--search", o->search_px, "First-iteration search radius, px (0 = from the prior errors)")->capture_default_str();
    cmd->add_option("--step", o->step_px, "Grid step of the matched patches, px")->capture_default_str();
    cmd->add_option("--dense-renders", o->dense_renders,
                    "Renders of the dense stage (all-pixel fit with one gain per class; 0 = off)")->capture_default_str();
    cmd->add_option("--polish", o->polish_evaluations, "Nelder-Mead renders after convergence (0 = off)")->capture_default_str();
    cmd->add_option("--bounces", o->bounces, "Reflections per ray")->capture_default_str();
    cmd->add_option("--rays-per-cell", o->rays_per_cell, "Rays per cell")->capture_default_str();
    cmd->add_option("--database", o->database,
                    "Reference database PREFIX_catalog.json: trials around its stored poses, its image size and "
                    "spacing; fixes from the stored references (docs/navigation.md)");
    cmd->add_option("--database-fixes", o->database_fixes,
                    "With --database: stored (match the stored references) or render (on the fly, same images)")
        ->capture_default_str();
    cmd->add_option("--database-fallback", o->database_fallback,
                    "No stored reference covers the prior: none (no fix) or render (on the fly)")->capture_default_str();
    cmd->add_option("--database-heading-tolerance", o->database_heading_tolerance_deg,
                    "Largest heading difference between the prior and a stored reference, deg")->capture_default_str();
    auto floor = std::make_shared<bool>(true);
    AddSwitch(cmd, "reference-floor", *floor,
              "References with the observed noise floor (--nesz), or (--no-reference-floor) dark areas at -40 dB");
    auto max_memory = std::make_shared<std::string>();
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    registry.Add(cmd, [=](const CommandContext& context) {
      EvaluateRequest r = *o;
      r.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, r.max_memory_bytes);
      r.compare_matchers = *compare;
      r.reference_floor = *floor;
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
