#include "gissar/material/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "gissar/util/error.h"

namespace gissar::material {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kC = 0.0555, kX = 0.031;  // C- and X-band wavelengths, m

double Db(double v) { return 10.0 * std::log10(v); }

TEST(MaterialTest, DefaultIsBareSoil) {
  const MaterialTable table;
  EXPECT_EQ(table.Get(0).model, ScatteringModel::kOh);
  EXPECT_EQ(table.Get(7).name, "default");
  EXPECT_FALSE(table.Get(0).source.empty());
}

// Lambertian albedo rho: sigma0 = 4 rho cos^2(theta).
TEST(MaterialTest, LegacyLambertLaw) {
  const Material m{"m", 0.5};
  EXPECT_NEAR(m.Sigma0(std::cos(60 * kDeg), kC, Polarization::kVV), 4 * 0.5 * 0.25, 1e-12);
  EXPECT_EQ(m.Sigma0(-0.1, kC, Polarization::kVV), 0.0);
}

// Oh et al. 1992 at nadir: p = 1 and both Fresnel terms are
// Gamma0 = |(1 - sqrt(eps)) / (1 + sqrt(eps))|^2, so
// sigma0_VV = sigma0_HH = 0.7 (1 - exp(-0.65 (ks)^1.8)) 2 Gamma0 and
// sigma0_HV = 0.23 sqrt(Gamma0) (1 - exp(-ks)) sigma0_VV.
TEST(MaterialTest, OhModelAtNadirIsClosedForm) {
  Material m;
  m.model = ScatteringModel::kOh;
  m.permittivity = {9.0, 0.0};  // sqrt = 3: Gamma0 = (2/4)^2 = 1/4
  m.rms_height_m = 0.01;
  const double ks = 2 * M_PI / kC * 0.01;
  const double g = 0.7 * (1 - std::exp(-0.65 * std::pow(ks, 1.8)));
  EXPECT_NEAR(m.Sigma0(1.0, kC, Polarization::kVV), g * 2 * 0.25, 1e-9);
  EXPECT_NEAR(m.Sigma0(1.0, kC, Polarization::kHH), g * 2 * 0.25, 1e-9);
  EXPECT_NEAR(m.Sigma0(1.0, kC, Polarization::kHV), 0.23 * 0.5 * (1 - std::exp(-ks)) * g * 0.5, 1e-9);
  // Away from nadir HH <= VV and the return falls with incidence.
  const double c30 = std::cos(30 * kDeg), c50 = std::cos(50 * kDeg);
  EXPECT_LT(m.Sigma0(c30, kC, Polarization::kHH), m.Sigma0(c30, kC, Polarization::kVV));
  EXPECT_LT(m.Sigma0(c50, kC, Polarization::kVV), m.Sigma0(c30, kC, Polarization::kVV));
  // Rougher (relative to the wavelength) is brighter.
  EXPECT_GT(m.Sigma0(c30, kX, Polarization::kVV), m.Sigma0(c30, kC, Polarization::kVV));
}

TEST(MaterialTest, TableInterpolatesInDecibels) {
  Material m;
  m.model = ScatteringModel::kTable;
  m.sigma0_db = {{10, -10}, {50, -18}};
  EXPECT_NEAR(Db(m.Sigma0(std::cos(30 * kDeg), kC, Polarization::kVV)), -14.0, 0.02);
  EXPECT_NEAR(Db(m.Sigma0(1.0, kC, Polarization::kVV)), -10.0, 1e-9);
  EXPECT_NEAR(Db(m.Sigma0(std::cos(80 * kDeg), kC, Polarization::kVV)), -18.0, 1e-9);
  m.gain_db = 3.0;
  EXPECT_NEAR(Db(m.Sigma0(1.0, kC, Polarization::kVV)), -7.0, 1e-9);
  // The renderers' lookup table agrees to 0.01 dB.
  const Sigma0Table t(m, kC, Polarization::kVV);
  EXPECT_NEAR(Db(t(std::cos(30 * kDeg))), -11.0, 0.01);
}

// MaterialTable keeps the tables it built per (wavelength, polarisation)
// and builds new ones when a material changes; a copy keeps its own.
TEST(MaterialTest, TablesAreKeptUntilAMaterialChanges) {
  MaterialTable table;
  Material flat;
  flat.model = ScatteringModel::kTable;
  flat.sigma0_db = {{0, -10}, {90, -10}};
  table.Set(1, flat);
  const std::vector<Sigma0Table> first = table.Tables(kC, Polarization::kVV);
  ASSERT_EQ(first.size(), 2u);
  EXPECT_NEAR(Db(first[1](std::cos(40 * kDeg))), -10.0, 1e-6);
  // The same request again: the same values.
  const std::vector<Sigma0Table> again = table.Tables(kC, Polarization::kVV);
  EXPECT_EQ(again[0](0.6), first[0](0.6));
  EXPECT_EQ(again[1](0.6), first[1](0.6));
  const MaterialTable copy = table;
  flat.sigma0_db = {{0, -20}, {90, -20}};
  table.Set(1, flat);
  EXPECT_NEAR(Db(table.Tables(kC, Polarization::kVV)[1](std::cos(40 * kDeg))), -20.0, 1e-6);
  EXPECT_NEAR(Db(copy.Tables(kC, Polarization::kVV)[1](std::cos(40 * kDeg))), -10.0, 1e-6);
  // Another wavelength or polarisation is its own table (Oh 1992 depends on both).
  EXPECT_NE(table.Tables(kC, Polarization::kVV)[0](0.6), table.Tables(kC, Polarization::kHH)[0](0.6));
  EXPECT_NE(table.Tables(kC, Polarization::kVV)[0](0.6), table.Tables(0.24, Polarization::kVV)[0](0.6));
}

// The table's angle lookup without libm: within 2e-8 rad of std::acos over
// [0, 1] (Abramowitz & Stegun's bound), exact at the ends, clamped outside.
TEST(MaterialTest, TableAngleLookupIsAcosTo2e8Radians) {
  double worst = 0.0;
  for (int i = 0; i <= 200000; ++i) {
    const double x = i / 200000.0;
    worst = std::max(worst, std::abs(AcosOfUnitInterval(x) - std::acos(x)));
  }
  EXPECT_LT(worst, 2.5e-8);
  EXPECT_NEAR(AcosOfUnitInterval(1.0), 0.0, 1e-15);
  EXPECT_NEAR(AcosOfUnitInterval(0.0), M_PI / 2, 2.5e-8);
  EXPECT_EQ(AcosOfUnitInterval(1.5), AcosOfUnitInterval(1.0));
  // A Lambertian law (4 cos^2) read through the table at random angles:
  // the table's own interpolation error only (0.05 deg steps).
  Material lambert{"default", 1.0};
  const Sigma0Table t(lambert, kC, Polarization::kVV);
  for (double deg = 0.0; deg < 89.9; deg += 0.731) {
    const double c = std::cos(deg * kDeg);
    EXPECT_NEAR(t(c), lambert.Sigma0(c, kC, Polarization::kVV), 2e-6) << deg;
  }
}

// The float lookup without an arc cosine: 4 cos^2 read at random angles
// within the two tables' interpolation errors (the angle table's 0.05 deg
// steps: |d2f/dtheta2| <= 8, so <= 8 (8.7e-4)^2 / 8 = 7.6e-7; steps of
// 1/4096 in s = sqrt(1 - cos): 4 (1 - s^2)^2 has |f''| <= 16, so <= 16 /
// (8 4096^2) = 1.2e-7) and float rounding; a table law (-10 dB at 10 deg,
// -18 dB at 50 deg) to 0.01 dB; 0 at and beyond grazing.
TEST(MaterialTest, FastLookupFollowsTheLaw) {
  Material lambert{"default", 1.0};
  const Sigma0Table t(lambert, kC, Polarization::kVV);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(0.0, 89.99);
  double worst = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const double c = std::cos(angle(rng) * kDeg);
    worst = std::max(worst, std::abs(double(t.Fast(float(c))) - 4.0 * c * c));
  }
  EXPECT_LT(worst, 2e-6);
  EXPECT_EQ(t.Fast(1.0f), 4.0f);
  EXPECT_EQ(t.Fast(0.0f), 0.0f);
  EXPECT_EQ(t.Fast(-0.5f), 0.0f);
  Material m;
  m.model = ScatteringModel::kTable;
  m.sigma0_db = {{10, -10}, {50, -18}};
  const Sigma0Table table(m, kC, Polarization::kVV);
  EXPECT_NEAR(Db(table.Fast(float(std::cos(30 * kDeg)))), -14.0, 0.01);
}

