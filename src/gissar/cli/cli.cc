#include "gissar/cli/cli.h"

#include <unistd.h>

#include <exception>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tbb/global_control.h>

#include "gissar/cli/command.h"
#include "gissar/cli/command_line.h"
#include "gissar/cli/terminal_reporter.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/provenance.h"

namespace gissar::cli {
namespace {

constexpr int kExitError = 2;
constexpr int kExitNoResult = 3;  // the result file says converged: false and why

std::string JoinCommandLine(int argc, const char* const* argv) {
  std::string line;
  for (int i = 0; i < argc; ++i) {
    if (i > 0) line += ' ';
    line += argv[i];
  }
  return line;
}

// One line, no trailing newline inside the message.
std::string OneLine(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

// Flags every command takes (docs/conventions.md, "Common flags").
struct CommonFlags {
  bool quiet = false;
  std::string log_level = std::string(kLogLevels.Name(LogLevel::kInfo));
  int threads = 0;  // 0 = all cores
  bool force = false;
  std::string options_file;  // expanded before parsing (ExpandOptionsFile)
};

// Adds the common flags to every command that runs something (the leaves
// of the command tree: `scene build`, not `scene`).
void AddCommonFlags(CLI::App& app, CommonFlags& flags) {
  for (CLI::App* sub : app.get_subcommands({})) {
    if (!sub->get_subcommands({}).empty()) {
      AddCommonFlags(*sub, flags);
      continue;
    }
    if (sub->get_name() == "corridor") continue;  // its own flags (the Python command)
    AddSwitch(sub, "quiet", flags.quiet, "Only warnings and errors on stderr (same as --log-level warning)");
    sub->add_option("--log-level", flags.log_level, kLogLevels.Alternatives())->capture_default_str();
    sub->add_option("--threads", flags.threads, "Worker threads (default: all cores)")
        ->check(CLI::NonNegativeNumber);
    AddSwitch(sub, "force", flags.force, "Run even when the job exceeds the memory budget (--max-memory) or the 2^28-pixel image limit");
    sub->add_option("--options", flags.options_file,
                    "JSON file of options: keys are the snake_case field names (docs/conventions.md); "
                    "flags on the command line win");
  }
}

}  // namespace

std::string HelpFormatter::make_option_name(const CLI::Option* option, bool positional) const {
  if (positional) return CLI::Formatter::make_option_name(option, positional);
  std::string names;
  for (const std::string& s : option->get_snames()) names += (names.empty() ? "-" : ", -") + s;
  for (const std::string& l : option->get_lnames()) names += (names.empty() ? "--" : ", --") + l;
  return names;
}

std::string HelpFormatter::make_option_opts(const CLI::Option* option) const {
  std::string text;
  if (option->get_type_size() != 0) {
    if (!option->get_type_name().empty()) text += " " + get_label(option->get_type_name());
    if (option->get_expected_max() == CLI::detail::expected_max_vector_size) text += " ...";
    if (option->get_required()) text += " " + get_label("REQUIRED");
  }
  if (!option->get_excludes().empty()) {
    text += " " + get_label("Excludes") + ":";
    for (const CLI::Option* other : option->get_excludes()) text += " " + other->get_name();
  }
  return text;
}

std::string HelpFormatter::make_option_desc(const CLI::Option* option) const {
  std::string text = option->get_description();
  if (option->get_type_size() != 0 && !option->get_default_str().empty()) {
    text += " (default: " + option->get_default_str() + ")";
  }
  return text;
}

int64_t MemoryBudgetBytes(const std::string& max_memory_flag, bool force, int64_t fallback_bytes) {
  const int64_t budget = max_memory_flag.empty() ? fallback_bytes : ParseByteSize(max_memory_flag, "--max-memory");
  return force ? std::numeric_limits<int64_t>::max() : budget;
}

int RunCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  InstallSignalCleanup();
  CLI::App app("gissar: simulate SAR images of real terrain from GIS data, and estimate an "
               "aircraft's pose from SAR images with an affine SAR camera model.",
               "gissar");
  app.set_version_flag("--version", VersionString());
  app.require_subcommand(1);
  app.formatter(std::make_shared<HelpFormatter>());  // before the commands: they inherit it
  CommandRegistry registry;
  ClearOptionKeyFlags();
  AddSimulateCommand(app, registry);
  AddSceneCommands(app, registry);
  AddViewCommands(app, registry);
  AddMvgCommands(app, registry);
  AddNavCommands(app, registry);
  AddProductCommands(app, registry);
  AddGeocodeCommand(app, registry);
  AddPolarimetryCommands(app, registry);
  // `gissar corridor` runs the Python package's command in place of this
  // process (apps/gissar_main.cc) before this parser sees it; listed here so
  // that `gissar --help` names every command.
  app.add_subcommand("corridor",
                     "Build a reference-image database along a route on Dask: one simulated image per pose and "
                     "heading (gissar corridor --help; docs/distributed.md).")
      ->allow_extras();
  // `gissar view` likewise runs the Python package's web server (gissar.view; docs/view.md).
  app.add_subcommand("view",
                     "Show a corridor catalogue, a simulation or a pose fix on a map in the browser: a local web "
                     "server (gissar view PATH [--port N] [--host ADDR] [--no-browser]; docs/view.md).")
      ->allow_extras();
  CommonFlags common;
  AddCommonFlags(app, common);

  std::vector<std::string> deprecation_warnings;
  std::vector<std::string> args = ReplaceDeprecatedFlags(argc, argv, deprecation_warnings);
  try {
    CheckCommandWords(app, args);
    ExpandOptionsFile(app, args);
  } catch (const Error& e) {
    err << "gissar: error: " << OneLine(e.what()) << "\n";
    return kExitError;
  }
  std::vector<const char*> arg_pointers;
  for (const std::string& a : args) arg_pointers.push_back(a.c_str());
  std::unique_ptr<TerminalReporter> reporter;
  std::optional<tbb::global_control> thread_limit;
  try {
    app.parse(static_cast<int>(arg_pointers.size()), arg_pointers.data());
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(e, out, err);
    }
    err << "gissar: error: " << OneLine(e.what()) << DidYouMean(app, args) << " (command line)\n";
    return kExitError;
  }
  try {
    const LogLevel level = common.quiet ? LogLevel::kWarning : ParseLogLevel(common.log_level);
    reporter = std::make_unique<TerminalReporter>(stderr, level, isatty(STDERR_FILENO) == 1);
    for (const std::string& w : deprecation_warnings) reporter->Warn(w);
    if (common.threads > 0) {
      thread_limit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(common.threads));
    }
    const CommandContext context{JoinCommandLine(argc, argv), out, *reporter, common.force};
    registry.RunParsed(context);
    if (context.no_result) {
      err << "gissar: no result: " << OneLine(*context.no_result) << "\n";
      return kExitNoResult;
    }
  } catch (const Error& e) {
    err << "gissar: error: " << OneLine(e.what()) << "\n";
    return kExitError;
  } catch (const std::bad_alloc&) {
    err << "gissar: error: out of memory (reduce the scene: a window or coarser spacing)\n";
    return kExitError;
  } catch (const std::exception& e) {
    err << "gissar: error: " << OneLine(e.what()) << " (internal)\n";
    return kExitError;
  }
  return 0;
}

}  // namespace gissar::cli
