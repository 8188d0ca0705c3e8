// The gissar executable: everything lives in the cli module.
#include <iostream>

#include "gissar/cli/cli.h"

int main(int argc, char** argv) { return gissar::cli::RunCli(argc, argv, std::cout, std::cerr); }
