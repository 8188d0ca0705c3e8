// `gissar corridor`: the Dask-distributed reference-image database lives in
// the Python package (gissar.corridor, docs/distributed.md); this door runs
// `PYTHON -m gissar.corridor ARGS` in place of the gissar process, so the
// exit status, stdout and stderr are the Python command's.
#pragma once

#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace gissar::cli {

// True when the command word (argv[1]) is "corridor".
bool IsCorridorCommand(int argc, const char* const* argv);

// The directory holding the gissar Python package that belongs to the
// executable at `executable`: EXE_DIR/../python (the build tree: build/bin/gissar
// beside build/python/gissar) or EXE_DIR/../lib/python3/dist-packages (an
// installed prefix, `make install`), the first that holds gissar/corridor.py;
// nullopt when neither does (then the interpreter's own sys.path must find
// the package, e.g. after `pip install .`).
std::optional<std::filesystem::path> PythonPackageDir(const std::filesystem::path& executable);

// The interpreter: $GISSAR_PYTHON when set, else the Python the module was
// built for (CMake's Python_EXECUTABLE), else "python3" from PATH.
std::string CorridorPython();

// argv of the Python command: PYTHON -m gissar.corridor ARGS (argv[2:]).
std::vector<std::string> CorridorArguments(const std::string& python, int argc, const char* const* argv);

// Prepends PythonPackageDir(/proc/self/exe) to PYTHONPATH and execs the
// Python command. Returns only when the exec failed: prints one
// "gissar: error: ..." line on `err` and returns 2.
int ExecCorridor(int argc, const char* const* argv, std::ostream& err);

}  // namespace gissar::cli
