#include "gissar/util/atomic_output.h"

#include <gtest/gtest.h>

#include <fstream>

#include "gissar/util/error.h"
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
  AtomicOutputs outputs;
  WriteText(outputs.Add(dir / "a.txt"), "A");
  outputs.Add(dir / "b.txt");
  EXPECT_THROW(outputs.Commit(), IoError);
  EXPECT_EQ(CountEntries(dir), 0u);
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

}  // namespace
}  // namespace gissar
