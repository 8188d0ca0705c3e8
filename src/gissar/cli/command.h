// How subcommands plug into the gissar CLI: each command file provides an
// Add<Name>Command function that declares its flags on a CLI11 subcommand
// (bound to the fields of its options struct) and registers the action to
// run when that subcommand was given.
#pragma once

#include <functional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

namespace gissar::cli {

struct CommandContext {
  std::string command_line;  // the whole command line, for provenance
  std::ostream& out;         // results (paths, tables)
};

using CommandAction = std::function<void(const CommandContext&)>;

class CommandRegistry {
 public:
  void Add(CLI::App* subcommand, CommandAction action) {
    commands_.emplace_back(subcommand, std::move(action));
  }
  // Runs the action of the subcommand that was parsed; false when none was.
  bool RunParsed(const CommandContext& context) const {
    for (const auto& [app, action] : commands_) {
      if (app->parsed()) {
        action(context);
        return true;
      }
    }
    return false;
  }

 private:
  std::vector<std::pair<CLI::App*, CommandAction>> commands_;
};

// Declares `gissar simulate`.
void AddSimulateCommand(CLI::App& root, CommandRegistry& registry);
// Declares `gissar scene build` and `gissar scene info`.
void AddSceneCommands(CLI::App& root, CommandRegistry& registry);
// Declares `gissar sequence` and `gissar ortho`.
void AddViewCommands(CLI::App& root, CommandRegistry& registry);
// Declares `gissar fmatrix`, `resect`, `register` and `epipolar`.
void AddMvgCommands(CLI::App& root, CommandRegistry& registry);

}  // namespace gissar::cli