// Debye water at 5.40 GHz (lambda 5.55 cm), 20 deg C:
// omega tau = 2 pi 5.4e9 9.36e-12 = 0.3177, eps = 4.9 + 75.2 / (1 + 0.3177 j)
// = 73.2 - 21.7 j.
TEST(MaterialTest, WaterPermittivityIsDebye) {
  const auto eps = WaterPermittivity(kC, 0.0);
  EXPECT_NEAR(eps.real(), 73.2, 0.2);
  EXPECT_NEAR(eps.imag(), -21.7, 0.2);
  // Sea water (35 psu): eps_s = 71.6, tau = 9.0 ps (omega tau = 0.3055)
  // and ionic loss 4.8 / (omega eps0) = 4.8 / 0.3005 = 15.97:
  // 4.9 + 66.7 / 1.0933 = 65.9 real, -66.7 * 0.3055 / 1.0933 - 15.97 = -34.6.
  const auto sea = WaterPermittivity(kC, 35.0);
  EXPECT_NEAR(sea.real(), 65.9, 0.3);
  EXPECT_NEAR(sea.imag(), -34.6, 0.3);
}

TEST(MaterialTest, WindRaisesTheSeaSpectrumAndBackscatter) {
  EXPECT_LT(ElfouhailyCurvature(150.0, 3.0), ElfouhailyCurvature(150.0, 7.0));
  Material sea = DefaultMaterial(scene::kClassWater);
  const double c40 = std::cos(40 * kDeg);
  const double calm = sea.Sigma0(c40, kC, Polarization::kVV);
  sea.wind_speed_m_s = 10.0;
  EXPECT_GT(sea.Sigma0(c40, kC, Polarization::kVV), 4.0 * calm);  // > 6 dB from 3 to 10 m/s
  // Bragg: VV above HH on the sea.
  EXPECT_GT(sea.Sigma0(c40, kC, Polarization::kVV), sea.Sigma0(c40, kC, Polarization::kHH));
}

