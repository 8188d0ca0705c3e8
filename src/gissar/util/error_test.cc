#include "gissar/util/error.h"

#include <gtest/gtest.h>

namespace gissar {
namespace {

TEST(ErrorTest, FormatsWhatAndWhere) {
  const InputError e("DEM has 403 no-data cells", "andorra.tif");
  EXPECT_STREQ(e.what(), "DEM has 403 no-data cells (andorra.tif)");
  EXPECT_EQ(e.message(), "DEM has 403 no-data cells");
  EXPECT_EQ(e.where(), "andorra.tif");
}

TEST(ErrorTest, OmitsEmptyWhere) {
  const ConfigError e("depression must be in (0, 90) degrees", "");
  EXPECT_STREQ(e.what(), "depression must be in (0, 90) degrees");
}

TEST(ErrorTest, FamilyIsCatchableAsBase) {
  try {
    throw IoError("disk full", "out.tif");
  } catch (const Error& e) {
    EXPECT_EQ(e.where(), "out.tif");
    return;
  }
  FAIL() << "IoError not caught as Error";
}

}  // namespace
}  // namespace gissar
