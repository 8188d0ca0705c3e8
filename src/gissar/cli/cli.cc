#include "gissar/cli/cli.h"

#include <exception>
#include <string>

#include "gissar/cli/command.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::cli {
namespace {

constexpr int kExitError = 2;

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

}  // namespace

int RunCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  InstallSignalCleanup();
  CLI::App app("gissar: simulate SAR images of real terrain from GIS data, and estimate an "
               "aircraft's pose from SAR images with an affine SAR camera model.",
               "gissar");
  app.set_version_flag("--version", VersionString());
  app.require_subcommand(1);
  CommandRegistry registry;
  AddSimulateCommand(app, registry);
  AddSceneCommands(app, registry);
  AddViewCommands(app, registry);
  AddMvgCommands(app, registry);
  AddNavCommands(app, registry);
  AddProductCommands(app, registry);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(e, out, err);
    }
    err << "gissar: error: " << OneLine(e.what()) << " (command line)\n";
    return kExitError;
  }
  try {
    registry.RunParsed(CommandContext{JoinCommandLine(argc, argv), out});
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
