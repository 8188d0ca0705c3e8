#include "gissar/mvg/match_io.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "gissar/mvg/reference_cases.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::mvg {
namespace {

std::filesystem::path Write(const std::string& name, const std::string& text) {
  const std::filesystem::path path = gissar::testing::MakeTempDir() / name;
  std::ofstream out(path, std::ios::binary);
  out << text;
  return path;
}

// The InputError thrown by `fn`, checked to name `where_suffix`.
template <typename Fn>
void ExpectInputError(Fn fn, const std::string& where_suffix, const std::string& what_part) {
  try {
    fn();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    const std::string where = e.where();
    EXPECT_GE(where.size(), where_suffix.size());
    EXPECT_EQ(where.substr(where.size() - std::min(where.size(), where_suffix.size())),
              where_suffix)
        << where;
    EXPECT_NE(e.message().find(what_part), std::string::npos) << e.message();
  }
}

TEST(MatchIoTest, ReadsTheReferenceCsv) {
  const auto rc = testing::LoadReferenceCase(testing::kCase3);
  const auto matches = ReadMatchesCsv(gissar::testing::TestDataPath(
      "affine/" + std::string(testing::kCase3) + "_points.csv"));
  const auto expected = rc.Matches();
  ASSERT_EQ(matches.size(), expected.size());
  for (size_t i = 0; i < matches.size(); ++i) {
    EXPECT_EQ(matches[i].p1, expected[i].p1);
    EXPECT_EQ(matches[i].p2, expected[i].p2);
  }
}

TEST(MatchIoTest, ColumnsByNameInAnyOrderWithExtras) {
  const auto path = Write("m.csv",
                          "\xEF\xBB\xBFid, \"y2\" ,x1,note,x2,y1\r\n"
                          "1,4.5,1.0,a,3,2\r\n"
                          "\r\n"
                          "2, -1e3 ,+5,b,\"7.25\",6\n");
  const auto m = ReadMatchesCsv(path);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].p1, Eigen::Vector2d(1.0, 2.0));
  EXPECT_EQ(m[0].p2, Eigen::Vector2d(3.0, 4.5));
  EXPECT_EQ(m[1].p1, Eigen::Vector2d(5.0, 6.0));
  EXPECT_EQ(m[1].p2, Eigen::Vector2d(7.25, -1000.0));
  // A header alone: no matches.
  EXPECT_TRUE(ReadMatchesCsv(Write("h.csv", "x1,y1,x2,y2\n")).empty());
}

TEST(MatchIoTest, ControlPoints) {
  const auto path = Write("p.csv", "name,x,y,X,Y,Z\nA,10,20,100.5,-200,35\nB,11,21,0,0,0\n");
  const auto p = ReadControlPointsCsv(path);
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].world, Eigen::Vector3d(100.5, -200.0, 35.0));
  EXPECT_EQ(p[0].pixel, Eigen::Vector2d(10.0, 20.0));
  EXPECT_EQ(p[1].pixel, Eigen::Vector2d(11.0, 21.0));
  // Column names are case-sensitive: x/X are different columns.
  ExpectInputError([&] { ReadControlPointsCsv(Write("q.csv", "x,y,Z,Y\n1,2,3,4\n")); }, "q.csv",
                   "'X'");
}

TEST(MatchIoTest, ErrorsNameFileAndLine) {
  ExpectInputError([&] { ReadMatchesCsv(Write("a.csv", "x1,y1,x2\n1,2,3\n")); }, "a.csv",
                   "required column 'y2'");
  ExpectInputError([&] { ReadMatchesCsv(Write("b.csv", "x1,y1,x2,y2\n1,2,3,4\n1,nan,3,4\n")); },
                   "b.csv:3", "not finite");
  ExpectInputError([&] { ReadMatchesCsv(Write("c.csv", "x1,y1,x2,y2\n1,2,3,inf\n")); }, "c.csv:2",
                   "not finite");
  ExpectInputError([&] { ReadMatchesCsv(Write("d.csv", "x1,y1,x2,y2\n1,2,3,4\n\n1,2,3\n")); },
                   "d.csv:4", "fields");
  ExpectInputError([&] { ReadMatchesCsv(Write("e.csv", "x1,y1,x2,y2\n1,2,three,4\n")); }, "e.csv:2",
                   "not a number");
  ExpectInputError([&] { ReadMatchesCsv(Write("f.csv", "x1,y1,x2,y2\n1,2,,4\n")); }, "f.csv:2",
                   "not a number");
  ExpectInputError([&] { ReadMatchesCsv(Write("g.csv", "x1,y1,x2,y2\n1,2,3 4,4\n")); }, "g.csv:2",
                   "not a number");
  ExpectInputError([&] { ReadMatchesCsv(Write("h.csv", "x1,y1,x1,x2,y2\n1,2,3,4,5\n")); },
                   "h.csv:1", "twice");
  ExpectInputError([&] { ReadMatchesCsv(Write("empty.csv", "")); }, "empty.csv", "empty");
  ExpectInputError([&] { ReadMatchesCsv("/nonexistent/dir/matches.csv"); }, "matches.csv",
                   "does not exist");
}

}  // namespace
}  // namespace gissar::mvg
