// Interrupted runs (docs/robustness.md): SIGINT, SIGTERM or SIGHUP at any
// point of `gissar simulate` (while tracing, while writing its outputs, during
// the final commit) ends it with status 128 + signal, leaves no temporary, and
// leaves an earlier run's outputs as they were; a second run on the same
// --out while one is running fails at once.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "gissar/util/testing.h"

namespace {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::vector<std::string> Entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

struct Job {
  std::string rays_per_cell = "1";
  std::string spacing_m = "30";
  bool contributions = true;  // also write a contributions CSV (written first)
  bool quiet = true;
  std::string commit_pause;  // GISSAR_TEST_COMMIT_PAUSE for the child ("" = none)
};

// Starts `gissar simulate` on the Andorra DEM (480 x 300 posts) with stderr
// to `err`.
pid_t StartSimulate(const fs::path& out_dir, const fs::path& err, const Job& job) {
  const std::string dem = gissar::testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  std::vector<std::string> args = {GISSAR_CLI_BINARY, "simulate", "--dem", dem, "--heading", "20",
                                   "--depression", "40", "--range-spacing", job.spacing_m,
                                   "--azimuth-spacing", job.spacing_m, "--rays-per-cell",
                                   job.rays_per_cell, "--bounces", "2", "--out",
                                   (out_dir / "sim").string()};
  if (job.contributions) {
    args.insert(args.end(), {"--contributions", (out_dir / "returns.csv").string()});
  }
  if (job.quiet) args.push_back("--quiet");
  const pid_t pid = fork();
  if (pid == 0) {
    if (!job.commit_pause.empty()) setenv("GISSAR_TEST_COMMIT_PAUSE", job.commit_pause.c_str(), 1);
    const int fd = open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 2);
    const int null_fd = open("/dev/null", O_WRONLY);
    dup2(null_fd, 1);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// Waits until `ready()` or the process ends; true when `ready()` came first.
template <typename Ready>
bool WaitFor(pid_t pid, Ready ready, double timeout_s = 300.0) {
  const auto start = Clock::now();
  while (std::chrono::duration<double>(Clock::now() - start).count() < timeout_s) {
    if (ready()) return true;
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  return false;
}

int StopAndWait(pid_t pid, int sig) {
  kill(pid, sig);
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

TEST(InterruptTest, SignalWhileTracingLeavesNothing) {
  for (int sig : {SIGINT, SIGTERM}) {
    const fs::path out = gissar::testing::MakeTempDir(), logs = gissar::testing::MakeTempDir();
    // About 5 million rays: seconds of tracing, with progress lines.
    const pid_t pid = StartSimulate(out, logs / "stderr", Job{"32", "30", false, false, ""});
    ASSERT_GT(pid, 0);
    const bool tracing = WaitFor(pid, [&] {
      return ReadText(logs / "stderr").find("simulate: tracing: 20%") != std::string::npos;
    });
    ASSERT_TRUE(tracing) << "the run ended before tracing was 20 % done: " << ReadText(logs / "stderr");
    const int status = StopAndWait(pid, sig);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 128 + sig);
    EXPECT_TRUE(Entries(out).empty()) << "left behind: " << Entries(out).front();
  }
}

TEST(InterruptTest, SignalWhileWritingRemovesPartialFiles) {
  const fs::path out = gissar::testing::MakeTempDir(), logs = gissar::testing::MakeTempDir();
  // Some 600,000 returns: a CSV of tens of MB, written first, under a
  // temporary name.
  const pid_t pid = StartSimulate(out, logs / "stderr", Job{"4", "30", true, true, ""});
  ASSERT_GT(pid, 0);
  const bool writing = WaitFor(pid, [&] {
    for (const auto& e : fs::directory_iterator(out)) {
      std::error_code ec;
      const std::string name = e.path().filename().string();
      if (name.rfind(".gs-", 0) == 0 && name.find(".tmp") != std::string::npos && fs::file_size(e.path(), ec) > 0) {
        return true;
      }
    }
    return false;
  });
  ASSERT_TRUE(writing) << "the run ended before its outputs were being written";
  const int status = StopAndWait(pid, SIGTERM);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM);
  EXPECT_TRUE(Entries(out).empty()) << "left behind: " << Entries(out).front();
}

TEST(InterruptTest, UninterruptedRunCommitsEveryOutput) {
  const fs::path out = gissar::testing::MakeTempDir(), logs = gissar::testing::MakeTempDir();
  const pid_t pid = StartSimulate(out, logs / "stderr", Job{"1", "60", true, true, ""});
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << ReadText(logs / "stderr");
  std::vector<std::string> names = Entries(out);
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"returns.csv", "sim.json", "sim.png", "sim.tif", "sim_mask.tif",
                                            "sim_quicklook.png", "sim_stac.json"}));
}

