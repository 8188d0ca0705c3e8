// The gissar executable: everything lives in the cli module. `gissar
// corridor` and `gissar view` are the Python package's commands (Dask; the
// map viewer's web server): they replace this process.
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

#include "gissar/cli/cli.h"
#include "gissar/cli/corridor_command.h"

namespace {

// `gissar view ARGS` runs the package's gissar/view.py in place of this
// process, as `gissar corridor` runs gissar.corridor (cli/corridor_command.h:
// the same package directory and interpreter). The file itself, not
// `-m gissar.view`: the server needs only the standard library, GDAL and
// NumPy, not the compiled core, so it runs after `make demo` (which builds
// the binary and the package's Python files, not the core). Without a
// package beside the binary (pip install), `PYTHON -m gissar.view ARGS`.
int ExecView(int argc, char** argv) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::string script;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    if (const auto dir = gissar::cli::PythonPackageDir(self)) {
      const char* old = std::getenv("PYTHONPATH");
      const std::string path = dir->string() + (old != nullptr && *old != '\0' ? ":" + std::string(old) : "");
      setenv("PYTHONPATH", path.c_str(), 1);
      if (fs::is_regular_file(*dir / "gissar" / "view.py", ec)) script = (*dir / "gissar" / "view.py").string();
    }
  }
  const std::string python = gissar::cli::CorridorPython();
  std::vector<std::string> args = {python};
  if (script.empty()) {
    args.insert(args.end(), {"-m", "gissar.view"});
  } else {
    args.push_back(script);
  }
  for (int i = 2; i < argc; ++i) args.emplace_back(argv[i]);
  std::vector<char*> pointers;
  for (std::string& a : args) pointers.push_back(a.data());
  pointers.push_back(nullptr);
  std::cerr.flush();
  execvp(python.c_str(), pointers.data());
  std::cerr << "gissar: error: cannot run " << python << ": " << std::strerror(errno)
            << " (view: needs Python 3 with the gissar package and python3-gdal; GISSAR_PYTHON names the "
               "interpreter)\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (gissar::cli::IsCorridorCommand(argc, argv)) return gissar::cli::ExecCorridor(argc, argv, std::cerr);
  if (argc >= 2 && std::strcmp(argv[1], "view") == 0) return ExecView(argc, argv);
  return gissar::cli::RunCli(argc, argv, std::cout, std::cerr);
}
