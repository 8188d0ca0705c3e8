// How subcommands plug into the gissar CLI: each command file provides an
// Add<Name>Command function that declares its flags on a CLI11 subcommand
// (bound to the fields of its options struct) and registers the action to
// run when that subcommand was given.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <ostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "gissar/util/error.h"
#include "gissar/util/reporter.h"

namespace gissar::cli {

struct CommandContext {
  std::string command_line;  // the whole command line, for provenance
  std::ostream& out;         // results (paths, tables)
  Reporter& reporter;        // progress, information, warnings (terminal_reporter.h)
  bool force = false;        // --force: run jobs over the memory budget
  // Set by a command that ran to the end and wrote its result file but found
  // no result (a pose fix that did not converge): the reason, for exit status 3.
  mutable std::optional<std::string> no_result;
};

using CommandAction = std::function<void(const CommandContext&)>;

// Throws ConfigError naming `flag` when the command line gave `flag` a
// value that is not > 0 (pixel spacings, where 0 means "automatic" only when
// the flag is omitted).
// Help of --vertical-datum, on every command that reads a DEM.
inline constexpr const char* kVerticalDatumHelp =
    "Datum of the DEM heights: ellipsoid, egm96, egm2008 or EPSG:n of a vertical CRS (default: the file's "
    "vertical CRS, else ellipsoid with a warning)";

inline void RequirePositiveIfGiven(const CLI::App& cmd, const std::string& flag, double value) {
  if (cmd.count(flag) > 0 && !(value > 0.0)) {
    std::ostringstream text;
    text << "must be a positive number, got " << value;
    throw ConfigError(text.str(), flag);
  }
}

// The memory budget of a job: --max-memory when given (throws ConfigError
// naming it when malformed), else the default; --force lifts it.
int64_t MemoryBudgetBytes(const std::string& max_memory_flag, bool force, int64_t fallback_bytes);

// `--out PREFIX` of a command that writes one file: PREFIX + extension. A
// value that already ends with the extension names that file (the older
// spelling, a path, keeps working).
inline std::string PrefixedOutput(const std::string& prefix, const std::string& extension) {
  if (prefix.size() > extension.size() &&
      prefix.compare(prefix.size() - extension.size(), extension.size(), extension) == 0) {
    return prefix;
  }
  return prefix + extension;
}

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

// Declares `gissar locate`, `evaluate` and `matchpair` (locate_command.cc).
void AddNavCommands(CLI::App& root, CommandRegistry& registry);
// Declares `gissar validate` (product_command.cc).
void AddProductCommands(CLI::App& root, CommandRegistry& registry);
// Declares `gissar geocode` (geocode_command.cc).
void AddGeocodeCommand(CLI::App& root, CommandRegistry& registry);

}  // namespace gissar::cli
