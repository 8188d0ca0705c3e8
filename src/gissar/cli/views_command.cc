// `gissar sequence` and `gissar ortho` flags.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/views.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds
namespace {

// Terrain and geometry flags shared with `simulate`, from its request's
// table (bound to `o`).
struct CommonFlags {
  std::shared_ptr<RequestFlags<SimulateRequest>> flags;
  std::shared_ptr<std::string> max_memory = std::make_shared<std::string>();
  CLI::App* app = nullptr;

  void Add(CLI::App* cmd, SimulateRequest& o, bool with_heading) {
    app = cmd;
    flags = std::make_shared<RequestFlags<SimulateRequest>>(cmd, SimulateFields(), &o);
    flags->Add({"dem", "scene", "fill_nodata", "vertical_datum"});
    if (with_heading) flags->Add("heading_deg")->required();
    flags->Add("depression_deg")->required();
    flags->Add({"look_side", "center_lonlat", "slant_range_m", "range_spacing_m", "azimuth_spacing_m"});
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    flags->Add({"rays_per_cell", "range_resolution_m", "azimuth_resolution_m", "psf_window", "speckle_looks",
                "seed"});
  }
  void Resolve(SimulateRequest& o, bool force) const {
    flags->Apply(o);
    RequirePositiveIfGiven(*app, "--range-spacing", o.geometry.range_spacing_m);
    RequirePositiveIfGiven(*app, "--azimuth-spacing", o.geometry.azimuth_spacing_m);
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
  sequence_flags->flags->Add("mode");
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
