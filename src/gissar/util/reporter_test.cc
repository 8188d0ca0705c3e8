#include "gissar/util/reporter.h"

#include <gtest/gtest.h>

#include <mutex>
#include <thread>
#include <vector>

namespace gissar {
namespace {

struct Recorder : Reporter {
  std::mutex mutex;
  std::vector<int64_t> done;
  std::vector<std::string> info;
  bool cancel = false;
  void StageProgress(const std::string&, int64_t d, int64_t total) override {
    std::lock_guard<std::mutex> lock(mutex);
    EXPECT_EQ(total, 1000);
    done.push_back(d);
  }
  void Info(const std::string& line) override { info.push_back(line); }
  bool CancelRequested() const override { return cancel; }
};

TEST(ProgressTest, ReportsAtMostOncePerPercentAndEndsComplete) {
  Recorder r;
  Progress p("stage", 1000, r);
  std::vector<std::thread> workers;
  for (int t = 0; t < 4; ++t) {
    workers.emplace_back([&] {
      for (int i = 0; i < 250; ++i) p.Advance(1);
    });
  }
  for (auto& w : workers) w.join();
  p.Done();
  p.Done();  // once only
  // 99 intermediate percents at most (1..99), then the closing 1000/1000.
  ASSERT_GE(r.done.size(), 2u);
  EXPECT_LE(r.done.size(), 100u);
  EXPECT_EQ(r.done.back(), 1000);
  ASSERT_EQ(r.info.size(), 1u);
  EXPECT_EQ(r.info[0].rfind("stage: done in ", 0), 0u);
}

TEST(ReporterTest, CancellationThrowsOnlyWhenRequested) {
  Recorder r;
  EXPECT_NO_THROW(ThrowIfCancelled(r, "here"));
  r.cancel = true;
  try {
    ThrowIfCancelled(r, "tracing");
    FAIL() << "no CancelledError";
  } catch (const CancelledError& e) {
    EXPECT_EQ(e.where(), "tracing");
  }
  EXPECT_NO_THROW(ThrowIfCancelled(NullReporter(), "here"));
}

}  // namespace
}  // namespace gissar
