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

#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/simulate_help.h"
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

// Help of --max-memory, on every command that has a memory budget.
inline constexpr const char* kMaxMemoryHelp =
    "Memory budget, e.g. 4G (default: 3/4 of physical memory); larger jobs fail early";

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

// "3,5,7" -> {3, 5, 7}: a comma-separated list of integers given to `flag`;
// throws ConfigError naming `flag` (and `expected`, e.g. "two integers R,A")
// for an item that is not an integer, or when `count` > 0 items were
// expected and another number was given.
inline std::vector<int> ParseIntegerList(const std::string& text, const std::string& flag,
                                         const std::string& expected, size_t count = 0) {
  std::vector<int> values;
  std::istringstream in(text);
  std::string item;
  bool ok = true;
  while (ok && std::getline(in, item, ',')) {
    try {
      size_t used = 0;
      const int k = std::stoi(item, &used);
      ok = used == item.size();
      values.push_back(k);
    } catch (const std::exception&) {
      ok = false;
    }
  }
  if (!ok || values.empty() || (count > 0 && values.size() != count)) {
    throw ConfigError("needs " + expected + ", got '" + text + "'", flag);
  }
  return values;
}

// An on/off option: accepted as --NAME and --no-NAME (the last one given
// wins) on every command that has it, shown in --help as
// "--NAME, --no-NAME" with its real default ("(default: on)"), read from
// options files as a JSON boolean. `extra_negations` are older spellings of
// --no-NAME that keep working (e.g. "--fixed-sampling").
inline CLI::Option* AddSwitch(CLI::App* cmd, const std::string& name, bool& value, const std::string& help,
                              const std::string& extra_negations = "") {
  std::string names = "--" + name + ",!--no-" + name;
  if (!extra_negations.empty()) names += ",!" + extra_negations;
  return cmd->add_flag(names, value, help + (value ? " (default: on)" : " (default: off)"));
}

// A flag of a simulate request field (`field`, snake_case with its unit
// suffix): the flag is pipeline::FlagOfField(field) and the help text
// pipeline::SimulateHelp(field), the same in every command that offers it
// (simulate, sequence, ortho, validate, corridor). The default is shown when
// `show_default`.
template <class T>
CLI::Option* AddSimulateOption(CLI::App* cmd, const std::string& field, T& value, bool show_default = true) {
  CLI::Option* option = cmd->add_option(pipeline::FlagOfField(field), value, pipeline::SimulateHelp(field));
  if (show_default) option->capture_default_str();
  return option;
}
inline CLI::Option* AddSimulateSwitch(CLI::App* cmd, const std::string& field, bool& value,
                                      const std::string& extra_negations = "") {
  const std::string flag = pipeline::FlagOfField(field);
  return AddSwitch(cmd, flag.substr(2), value, pipeline::SimulateHelp(field), extra_negations);
}

// The help layout of every command: "--name, --no-name TYPE REQUIRED" on the
// left, the description with "(default: X)" on the right (CLI11's own shows
// "--no-x{false}" and "TYPE=X").
class HelpFormatter : public CLI::Formatter {
 public:
  std::string make_option_name(const CLI::Option* option, bool positional) const override;
  std::string make_option_opts(const CLI::Option* option) const override;
  std::string make_option_desc(const CLI::Option* option) const override;
};

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
// Declares `gissar pta` and `gissar polsar` (polarimetry_command.cc).
void AddPolarimetryCommands(CLI::App& root, CommandRegistry& registry);

}  // namespace gissar::cli
