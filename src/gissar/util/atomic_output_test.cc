#include "gissar/util/atomic_output.h"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

#include "gissar/util/error.h"
#include "gissar/util/provenance.h"
#include "gissar/util/testing.h"

namespace gissar {
namespace {
namespace fs = std::filesystem;

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

size_t CountEntries(const fs::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++n;
  return n;
}

TEST(AtomicOutputsTest, CommitRenamesEveryOutput) {
  const fs::path dir = testing::MakeTempDir();
  {
    AtomicOutputs outputs;
    const fs::path a = outputs.Add(dir / "a.txt");
    const fs::path b = outputs.Add(dir / "b.txt");
    EXPECT_NE(a, dir / "a.txt");
    EXPECT_EQ(a.parent_path(), dir);
    WriteText(a, "A");
    WriteText(b, "B");
    EXPECT_FALSE(fs::exists(dir / "a.txt"));
    outputs.Commit();
  }
  EXPECT_TRUE(fs::exists(dir / "a.txt"));
  EXPECT_TRUE(fs::exists(dir / "b.txt"));
  EXPECT_EQ(CountEntries(dir), 2u);
}

TEST(AtomicOutputsTest, DestructionWithoutCommitLeavesNothing) {
  const fs::path dir = testing::MakeTempDir();
  {
    AtomicOutputs outputs;
    WriteText(outputs.Add(dir / "a.txt"), "partial");
  }
  EXPECT_EQ(CountEntries(dir), 0u);
}

TEST(AtomicOutputsTest, CommitFailsWhenAnOutputWasNeverWritten) {
  const fs::path dir = testing::MakeTempDir();
  WriteText(dir / "a.txt", "old");
  {
    AtomicOutputs outputs;
    WriteText(outputs.Add(dir / "a.txt"), "A");
    outputs.Add(dir / "b.txt");
    EXPECT_THROW(outputs.Commit(), IoError);
    // Only the earlier output and the lock of the live run.
    EXPECT_EQ(CountEntries(dir), 2u);
  }
  EXPECT_EQ(CountEntries(dir), 1u);
  std::ifstream in(dir / "a.txt");
  std::string text;
  in >> text;
  EXPECT_EQ(text, "old");
}

TEST(AtomicOutputsTest, MissingDirectoryIsAnIoError) {
  const fs::path dir = testing::MakeTempDir();
  AtomicOutputs outputs;
  try {
    outputs.Add(dir / "missing" / "a.txt");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_EQ(e.message(), "output directory does not exist");
    EXPECT_EQ(e.where(), (dir / "missing").string());
  }
}

TEST(AtomicOutputsTest, AnOutputThatIsAnInputIsAConfigError) {
  const fs::path dir = testing::MakeTempDir();
  WriteText(dir / "in.json", "{}");
  EXPECT_NO_THROW(CheckOutputsAreNotInputs({dir / "out.json", ""}, {(dir / "in.json").string(), ""}));
  try {
    CheckOutputsAreNotInputs({dir / "out.tif", dir / "." / "in.json"},
                             {(dir / "in.json").string()});
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "output would overwrite the input " + (dir / "in.json").string());
    EXPECT_EQ(e.where(), (dir / "." / "in.json").string());
  }
}


std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<std::string> SortedEntries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string FrameName(int i) { return "frame_" + std::to_string(1000 + i) + ".txt"; }

// Forks a child that writes `frames` outputs "new <i>" in `dir` and commits
// them, pausing at `stage` (the test hook); the parent waits for the pause,
// sends `sig` and returns the child's wait status.
int InterruptedCommit(const fs::path& dir, int frames, const std::string& stage, int sig) {
  const fs::path marker = testing::MakeTempDir() / "paused";
  const pid_t pid = fork();
  if (pid == 0) {
    setenv("GISSAR_TEST_COMMIT_PAUSE", (stage + ":" + marker.string()).c_str(), 1);
    InstallSignalCleanup();
    try {
      AtomicOutputs outputs;
      for (int i = 0; i < frames; ++i) WriteText(outputs.Add(dir / FrameName(i)), "new " + std::to_string(i));
      outputs.Commit();
    } catch (...) {
      _exit(90);
    }
    _exit(0);
  }
  for (int i = 0; i < 60000 && !fs::exists(marker); ++i) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  kill(pid, sig);
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

// 360 outputs: more than any fixed table of the old design (256 slots).
constexpr int kFrames = 360;

TEST(AtomicOutputsTest, SignalBeforeAnyRenameLeavesNothing) {
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    const fs::path dir = testing::MakeTempDir();
    const int status = InterruptedCommit(dir, kFrames, "written", sig);
    ASSERT_TRUE(WIFEXITED(status)) << status;
    EXPECT_EQ(WEXITSTATUS(status), 128 + sig);
    EXPECT_EQ(CountEntries(dir), 0u) << "left: " << SortedEntries(dir).front();
  }
}

TEST(AtomicOutputsTest, SignalDuringTheFinalCommitKeepsThePreviousSet) {
  const fs::path dir = testing::MakeTempDir();
  for (int i = 0; i < kFrames; ++i) WriteText(dir / FrameName(i), "old " + std::to_string(i));
  const std::vector<std::string> before = SortedEntries(dir);
  for (int sig : {SIGTERM, SIGHUP}) {
    const int status = InterruptedCommit(dir, kFrames, "renamed", sig);
    ASSERT_TRUE(WIFEXITED(status)) << status;
    EXPECT_EQ(WEXITSTATUS(status), 128 + sig);
    EXPECT_EQ(SortedEntries(dir), before);
    for (int i = 0; i < kFrames; ++i) ASSERT_EQ(ReadText(dir / FrameName(i)), "old " + std::to_string(i)) << i;
  }
}

TEST(AtomicOutputsTest, SignalDuringTheFirstCommitLeavesNothing) {
  const fs::path dir = testing::MakeTempDir();
  const int status = InterruptedCommit(dir, kFrames, "renamed", SIGTERM);
  ASSERT_TRUE(WIFEXITED(status)) << status;
  EXPECT_EQ(WEXITSTATUS(status), 128 + SIGTERM);
  EXPECT_EQ(CountEntries(dir), 0u) << "left: " << SortedEntries(dir).front();
}

TEST(AtomicOutputsTest, NextRunRemovesTheLeftoversOfAKilledRun) {
  const fs::path dir = testing::MakeTempDir();
  const int status = InterruptedCommit(dir, 3, "written", SIGKILL);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(CountEntries(dir), 4u);  // three temporaries and the lock file
  {
    AtomicOutputs outputs;
    for (int i = 0; i < 3; ++i) WriteText(outputs.Add(dir / FrameName(i)), "again");
    outputs.Commit();
  }
  EXPECT_EQ(SortedEntries(dir), (std::vector<std::string>{FrameName(0), FrameName(1), FrameName(2)}));
}

TEST(AtomicOutputsTest, CommitReplacesThePreviousSetAndLeavesNoBackup) {
  const fs::path dir = testing::MakeTempDir();
  WriteText(dir / "a.txt", "old");
  {
    AtomicOutputs outputs;
    WriteText(outputs.Add(dir / "a.txt"), "new");
    WriteText(outputs.Add(dir / "b.txt"), "B");
    outputs.Commit();
  }
  EXPECT_EQ(ReadText(dir / "a.txt"), "new");
  EXPECT_EQ(SortedEntries(dir), (std::vector<std::string>{"a.txt", "b.txt"}));
}

TEST(AtomicOutputsTest, ASecondRunOnTheSamePrefixFailsAtOnce) {
  const fs::path dir = testing::MakeTempDir();
  AtomicOutputs first;
  WriteText(first.Add(dir / "sim.tif"), "A");
  AtomicOutputs second;
  try {
    second.Add(dir / "sim.json");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(e.message().find("another gissar run"), std::string::npos) << e.message();
    EXPECT_EQ(e.where(), (dir / "sim").string());
  }
  AtomicOutputs other_prefix;  // another prefix in the same directory is free
  EXPECT_NO_THROW(other_prefix.Add(dir / "other.tif"));
}

TEST(AtomicOutputsTest, AnOutputNameOf255BytesWorks) {
  const fs::path dir = testing::MakeTempDir();
  const std::string name = std::string(251, 'n') + ".tif";
  ASSERT_EQ(name.size(), 255u);
  {
    AtomicOutputs outputs;
    const fs::path temp = outputs.Add(dir / name);
    EXPECT_LE(temp.filename().string().size(), 40u);
    WriteText(temp, "x");
    outputs.Commit();
  }
  EXPECT_EQ(SortedEntries(dir), std::vector<std::string>{name});
}

TEST(AtomicOutputsTest, AnOutputThatIsNotARegularFileIsAnError) {
  const fs::path dir = testing::MakeTempDir();
  ASSERT_EQ(mkfifo((dir / "pipe.tif").c_str(), 0644), 0);
  AtomicOutputs outputs;
  try {
    outputs.Add(dir / "pipe.tif");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_EQ(e.message(), "output exists and is not a regular file");
  }
  EXPECT_EQ(SortedEntries(dir), std::vector<std::string>{"pipe.tif"});
}

TEST(AtomicOutputsTest, AFifoAsInputIsRefusedBeforeOpening) {
  const fs::path dir = testing::MakeTempDir();
  ASSERT_EQ(mkfifo((dir / "dem.tif").c_str(), 0644), 0);
  // Opening the FIFO would block: the check must only stat it.
  try {
    CheckOutputsAreNotInputs({dir / "out.tif"}, {(dir / "dem.tif").string()});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.message(), "input is not a regular file (a FIFO, device or socket)");
    EXPECT_EQ(e.where(), (dir / "dem.tif").string());
  }
  EXPECT_NO_THROW(CheckOutputsAreNotInputs({dir / "out.tif"}, {"/vsizip/absent.zip/dem.tif"}));
}

