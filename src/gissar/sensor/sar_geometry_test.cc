#include "gissar/sensor/sar_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::sensor {
namespace {

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  int Column(const std::string& name) const {
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    return -1;
  }
};

CsvTable ReadCsv(const std::filesystem::path& path) {
  std::ifstream in(path);
  CsvTable table;
  std::string line;
  std::getline(in, line);
  std::stringstream hs(line);
  for (std::string cell; std::getline(hs, cell, ',');) table.header.push_back(cell);
  while (std::getline(in, line)) {
    std::stringstream ls(line);
    std::vector<double> row;
    for (std::string cell; std::getline(ls, cell, ',');) row.push_back(std::stod(cell));
    table.rows.push_back(row);
  }
  return table;
}

SarGeometryOptions Options(double heading, double depression, double res_r, double res_a) {
  SarGeometryOptions o;
  o.heading_deg = heading;
  o.depression_deg = depression;
  o.range_spacing_m = res_r;
  o.azimuth_spacing_m = res_a;
  return o;
}

// The affine mode is the camera P_SAR = C_SAR P_par G_perp of the shared
// reference cases: every noise-free reference pixel is reproduced.
void ExpectReferenceCaseProjects(const std::string& name) {
  const auto json_path = testing::TestDataPath("affine/" + name + ".json");
  const auto csv_path = testing::TestDataPath("affine/" + name + "_points.csv");
  ASSERT_TRUE(std::filesystem::exists(json_path)) << json_path;
  nlohmann::json ref;
  std::ifstream(json_path) >> ref;
  const auto& g = ref["geometry"];
  const SarGeometry view1(Options(g["heading1_deg"], g["depression1_deg"], g["res_range1_m"],
                                  g["res_az1_m"]),
                          Eigen::Vector3d::Zero(), g["u0"], g["v0"], 1024, 1024);
  const SarGeometry view2(Options(g["heading2_deg"], g["depression2_deg"], g["res_range2_m"],
                                  g["res_az2_m"]),
                          Eigen::Vector3d::Zero(), g["u0"], g["v0"], 1024, 1024);
  const CsvTable points = ReadCsv(csv_path);
  const int cx = points.Column("X"), cy = points.Column("Y"), cz = points.Column("Z");
  const int x1 = points.Column("x1_true"), y1 = points.Column("y1_true");
  const int x2 = points.Column("x2_true"), y2 = points.Column("y2_true");
  ASSERT_GT(points.rows.size(), 40u);
  for (const auto& row : points.rows) {
    const Eigen::Vector3d X(row[cx], row[cy], row[cz]);
    const Eigen::Vector2d p1 = view1.Project(X), p2 = view2.Project(X);
    EXPECT_NEAR(p1.x(), row[x1], 1e-9);
    EXPECT_NEAR(p1.y(), row[y1], 1e-9);
    EXPECT_NEAR(p2.x(), row[x2], 1e-9);
    EXPECT_NEAR(p2.y(), row[y2], 1e-9);
  }
}

TEST(SarGeometryTest, AffineModeReproducesReferenceCase2) {
  ExpectReferenceCaseProjects("case2_thesis_dpsi30_dep40_noisefree");
}

TEST(SarGeometryTest, AffineModeReproducesReferenceCase3) {
  ExpectReferenceCaseProjects("case3_dpsi30_dep40_45_res1_0.75");
}

