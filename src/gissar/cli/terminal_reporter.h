// The CLI's Reporter: information lines and warnings on stderr, filtered by
// --log-level (--quiet = warnings only), and stage progress: a bar redrawn
// in place when stderr is a terminal, else one line per 10 % (logs, pipes).
#pragma once

#include <cstdio>
#include <map>
#include <mutex>
#include <string>

#include "gissar/util/enum_table.h"
#include "gissar/util/reporter.h"

namespace gissar::cli {

enum class LogLevel { kError = 0, kWarning = 1, kInfo = 2 };
inline constexpr auto kLogLevels = util::MakeEnumTable<LogLevel>(
    "log level", {{LogLevel::kError, "error"}, {LogLevel::kWarning, "warning"}, {LogLevel::kInfo, "info"}});

// kLogLevels.Parse: "error", "warning" or "info"; throws ConfigError naming
// --log-level and the levels otherwise.
LogLevel ParseLogLevel(const std::string& text);

class TerminalReporter : public Reporter {
 public:
  // `stream`: where lines go (stderr); `is_terminal`: draw progress bars.
  TerminalReporter(std::FILE* stream, LogLevel level, bool is_terminal);
  ~TerminalReporter() override;

  void StageProgress(const std::string& stage, int64_t done, int64_t total) override;
  void Info(const std::string& line) override;
  void Warn(const std::string& line) override;

 private:
  void EndBarLocked();
  std::FILE* stream_;
  LogLevel level_;
  bool is_terminal_;
  std::mutex mutex_;
  bool bar_open_ = false;
  std::map<std::string, int> last_decile_;  // per stage, off a terminal
};

}  // namespace gissar::cli
