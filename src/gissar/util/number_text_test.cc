#include "gissar/util/number_text.h"

#include <gtest/gtest.h>

namespace gissar::util {
namespace {

TEST(ParseFiniteNumber, ReadsAWholeFiniteNumber) {
  EXPECT_EQ(ParseFiniteNumber("1.5"), 1.5);
  EXPECT_EQ(ParseFiniteNumber("-2e3"), -2000.0);
  EXPECT_EQ(ParseFiniteNumber(" 7"), 7.0);  // stod skips leading white space
  EXPECT_EQ(ParseFiniteNumber("0x10"), 16.0);
}

TEST(ParseFiniteNumber, RefusesEverythingElseWithoutThrowing) {
  for (const char* text : {"", " ", "abc", "1.5m", "1.5 ", "1,5", "inf", "-inf", "nan", "1e400", "--1"}) {
    EXPECT_FALSE(ParseFiniteNumber(text).has_value()) << text;
  }
}

}  // namespace
}  // namespace gissar::util
