#include "gissar/util/progress.h"

#include <cstdio>
#include <fstream>
#include <string>

namespace gissar {

Progress::Progress(std::string label, int64_t total_units, bool enabled)
    : label_(std::move(label)),
      total_units_(total_units > 0 ? total_units : 1),
      enabled_(enabled),
      start_(std::chrono::steady_clock::now()) {}

void Progress::Advance(int64_t units) {
  const int64_t done = done_units_.fetch_add(units) + units;
  if (!enabled_) return;
  const int decile = static_cast<int>(10 * done / total_units_);
  int last = last_decile_.load();
  while (decile > last && decile < 10) {
    if (last_decile_.compare_exchange_weak(last, decile)) {
      std::fprintf(stderr, "%s: %d%%\n", label_.c_str(), decile * 10);
      break;
    }
  }
}

void Progress::Done() {
  if (finished_.exchange(true) || !enabled_) return;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::fprintf(stderr, "%s: done in %.2f s\n", label_.c_str(), seconds);
}

int64_t PeakResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      int64_t kib = 0;
      status >> kib;
      return kib * 1024;
    }
    std::getline(status, key);
  }
  return 0;
}

}  // namespace gissar
