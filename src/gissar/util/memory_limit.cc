#include "gissar/util/memory_limit.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "gissar/util/error.h"

namespace gissar {

namespace {

// A positive byte count from the first word of `path`; 0 when the file is
// missing, says "max", or holds anything else.
int64_t ReadLimitFile(const std::string& path) {
  std::ifstream in(path);
  std::string limit;
  if (!(in >> limit) || limit.empty() || limit == "max") return 0;
  char* end = nullptr;
  errno = 0;
  const long long value = std::strtoll(limit.c_str(), &end, 10);
  if (errno != 0 || end == nullptr || *end != '\0' || value <= 0) return 0;
  return value;
}

}  // namespace

int64_t CgroupMemoryLimitBytes(const std::string& cgroup_root) {
  const int64_t v2 = ReadLimitFile(cgroup_root + "/memory.max");
  int64_t v1 = ReadLimitFile(cgroup_root + "/memory/memory.limit_in_bytes");
  // cgroup v1 says "no limit" with a huge number (PAGE_COUNTER_MAX pages).
  if (v1 >= (int64_t{1} << 60)) v1 = 0;
  if (v2 > 0 && v1 > 0) return std::min(v1, v2);
  return v2 > 0 ? v2 : v1;
}

int64_t PhysicalMemoryBytes() {
  int64_t bytes = 0;
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGESIZE);
  if (pages > 0 && page_size > 0) bytes = int64_t{pages} * page_size;
  const int64_t cgroup = CgroupMemoryLimitBytes("/sys/fs/cgroup");
  if (cgroup > 0 && (bytes == 0 || cgroup < bytes)) bytes = cgroup;
  return bytes;
}

int64_t DefaultMemoryLimitBytes() {
  const int64_t physical = PhysicalMemoryBytes();
  return physical > 0 ? physical / 4 * 3 : int64_t{4} << 30;
}

int64_t ParseByteSize(const std::string& text, const std::string& option) {
  auto fail = [&]() -> int64_t {
    throw ConfigError("expected a memory size such as 512M, 8G or 1.5GiB, got '" + text + "'",
                      option);
  };
  size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    return fail();
  }
  std::string suffix = text.substr(used);
  double scale = 1.0;
  if (!suffix.empty()) {
    const char unit = static_cast<char>(std::toupper(static_cast<unsigned char>(suffix[0])));
    const std::string rest = suffix.substr(1);
    if (rest != "" && rest != "B" && rest != "iB") return fail();
    switch (unit) {
      case 'K': scale = 1024.0; break;
      case 'M': scale = 1024.0 * 1024.0; break;
      case 'G': scale = 1024.0 * 1024.0 * 1024.0; break;
      case 'T': scale = 1024.0 * 1024.0 * 1024.0 * 1024.0; break;
      case 'B': if (!rest.empty()) return fail(); break;
      default: return fail();
    }
  }
  const double bytes = value * scale;
  if (!std::isfinite(bytes) || bytes < 1.0 || bytes > 9.0e18) return fail();
  return static_cast<int64_t>(bytes);
}

std::string FormatBytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 6) {
    bytes /= 1024.0;
    ++u;
  }
  char text[64];
  std::snprintf(text, sizeof(text), bytes < 10.0 && u > 0 ? "%.1f %s" : "%.0f %s", bytes, units[u]);
  return text;
}

void CheckMemoryBudget(double needed_bytes, int64_t limit_bytes, const std::string& what,
                       const std::string& how_to_reduce) {
  if (needed_bytes <= static_cast<double>(limit_bytes)) return;
  throw ConfigError(what + " needs about " + FormatBytes(needed_bytes) +
                        ", over the memory limit of " + FormatBytes(static_cast<double>(limit_bytes)) +
                        "; " + how_to_reduce + ", raise --max-memory, or run it anyway with --force",
                    "--max-memory");
}

void CheckImagePixels(double width, double height, int64_t limit_bytes, const std::string& what,
                      const std::string& how_to_reduce, const std::string& option) {
  if (width * height <= static_cast<double>(kUnforcedImagePixels) || limit_bytes >= kForcedMemoryLimitBytes) return;
  throw ConfigError(what + " is over the 2^28-pixel limit (" + std::to_string(kUnforcedImagePixels) + " pixels); " +
                        how_to_reduce + ", or run it anyway with --force",
                    option);
}

}  // namespace gissar
