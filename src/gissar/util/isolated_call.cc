#include "gissar/util/isolated_call.h"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <thread>

#include "gissar/util/check.h"

namespace gissar {
namespace {

// The child's exit status when `work` threw: one no sanitizer or runtime
// uses (ASan and UBSan exit 1, abort() is a signal).
constexpr int kThrewStatus = 86;

[[noreturn]] void RunChild(const std::function<void()>& work) {
  // The default action for the crash signals: the child dies by the signal
  // itself, and no handler inherited from the caller (a sanitizer's report,
  // a fuzzer writing a crash input, a crash reporter) runs in its name.
  for (const int crash_signal : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) std::signal(crash_signal, SIG_DFL);
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  const int null_fd = open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null_fd >= 0) dup2(null_fd, STDERR_FILENO);
  int status = 0;
  try {
    work();
  } catch (...) {
    status = kThrewStatus;
  }
  _exit(status);
}

}  // namespace

std::string IsolatedOutcome::Describe(double timeout_s) const {
  switch (kind) {
    case Kind::kReturned:
      return "returned";
    case Kind::kThrew:
      return "threw";
    case Kind::kCrashed:
      if (signal != 0) {
        const char* name = strsignal(signal);
        return "signal " + std::to_string(signal) + (name != nullptr ? " (" + std::string(name) + ")" : "");
      }
      return "exit status " + std::to_string(exit_status);
    case Kind::kTimedOut: {
      char text[32];
      std::snprintf(text, sizeof(text), "%g", timeout_s);
      return std::string("no answer within ") + text + " s";
    }
    case Kind::kNotIsolated:
      return "not isolated (fork failed)";
  }
  return "?";
}

IsolatedOutcome RunIsolated(const std::function<void()>& work, double timeout_s) {
  GISSAR_CHECK(timeout_s > 0.0);
  IsolatedOutcome outcome;
  std::fflush(nullptr);  // nothing buffered is written twice
  const pid_t pid = fork();
  if (pid < 0) return outcome;  // kNotIsolated
  if (pid == 0) RunChild(work);

  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  auto pause = std::chrono::microseconds(200);
  int status = 0;
  while (true) {
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (done < 0 && errno != EINTR) return outcome;  // reaped elsewhere (SIGCHLD ignored): unknown
    if (Clock::now() >= deadline) {
      kill(pid, SIGKILL);
      while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      outcome.kind = IsolatedOutcome::Kind::kTimedOut;
      return outcome;
    }
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::microseconds(20000));
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    outcome.kind = IsolatedOutcome::Kind::kReturned;
  } else if (WIFEXITED(status) && WEXITSTATUS(status) == kThrewStatus) {
    outcome.kind = IsolatedOutcome::Kind::kThrew;
  } else {
    outcome.kind = IsolatedOutcome::Kind::kCrashed;
    if (WIFSIGNALED(status)) outcome.signal = WTERMSIG(status);
    if (WIFEXITED(status)) outcome.exit_status = WEXITSTATUS(status);
  }
  return outcome;
}

}  // namespace gissar
