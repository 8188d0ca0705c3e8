#include "gissar/cli/corridor_command.h"

#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>

namespace gissar::cli {
namespace fs = std::filesystem;

bool IsCorridorCommand(int argc, const char* const* argv) {
  return argc >= 2 && std::strcmp(argv[1], "corridor") == 0;
}

std::optional<fs::path> PythonPackageDir(const fs::path& executable) {
  const fs::path bin = executable.parent_path();
  for (const fs::path& candidate : {bin / ".." / "python", bin / ".." / "lib" / "python3" / "dist-packages"}) {
    std::error_code ec;
    if (fs::is_regular_file(candidate / "gissar" / "corridor.py", ec)) return fs::weakly_canonical(candidate, ec);
  }
  return std::nullopt;
}

std::string CorridorPython() {
  if (const char* python = std::getenv("GISSAR_PYTHON"); python != nullptr && *python != '\0') return python;
#ifdef GISSAR_PYTHON_EXECUTABLE
  if (access(GISSAR_PYTHON_EXECUTABLE, X_OK) == 0) return GISSAR_PYTHON_EXECUTABLE;
#endif
  return "python3";
}

std::vector<std::string> CorridorArguments(const std::string& python, int argc, const char* const* argv) {
  std::vector<std::string> args = {python, "-m", "gissar.corridor"};
  for (int i = 2; i < argc; ++i) args.emplace_back(argv[i]);
  return args;
}

int ExecCorridor(int argc, const char* const* argv, std::ostream& err) {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    if (const auto dir = PythonPackageDir(self)) {
      const char* old = std::getenv("PYTHONPATH");
      const std::string path = dir->string() + (old != nullptr && *old != '\0' ? ":" + std::string(old) : "");
      setenv("PYTHONPATH", path.c_str(), 1);
    }
  }
  const std::string python = CorridorPython();
  const std::vector<std::string> args = CorridorArguments(python, argc, argv);
  std::vector<char*> pointers;
  for (const std::string& a : args) pointers.push_back(const_cast<char*>(a.c_str()));
  pointers.push_back(nullptr);
  err.flush();
  execvp(python.c_str(), pointers.data());
  err << "gissar: error: cannot run " << python << ": " << std::strerror(errno)
      << " (corridor: needs Python 3 with the gissar package and python3-distributed; GISSAR_PYTHON names the "
         "interpreter)\n";
  return 2;
}

}  // namespace gissar::cli