std::map<std::string, std::string> Snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::directory_iterator(dir)) files[e.path().filename().string()] = ReadText(e.path());
  return files;
}

int RunToEnd(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

TEST(InterruptTest, SignalDuringTheFinalCommitKeepsTheEarlierRun) {
  const fs::path out = gissar::testing::MakeTempDir(), logs = gissar::testing::MakeTempDir();
  Job job{"1", "60", true, true, ""};
  const int first = RunToEnd(StartSimulate(out, logs / "first", job));
  ASSERT_TRUE(WIFEXITED(first) && WEXITSTATUS(first) == 0) << ReadText(logs / "first");
  const std::map<std::string, std::string> before = Snapshot(out);
  ASSERT_EQ(before.size(), 7u);
  for (int sig : {SIGTERM, SIGHUP, SIGINT}) {
    for (const char* stage : {"written", "renamed"}) {
      const fs::path marker = logs / (std::string("paused_") + stage + std::to_string(sig));
      job.commit_pause = std::string(stage) + ":" + marker.string();
      job.rays_per_cell = "2";  // a different image: the earlier one must survive
      const pid_t pid = StartSimulate(out, logs / "second", job);
      ASSERT_TRUE(WaitFor(pid, [&] { return fs::exists(marker); })) << ReadText(logs / "second");
      const int status = StopAndWait(pid, sig);
      ASSERT_TRUE(WIFEXITED(status)) << stage;
      EXPECT_EQ(WEXITSTATUS(status), 128 + sig) << stage;
      EXPECT_TRUE(Snapshot(out) == before) << "signal " << sig << " at '" << stage
                                           << "' changed the earlier outputs; now " << Entries(out).size()
                                           << " entries";
    }
  }
}

TEST(InterruptTest, ASecondRunOnTheSameOutFailsAtOnce) {
  const fs::path out = gissar::testing::MakeTempDir(), logs = gissar::testing::MakeTempDir();
  Job job{"1", "60", true, true, ""};
  const fs::path marker = logs / "paused";
  job.commit_pause = "written:" + marker.string();
  const pid_t first = StartSimulate(out, logs / "first", job);
  ASSERT_TRUE(WaitFor(first, [&] { return fs::exists(marker); })) << ReadText(logs / "first");
  job.commit_pause.clear();
  const auto start = Clock::now();
  const int second = RunToEnd(StartSimulate(out, logs / "second", job));
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  ASSERT_TRUE(WIFEXITED(second));
  EXPECT_EQ(WEXITSTATUS(second), 2);
  const std::string err = ReadText(logs / "second");
  EXPECT_EQ(err.rfind("gissar: error: another gissar run is writing outputs with this prefix", 0), 0u) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_LT(seconds, 30.0);  // refused when reserving its outputs, before the DEM is read
  const int status = StopAndWait(first, SIGTERM);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM);
  EXPECT_TRUE(Entries(out).empty()) << "left behind: " << Entries(out).front();
}

}  // namespace
