#include "gissar/util/isolated_call.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <stdexcept>

namespace gissar {
namespace {

using Kind = IsolatedOutcome::Kind;

TEST(IsolatedCall, ReturnedWork) {
  int touched = 0;
  const IsolatedOutcome o = RunIsolated([&] { touched = 1; }, 10.0);
  EXPECT_EQ(o.kind, Kind::kReturned);
  EXPECT_EQ(touched, 0);  // the child's memory is its own
  EXPECT_EQ(o.Describe(10.0), "returned");
}

TEST(IsolatedCall, ThrowingWork) {
  const IsolatedOutcome o = RunIsolated([] { throw std::runtime_error("bad file"); }, 10.0);
  EXPECT_EQ(o.kind, Kind::kThrew);
}

TEST(IsolatedCall, CrashBySignalIsReportedNotSuffered) {
  // SIGKILL cannot be caught, by a sanitizer either: the signal reaches us.
  const IsolatedOutcome o = RunIsolated([] { raise(SIGKILL); }, 10.0);
  EXPECT_EQ(o.kind, Kind::kCrashed);
  EXPECT_EQ(o.signal, SIGKILL);
  EXPECT_NE(o.Describe(10.0).find("signal 9"), std::string::npos);
}

TEST(IsolatedCall, SegmentationFault) {
  // Under ASan the child's SEGV is reported and exits 1: crashed either way.
  const IsolatedOutcome o = RunIsolated(
      [] {
        volatile int* p = nullptr;
        *p = 1;
      },
      10.0);
  EXPECT_EQ(o.kind, Kind::kCrashed);
  EXPECT_TRUE(o.signal == SIGSEGV || o.exit_status != 0);
}

TEST(IsolatedCall, UnexpectedExitStatusIsACrash) {
  const IsolatedOutcome o = RunIsolated([] { _exit(3); }, 10.0);
  EXPECT_EQ(o.kind, Kind::kCrashed);
  EXPECT_EQ(o.signal, 0);
  EXPECT_EQ(o.exit_status, 3);
  EXPECT_EQ(o.Describe(10.0), "exit status 3");
}

TEST(IsolatedCall, HangIsKilledAtTheTimeout) {
  const IsolatedOutcome o = RunIsolated([] { pause(); }, 0.3);
  EXPECT_EQ(o.kind, Kind::kTimedOut);
  EXPECT_EQ(o.Describe(0.3), "no answer within 0.3 s");
}

}  // namespace
}  // namespace gissar
