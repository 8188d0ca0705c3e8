// `gissar sequence` and `gissar ortho` flags.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/views.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds
namespace {

// Terrain and geometry flags shared with `simulate` (bound to `o`).
struct CommonFlags {
  std::shared_ptr<std::string> center = std::make_shared<std::string>();
  std::shared_ptr<std::string> mode = std::make_shared<std::string>("affine");
  std::shared_ptr<std::string> look = std::make_shared<std::string>("right");
  std::shared_ptr<std::string> max_memory = std::make_shared<std::string>();

  CLI::App* app = nullptr;

  void Add(CLI::App* cmd, SimulateRequest& o, bool with_heading) {
    app = cmd;
    cmd->add_option("--dem", o.dem, "DEM raster (or --scene)");
    cmd->add_option("--scene", o.scene, "Scene file from `gissar scene build`");
    cmd->add_flag("--fill-nodata", o.fill_nodata, "Fill DEM no-data cells");
    cmd->add_option("--vertical-datum", o.vertical_datum, kVerticalDatumHelp);
    if (with_heading) cmd->add_option("--heading", o.geometry.heading_deg, "Heading, degrees from north")->required();
    cmd->add_option("--depression", o.geometry.depression_deg, "Depression at the scene centre, degrees")->required();
    cmd->add_option("--look", *look, "right or left")->capture_default_str();
    cmd->add_option("--center", *center, "Scene centre LON,LAT");
    cmd->add_option("--slant-range", o.geometry.slant_range_m, "Slant range to the scene centre, m")->capture_default_str();
    cmd->add_option("--range-spacing", o.geometry.range_spacing_m, "Slant-range pixel spacing, m");
    cmd->add_option("--azimuth-spacing", o.geometry.azimuth_spacing_m, "Azimuth pixel spacing, m");
    cmd->add_option("--max-memory", *max_memory, "Memory budget, e.g. 4G (default: 3/4 of RAM)");
    cmd->add_option("--rays-per-cell", o.rays_per_cell, "Rays per resolution cell")->capture_default_str();
    cmd->add_option("--range-resolution", o.range_resolution_m, "3 dB range resolution, m (0 = none)");
    cmd->add_option("--azimuth-resolution", o.azimuth_resolution_m, "3 dB azimuth resolution, m (0 = none)");
    cmd->add_option("--psf-window", o.psf_window, "none, hamming or taylor")->capture_default_str();
    cmd->add_option("--speckle-looks", o.speckle_looks, "L-look speckle (0 = off)")->capture_default_str();
    cmd->add_option("--seed", o.seed, "Seed of speckle and noise")->capture_default_str();
  }
  void Resolve(SimulateRequest& o, bool force) const {
    RequirePositiveIfGiven(*app, "--range-spacing", o.geometry.range_spacing_m);
    RequirePositiveIfGiven(*app, "--azimuth-spacing", o.geometry.azimuth_spacing_m);
    o.geometry.mode = sensor::ParseProjectionMode(*mode);
    o.geometry.look_side = sensor::ParseLookSide(*look);
    if (!center->empty()) o.center_lonlat = ParseNumberPair(*center, "--center");
    o.max_memory_bytes = MemoryBudgetBytes(*max_memory, force, o.max_memory_bytes);
  }
};

}  // namespace

void AddViewCommands(CLI::App& root, CommandRegistry& registry) {
  auto sequence = std::make_shared<SequenceRequest>();
  auto sequence_flags = std::make_shared<CommonFlags>();
  CLI::App* seq = root.add_subcommand(
      "sequence", "Render a heading sequence (same depression and altitude) from one scene build.");
  sequence_flags->Add(seq, sequence->base, false);
  seq->add_option("--mode", *sequence_flags->mode, "affine or exact")->capture_default_str();
  seq->add_option("--heading-from", sequence->heading_from_deg, "First heading, degrees")->capture_default_str();
  seq->add_option("--heading-to", sequence->heading_to_deg, "Last heading, degrees")->capture_default_str();
  seq->add_option("--frames", sequence->frames, "Number of frames (>= 2)")->capture_default_str();
  seq->add_option("--frame-delay", sequence->frame_delay_cs, "GIF frame time, 1/100 s")->capture_default_str();
  seq->add_option("--out", sequence->base.out_prefix,
                  "Output prefix: PREFIX_fNN.tif/.png, PREFIX_contact.png, PREFIX.gif, PREFIX.json")
      ->required();
  registry.Add(seq, [=](const CommandContext& context) {
    SequenceRequest resolved = *sequence;
    sequence_flags->Resolve(resolved.base, context.force);
    const SequenceResult result = RunSequence(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });

  auto ortho = std::make_shared<OrthoRequest>();
  auto ortho_flags = std::make_shared<CommonFlags>();
  CLI::App* ort = root.add_subcommand(
      "ortho", "Orthographic views: along the line of sight, and the virtual camera G_perp, beside the SAR image.");
  ortho_flags->Add(ort, ortho->base, true);
  ort->add_option("--orthophoto", ortho->orthophoto, "RGB raster draped instead of class colours");
  ort->add_option("--out", ortho->base.out_prefix,
                  "Output prefix: PREFIX_los.png, PREFIX_sar.png, PREFIX_gperp.png, PREFIX_trio.png, PREFIX.json")
      ->required();
  registry.Add(ort, [=](const CommandContext& context) {
    OrthoRequest resolved = *ortho;
    ortho_flags->Resolve(resolved.base, context.force);
    for (const auto& path : RunOrtho(resolved, context.command_line, context.reporter)) context.out << path.string() << "\n";
  });
}

}  // namespace gissar::cli
