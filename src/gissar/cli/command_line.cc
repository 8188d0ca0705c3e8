#include "gissar/cli/command_line.h"

#include <algorithm>
#include <fstream>
#include <map>

#include <nlohmann/json.hpp>

#include "gissar/pipeline/field_names.h"
#include "gissar/util/error.h"

namespace gissar::cli {
namespace {

// Old flag spellings that keep working for one release (docs/conventions.md).
struct DeprecatedFlag {
  const char* old_name;
  const char* new_name;
};

constexpr DeprecatedFlag kDeprecatedFlags[] = {
    {"--range-res", "--range-spacing"},
    {"--azimuth-res", "--azimuth-spacing"},
    {"--range", "--slant-range"},
    {"--scene-centre", "--center-enu"},  // resect
    {"--prior-horizontal", "--prior-error-horizontal"},  // evaluate
    {"--prior-vertical", "--prior-error-vertical"},
    {"--prior-heading", "--prior-error-heading"},
    // fmatrix --res1/--res2 regroup their values, and fmatrix/resect --json
    // FILE named the JSON file itself (not a prefix): hidden options of
    // those commands (cli/mvg_command.cc) warn with DeprecationWarning.
};

// The command a command line names ("simulate", "scene build") and the
// index of its first argument after the command words.
std::pair<CLI::App*, size_t> LeafCommand(CLI::App& app, const std::vector<std::string>& args) {
  CLI::App* current = &app;
  size_t i = 1;
  while (i < args.size() && !args[i].empty() && args[i][0] != '-') {
    CLI::App* next = nullptr;
    for (CLI::App* sub : current->get_subcommands({})) {
      if (sub->get_name() == args[i]) next = sub;
    }
    if (next == nullptr) break;
    current = next;
    ++i;
  }
  return {current, i};
}

bool HasFlag(const std::vector<std::string>& args, const std::string& flag) {
  for (const std::string& a : args) {
    if (a == flag || a.rfind(flag + "=", 0) == 0) return true;
  }
  return false;
}

using pipeline::EditDistance;

// The deepest nesting of [ ] in `text`. CLI11 (2.1) expands a "[a,b]" value
// of a list flag recursively, copying the rest at each level: a value nested
// thousands deep takes gigabytes.
int BracketDepth(const std::string& text) {
  int depth = 0, deepest = 0;
  for (const char c : text) {
    if (c == '[') deepest = std::max(deepest, ++depth);
    if (c == ']' && depth > 0) --depth;
  }
  return deepest;
}

}  // namespace

std::string DeprecationWarning(const std::string& old_flag, const std::string& replacement) {
  return old_flag + " is deprecated and will be removed; use " + replacement;
}

std::vector<std::string> ReplaceDeprecatedFlags(int argc, const char* const* argv,
                                                std::vector<std::string>& warnings) {
  std::vector<std::string> args(argv, argv + argc);
  for (size_t i = 1; i < args.size(); ++i) {
    if (args[i] == "--") break;
    for (const DeprecatedFlag& d : kDeprecatedFlags) {
      const std::string old_name = d.old_name;
      if (args[i] == old_name || args[i].rfind(old_name + "=", 0) == 0) {
        args[i] = d.new_name + args[i].substr(old_name.size());
        warnings.push_back(DeprecationWarning(old_name, d.new_name));
      }
    }
  }
  return args;
}


namespace {

std::map<const CLI::App*, std::map<std::string, std::string>>& OptionKeyFlags() {
  static std::map<const CLI::App*, std::map<std::string, std::string>> flags;
  return flags;
}

// The flag an options-file key names on `command`.
std::string FlagOfOptionKey(const CLI::App* command, const std::string& key) {
  const auto by_command = OptionKeyFlags().find(command);
  if (by_command != OptionKeyFlags().end()) {
    const auto flag = by_command->second.find(key);
    if (flag != by_command->second.end()) return flag->second;
  }
  return pipeline::FlagOfField(key);
}

}  // namespace

void RegisterOptionKeyFlag(const CLI::App* command, const std::string& key, const std::string& flag) {
  OptionKeyFlags()[command][key] = flag;
}

void ClearOptionKeyFlags() { OptionKeyFlags().clear(); }

void ExpandOptionsFile(CLI::App& app, std::vector<std::string>& args) {
  std::string file;
  for (size_t i = 1; i < args.size(); ++i) {
    if (args[i] == "--options" && i + 1 < args.size()) {
      file = args[i + 1];
      args.erase(args.begin() + long(i), args.begin() + long(i) + 2);
      break;
    }
    if (args[i].rfind("--options=", 0) == 0) {
      file = args[i].substr(10);
      args.erase(args.begin() + long(i));
      break;
    }
  }
  if (file.empty()) return;
  std::ifstream in(file);
  if (!in) throw ConfigError("cannot read the options file", file);
  nlohmann::json values;
  try {
    values = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw ConfigError(std::string("options file is not valid JSON: ") + e.what(), file);
  }
  if (!values.is_object()) throw ConfigError("options file must hold a JSON object", file);
  auto [command, insert_at] = LeafCommand(app, args);
  std::vector<std::string> expanded;
  for (const auto& [key, value] : values.items()) {
    const std::string flag = FlagOfOptionKey(command, key);
    const CLI::Option* option = command->get_option_no_throw(flag);
    if (option == nullptr || key == "options") throw ConfigError("unknown key '" + key + "'", file);
    // A switch that is on by default has a negated form (--no-NAME).
    const std::string negated = "--no-" + flag.substr(2);
    if (HasFlag(args, flag) || HasFlag(args, negated) || value.is_null()) continue;
    if (value.is_boolean()) {
      if (value.get<bool>()) expanded.push_back(flag);
      else if (command->get_option_no_throw(negated) != nullptr) expanded.push_back(negated);
      continue;
    }
    std::string text;
    if (value.is_string()) {
      text = value.get<std::string>();
    } else if (value.is_array()) {
      for (const auto& item : value) {
        // A nested list or object is no flag value (and dumping a deeply
        // nested one would overflow the stack).
        if (!item.is_primitive() || item.is_null()) {
          throw ConfigError("key '" + key + "' must be a list of strings, numbers or booleans", file);
        }
        if (!text.empty()) text += ",";
        text += item.is_string() ? item.get<std::string>() : item.dump();
      }
    } else if (value.is_number()) {
      text = value.dump();
    } else {
      throw ConfigError("key '" + key + "' must be a string, number, boolean or list", file);
    }
    if (BracketDepth(text) > 1) {
      throw ConfigError("key '" + key + "' has nested [ ] (a list is [a,b] or a JSON list)", file);
    }
    expanded.push_back(flag);
    expanded.push_back(text);
  }
  args.insert(args.begin() + long(insert_at), expanded.begin(), expanded.end());
}

void CheckCommandWords(CLI::App& app, const std::vector<std::string>& args) {
  auto [command, next] = LeafCommand(app, args);
  if (command->get_subcommands({}).empty() || next >= args.size() || args[next].empty() ||
      args[next][0] == '-') {
    return;
  }
  std::string best;
  size_t best_distance = 3;  // at most 2 edits
  for (const CLI::App* sub : command->get_subcommands({})) {
    const size_t d = EditDistance(args[next], sub->get_name());
    if (d < best_distance) best_distance = d, best = sub->get_name();
  }
  throw ConfigError("unknown command '" + args[next] + "'" + (best.empty() ? "" : "; did you mean " + best + "?") +
                        " (`gissar --help` lists the commands)",
                    "command line");
}

std::string DidYouMean(CLI::App& app, const std::vector<std::string>& args) {
  auto [command, first] = LeafCommand(app, args);
  std::vector<std::string> names;
  for (const CLI::Option* option : command->get_options()) {
    for (const std::string& long_name : option->get_lnames()) names.push_back("--" + long_name);
  }
  for (const CLI::App* sub : command->get_subcommands({})) names.push_back(sub->get_name());
  for (size_t i = first; i < args.size(); ++i) {
    std::string word = args[i].substr(0, args[i].find('='));
    if (word.empty() || (word[0] == '-' && command->get_option_no_throw(word) != nullptr)) continue;
    if (i > first && word[0] != '-') continue;  // a value
    std::string best;
    size_t best_distance = 3;  // at most 2 edits
    for (const std::string& name : names) {
      const size_t d = EditDistance(word, name);
      if (d < best_distance) best_distance = d, best = name;
    }
    if (!best.empty()) return "; did you mean " + best + "?";
    return "";
  }
  return "";
}

}  // namespace gissar::cli
