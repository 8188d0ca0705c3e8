#include "gissar/util/testing.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <string>
#include <vector>

#include "gissar/util/check.h"

namespace gissar::testing {
namespace fs = std::filesystem;
namespace {

fs::path EnvOr(const char* name, const fs::path& fallback) {
  const char* value = std::getenv(name);
  return (value != nullptr && *value != '\0') ? fs::path(value) : fallback;
}

struct TempDirs {
  std::vector<fs::path> dirs;
  ~TempDirs() {
    for (const fs::path& dir : dirs) {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  }
};

}  // namespace

fs::path DataPath(std::string_view relative) {
  return EnvOr("GISSAR_DATA_DIR", fs::path(GISSAR_SOURCE_DIR) / "data") / relative;
}

fs::path TestDataPath(std::string_view relative) {
  return EnvOr("GISSAR_TEST_DATA_DIR", fs::path(GISSAR_SOURCE_DIR) / "tests" / "data") / relative;
}

fs::path MakeTempDir() {
  static TempDirs registry;
  static std::atomic<int> counter{0};
  const fs::path dir = fs::temp_directory_path() /
                       ("gissar-test-" + std::to_string(getpid()) + "-" + std::to_string(counter++));
  fs::remove_all(dir);
  GISSAR_CHECK(fs::create_directories(dir));
  registry.dirs.push_back(dir);
  return dir;
}

}  // namespace gissar::testing