// Sea at 3 m/s wind, C band, VV, against an independent reference: the
// CMOD5.n geophysical model function (Hersbach 2010, ECMWF Tech. Memo. 615;
// C-band VV scatterometer calibration), its azimuth mean of sigma0 (linear)
// at 3 m/s evaluated from its published coefficients:
//   30 deg -16.8, 35 deg -20.4, 40 deg -23.0, 45 deg -25.1, 50 deg -26.9 dB.
// The two-scale model must stay within 2 dB of it. Issue 17 asks the sea to
// be >= 15 dB below `default` and `forest` at 30-50 deg; CMOD5.n itself puts
// 3 m/s sea only 6.6 (30 deg) to 13.5 dB (50 deg) below the -10 to -13 dB
// dry-soil `default` law, so that target is not physical at 3 m/s
// (docs/radiometry.md): the contrasts asserted are those of the reference
// less its 2 dB tolerance, and the 15 dB contrast to forest where the
// reference itself reaches it by 2 dB (45-50 deg).
TEST(MaterialTest, SeaMatchesCmod5nAndIsDarkerThanLand) {
  const MaterialTable t = SceneMaterials(nullptr, "test");
  const scene::ClassId sea = *scene::ClassIdFromName("sea");
  EXPECT_EQ(t.Get(sea).model, ScatteringModel::kBragg);
  EXPECT_EQ(t.Get(sea).wind_speed_m_s, 3.0);
  const std::pair<double, double> cmod5n[] = {{30, -16.8}, {35, -20.4}, {40, -23.0}, {45, -25.1}, {50, -26.9}};
  for (const auto& [inc, reference_db] : cmod5n) {
    const double c = std::cos(inc * kDeg);
    const double water = Db(t.Get(sea).Sigma0(c, kC, Polarization::kVV));
    const double land = Db(t.Get(scene::kClassDefault).Sigma0(c, kC, Polarization::kVV));
    const double forest = Db(t.Get(scene::kClassForest).Sigma0(c, kC, Polarization::kVV));
    std::printf("incidence %.0f: sea %.1f dB (CMOD5.n %.1f), default %.1f, forest %.1f: sea - default %.1f, "
                "sea - forest %.1f dB\n",
                inc, water, reference_db, land, forest, water - land, water - forest);
    EXPECT_NEAR(water, reference_db, 2.0) << inc;
    EXPECT_LE(water - land, reference_db - land + 2.0) << inc;
    EXPECT_LE(water - forest, reference_db - forest + 2.0) << inc;
    if (reference_db - forest <= -17.0) {
      EXPECT_LE(water - forest, -15.0) << inc;
    }
  }
}

// Water-cloud: an opaque canopy returns gamma cos(theta).
TEST(MaterialTest, OpaqueCanopyReturnsGammaCosTheta) {
  Material m = DefaultMaterial(scene::kClassForest);
  m.canopy_optical_depth = 50.0;
  const double c = std::cos(40 * kDeg);
  EXPECT_NEAR(Db(m.Sigma0(c, kC, Polarization::kVV)), m.canopy_gamma_db + Db(c), 1e-6);
  EXPECT_NEAR(Db(m.Sigma0(c, kC, Polarization::kHV)), m.canopy_cross_gamma_db + Db(c), 1e-6);
}

TEST(MaterialTest, EnergyIsConserved) {
  Material m{"bright", 0.6, 0.0, 1.0, 0.5};
  EXPECT_THROW(m.Check(), ConfigError);
  for (int c = 0; c < scene::kClassCount; ++c) {
    const Material d = DefaultMaterial(c);
    EXPECT_LE(d.diffuse + d.mirror, 1.0) << d.name;
  }
}

TEST(MaterialTest, PolarizationParses) {
  EXPECT_EQ(ParsePolarization("hv", "--polarization"), Polarization::kHV);
  EXPECT_EQ(ToString(Polarization::kVH), "VH");
  EXPECT_THROW(ParsePolarization("RH", "--polarization"), ConfigError);
}