TEST(AtomicOutputsTest, TwoOutputsNamingTheSameFileAreAConfigError) {
  const fs::path dir = testing::MakeTempDir();
  {
    AtomicOutputs outputs;
    outputs.Add(dir / "a.png");
    try {
      outputs.Add(dir / "." / "a.png");
      FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.message(), "two outputs name the same file " + (dir / "a.png").string());
    }
  }
  EXPECT_THROW(CheckOutputsAreNotInputs({dir / "x.json", dir / "sub" / ".." / "x.json"}, {}), ConfigError);
  EXPECT_EQ(CountEntries(dir), 0u);
}

// Writers get temporaries: their errors name the output the user asked for.
// A full disk (errno ENOSPC or EDQUOT, or no free block on the file system)
// says "no space left on the device holding DIR"; other failures keep their
// message. Leaving nothing behind stays the destructor's job.
TEST(AtomicOutputsTest, WriteErrorsNameTheOutputAndAFullDisk) {
  const fs::path dir = testing::MakeTempDir();
  fs::path temp;
  {
    AtomicOutputs outputs;
    temp = outputs.Add(dir / "sim.json");
    EXPECT_NE(temp, dir / "sim.json");
    EXPECT_EQ(OutputPathOf(temp), dir / "sim.json");
    EXPECT_EQ(OutputPathOf(dir / "other.json"), dir / "other.json");  // not an output's temporary
    EXPECT_EQ(OutputPathOf(""), fs::path());
    IoError e = WriteError("failed writing JSON output", temp, ENOSPC);
    EXPECT_EQ(e.message(), "failed writing JSON output: no space left on the device holding " + dir.string());
    EXPECT_EQ(e.where(), (dir / "sim.json").string());
    e = WriteError("failed writing JSON output", temp, EDQUOT);
    EXPECT_EQ(e.message(), "failed writing JSON output: no space left on the device holding " + dir.string());
    e = WriteError("failed writing JSON output", temp, EIO);  // a disk with room: another failure
    EXPECT_EQ(e.message(), "failed writing JSON output");
    EXPECT_EQ(e.where(), (dir / "sim.json").string());
    // The failure injected: the temporary a link to /dev/full (ENOSPC on
    // every write), through the JSON writer every command uses.
    fs::create_symlink("/dev/full", temp);
    try {
      WriteJsonFile(nlohmann::json{{"a", 1}}, temp);
      ADD_FAILURE() << "expected IoError";
    } catch (const IoError& error) {
      EXPECT_EQ(error.message(), "failed writing JSON output: no space left on the device holding " + dir.string());
      EXPECT_EQ(error.where(), (dir / "sim.json").string());
    }
  }
  EXPECT_EQ(CountEntries(dir), 0u);
  EXPECT_EQ(OutputPathOf(temp), temp);  // the outputs are gone: the path is only itself
  EXPECT_FALSE(OutOfSpace(EACCES, dir / "x.tif"));
  EXPECT_FALSE(OutOfSpace(ENOENT, "/nonexistent/dir/x.tif"));
  EXPECT_EQ(NoSpaceMessage(dir / "sub" / ".." / "x.tif"), "no space left on the device holding " + dir.string());
}

}  // namespace
}  // namespace gissar
