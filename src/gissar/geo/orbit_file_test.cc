#include "gissar/geo/orbit_file.h"

#include <gtest/gtest.h>

#include <fstream>

#include "gissar/util/error.h"
#include "gissar/util/testing.h"
#include "gissar/util/utc_time.h"

namespace gissar::geo {
namespace {

using testing::MakeTempDir;
using testing::TestDataPath;

std::filesystem::path WriteFile(const std::filesystem::path& dir, const std::string& name, const std::string& text) {
  const auto path = dir / name;
  std::ofstream(path) << text;
  return path;
}

// Five vectors 10 s apart from 2021-11-19T01:59:50 along +Y at 7 km/s, x = 7000 km.
void ExpectExcerpt(const StateVectors& v) {
  ASSERT_EQ(v.utc_s.size(), 5u);
  const double start = ParseUtcSeconds("2021-11-19T01:59:50", "t");
  for (int i = 0; i < 5; ++i) {
    EXPECT_DOUBLE_EQ(v.utc_s[i], start + 10.0 * i);
    EXPECT_DOUBLE_EQ(v.position_m[i].x(), 7.0e6);
    EXPECT_DOUBLE_EQ(v.position_m[i].y(), -140000.0 + 70000.0 * i);
    EXPECT_DOUBLE_EQ(v.velocity_mps[i].y(), 7000.0);
  }
}

TEST(OrbitFileTest, ReadsEarthExplorerOrbitFile) {
  const StateVectors v = ReadStateVectors(TestDataPath("orbits/s1_poeorb_excerpt.EOF"));
  EXPECT_EQ(v.format, "eof");
  ExpectExcerpt(v);
}

TEST(OrbitFileTest, CsvAndJsonGiveTheSameVectorsAsTheEofFile) {
  const auto dir = MakeTempDir();
  const StateVectors eof = ReadStateVectors(TestDataPath("orbits/s1_poeorb_excerpt.EOF"));
  WriteStateVectorsCsv(dir / "orbit.csv", eof);
  const StateVectors csv = ReadStateVectors(dir / "orbit.csv");
  EXPECT_EQ(csv.format, "csv");
  ExpectExcerpt(csv);
  // Columns in another order are fine.
  const auto reordered = WriteFile(dir, "reordered.csv",
                                   "# a comment\nx_m,y_m,z_m,vx_mps,vy_mps,vz_mps,time_utc\n"
                                   "7000000,-140000,0,0,7000,0,2021-11-19T01:59:50Z\n"
                                   "7000000,-70000,0,0,7000,0,2021-11-19T02:00:00Z\n"
                                   "7000000,0,0,0,7000,0,2021-11-19T02:00:10Z\n"
                                   "7000000,70000,0,0,7000,0,2021-11-19T02:00:20Z\n"
                                   "7000000,140000,0,0,7000,0,2021-11-19T02:00:30Z\n");
  ExpectExcerpt(ReadStateVectors(reordered));
  std::string json = "{\"state_vectors\": [";
  for (int i = 0; i < 5; ++i) {
    json += std::string(i ? "," : "") + "{\"time_utc\": \"" + FormatUtc(eof.utc_s[i]) + "\", \"position_m\": [7e6, " +
            std::to_string(-140000 + 70000 * i) + ", 0], \"velocity_mps\": [0, 7000, 0]}";
  }
  json += "]}";
  const StateVectors from_json = ReadStateVectors(WriteFile(dir, "orbit.json", json));
  EXPECT_EQ(from_json.format, "json");
  ExpectExcerpt(from_json);
}

// Each malformed orbit names its problem and the file.
TEST(OrbitFileTest, BadOrbitsAreClearErrors) {
  const auto dir = MakeTempDir();
  const std::string header = "time_utc,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n";
  auto row = [](const char* time) { return std::string(time) + ",7000000,0,0,0,7000,0\n"; };
  const struct {
    const char* name;
    std::string text;
    const char* expected;
  } cases[] = {
      {"few.csv", header + row("2021-11-19T02:00:00") + row("2021-11-19T02:00:10") + row("2021-11-19T02:00:20"),
       "3 state vectors, at least 4 needed"},
      {"backwards.csv",
       header + row("2021-11-19T02:00:00") + row("2021-11-19T02:00:10") + row("2021-11-19T02:00:05") +
           row("2021-11-19T02:00:20"),
       "not strictly increasing"},
      {"gap.csv",
       header + row("2021-11-19T02:00:00") + row("2021-11-19T02:00:10") + row("2021-11-19T02:00:20") +
           row("2021-11-19T02:01:20") + row("2021-11-19T02:01:30"),
       "gap of 60.000 s between state vectors 3 and 4"},
      {"column.csv", "time_utc,x_m,y_m,z_m,vx_mps,vy_mps,speed\n", "unknown column 'speed'"},
      {"nan.csv", header + "2021-11-19T02:00:00,nan,0,0,0,7000,0\n", "is not a finite number"},
      {"time.csv", header + "19/11/2021,7000000,0,0,0,7000,0\n", "is not a UTC timestamp"},
      {"key.json", "{\"state_vectors\": [], \"frame\": \"ECEF\"}", "unknown key 'frame'"},
      {"empty.eof", "<Earth_Explorer_File><Data_Block/></Earth_Explorer_File>", "List_of_OSVs"},
  };
  for (const auto& c : cases) {
    const auto path = WriteFile(dir, c.name, c.text);
    try {
      ReadStateVectors(path);
      ADD_FAILURE() << c.name << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << c.name << ": " << e.what();
      EXPECT_NE(e.where().find(c.name), std::string::npos) << e.where();
    }
  }
  EXPECT_THROW(ReadStateVectors(dir / "missing.csv"), InputError);
}

const char* kGridJson = R"({"starting_range_m": 850000.0, "range_spacing_m": 2.33, "sensing_start_utc":
  "2021-11-19T02:00:05.5", "azimuth_time_interval_s": 0.002, "width": 300, "length": 200, "look_side": "right",
  "wavelength_m": 0.0555})";

