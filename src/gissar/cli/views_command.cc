// `gissar sequence` and `gissar ortho` flags, from their requests' tables
// (pipeline/views_fields.cc: simulate's terrain, geometry and sensor rows
// and their own).
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/views.h"
#include "gissar/pipeline/views_fields.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds
namespace {

// The flags of a view request R (its table's rows, `required` marked) and
// --max-memory; Resolve sets the text fields and the budget into a copy.
template <class R>
struct ViewFlags {
  std::shared_ptr<RequestFlags<R>> flags;
  std::shared_ptr<std::string> max_memory = std::make_shared<std::string>();
  CLI::App* app = nullptr;

  ViewFlags(CLI::App* cmd, const FieldTable<R>& table, R& request, std::initializer_list<std::string> required)
      : flags(std::make_shared<RequestFlags<R>>(cmd, table, &request)), app(cmd) {
    flags->AddAll(required);
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
  }
  void Resolve(R& request, bool force) const {
    flags->Apply(request);
    SimulateRequest& o = request.base;
    RequirePositiveIfGiven(*app, "--range-spacing", o.geometry.range_spacing_m);
    RequirePositiveIfGiven(*app, "--azimuth-spacing", o.geometry.azimuth_spacing_m);
    o.max_memory_bytes = MemoryBudgetBytes(*max_memory, force, o.max_memory_bytes);
  }
};

}  // namespace

void AddViewCommands(CLI::App& root, CommandRegistry& registry) {
  auto sequence = std::make_shared<SequenceRequest>();
  CLI::App* seq = root.add_subcommand(
      "sequence", "Render a heading sequence (same depression and altitude) from one scene build.");
  auto sequence_flags =
      std::make_shared<ViewFlags<SequenceRequest>>(seq, SequenceFields(), *sequence,
                                                   std::initializer_list<std::string>{"depression_deg", "out_prefix"});
  registry.Add(seq, [=](const CommandContext& context) {
    SequenceRequest resolved = *sequence;
    sequence_flags->Resolve(resolved, context.force);
    const SequenceResult result = RunSequence(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });

  auto ortho = std::make_shared<OrthoRequest>();
  CLI::App* ort = root.add_subcommand(
      "ortho", "Orthographic views: along the line of sight, and the virtual camera G_perp, beside the SAR image.");
  auto ortho_flags = std::make_shared<ViewFlags<OrthoRequest>>(
      ort, OrthoFields(), *ortho, std::initializer_list<std::string>{"heading_deg", "depression_deg", "out_prefix"});
  registry.Add(ort, [=](const CommandContext& context) {
    OrthoRequest resolved = *ortho;
    ortho_flags->Resolve(resolved, context.force);
    for (const auto& path : RunOrtho(resolved, context.command_line, context.reporter)) context.out << path.string() << "\n";
  });
}

}  // namespace gissar::cli