TEST(SarGeometryTest, UnitVectorsFollowTheConventions) {
  const SarGeometry g(Options(90.0, 30.0, 1, 1), Eigen::Vector3d::Zero(), 0, 0, 10, 10);
  // Flying east, right-looking: looking south and down.
  EXPECT_NEAR((g.flight_direction() - Eigen::Vector3d(1, 0, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((g.look_direction() - Eigen::Vector3d(0, -std::cos(M_PI / 6), -0.5)).norm(), 0,
              1e-12);
  // The sensor is R away, up-range and above the scene centre.
  const Eigen::Vector3d s = g.SensorPosition(0.0);
  EXPECT_NEAR(s.z(), 10000.0 * 0.5, 1e-9);
  EXPECT_NEAR(s.y(), 10000.0 * std::cos(M_PI / 6), 1e-9);
}

TEST(SarGeometryTest, LeftLookingMirrorsTheLookDirection) {
  SarGeometryOptions o = Options(0.0, 40.0, 1, 1);
  o.look_side = LookSide::kLeft;
  const SarGeometry g(o, Eigen::Vector3d::Zero(), 0, 0, 10, 10);
  EXPECT_LT(g.look_direction().x(), 0.0);
  EXPECT_GT(g.UpwardRangePlaneNormal(Eigen::Vector3d::Zero()).z(), 0.0);
}

// Exact (zero-Doppler, true range) geometry against a closed form in the
// vertical plane through the sensor: a point at ground-range offset g and
// height z relative to Xc has range sqrt((R cos d + g)^2 + (R sin d - z)^2).
double ExactRangeClosedForm(double R, double dep_deg, double g, double z) {
  const double d = dep_deg * M_PI / 180.0;
  return std::hypot(R * std::cos(d) + g, R * std::sin(d) - z);
}

TEST(SarGeometryTest, ExactModeUsesTrueSlantRange) {
  SarGeometryOptions o = Options(0.0, 40.0, 1.0, 1.0);
  o.mode = ProjectionMode::kExact;
  o.slant_range_m = 2000.0;
  const SarGeometry g(o, Eigen::Vector3d::Zero(), 100, 100, 200, 200);
  // Heading north, right-looking: ground range is +x (east).
  const Eigen::Vector3d p(60.0, 35.0, 12.0);
  EXPECT_NEAR(g.SlantRange(p), ExactRangeClosedForm(2000.0, 40.0, 60.0, 12.0), 1e-9);
  EXPECT_NEAR(g.Project(p).y(), 100.0 + 35.0, 1e-12);
}

TEST(SarGeometryTest, ExactAndAffineAgreeInTheFarField) {
  // Scene of 100 m; range 100x the scene size.
  const Eigen::Vector3d p(50.0, -40.0, 20.0);
  for (double heading : {0.0, 30.0, 135.0}) {
    SarGeometryOptions o = Options(heading, 40.0, 1.0, 1.0);
    o.slant_range_m = 10000.0;
    const SarGeometry affine(o, Eigen::Vector3d::Zero(), 100, 100, 200, 200);
    o.mode = ProjectionMode::kExact;
    const SarGeometry exact(o, Eigen::Vector3d::Zero(), 100, 100, 200, 200);
    EXPECT_LT((affine.Project(p) - exact.Project(p)).norm(), 0.5);
  }
}

TEST(SarGeometryTest, ExactAndAffineDifferByTheRangeCurvatureAtShortRange) {
  SarGeometryOptions o = Options(0.0, 40.0, 1.0, 1.0);
  o.slant_range_m = 1000.0;
  const SarGeometry affine(o, Eigen::Vector3d::Zero(), 100, 100, 200, 200);
  o.mode = ProjectionMode::kExact;
  const SarGeometry exact(o, Eigen::Vector3d::Zero(), 100, 100, 200, 200);
  const double g = 150.0, z = 30.0;
  const Eigen::Vector3d p(g, 0.0, z);
  const double d = 40.0 * M_PI / 180.0;
  const double affine_range = 1000.0 + g * std::cos(d) - z * std::sin(d);
  const double expected_px = ExactRangeClosedForm(1000.0, 40.0, g, z) - affine_range;
  EXPECT_GT(expected_px, 5.0);  // clearly not far field
  EXPECT_NEAR(exact.Project(p).x() - affine.Project(p).x(), expected_px, 1e-9);
}

TEST(SarGeometryTest, CoveringFramesEveryPoint) {
  SarGeometryOptions o = Options(30.0, 40.0, 2.0, 3.0);
  std::vector<Eigen::Vector3f> points = {{-500, -400, 0}, {600, 300, 100}, {100, -200, 50}};
  const SarGeometry g = SarGeometry::Covering(o, Eigen::Vector3d::Zero(), points);
  for (const auto& p : points) {
    const Eigen::Vector2d px = g.Project(p.cast<double>());
    EXPECT_GE(px.x(), 1.0);
    EXPECT_GE(px.y(), 1.0);
    EXPECT_LE(px.x(), g.width() - 2.0);
    EXPECT_LE(px.y(), g.height() - 2.0);
  }
}

TEST(SarGeometryTest, RejectsBadOptions) {
  SarGeometryOptions o = Options(0.0, 40.0, 1.0, 1.0);
  for (double dep : {0.0, 90.0, -10.0, std::nan("")}) {
    o.depression_deg = dep;
    EXPECT_THROW(o.Check(), ConfigError) << dep;
  }
  o.depression_deg = 40.0;
  o.heading_deg = std::nan("");
  EXPECT_THROW(o.Check(), ConfigError);
  o.heading_deg = 0.0;
  o.range_spacing_m = 0.0;
  EXPECT_THROW(o.Check(), ConfigError);
  o.range_spacing_m = 1.0;
  o.azimuth_spacing_m = -2.0;
  EXPECT_THROW(o.Check(), ConfigError);
  EXPECT_THROW(ParseProjectionMode("fisheye"), ConfigError);
}

// A given size is refused before anything projects its footprint: over
// kMaxImagePixels (from the options alone, whatever the spacings), or
// spanning more than the Earth's radius on an axis at the resolved spacing
// (gissar simulate --width 2147483647 --height 1 once reached PROJ with
// points off the Earth: "Reprojection failed, err = 2050").
TEST(SarGeometryTest, RejectsGivenSizesTooLargeOrLeavingTheEarth) {
  auto error_of = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.where(), "--width/--height");
      return e.message();
    }
    return "";
  };
  const std::vector<Eigen::Vector3f> points = {{-50, -40, 0}, {60, 30, 10}};
  SarGeometryOptions o = Options(0.0, 40.0, 90.0, 90.0);
  auto check = [&] { o.Check(); };
  auto covering = [&] { SarGeometry::Covering(o, Eigen::Vector3d::Zero(), points); };
  o.width = 2147483647;
  o.height = 1;
  EXPECT_EQ(error_of(check),
            "image of 2147483647 x 1 pixels is over the 1073741824-pixel limit; use a smaller --width/--height");
  o.width = 100000;  // 9000 km at 90 m
  EXPECT_EQ(error_of(check), "");  // the spacing may be a placeholder in Check
  EXPECT_EQ(error_of(covering),
            "--width 100000 at 90 m per pixel spans 9000 km, beyond the Earth's radius (6371 km): the image's "
            "footprint would leave the Earth; use a smaller --width or a finer --range-spacing");
  o.width = 1;
  o.height = 100000;
  EXPECT_NE(error_of(covering).find("--height 100000 at 90 m per pixel spans 9000 km"), std::string::npos);
  o.height = 70000;  // 6300 km: within the Earth's radius
  EXPECT_EQ(error_of(covering), "");
  o.height = 0;  // covering the points
  EXPECT_EQ(error_of(covering), "");
  // One side given, the other covering: the image made is checked.
  o = Options(0.0, 40.0, 0.001, 1.0);
  o.width = 2147483647;  // 2147 km
  EXPECT_NE(error_of(covering).find("pixels is too large; use a smaller --width/--height"), std::string::npos)
      << error_of(covering);
  // Both given, over a caller's smaller limit.
  o.width = 3000;
  o.height = 3000;
  EXPECT_THROW(SarGeometry::Covering(o, Eigen::Vector3d::Zero(), points, 2, 1000000), ConfigError);
  EXPECT_EQ(SarGeometry::Covering(o, Eigen::Vector3d::Zero(), points).width(), 3000);
}

}  // namespace
}  // namespace gissar::sensor