TEST(OrbitFileTest, RadarGridAndOrbitMakeAProductGeometry) {
  const auto dir = MakeTempDir();
  const RadarGridSpec grid = ReadRadarGrid(WriteFile(dir, "grid.json", kGridJson));
  EXPECT_EQ(grid.width, 300);
  EXPECT_EQ(grid.length, 200);
  EXPECT_FALSE(grid.look_left);
  const StateVectors v = ReadStateVectors(TestDataPath("orbits/s1_poeorb_excerpt.EOF"));
  const RslcProduct p = ProductFromOrbit(v, "orbit.EOF", grid, "grid.json");
  EXPECT_EQ(p.epoch_utc, "2021-11-19 00:00:00");
  ASSERT_EQ(p.rows(), 200);
  ASSERT_EQ(p.cols(), 300);
  EXPECT_NEAR(p.zero_doppler_time_s.front(), 2 * 3600 + 5.5, 1e-6);  // seconds since midnight
  EXPECT_NEAR(p.azimuth_spacing_s(), 0.002, 1e-12);
  EXPECT_NEAR(p.range_spacing_m(), 2.33, 1e-9);
  EXPECT_DOUBLE_EQ(p.slant_range_m.front(), 850000.0);
  EXPECT_NEAR(p.wavelength_m, 0.0555, 1e-15);
  EXPECT_NEAR(p.orbit.time_s.front(), 1 * 3600 + 59 * 60 + 50, 1e-6);
  ASSERT_EQ(p.orbit.position_m.size(), 5u);
}

// A look_side nested a million [ ] deep (2 MB) overflowed the stack when
// the error message dumped it; only scalars are quoted now.
TEST(OrbitFileTest, DeeplyNestedRadarGridValueIsAClearError) {
  const auto dir = MakeTempDir();
  const std::string deep = std::string(1000000, '[') + std::string(1000000, ']');
  const std::string text =
      "{\"starting_range_m\": 850000, \"range_spacing_m\": 2.3, \"sensing_start_utc\": \"2021-11-19T02:00:05\", "
      "\"azimuth_time_interval_s\": 0.002, \"width\": 100, \"length\": 100, \"wavelength_m\": 0.0555, "
      "\"look_side\": " + deep + "}";
  try {
    ReadRadarGrid(WriteFile(dir, "deep.json", text));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'look_side' must be"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("a JSON array"), std::string::npos) << e.what();
  }
}

TEST(OrbitFileTest, OrbitMustCoverTheImageAndGridKeysAreChecked) {
  const auto dir = MakeTempDir();
  const StateVectors v = ReadStateVectors(TestDataPath("orbits/s1_poeorb_excerpt.EOF"));
  std::string late = kGridJson;
  late.replace(late.find("02:00:05.5"), 10, "02:00:29.9");  // 200 lines x 2 ms run past 02:00:30
  const RadarGridSpec grid = ReadRadarGrid(WriteFile(dir, "late.json", late));
  try {
    ProductFromOrbit(v, "orbit.EOF", grid, "late.json");
    ADD_FAILURE() << "an orbit not covering the image was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not cover"), std::string::npos) << e.what();
    EXPECT_EQ(e.where(), "orbit.EOF");
  }
  for (const auto& [edit, expected] : std::vector<std::pair<std::pair<std::string, std::string>, std::string>>{
           {{"\"width\": 300", "\"width\": 0"}, "'width'"},
           {{"\"look_side\": \"right\"", "\"look_side\": \"up\""}, "'look_side'"},
           {{"\"wavelength_m\"", "\"wavelength\""}, "unknown key 'wavelength'"},
           {{"\"range_spacing_m\": 2.33,", ""}, "missing key 'range_spacing_m'"}}) {
    std::string text = kGridJson;
    text.replace(text.find(edit.first), edit.first.size(), edit.second);
    try {
      ReadRadarGrid(WriteFile(dir, "bad.json", text));
      ADD_FAILURE() << "accepted " << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace gissar::geo
