#include "gissar/util/utc_time.h"

#include <gtest/gtest.h>

#include "gissar/util/error.h"

namespace gissar {
namespace {

TEST(UtcTimeTest, KnownDatesCountDaysFromTheUnixEpoch) {
  EXPECT_EQ(DaysFromCivil(1970, 1, 1), 0);
  EXPECT_EQ(DaysFromCivil(2000, 3, 1), 11017);  // 30 years incl. 7 leap days + Jan + Feb 2000 (29 d)
  EXPECT_EQ(DaysFromCivil(1969, 12, 31), -1);
}

TEST(UtcTimeTest, ParsesIsoAndEarthExplorerSpellings) {
  // 2018-11-12T22:59:42 = 17847 days + 82782 s.
  const double expected = 17847.0 * 86400.0 + 22 * 3600 + 59 * 60 + 42;
  EXPECT_DOUBLE_EQ(ParseUtcSeconds("2018-11-12T22:59:42", "t"), expected);
  EXPECT_DOUBLE_EQ(ParseUtcSeconds("UTC=2018-11-12T22:59:42.000000", "t"), expected);
  EXPECT_DOUBLE_EQ(ParseUtcSeconds("2018-11-12 22:59:42Z", "t"), expected);
  EXPECT_NEAR(ParseUtcSeconds("2018-11-12T22:59:42.25", "t") - expected, 0.25, 1e-6);
}

TEST(UtcTimeTest, RejectsMalformedOrOutOfRangeTimestamps) {
  for (const char* bad : {"", "2018-11-12", "2018-13-01T00:00:00", "2019-02-29T00:00:00", "2018-11-12T24:00:00",
                          "2018-11-12T22:59:42 junk", "yesterday"}) {
    try {
      ParseUtcSeconds(bad, "orbit.csv row 2");
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const InputError& e) {
      EXPECT_EQ(e.where(), "orbit.csv row 2");
    }
  }
  EXPECT_NO_THROW(ParseUtcSeconds("2020-02-29T00:00:00", "leap day"));
}

TEST(UtcTimeTest, FormatIsTheInverseOfParse) {
  for (const char* text : {"2018-11-12T22:59:42.125000Z", "1999-12-31T23:59:59.999999Z", "2024-02-29T00:00:00.000000Z"}) {
    EXPECT_EQ(FormatUtc(ParseUtcSeconds(text, "t")), text);
  }
}

}  // namespace
}  // namespace gissar
