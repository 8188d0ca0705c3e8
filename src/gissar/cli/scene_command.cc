// `gissar scene build` and `gissar scene info` flags; scene build's from its
// request's field table (pipeline/scene_build_fields.cc).
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/scene_build_fields.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddSceneCommands(CLI::App& root, CommandRegistry& registry) {
  CLI::App* scene = root.add_subcommand("scene", "Build GIS scenes and inspect scene files.");
  scene->require_subcommand(1);

  auto options = std::make_shared<SceneBuildRequest>();
  CLI::App* build = scene->add_subcommand(
      "build", "DEM + vector layers -> classified constrained Delaunay mesh (.gscene, .ply, class map).");
  // Every field of the request's table that has a help text is a flag
  // (pipeline/scene_build_fields.cc), in the table's order; --max-memory SIZE
  // is its own.
  auto flags = std::make_shared<RequestFlags<SceneBuildRequest>>(build, SceneBuildFields(), options.get());
  flags->AddAll({"dem", "out_prefix"});
  auto max_memory = std::make_shared<std::string>();
  build->add_option("--max-memory", *max_memory, kMaxMemoryHelp);
  registry.Add(build, [=](const CommandContext& context) {
    SceneBuildRequest resolved = *options;
    flags->Apply(resolved);
    resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
    const SceneBuildResult result = RunSceneBuild(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });

  auto info_path = std::make_shared<std::string>();
  CLI::App* info = scene->add_subcommand("info", "Counts per class, extent, triangles and memory of a scene.");
  info->add_option("scene", *info_path, "Scene file (.gscene)")->required();
  registry.Add(info, [=](const CommandContext& context) { PrintSceneInfo(*info_path, context.out); });
}

}  // namespace gissar::cli
