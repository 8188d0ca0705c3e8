#include "gissar/material/material.h"

#include <gtest/gtest.h>

#include "gissar/util/error.h"

namespace gissar::material {
namespace {

TEST(MaterialTest, DefaultIsUnitLambertian) {
  const MaterialTable table;
  EXPECT_EQ(table.Get(0).diffuse, 1.0);
  EXPECT_EQ(table.Get(7).name, "default");
}

TEST(MaterialTest, SetGrowsTheTable) {
  MaterialTable table;
  table.Set(3, Material{"water", 0.05});
  EXPECT_EQ(table.size(), 4u);
  EXPECT_EQ(table.Get(3).diffuse, 0.05);
  EXPECT_EQ(table.Get(2).name, "default");
}

TEST(MaterialTest, RejectsOutOfRangeCoefficients) {
  MaterialTable table;
  EXPECT_THROW(table.Set(1, Material{"bad", -0.1}), ConfigError);
  EXPECT_THROW(table.Set(1, Material{"bad", 1.5}), ConfigError);
}

}  // namespace
}  // namespace gissar::material
