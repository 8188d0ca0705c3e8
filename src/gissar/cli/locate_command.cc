// Flags of `gissar locate`, `gissar evaluate` and `gissar matchpair`.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/cli/headline.h"
#include "gissar/pipeline/evaluate_fields.h"
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_door.h"
#include "gissar/pipeline/locate_fields.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddNavCommands(CLI::App& root, CommandRegistry& registry) {
  {
    auto o = std::make_shared<LocateRequest>();
    CLI::App* cmd = root.add_subcommand(
        "locate", "Pose fix from one SAR image: match to simulated SAR at the INS prior, resect, iterate.");
    // Every field of the request's table that has a help text is a flag
    // (pipeline/locate_fields.cc), in the table's order.
    auto flags = std::make_shared<RequestFlags<LocateRequest>>(cmd, LocateFields(), o.get());
    flags->AddAll({"out"});
    auto max_memory = std::make_shared<std::string>();
    cmd->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
    registry.Add(cmd, [=](const CommandContext& context) {
      LocateRequest resolved = *o;
      flags->Apply(resolved);
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
    flags->AddAll({"out_prefix"});
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
    auto flags = std::make_shared<RequestFlags<MatchPairRequest>>(cmd, MatchPairFields(), o.get());
    flags->AddAll({"fixed", "moving", "out"});
    registry.Add(cmd, [=](const CommandContext& context) {
      MatchPairRequest resolved = *o;
      flags->Apply(resolved);
      resolved.out = PrefixedOutput(o->out, ".json");
      RunMatchPair(resolved, context.command_line, context.reporter);
      context.out << resolved.out << "\n";
    });
  }
}

}  // namespace gissar::cli
