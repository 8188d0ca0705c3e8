// The gissar executable: everything lives in the cli module. `gissar
// corridor` is the Python package's command (Dask): it replaces this process.
#include <iostream>

#include "gissar/cli/cli.h"
#include "gissar/cli/corridor_command.h"

int main(int argc, char** argv) {
  if (gissar::cli::IsCorridorCommand(argc, argv)) return gissar::cli::ExecCorridor(argc, argv, std::cerr);
  return gissar::cli::RunCli(argc, argv, std::cout, std::cerr);
}
