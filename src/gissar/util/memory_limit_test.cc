#include "gissar/util/memory_limit.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar {
namespace {

TEST(MemoryLimitTest, ParsesSizesWithBinarySuffixes) {
  EXPECT_EQ(ParseByteSize("1000", "--max-memory"), 1000);
  EXPECT_EQ(ParseByteSize("512M", "--max-memory"), int64_t{512} << 20);
  EXPECT_EQ(ParseByteSize("8G", "--max-memory"), int64_t{8} << 30);
  EXPECT_EQ(ParseByteSize("8GiB", "--max-memory"), int64_t{8} << 30);
  EXPECT_EQ(ParseByteSize("1.5g", "--max-memory"), int64_t{3} << 29);
  EXPECT_EQ(ParseByteSize("2T", "--max-memory"), int64_t{2} << 40);
}

TEST(MemoryLimitTest, RejectsBadSizesNamingTheOption) {
  for (const char* text : {"", "-1G", "0", "nan", "inf", "8X", "8GB2", "G", "1e30T", "0.5"}) {
    try {
      ParseByteSize(text, "--max-memory");
      ADD_FAILURE() << "accepted '" << text << "'";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.where(), "--max-memory") << text;
    }
  }
}

TEST(MemoryLimitTest, DefaultIsAFractionOfPhysicalMemory) {
  const int64_t physical = PhysicalMemoryBytes();
  ASSERT_GT(physical, 0);
  EXPECT_EQ(DefaultMemoryLimitBytes(), physical / 4 * 3);
}

TEST(MemoryLimitTest, BudgetCheckSaysHowToReduceTheJob) {
  EXPECT_NO_THROW(CheckMemoryBudget(1000.0, 1000, "image", "use coarser spacing"));
  try {
    CheckMemoryBudget(3.0 * (int64_t{1} << 30), int64_t{1} << 30, "image of 10 x 10 pixels",
                      "use coarser spacing");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(),
              "image of 10 x 10 pixels needs about 3.0 GiB, over the memory limit of 1.0 GiB; use "
              "coarser spacing, raise --max-memory, or run it anyway with --force");
    EXPECT_EQ(e.where(), "--max-memory");
  }
  EXPECT_EQ(FormatBytes(100), "100 B");
  EXPECT_EQ(FormatBytes(1536), "1.5 KiB");
  EXPECT_EQ(FormatBytes(300.0 * (1 << 20)), "300 MiB");
}

// 16384 x 16384 = 2^28 pixels is the most without --force; one more row is
// refused, naming the option, unless the budget is --force's.
TEST(MemoryLimitTest, ImagesOver2To28PixelsNeedForce) {
  const int64_t budget = int64_t{8} << 30;
  EXPECT_NO_THROW(CheckImagePixels(16384, 16384, budget, "image", "use coarser spacing", "--width"));
  try {
    CheckImagePixels(16384, 16385, budget, "image of 16384 x 16385 pixels", "use coarser spacing", "--height");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(),
              "image of 16384 x 16385 pixels is over the 2^28-pixel limit (268435456 pixels); use coarser "
              "spacing, or run it anyway with --force");
    EXPECT_EQ(e.where(), "--height");
  }
  EXPECT_NO_THROW(CheckImagePixels(16384, 16385, kForcedMemoryLimitBytes, "image", "x", "--height"));
  EXPECT_NO_THROW(CheckImagePixels(65536, 65536, std::numeric_limits<int64_t>::max(), "image", "x", "--height"));
  EXPECT_THROW(CheckImagePixels(65536, 65536, kForcedMemoryLimitBytes - 1, "image", "x", "--height"), ConfigError);
}

TEST(MemoryLimitTest, CgroupV1AndV2LimitsAreRead) {
  namespace fs = std::filesystem;
  const fs::path root = testing::MakeTempDir();
  EXPECT_EQ(CgroupMemoryLimitBytes(root.string()), 0);  // neither file
  fs::create_directories(root / "memory");
  std::ofstream(root / "memory" / "memory.limit_in_bytes") << "9223372036854771712\n";  // v1: no limit
  EXPECT_EQ(CgroupMemoryLimitBytes(root.string()), 0);
  std::ofstream(root / "memory" / "memory.limit_in_bytes") << "2147483648\n";  // v1: 2 GiB
  EXPECT_EQ(CgroupMemoryLimitBytes(root.string()), int64_t{2} << 30);
  std::ofstream(root / "memory.max") << "1073741824\n";  // v2: 1 GiB, the smaller
  EXPECT_EQ(CgroupMemoryLimitBytes(root.string()), int64_t{1} << 30);
  std::ofstream(root / "memory.max") << "max\n";
  EXPECT_EQ(CgroupMemoryLimitBytes(root.string()), int64_t{2} << 30);
}

}  // namespace
}  // namespace gissar
