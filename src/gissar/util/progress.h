// Progress reporting on stderr for long runs. Thread-safe: Advance() may be
// called from TBB workers. Prints "<label>: NN%" lines at 10 % steps and a
// final line with the elapsed time; prints nothing when disabled (--quiet).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>

namespace gissar {

class Progress {
 public:
  // `total_units`: the amount of work (any unit, > 0); `enabled`: false
  // silences every line.
  Progress(std::string label, int64_t total_units, bool enabled);

  // Adds `units` of finished work and prints when a new 10 % step is passed.
  void Advance(int64_t units);

  // Prints the closing line "<label>: done in S s" (once).
  void Done();

 private:
  std::string label_;
  int64_t total_units_;
  bool enabled_;
  std::atomic<int64_t> done_units_{0};
  std::atomic<int> last_decile_{0};
  std::atomic<bool> finished_{false};
  std::chrono::steady_clock::time_point start_;
};

// Peak resident set size of this process so far, bytes (VmHWM); 0 when
// the platform does not report it.
int64_t PeakResidentBytes();

// Wall-clock stopwatch in seconds.
class Stopwatch {
 public:
  Stopwatch() : start_(std::chrono::steady_clock::now()) {}
  double ElapsedSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace gissar