TEST(MaterialTest, SpecularHighlightIsAConeAroundNormalIncidence) {
  const Material m{"m", 0.0, 1.0, 0.5, 0.0};
  EXPECT_NEAR(m.Backscatter(1.0), 1.0, 1e-12);  // facing the radar
  const double c = std::cos(20.0 * M_PI / 180);
  EXPECT_NEAR(m.Backscatter(c), std::pow(std::cos(40.0 * M_PI / 180), 2.0), 1e-12);
  EXPECT_EQ(m.Backscatter(std::cos(50.0 * M_PI / 180)), 0.0);  // beyond 45 deg
  EXPECT_EQ(m.Backscatter(-0.3), 0.0);
  // Rougher: wider cone.
  const Material rough{"r", 0.0, 1.0, 1.0, 0.0};
  EXPECT_GT(rough.Backscatter(c), m.Backscatter(c));
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
  EXPECT_THROW(table.Set(1, Material{"bad", 0.5, 0.5, 0.0}), ConfigError);
}

TEST(MaterialTest, SceneDefaultsFollowTheThesis) {
  const MaterialTable t = SceneMaterials(nullptr, "test");
  EXPECT_LT(t.Get(scene::kClassWater).diffuse, 0.1);
  EXPECT_GT(t.Get(scene::kClassWater).mirror, 0.5);
  EXPECT_GT(t.Get(scene::kClassForest).diffuse, t.Get(scene::kClassDefault).diffuse);
  EXPECT_GT(t.Get(scene::kClassRoad).specular, t.Get(scene::kClassRoad).diffuse);
  EXPECT_GT(t.Get(scene::kClassBuilding).mirror, 0.5);
}

TEST(MaterialTest, OverridesAreValidatedNamingKeyAndSource) {
  const MaterialTable t = SceneMaterials(nlohmann::json::parse(R"({"water": {"diffuse": 0.01}})"), "s.json");
  EXPECT_EQ(t.Get(scene::kClassWater).diffuse, 0.01);
  EXPECT_EQ(t.Get(scene::kClassWater).mirror, DefaultMaterial(scene::kClassWater).mirror);
  auto expect_error = [](const char* text, const std::string& needle) {
    try {
      SceneMaterials(nlohmann::json::parse(text), "s.json");
      FAIL() << text;
    } catch (const ConfigError& e) {
      EXPECT_NE(e.message().find(needle), std::string::npos) << e.what();
      EXPECT_EQ(e.where(), "s.json");
    }
  };
  expect_error(R"({"lava": {}})", "materials.lava");
  expect_error(R"({"water": {"shininess": 3}})", "materials.water.shininess");
  expect_error(R"({"water": {"diffuse": "dark"}})", "must be a number");
  expect_error(R"({"road": {"diffuse": -0.2}})", "diffuse must be in [0, 1]");
  expect_error(R"({"road": {"sigma0_db": [[10, -5], [5, -6]]}})", "sigma0_db row 1");
  expect_error(R"({"road": {"sigma0_db": [10, -5]}})", "incidence_deg, dB");
  expect_error(R"({"road": {"model": "iem"}})", "materials.road.model");
  expect_error(R"({"road": {"diffuse": 0.8, "mirror": 0.5}})", "albedo");
  const MaterialTable u = SceneMaterials(
      nlohmann::json::parse(R"({"default": {"sigma0_db": [[0, -10], [90, -10]]}})"), "s.json");
  EXPECT_EQ(u.Get(scene::kClassDefault).model, ScatteringModel::kTable);
  EXPECT_NEAR(u.Get(scene::kClassDefault).Sigma0(0.5, kC, Polarization::kHH), 0.1, 1e-12);
}

}  // namespace
}  // namespace gissar::material

#include "gissar/material/reflector.h"

#include <filesystem>
#include <fstream>

