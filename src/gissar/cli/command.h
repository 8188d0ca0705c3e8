// How subcommands plug into the gissar CLI: each command file provides an
// Add<Name>Command function that declares its flags on a CLI11 subcommand
// (bound to the fields of its options struct) and registers the action to
// run when that subcommand was given.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <iomanip>
#include <memory>
#include <optional>
#include <ostream>
#include <sstream>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <CLI/CLI.hpp>

#include "gissar/cli/command_line.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/simulate_fields.h"
#include "gissar/util/check.h"
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
  mutable std::optional<std::string> no_result = {};
};

using CommandAction = std::function<void(const CommandContext&)>;

// Throws ConfigError naming `flag` when the command line gave `flag` a
// value that is not > 0 (pixel spacings, where 0 means "automatic" only when
// the flag is omitted).
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

// ParseIntegerList (pipeline/field_names.h) for the flags still read here.
using pipeline::ParseIntegerList;

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

// The flags of a request's fields (pipeline/request_fields.h), declared from
// its table: the flag is the field's Flag(), the help its help text (with
// "(default: X)" when the field shows its default), a bool field an on/off
// switch (AddSwitch). Plain fields are bound to the request `target` points
// to (CLI11 converts and checks their values); the others (enums, pairs,
// windows) are kept as the text given and set by Apply() when the command
// runs, so that their errors name the flag as every ConfigError does.
// `target` must outlive the command line's parse (a member of the command's
// shared request).
// A text field's default as its flag would take it: a name as is, a list as
// "A,B,C", a number in its shortest form (0, 0.05).
inline std::string DefaultText(const nlohmann::json& value) {
  if (value.is_string()) return value.get<std::string>();
  if (value.is_array()) {
    std::string text;
    for (const nlohmann::json& item : value) text += (text.empty() ? "" : ",") + DefaultText(item);
    return text;
  }
  if (value.is_number_float()) {
    std::ostringstream text;
    text << std::setprecision(15) << value.get<double>();
    return text.str();
  }
  return value.dump();
}

template <class R>
class RequestFlags {
 public:
  RequestFlags(CLI::App* cmd, const pipeline::FieldTable<R>& table, R* target)
      : cmd_(cmd), table_(table), target_(target) {}

  // Declares the flag of field `name` (a name the table lacks is a bug).
  CLI::Option* Add(const std::string& name) {
    const pipeline::RequestField<R>& field = table_.at(name);
    const std::string flag = field.Flag();
    if (flag != pipeline::FlagOfField(name)) RegisterOptionKeyFlag(cmd_, name, flag);
    const pipeline::FieldRef ref = field.ref(*target_);
    if (bool* const* value = std::get_if<bool*>(&ref)) {
      return AddSwitch(cmd_, flag.substr(2), **value, field.help, field.extra_negations);
    }
    CLI::Option* option = std::visit(
        [&](auto pointer) -> CLI::Option* {
          if constexpr (std::is_same_v<decltype(pointer), std::monostate>) {
            auto& text = texts_.emplace_back(name, std::make_shared<std::string>()).second;
            CLI::Option* o = cmd_->add_option(Names(field), *text, field.help);
            if (field.show_default) o->default_str(DefaultText(field.get(*target_)));
            return o;
          } else {
            return cmd_->add_option(Names(field), *pointer, field.help);
          }
        },
        ref);
    if (field.show_default && !std::holds_alternative<std::monostate>(ref)) option->capture_default_str();
    return option;
  }
  void Add(std::initializer_list<const char*> names) {
    for (const char* name : names) Add(name);
  }
  // Declares the flag of every field of the table that has a help text (the
  // fields a door offers), in the table's order, and marks the fields named
  // in `required` required (a name that is not among them is a bug).
  void AddAll(std::initializer_list<std::string> required = {}) {
    size_t marked = 0;
    for (const pipeline::RequestField<R>& field : table_.fields()) {
      if (field.help.empty()) continue;
      CLI::Option* option = Add(field.name);
      if (std::find(required.begin(), required.end(), field.name) != required.end()) {
        option->required();
        ++marked;
      }
    }
    GISSAR_CHECK_MSG(marked == required.size(), "a required field has no flag in the table");
  }

  // Sets the text fields given on the command line into `request` (the
  // command's resolved copy); ConfigError naming the flag for a bad value.
  void Apply(R& request) const {
    for (const auto& [name, text] : texts_) {
      const pipeline::RequestField<R>& field = table_.at(name);
      const std::string flag = field.Flag();
      if (cmd_->count(flag) == 0) continue;
      field.set(request, field.from_text(*text, flag), flag, "command line");
    }
  }

 private:
  // The flag and its other spellings, as CLI11 takes them ("--multilook,--looks").
  static std::string Names(const pipeline::RequestField<R>& field) {
    return field.aliases.empty() ? field.Flag() : field.Flag() + "," + field.aliases;
  }

  CLI::App* cmd_;
  const pipeline::FieldTable<R>& table_;
  R* target_;
  std::vector<std::pair<std::string, std::shared_ptr<std::string>>> texts_;
};

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
