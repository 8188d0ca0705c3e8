// Timing and memory figures of a run (stage progress goes through
// gissar/util/reporter.h).
#pragma once

#include <chrono>
#include <cstdint>

namespace gissar {

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
