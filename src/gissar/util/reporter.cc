#include "gissar/util/reporter.h"

#include <cstdio>

namespace gissar {

Reporter& NullReporter() {
  static Reporter silent;
  return silent;
}

void ThrowIfCancelled(const Reporter& reporter, const std::string& where) {
  if (reporter.CancelRequested()) throw CancelledError("cancelled on request", where);
}

Progress::Progress(std::string stage, int64_t total_units, Reporter& reporter)
    : stage_(std::move(stage)),
      total_units_(total_units > 0 ? total_units : 1),
      reporter_(reporter),
      start_(std::chrono::steady_clock::now()) {}

void Progress::Advance(int64_t units) {
  const int64_t done = done_units_.fetch_add(units) + units;
  const int percent = static_cast<int>(100 * done / total_units_);
  int last = last_percent_.load();
  while (percent > last && percent < 100) {
    if (last_percent_.compare_exchange_weak(last, percent)) {
      reporter_.StageProgress(stage_, done, total_units_);
      break;
    }
  }
}

void Progress::Done() {
  if (finished_.exchange(true)) return;
  reporter_.StageProgress(stage_, total_units_, total_units_);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  char line[256];
  std::snprintf(line, sizeof(line), "%s: done in %.2f s", stage_.c_str(), seconds);
  reporter_.Info(line);
}

}  // namespace gissar