namespace gissar::material {
namespace {

TEST(ReflectorPhysicsTest, BoresightRcsIsClosedForm) {
  const double a = 0.5, l = 0.0555, a4 = a * a * a * a;
  EXPECT_NEAR(PeakRcs(ReflectorType::kTrihedral, a, l), 4 * M_PI * a4 / (3 * l * l), 1e-9);
  EXPECT_NEAR(PeakRcs(ReflectorType::kTrihedralSquare, a, l), 12 * M_PI * a4 / (l * l), 1e-9);
  EXPECT_NEAR(PeakRcs(ReflectorType::kDihedral, a, l), 8 * M_PI * a4 / (l * l), 1e-9);
  EXPECT_NEAR(PeakRcs(ReflectorType::kPlate, a, l), 4 * M_PI * a4 / (l * l), 1e-9);
  const Eigen::Vector3d b = BoresightVector(120.0, 30.0);
  for (ReflectorType t : {ReflectorType::kTrihedral, ReflectorType::kTrihedralSquare, ReflectorType::kDihedral,
                          ReflectorType::kPlate}) {
    EXPECT_NEAR(ReflectorRcs(t, a, l, b, b), PeakRcs(t, a, l), 1e-9 * PeakRcs(t, a, l)) << ToString(t);
    EXPECT_EQ(ReflectorRcs(t, a, l, b, -b), 0.0);
  }
}

// Off boresight: a plate's first null in elevation is at k a sin(eps) = pi
// (sin eps = lambda / (2 a)); a dihedral keeps (sin(45 - eps) / sin 45)^2 in
// the plane normal to its fold; a trihedral falls off smoothly.
TEST(ReflectorPhysicsTest, OffBoresightFollowsPhysicalOptics) {
  const double a = 1.0, l = 0.031;
  const double null_deg = std::asin(l / (2 * a)) * 180 / M_PI;
  const Eigen::Vector3d b = BoresightVector(0.0, 10.0);
  EXPECT_LT(ReflectorRcs(ReflectorType::kPlate, a, l, b, BoresightVector(0.0, 10.0 + null_deg)),
            1e-9 * PeakRcs(ReflectorType::kPlate, a, l));
  const double f = std::sin((45.0 - 10.0) * M_PI / 180) / std::sin(45.0 * M_PI / 180);
  EXPECT_NEAR(ReflectorRcs(ReflectorType::kDihedral, a, l, b, BoresightVector(0.0, 20.0)),
              PeakRcs(ReflectorType::kDihedral, a, l) * f * f, 1e-6 * PeakRcs(ReflectorType::kDihedral, a, l));
  const double t10 = ReflectorRcs(ReflectorType::kTrihedral, a, l, b, BoresightVector(0.0, 20.0));
  const double t30 = ReflectorRcs(ReflectorType::kTrihedral, a, l, b, BoresightVector(0.0, 40.0));
  EXPECT_LT(t10, PeakRcs(ReflectorType::kTrihedral, a, l));
  EXPECT_GT(t10, 0.3 * PeakRcs(ReflectorType::kTrihedral, a, l));
  EXPECT_LT(t30, t10);
}

TEST(ReflectorPhysicsTest, CsvRowsAreCheckedByRow) {
  const auto dir = std::filesystem::temp_directory_path() / "gissar_reflector_csv_test";
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& text) {
    const auto p = dir / "r.csv";
    std::ofstream(p) << text;
    return p.string();
  };
  const std::string header = "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n";
  const auto ok = ReadReflectorsCsv(write(header + "trihedral,7.42,43.73,0,1.0,270,35\n# note\ndihedral,7.43,43.74,1.5,0.5,90,0\n"));
  ASSERT_EQ(ok.size(), 2u);
  EXPECT_EQ(ok[1].type, ReflectorType::kDihedral);
  EXPECT_EQ(ok[1].row, 2);
  EXPECT_EQ(ok[0].boresight_elevation_deg, 35.0);
  auto expect_row_error = [&](const std::string& rows, const std::string& row, const std::string& needle) {
    try {
      ReadReflectorsCsv(write(header + rows));
      FAIL() << rows;
    } catch (const InputError& e) {
      EXPECT_NE(e.where().find(row), std::string::npos) << e.what();
      EXPECT_NE(e.message().find(needle), std::string::npos) << e.what();
    }
  };
  expect_row_error("trihedral,7,43,0,1,0,0\nluneburg,7,43,0,1,0,0\n", "row 2", "unknown reflector type");
  expect_row_error("plate,7,43,0,0,0,0\n", "row 1", "size_m");
  expect_row_error("plate,7,43,0,1,0\n", "row 1", "7 fields");
  expect_row_error("plate,7,north,0,1,0,0\n", "row 1", "lat must be a number");
  std::filesystem::remove_all(dir);
}

// The optional roll_deg column: named by the header (any column order),
// 0 when absent; a header with an unknown or missing column is an error
// naming the header, a row without the header's field count one naming
// the row.
TEST(ReflectorPhysicsTest, CsvRollColumnIsOptional) {
  const auto dir = std::filesystem::temp_directory_path() / "gissar_reflector_roll_test";
  std::filesystem::create_directories(dir);
  auto write = [&](const std::string& text) {
    const auto p = dir / "r.csv";
    std::ofstream(p) << text;
    return p.string();
  };
  const std::string seven = "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg";
  const auto rolled = ReadReflectorsCsv(write(seven + ",roll_deg\ndihedral,7.4,43.7,1,0.5,90,0,45\n"
                                                       "trihedral,7.4,43.7,1,0.5,90,35,-10.5\n"));
  ASSERT_EQ(rolled.size(), 2u);
  EXPECT_EQ(rolled[0].roll_deg, 45.0);
  EXPECT_EQ(rolled[1].roll_deg, -10.5);
  EXPECT_EQ(rolled[1].boresight_elevation_deg, 35.0);
  const auto plain = ReadReflectorsCsv(write(seven + "\ndihedral,7.4,43.7,1,0.5,90,0\n"));
  ASSERT_EQ(plain.size(), 1u);
  EXPECT_EQ(plain[0].roll_deg, 0.0);
  // No header: the seven columns, roll 0.
  const auto bare = ReadReflectorsCsv(write("plate,7.4,43.7,1,0.5,90,0\n"));
  ASSERT_EQ(bare.size(), 1u);
  EXPECT_EQ(bare[0].roll_deg, 0.0);
  // Columns in another order.
  const auto shuffled = ReadReflectorsCsv(
      write("roll_deg,type,lat,lon,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
            "30,dihedral,43.7,7.4,1,0.5,90,0\n"));
  ASSERT_EQ(shuffled.size(), 1u);
  EXPECT_EQ(shuffled[0].roll_deg, 30.0);
  EXPECT_EQ(shuffled[0].lon_deg, 7.4);
  EXPECT_EQ(shuffled[0].lat_deg, 43.7);
  auto expect_error = [&](const std::string& text, const std::string& where, const std::string& needle) {
    try {
      ReadReflectorsCsv(write(text));
      FAIL() << text;
    } catch (const InputError& e) {
      EXPECT_NE(e.where().find(where), std::string::npos) << e.what();
      EXPECT_NE(e.message().find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(seven + ",tilt_deg\ndihedral,7,43,1,1,0,0,5\n", "header", "unknown column 'tilt_deg'");
  expect_error("type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,roll_deg\ndihedral,7,43,1,1,0,5\n", "header",
               "missing column 'boresight_elevation_deg'");
  expect_error(seven + ",roll_deg\ndihedral,7,43,1,1,0,0\n", "row 1", "expected 8 fields");
  expect_error(seven + "\ndihedral,7,43,1,1,0,0,45\n", "row 1", "expected 7 fields");
  expect_error(seven + ",roll_deg\ndihedral,7,43,1,1,0,0,left\n", "row 1", "roll_deg must be a number");
  std::filesystem::remove_all(dir);
}

// Fresnel reflectivities against the closed forms: at normal incidence
// |(1 - sqrt(eps)) / (1 + sqrt(eps))|^2 for both polarisations; at 45 deg on
// a lossless half-space the Snell-angle forms Gamma_h = -sin(ti - tt) /
// sin(ti + tt), Gamma_v = tan(ti - tt) / tan(ti + tt), and Gamma_v =
// Gamma_h^2 (the 45 deg identity); cross-polarised: their mean.
TEST(FresnelTest, MatchesTheClosedForms) {
  for (const std::complex<double> eps : {std::complex<double>(4.0, 0.0), std::complex<double>(6.0, -1.0),
                                         std::complex<double>(70.0, -30.0)}) {
    const double r0 = std::norm((1.0 - std::sqrt(eps)) / (1.0 + std::sqrt(eps)));
    EXPECT_NEAR(FresnelReflectivity(eps, 1.0, Polarization::kHH), r0, 1e-12);
    EXPECT_NEAR(FresnelReflectivity(eps, 1.0, Polarization::kVV), r0, 1e-12);
  }
  EXPECT_NEAR(FresnelReflectivity({4.0, 0.0}, 1.0, Polarization::kVV), 1.0 / 9.0, 1e-12);  // ((1-2)/(1+2))^2
  for (const double eps : {4.0, 9.0, 25.0}) {
    const double ti = 45 * kDeg, tt = std::asin(std::sin(ti) / std::sqrt(eps));
    const double gh = -std::sin(ti - tt) / std::sin(ti + tt), gv = std::tan(ti - tt) / std::tan(ti + tt);
    const double c = std::cos(ti);
    EXPECT_NEAR(FresnelReflectivity(eps, c, Polarization::kHH), gh * gh, 1e-12) << eps;
    EXPECT_NEAR(FresnelReflectivity(eps, c, Polarization::kVV), gv * gv, 1e-12) << eps;
    EXPECT_NEAR(FresnelReflectivity(eps, c, Polarization::kVV), std::pow(gh * gh, 2.0), 1e-12) << eps;
    EXPECT_NEAR(FresnelReflectivity(eps, c, Polarization::kHV), 0.5 * (gh * gh + gv * gv), 1e-12) << eps;
  }
  // eps = 4 at 45 deg: |Gamma_h|^2 = 0.2038, |Gamma_v|^2 = 0.0415 (by hand).
  EXPECT_NEAR(FresnelReflectivity({4.0, 0.0}, std::cos(45 * kDeg), Polarization::kHH), 0.2038, 5e-4);
  EXPECT_NEAR(FresnelReflectivity({4.0, 0.0}, std::cos(45 * kDeg), Polarization::kVV), 0.0415, 5e-4);
  // Grazing: total reflection; behind: nothing.
  EXPECT_NEAR(FresnelReflectivity({4.0, 0.0}, 1e-9, Polarization::kHH), 1.0, 1e-6);
  EXPECT_EQ(FresnelReflectivity({4.0, 0.0}, -0.5, Polarization::kHH), 0.0);
}

// The mirror ray carries mirror * |Gamma_p|^2 of the class's permittivity
// (Debye water for the two-scale water classes).
TEST(FresnelTest, MirrorReflectivityIsTheCoherentShareOfFresnel) {
  Material road = DefaultMaterial(scene::kClassRoad);
  ASSERT_GT(road.mirror, 0.0);
  const double c = std::cos(50 * kDeg);
  EXPECT_NEAR(road.MirrorReflectivity(c, kX, Polarization::kHH),
              road.mirror * FresnelReflectivity(road.permittivity, c, Polarization::kHH), 1e-15);
  const Material water = DefaultMaterial(scene::kClassWater);
  EXPECT_NEAR(water.MirrorReflectivity(c, kC, Polarization::kVV),
              water.mirror * FresnelReflectivity(WaterPermittivity(kC, 0.0), c, Polarization::kVV), 1e-15);
  Material rough = road;
  rough.mirror = 0.0;
  EXPECT_EQ(rough.MirrorReflectivity(c, kX, Polarization::kVV), 0.0);
}

// The bistatic law is symmetric in its two directions and its monostatic
// value is the legacy Lambertian + specular law.
TEST(BistaticTest, SymmetricAndMonostaticLimit) {
  Material m{"m", 0.4, 0.5, 0.3, 0.2};
  for (double ti : {10.0, 35.0, 70.0}) {
    for (double to : {0.0, 20.0, 55.0}) {
      const double a = m.BistaticSigma0(std::cos(ti * kDeg), std::cos(to * kDeg), 0.8);
      const double b = m.BistaticSigma0(std::cos(to * kDeg), std::cos(ti * kDeg), 0.8);
      EXPECT_NEAR(a, b, 1e-15 * a);
      // 4 (0.4 ci co + 0.5 * 0.8^(1/0.3) sqrt(ci co)).
      const double ci = std::cos(ti * kDeg), co = std::cos(to * kDeg);
      EXPECT_NEAR(a, 4 * (0.4 * ci * co + 0.5 * std::pow(0.8, 1 / 0.3) * std::sqrt(ci * co)), 1e-12);
    }
    const double c = std::cos(ti * kDeg);
    EXPECT_NEAR(m.BistaticSigma0(c, c, std::cos(2 * ti * kDeg)), m.Sigma0(c, kX, Polarization::kVV), 1e-12) << ti;
  }
  EXPECT_EQ(m.BistaticSigma0(0.0, 0.5, 1.0), 0.0);
}

// The radar's H/V basis on a surface's plane of incidence: on horizontal
// ground and on a wall seen broadside V is TM (TE share 0); on a vertical
// wall at horizontal aspect phi, seen at depression delta, the TE share of V
// is sin^2 phi / (sin^2 delta + cos^2 delta sin^2 phi) (hand-derived: V =
// (sin d cos p, sin d sin p, cos d) in the wall's frame, TE direction along
// dir x n). The oriented mirror reflectivity mixes |Gamma_h|^2 and
// |Gamma_v|^2 with it, for H the complement.
TEST(FresnelTest, PolarisationBasisProjectedOnThePlaneOfIncidence) {
  using Eigen::Vector3d;
  const double d = 40 * kDeg;
  auto ray = [&](double aspect) {  // towards +x (the wall's normal is -x), rotated by `aspect`
    return Vector3d(std::cos(d) * std::cos(aspect), std::cos(d) * std::sin(aspect), -std::sin(d));
  };
  const Vector3d ground(0, 0, 1), wall(-1, 0, 0);
  EXPECT_NEAR(VerticalTeShare(ray(0.3), ground), 0.0, 1e-12);
  EXPECT_NEAR(VerticalTeShare(ray(0.0), wall), 0.0, 1e-12);
  for (double phi_deg : {15.0, 30.0, 45.0, 60.0}) {
    const double p = phi_deg * kDeg;
    const double expected = std::pow(std::sin(p), 2) / (std::pow(std::sin(d), 2) + std::pow(std::cos(d) * std::sin(p), 2));
    EXPECT_NEAR(VerticalTeShare(ray(p), wall), expected, 1e-12) << phi_deg;
    EXPECT_NEAR(VerticalTeShare(-ray(p), -wall), expected, 1e-12) << phi_deg;
  }
  // 45 deg aspect: 0.5 / (0.4132 + 0.2934) = 0.7077 of V is TE on the wall.
  EXPECT_NEAR(VerticalTeShare(ray(45 * kDeg), wall), 0.7077, 1e-4);
  const std::complex<double> eps(6.0, -0.5);
  const Vector3d in = ray(45 * kDeg);
  const double cos_wall = -in.dot(wall);  // cos 40 cos 45 = 0.5417
  const Vector3d out = in - 2.0 * in.dot(wall) * wall;
  const double t = VerticalTeShare(in, wall);
  const double gh = FresnelReflectivity(eps, cos_wall, Polarization::kHH);
  const double gv = FresnelReflectivity(eps, cos_wall, Polarization::kVV);
  EXPECT_NEAR(OrientedFresnelReflectivity(eps, cos_wall, in, out, wall, Polarization::kVV), t * gh + (1 - t) * gv, 1e-12);
  EXPECT_NEAR(OrientedFresnelReflectivity(eps, cos_wall, in, out, wall, Polarization::kHH), (1 - t) * gh + t * gv, 1e-12);
  EXPECT_NEAR(OrientedFresnelReflectivity(eps, cos_wall, in, out, wall, Polarization::kHV), 0.5 * (gh + gv), 1e-12);
  std::printf("wall at 45 deg aspect, 40 deg depression, eps 6-0.5j: |G_h|^2 %.4f |G_v|^2 %.4f, VV mirror %.4f\n", gh,
              gv, t * gh + (1 - t) * gv);
  // On the ground the oriented value is the plain one.
  const Vector3d g_out = in - 2.0 * in.dot(ground) * ground;
  for (const Polarization pol : {Polarization::kHH, Polarization::kVV}) {
    EXPECT_NEAR(OrientedFresnelReflectivity(eps, std::sin(d), in, g_out, ground, pol),
                FresnelReflectivity(eps, std::sin(d), pol), 1e-12);
  }
}

// Reciprocity: a two- and a three-bounce path and the same paths reversed
// (source and receiver swapped, bistatic) carry the same power.
TEST(BistaticTest, ReversedPathsCarryEqualPower) {
  using Eigen::Vector3d;
  Material ground{"ground", 0.3, 0.4, 0.2, 0.6};
  ground.permittivity = {5.0, -0.7};
  Material wall{"wall", 0.2, 0.6, 0.1, 0.7};
  wall.permittivity = {7.0, -1.2};
  Material plate{"plate", 0.5, 0.3, 0.5, 0.4};
  plate.permittivity = {3.0, -0.1};
  plate.model = ScatteringModel::kBragg;  // Fresnel of Debye water
  plate.salinity_psu = 35.0;
  auto reflect = [](const Vector3d& d, const Vector3d& n) { return Vector3d(d - 2.0 * d.dot(n) * n); };
  const Vector3d to_source = Vector3d(-std::cos(40 * kDeg), 0.15, std::sin(40 * kDeg)).normalized();
  const Vector3d to_receiver = Vector3d(-std::cos(25 * kDeg), -0.3, std::sin(25 * kDeg)).normalized();
  // Ground (z = 0) mirror at the origin, then a wall x = 12 facing -x.
  const Vector3d n_ground(0, 0, 1), n_wall(-1, 0, 0);
  const Vector3d p0(0, 0, 0);
  const Vector3d d1 = reflect(-to_source, n_ground);
  const Vector3d p1 = p0 + (12.0 / d1.x()) * d1;
  // Then a tilted plate facing the wall's mirror ray.
  const Vector3d d2 = reflect(d1, n_wall);
  const Vector3d p2 = p1 + 7.0 * d2;
  const Vector3d n_plate = Vector3d((-d2 + to_receiver).normalized() + Vector3d(0.1, 0.05, -0.08)).normalized();
  const PathVertex v0{p0, n_ground, &ground}, v1{p1, n_wall, &wall}, v2{p2, n_plate, &plate};
  for (const Polarization pol : {Polarization::kHH, Polarization::kVV, Polarization::kHV}) {
    // Two bounces: ground mirror, wall scatters.
    const double two = PathRcsPerArea({v0, v1}, 1, to_source, to_receiver, kC, pol);
    const double two_rev = PathRcsPerArea({v1, v0}, 0, to_receiver, to_source, kC, pol);
    ASSERT_GT(two, 0.0);
    EXPECT_NEAR(two_rev / two, 1.0, 1e-6);
    // By hand: the ground's mirror reflectivity at its incidence (the angle
    // of to_source from the normal) times the wall's bistatic law.
    const double cos_g = to_source.z();
    const double cos_wi = -d1.dot(n_wall), cos_wo = to_receiver.dot(n_wall);
    EXPECT_NEAR(two, ground.MirrorReflectivity(cos_g, kC, pol) *
                         wall.BistaticSigma0(cos_wi, cos_wo, reflect(d1, n_wall).dot(to_receiver)),
                1e-12 * two);
    // Three bounces: ground and wall mirrors, the plate scatters; and the
    // scatterer in the middle.
    for (int scatter : {2, 1, 0}) {
      const double three = PathRcsPerArea({v0, v1, v2}, scatter, to_source, to_receiver, kC, pol);
      const double three_rev = PathRcsPerArea({v2, v1, v0}, 2 - scatter, to_receiver, to_source, kC, pol);
      ASSERT_GT(three, 0.0) << scatter;
      EXPECT_NEAR(three_rev / three, 1.0, 1e-6) << scatter;
    }
  }
  // A vertex met from behind ends the path.
  const PathVertex back{p1, -n_wall, &wall};
  EXPECT_EQ(PathRcsPerArea({v0, back}, 1, to_source, to_receiver, kC, Polarization::kVV), 0.0);
}

}  // namespace
}  // namespace gissar::material
