#include "gissar/geo/vertical_datum.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "gissar/geo/dem.h"
#include "gissar/geo/geoid.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::geo {
namespace {
namespace fs = std::filesystem;

std::string ConfigErrorOf(const std::string& value) {
  try {
    CanonicalVerticalDatum(value);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(VerticalDatumTest, FlagValuesBecomeCanonicalNames) {
  EXPECT_EQ(CanonicalVerticalDatum(""), "");
  EXPECT_EQ(CanonicalVerticalDatum("ellipsoid"), "ellipsoid");
  EXPECT_EQ(CanonicalVerticalDatum("EGM96"), "egm96");
  EXPECT_EQ(CanonicalVerticalDatum("egm2008"), "egm2008");
  EXPECT_EQ(CanonicalVerticalDatum("EPSG:5773"), "egm96");  // EGM96 height
  EXPECT_EQ(CanonicalVerticalDatum("epsg:3855"), "egm2008");  // EGM2008 height
  EXPECT_EQ(CanonicalVerticalDatum("EPSG:4979"), "ellipsoid");  // WGS 84 3-D
  EXPECT_EQ(CanonicalVerticalDatum("EPSG:5703"), "EPSG:5703");  // NAVD88 height
  for (const std::string bad : {"egm97", "EPSG:4326", "EPSG:", "EPSG:12x", "EPSG:999999", "5773"}) {
    const std::string what = ConfigErrorOf(bad);
    EXPECT_NE(what.find("--vertical-datum"), std::string::npos) << bad << ": " << what;
    EXPECT_NE(what.find(bad), std::string::npos) << bad << ": " << what;
  }
  EXPECT_NE(ConfigErrorOf("EPSG:4326").find("not a vertical CRS"), std::string::npos);
}

TEST(VerticalDatumTest, FileDatumFromTheCompoundOr3dCrsOrTheSrtmDriver) {
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:4326+5773"), "egm96");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:32631+3855"), "egm2008");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:4326+5703"), "EPSG:5703");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:4979"), "ellipsoid");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:4326"), "");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:32631"), "");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:4326", "SRTMHGT"), "egm96");
  EXPECT_EQ(VerticalDatumOfCrs("EPSG:4979", "SRTMHGT"), "ellipsoid");  // the CRS wins

  EXPECT_EQ(ResolveVerticalDatum("egm2008", "egm96").source, "flag");
  EXPECT_EQ(ResolveVerticalDatum("", "egm96").datum, "egm96");
  EXPECT_EQ(ResolveVerticalDatum("", "egm96").source, "file");
  EXPECT_EQ(ResolveVerticalDatum("", "").datum, "ellipsoid");
  EXPECT_EQ(ResolveVerticalDatum("", "").source, "assumed");
  const std::string warning = AssumedDatumWarning("dem.tif");
  EXPECT_NE(warning.find("dem.tif"), std::string::npos);
  EXPECT_NE(warning.find("--vertical-datum"), std::string::npos);
  EXPECT_EQ(warning.find('\n'), std::string::npos);
}

// EGM96 through PROJ (EPSG:4326+5773 -> EPSG:4979, egm96_15.gtx) and the fast
// path agree within 1 cm; at Winnipeg the grid posts give N = -26.4587 m
// (Egm96GeoidTest.MatchesProjAtWinnipeg).
TEST(VerticalDatumTest, Egm96ThroughProjAgreesWithTheFastPath) {
  const std::vector<double> lon = {-97.625, 7.42, 1.52, -120.0}, lat = {49.5, 43.73, 42.5, 36.3};
  const std::vector<double> fast = GeoidUndulationsM("egm96", lon, lat, "test");
  const std::vector<double> proj = GeoidUndulationsViaProjM("egm96", lon, lat, "test");
  const std::vector<double> by_code = GeoidUndulationsViaProjM("EPSG:5773", lon, lat, "test");
  ASSERT_EQ(fast.size(), 4u);
  EXPECT_NEAR(fast[0], -26.4587, 1e-3);
  for (size_t i = 0; i < lon.size(); ++i) {
    EXPECT_NEAR(proj[i], fast[i], 0.01) << i;
    EXPECT_EQ(by_code[i], proj[i]) << i;
  }
  EXPECT_EQ(GeoidUndulationsM("ellipsoid", lon, lat, "test"), std::vector<double>(4, 0.0));
}

// Debian's proj-data has no EGM2008 grid: an InputError naming the grid and
// the DEM, never a zero shift.
TEST(VerticalDatumTest, MissingEgm2008GridIsAnInputErrorNamingIt) {
  try {
    const std::vector<double> n = GeoidUndulationsM("egm2008", {-97.625}, {49.5}, "dem.tif");
    GTEST_SKIP() << "PROJ found the EGM2008 grid here (N = " << n[0] << " m)";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("us_nga_egm08_25.tif"), std::string::npos) << what;
    EXPECT_NE(what.find("dem.tif"), std::string::npos) << what;
    EXPECT_NE(what.find("PROJ_DATA"), std::string::npos) << what;
  }
}

// A DEM tagged EPSG:4326+5773 reads as egm96 and its heights rise by the
// undulation at each post; an untagged one names no datum.
TEST(VerticalDatumTest, TaggedDemConvertsToEllipsoidalHeights) {
  const fs::path dir = testing::MakeTempDir();
  // 3 x 3 posts of 0.25 deg around Winnipeg: post (1, 1) at (-97.625, 49.5).
  const std::array<double, 6> gt = {-98.0, 0.25, 0.0, 49.875, 0.0, -0.25};
  const std::vector<float> heights(9, 230.0f);
  WriteDemGeoTiff(dir / "tagged.tif", heights, 3, 3, gt, "EPSG:4326+5773");
  WriteDemGeoTiff(dir / "plain.tif", heights, 3, 3, gt, "EPSG:4326");
  Dem tagged = ReadDem(dir / "tagged.tif");
  EXPECT_EQ(tagged.file_vertical_datum, "egm96");
  EXPECT_EQ(ReadDem(dir / "plain.tif").file_vertical_datum, "");
  ToEllipsoidalHeights(tagged, tagged.file_vertical_datum);
  EXPECT_NEAR(tagged.HeightAt(1, 1), 230.0 - 26.4587, 1e-3);
  EXPECT_NEAR(tagged.HeightAt(1, 1), 230.0 + Egm96Geoid().UndulationM(-97.625, 49.5), 1e-4);
  Dem plain = ReadDem(dir / "plain.tif");
  ToEllipsoidalHeights(plain, "ellipsoid");
  EXPECT_EQ(plain.HeightAt(1, 1), 230.0f);
}

}  // namespace
}  // namespace gissar::geo
