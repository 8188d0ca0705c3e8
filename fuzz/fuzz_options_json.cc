// Fuzzes the options file of the command line (`--options FILE.json`,
// cli::ExpandOptionsFile: its keys become flags) on a command with flags of
// every kind the commands use (string, number, integer, list, switch, a
// switch with a --no- form, a nested command), then CLI11's parse of the
// result and the "did you mean" of a parse error, as cli.cc runs them: any
// bytes must give an expanded command line that keeps the command line's
// own flags, or a gissar::Error, never a crash, a hang or another exception
// (CLI11's ParseError is the command-line error cli.cc reports).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "fuzz_support.h"
#include "gissar/cli/command_line.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  CLI::App app("gissar");
  app.require_subcommand(1);
  CLI::App* simulate = app.add_subcommand("simulate", "simulate");
  std::string dem, out;
  double heading = 0.0, depression = 45.0;
  int looks = 1;
  std::vector<std::string> polarizations;
  std::vector<double> center;
  bool quiet = false, speckle = true;
  simulate->add_option("--dem", dem);
  simulate->add_option("--out", out);
  simulate->add_option("--heading", heading);
  simulate->add_option("--depression", depression)->check(CLI::Range(0.0, 90.0));
  simulate->add_option("--looks", looks);
  simulate->add_option("--polarizations", polarizations)->delimiter(',');
  simulate->add_option("--center-enu", center)->delimiter(',')->expected(3);
  simulate->add_flag("--quiet", quiet);
  simulate->add_flag("--speckle,!--no-speckle", speckle);
  CLI::App* scene = app.add_subcommand("scene", "scene");
  CLI::App* build = scene->add_subcommand("build", "build");
  std::string reflectors;
  build->add_option("--reflectors", reflectors);
  build->add_option("--dem", dem);

  const bool nested = size > 0 && (data[0] & 1) != 0;
  std::vector<std::string> args = {"gissar"};
  if (nested) {
    args.insert(args.end(), {"scene", "build", "--options", file.path(), "--dem", "own.tif"});
  } else {
    args.insert(args.end(), {"simulate", "--options", file.path(), "--heading", "12"});
  }
  try {
    gissar::cli::ExpandOptionsFile(app, args);
  } catch (const gissar::Error&) {
    return 0;
  }
  // The command words stay first and the command line's own flag wins.
  if (args.size() < 3 || args[0] != "gissar") std::abort();
  if (nested ? (args[1] != "scene" || args[2] != "build" || args[args.size() - 2] != "--dem")
             : (args[1] != "simulate" || args[args.size() - 2] != "--heading")) {
    std::abort();
  }
  std::vector<const char*> pointers;
  for (const std::string& a : args) pointers.push_back(a.c_str());
  try {
    app.parse(static_cast<int>(pointers.size()), pointers.data());
    if (nested ? dem != "own.tif" : heading != 12.0) std::abort();
  } catch (const CLI::ParseError&) {
    (void)gissar::cli::DidYouMean(app, args);
  }
  return 0;
}
