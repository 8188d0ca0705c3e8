// Runs a piece of work in a forked child process first, so that a crash
// inside a system library (a SEGV in libhdf5 on a corrupt file, say) ends
// the child, not the caller: the caller learns how the child ended and
// decides what to tell the user (docs/robustness.md "Hostile files").
//
// The child is a fork() of the caller: it sees the caller's memory as it was
// and changes nothing the caller can see (results are not sent back; run the
// work again in the caller once the child returned). It runs only `work`,
// with standard error sent to /dev/null, no core file and the default action
// for SIGSEGV, SIGBUS, SIGFPE, SIGILL and SIGABRT (no handler of the
// caller's, a sanitizer's or a fuzzer's, reports the crash as its own), then
// leaves with _exit (no atexit handlers, no static destructors, no Python
// finaliser). A sanitizer's own finding in instrumented code still reports
// (to /dev/null) and exits 1: kCrashed.
// Work run this way must not need other threads of the caller (a fork copies
// only the calling thread): plain reading of a file is fine; TBB, Python or
// a lock another thread may hold at the fork are not.
#pragma once

#include <functional>
#include <string>

namespace gissar {

struct IsolatedOutcome {
  enum class Kind {
    kReturned,     // `work` returned
    kThrew,        // `work` threw (any exception; run it in the caller to see which)
    kCrashed,      // the child died by a signal or ended otherwise (a sanitizer's report exits 1)
    kTimedOut,     // still running after the timeout: killed (SIGKILL)
    kNotIsolated,  // fork() failed (no process or memory left), or the child was reaped
                   // by someone else (SIGCHLD ignored): how it ended is unknown
  };
  Kind kind = Kind::kNotIsolated;
  int signal = 0;       // kCrashed by a signal: its number (SIGSEGV, ...), else 0
  int exit_status = 0;  // kCrashed by an exit: its status, else 0

  // "signal 11 (Segmentation fault)", "exit status 1", "no answer within 60 s", ...
  std::string Describe(double timeout_s) const;
};

// Forks, runs `work` in the child and waits for it at most `timeout_s`
// seconds (> 0). Never throws for what happened in the child.
IsolatedOutcome RunIsolated(const std::function<void()>& work, double timeout_s);

}  // namespace gissar
