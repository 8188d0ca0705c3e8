// How a long run talks to whoever started it: progress of its stages,
// information lines, warnings, and a request to stop. The library never
// prints; it reports here. Each door implements it once: the CLI draws a
// progress bar on a terminal and prints warnings on stderr
// (cli/terminal_reporter.h), the Python module calls the user's callback
// and raises Python warnings. NullReporter() swallows everything.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>

#include "gissar/util/error.h"

namespace gissar {

class Reporter {
 public:
  virtual ~Reporter() = default;
  // `done` of `total` units (> 0) of `stage` ("simulate: tracing") are
  // finished. May be called from any thread; callers throttle (Progress
  // below calls at most once per percent) and the last call of a stage has
  // done == total.
  virtual void StageProgress(const std::string& stage, int64_t done, int64_t total) {
    (void)stage, (void)done, (void)total;
  }
  // An informative line ("simulate: image 512 x 480 pixels"); main thread.
  virtual void Info(const std::string& line) { (void)line; }
  // Something the user should know although the run goes on (a void was
  // filled, a feature was skipped); main thread.
  virtual void Warn(const std::string& line) { (void)line; }
  // True once the caller asked the run to stop; long loops poll it (from
  // any thread) through ThrowIfCancelled.
  virtual bool CancelRequested() const { return false; }
};

// A reporter that discards everything and never cancels.
Reporter& NullReporter();

// The run was stopped on request (Reporter::CancelRequested). Not a user
// error: the CLI never sees it (signals end the CLI), Python raises
// KeyboardInterrupt-like `gissar.Cancelled`.
class CancelledError : public Error {
 public:
  using Error::Error;
};

// Throws CancelledError("cancelled", where) when `reporter` asks to stop.
void ThrowIfCancelled(const Reporter& reporter, const std::string& where);

// Counts finished units of one stage and forwards them to a reporter at
// most once per percent. Thread-safe: Advance() may be called from TBB
// workers.
class Progress {
 public:
  // `total_units`: the amount of work (any unit; <= 0 is taken as 1).
  Progress(std::string stage, int64_t total_units, Reporter& reporter);

  // Adds `units` of finished work.
  void Advance(int64_t units);

  // Reports the stage complete and an Info line "<stage>: done in S s" (once).
  void Done();

  Reporter& reporter() const { return reporter_; }

 private:
  std::string stage_;
  int64_t total_units_;
  Reporter& reporter_;
  std::atomic<int64_t> done_units_{0};
  std::atomic<int> last_percent_{0};
  std::atomic<bool> finished_{false};
  std::chrono::steady_clock::time_point start_;
};

}  // namespace gissar
