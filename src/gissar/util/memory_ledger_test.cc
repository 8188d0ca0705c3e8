#include "gissar/util/memory_ledger.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/testing.h"

namespace gissar {
namespace {

// Each test has its own ledger file: nothing here depends on the other gissar
// runs of the machine (their ledger is another file).
class MemoryLedgerTest : public ::testing::Test {
 protected:
  std::string ledger_ = (testing::MakeTempDir() / "memory.ledger").string();
};

TEST_F(MemoryLedgerTest, AReservationIsCountedUntilReleased) {
  {
    const MemoryReservation held = ReserveMemory(600, 1000, "job", "shrink it", 0.0, ledger_);
    EXPECT_EQ(held.bytes(), 600.0);
    EXPECT_LT(held.waited_s(), 0.1);  // no other run: no wait
    const LedgerTotal total = ReadMemoryLedger(ledger_);
    EXPECT_EQ(total.bytes, 600.0);
    EXPECT_EQ(total.entries, 1);
    // 400 more fit exactly beside it.
    const MemoryReservation second = ReserveMemory(400, 1000, "job", "shrink it", 0.0, ledger_);
    EXPECT_EQ(ReadMemoryLedger(ledger_).bytes, 1000.0);
  }
  EXPECT_EQ(ReadMemoryLedger(ledger_).entries, 0);
}

TEST_F(MemoryLedgerTest, ANeedThatFitsAloneButNotBesideTheOthersIsRefusedAfterTheWait) {
  const MemoryReservation held = ReserveMemory(600, 1000, "job A", "shrink it", 0.0, ledger_);
  try {
    ReserveMemory(500, 1000, "image of 10 x 10 pixels", "use coarser spacings", 0.2, ledger_);
    FAIL() << "reserved 500 B beside 600 B of a 1000 B limit";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.where(), "--max-memory");
    const std::string message = e.message();
    EXPECT_NE(message.find("image of 10 x 10 pixels needs about 500 B, and other gissar runs on this machine hold "
                           "600 B of the memory limit of 1000 B (1 run, ledger " + ledger_),
              std::string::npos)
        << message;
    EXPECT_NE(message.find("run it when they have finished, use coarser spacings, raise --max-memory"),
              std::string::npos)
        << message;
  }
  EXPECT_EQ(ReadMemoryLedger(ledger_).bytes, 600.0) << "a refused run reserves nothing";
}

TEST_F(MemoryLedgerTest, AWaitingRunGoesOnWhenTheOtherFinishes) {
  MemoryReservation held = ReserveMemory(600, 1000, "job A", "shrink it", 0.0, ledger_);
  std::thread finisher([&held] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    held.Release();
  });
  const MemoryReservation waiting = ReserveMemory(500, 1000, "job B", "shrink it", 30.0, ledger_);
  finisher.join();
  EXPECT_EQ(waiting.bytes(), 500.0);
  EXPECT_GE(waiting.waited_s(), 0.25);
  EXPECT_LT(waiting.waited_s(), 10.0);
  EXPECT_EQ(ReadMemoryLedger(ledger_).bytes, 500.0);
}

TEST_F(MemoryLedgerTest, OverTheLimitAloneIsRefusedAtOnceAsByCheckMemoryBudget) {
  try {
    ReserveMemory(2000, 1000, "job", "shrink it", 30.0, ledger_);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "job needs about 2.0 KiB, over the memory limit of 1000 B; shrink it, raise --max-memory, "
                           "or run it anyway with --force")
        << e.message();
  }
  EXPECT_EQ(ReadMemoryLedger(ledger_).entries, 0);
}

TEST_F(MemoryLedgerTest, EntriesOfProcessesThatAreGoneDoNotCount) {
  // A child that has exited (its pid no longer exists), an entry with this
  // process's pid but another start time (a reused pid), and a malformed line.
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) _exit(0);
  ASSERT_EQ(waitpid(child, nullptr, 0), child);
  {
    std::ofstream out(ledger_);
    out << child << " 12345 1 900\n" << getpid() << " 1 2 900\n" << "not an entry\n";
  }
  EXPECT_EQ(ReadMemoryLedger(ledger_).entries, 0);
  const MemoryReservation held = ReserveMemory(900, 1000, "job", "shrink it", 0.0, ledger_);
  EXPECT_EQ(held.bytes(), 900.0);
  std::ifstream in(ledger_);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first.rfind(std::to_string(getpid()) + " ", 0), 0u) << "the dead entries were dropped: " << first;
}

TEST_F(MemoryLedgerTest, AForcedBudgetAndAnUnopenableLedgerReserveNothing) {
  const MemoryReservation forced = ReserveMemory(1e15, kForcedMemoryLimitBytes, "job", "shrink it", 0.0, ledger_);
  EXPECT_EQ(forced.bytes(), 0.0);
  EXPECT_EQ(ReadMemoryLedger(ledger_).entries, 0);
  const std::string nowhere = (std::filesystem::path(ledger_).parent_path() / "missing" / "ledger").string();
  const MemoryReservation alone = ReserveMemory(600, 1000, "job", "shrink it", 0.0, nowhere);
  EXPECT_EQ(alone.bytes(), 0.0);
  EXPECT_THROW(ReserveMemory(2000, 1000, "job", "shrink it", 0.0, nowhere), ConfigError);
}

TEST_F(MemoryLedgerTest, AMovedReservationIsReleasedOnce) {
  MemoryReservation a = ReserveMemory(300, 1000, "job", "shrink it", 0.0, ledger_);
  MemoryReservation b = std::move(a);
  EXPECT_EQ(a.bytes(), 0.0);  // NOLINT(bugprone-use-after-move): a moved-from reservation holds nothing
  EXPECT_EQ(b.bytes(), 300.0);
  MemoryReservation c = ReserveMemory(200, 1000, "job", "shrink it", 0.0, ledger_);
  c = std::move(b);  // releases c's 200 B, takes b's 300 B
  EXPECT_EQ(ReadMemoryLedger(ledger_).bytes, 300.0);
  c.Release();
  c.Release();
  EXPECT_EQ(ReadMemoryLedger(ledger_).entries, 0);
}

TEST_F(MemoryLedgerTest, TheLedgerPathFollowsTheEnvironment) {
  const char* saved = std::getenv("GISSAR_MEMORY_LEDGER");
  const std::string previous = saved == nullptr ? "" : saved;
  setenv("GISSAR_MEMORY_LEDGER", ledger_.c_str(), 1);
  EXPECT_EQ(DefaultMemoryLedgerPath(), ledger_);
  unsetenv("GISSAR_MEMORY_LEDGER");
  EXPECT_NE(DefaultMemoryLedgerPath().find("gissar-memory"), std::string::npos);
  if (saved != nullptr) setenv("GISSAR_MEMORY_LEDGER", previous.c_str(), 1);
}

}  // namespace
}  // namespace gissar
