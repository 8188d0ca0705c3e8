#include "gissar/cli/terminal_reporter.h"

#include "gissar/util/error.h"

namespace gissar::cli {

LogLevel ParseLogLevel(const std::string& text) { return kLogLevels.Parse(text, "--log-level"); }

TerminalReporter::TerminalReporter(std::FILE* stream, LogLevel level, bool is_terminal)
    : stream_(stream), level_(level), is_terminal_(is_terminal) {}

TerminalReporter::~TerminalReporter() {
  std::lock_guard<std::mutex> lock(mutex_);
  EndBarLocked();
}

void TerminalReporter::EndBarLocked() {
  if (!bar_open_) return;
  std::fputc('\n', stream_);
  bar_open_ = false;
}

void TerminalReporter::StageProgress(const std::string& stage, int64_t done, int64_t total) {
  if (level_ < LogLevel::kInfo || total <= 0) return;
  std::lock_guard<std::mutex> lock(mutex_);
  if (!is_terminal_) {
    // A log: one line per 10 % passed ("stage: 30%"), none for completion
    // (the stage's "done in" line follows).
    const int decile = static_cast<int>(10 * done / total);
    int& last = last_decile_[stage];
    if (decile > last && decile < 10) {
      last = decile;
      std::fprintf(stream_, "%s: %d%%\n", stage.c_str(), decile * 10);
    }
    return;
  }
  constexpr int kWidth = 30;
  const double fraction = std::min(1.0, std::max(0.0, double(done) / double(total)));
  const int filled = static_cast<int>(fraction * kWidth + 0.5);
  std::fprintf(stream_, "\r%s [%.*s%*s] %3d%%", stage.c_str(), filled, "##############################",
               kWidth - filled, "", static_cast<int>(fraction * 100.0 + 0.5));
  bar_open_ = true;
  if (done >= total) EndBarLocked();
  std::fflush(stream_);
}

void TerminalReporter::Info(const std::string& line) {
  if (level_ < LogLevel::kInfo) return;
  std::lock_guard<std::mutex> lock(mutex_);
  EndBarLocked();
  std::fprintf(stream_, "%s\n", line.c_str());
}

void TerminalReporter::Warn(const std::string& line) {
  if (level_ < LogLevel::kWarning) return;
  std::lock_guard<std::mutex> lock(mutex_);
  EndBarLocked();
  std::fprintf(stream_, "gissar: warning: %s\n", line.c_str());
}

}  // namespace gissar::cli
