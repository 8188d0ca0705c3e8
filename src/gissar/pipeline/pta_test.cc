#include "gissar/pipeline/pta.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::DataPath;
using testing::MakeTempDir;

const char* kAlos = "alos_rio_branco/calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5";
const char* kHeader = "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n";

PtaRequest AlosRequest(const fs::path& dir) {
  PtaRequest r;
  r.product = DataPath(kAlos).string();
  r.reflectors = DataPath("alos_rio_branco/rio_branco_reflector.csv").string();
  r.out_prefix = (dir / "pta").string();
  return r;
}

// lon,lat (h = 0) of a pixel of the ALOS chip, by rdr2geo on its orbit.
Eigen::Vector3d AlosPixel(double col, double row) {
  const geo::RslcProduct p = geo::ReadRslcProduct(DataPath(kAlos), {"A", "HH", false});
  const sensor::Orbit orbit(p.orbit.time_s, p.orbit.position_m, p.orbit.velocity_mps);
  const auto g = sensor::Rdr2Geo(orbit, p.zero_doppler_time_s[0] + row * p.azimuth_spacing_s(),
                                 p.slant_range_m[0] + col * p.range_spacing_m(), sensor::LookSide::kRight,
                                 [](double, double) { return std::optional<double>(0.0); });
  EXPECT_TRUE(g.has_value());
  return *g;
}

fs::path WriteCsv(const fs::path& path, const std::string& rows) {
  std::ofstream(path) << kHeader << rows;
  return path;
}

// The surveyed trihedral of the ALOS-1 quad-pol chip (data/alos_rio_branco),
// predicted by zero-Doppler geo2rdr on the product's orbit: found within a
// pixel of the prediction, every key of CONVENTIONS.md "Polarimetry" there.
TEST(PtaTest, FindsTheRioBrancoCornerReflector) {
  const fs::path dir = MakeTempDir();
  const PtaResult result = RunPta(AlosRequest(dir), "test");
  ASSERT_EQ(result.measured, 1);
  ASSERT_EQ(result.total, 1);
  EXPECT_TRUE(fs::exists(dir / "pta.json"));
  EXPECT_TRUE(fs::exists(dir / "pta_irf.png"));
  const json& report = result.report;
  EXPECT_EQ(report["command"], "pta");
  EXPECT_TRUE(report["converged"].get<bool>());
  ASSERT_EQ(report["inputs"].size(), 2u);
  EXPECT_EQ(report["inputs"][0]["sha256"].get<std::string>().size(), 64u);
  EXPECT_TRUE(report["quad_pol"].get<bool>());
  EXPECT_TRUE(report["calibration"]["calibrated"].get<bool>());  // the product's beta0 LUT (= 1)
  const json& r = report["reflectors"][0];
  for (const char* key : {"id", "predicted_px", "peak_px", "location_error_px", "location_error_m", "resolution_m",
                          "pslr_db", "islr_db", "rcs_dbsm", "rcs_expected_dbsm", "calibration_offset_db",
                          "hh_vv_ratio_db", "hh_vv_phase_deg", "cross_pol_isolation_db"}) {
    EXPECT_TRUE(r.contains(key)) << key;
  }
  for (const char* key : {"predicted_px", "peak_px", "location_error_px", "location_error_m", "resolution_m",
                          "pslr_db", "islr_db"}) {
    EXPECT_TRUE(r[key]["range"].is_number() && r[key]["azimuth"].is_number()) << key;
  }
  EXPECT_EQ(r["id"], 1);
  EXPECT_LE(std::abs(r["location_error_px"]["range"].get<double>()), 1.0);
  EXPECT_LE(std::abs(r["location_error_px"]["azimuth"].get<double>()), 1.0);
  // The prediction sits at the chip's centre (column 25, row 50).
  EXPECT_NEAR(r["predicted_px"]["range"].get<double>(), 25.0, 1.0);
  EXPECT_NEAR(r["predicted_px"]["azimuth"].get<double>(), 50.0, 1.0);
  // ALOS PLR: about 9.5 m slant range (14 MHz), 4.5 m azimuth.
  EXPECT_NEAR(r["resolution_m"]["range"].get<double>(), 9.6, 1.0);
  EXPECT_NEAR(r["resolution_m"]["azimuth"].get<double>(), 4.7, 1.0);
  EXPECT_LT(r["pslr_db"]["range"].get<double>(), -10.0);
  EXPECT_LT(r["pslr_db"]["azimuth"].get<double>(), -10.0);
  EXPECT_NEAR(r["calibration_offset_db"].get<double>(),
              r["rcs_dbsm"].get<double>() - r["rcs_expected_dbsm"].get<double>(), 1e-9);
  // Trihedral at L band, a = 2.5 m: 4 pi a^4 / (3 lambda^2) = 34.68 dBsm at boresight.
  EXPECT_NEAR(r["expected"]["peak_rcs_dbsm"].get<double>(), 34.678, 0.01);
  // Along-track spacing from the orbit matches the product's groundTrackVelocity (6843-6847 m/s).
  EXPECT_NEAR(r["prediction"]["ground_speed_mps"].get<double>(), 6845.0, 5.0);
  EXPECT_GT(r["cross_pol_isolation_db"].get<double>(), 15.0);
  EXPECT_LT(std::abs(r["hh_vv_ratio_db"].get<double>()), 6.0);
  const double phase = r["hh_vv_phase_deg"].get<double>();
  EXPECT_TRUE(phase >= -180.0 && phase <= 180.0);
  std::printf("ALOS Rio Branco CR1: location error %.4f / %.4f px = %.3f / %.3f m; resolution %.2f / %.2f m; "
              "PSLR %.2f / %.2f dB; ISLR %.2f / %.2f dB; RCS %.2f dBsm, expected %.2f dBsm, offset %.2f dB; SCR %.1f dB; "
              "HH/VV %.2f dB %.1f deg; isolation %.1f dB\n",
              r["location_error_px"]["range"].get<double>(), r["location_error_px"]["azimuth"].get<double>(),
              r["location_error_m"]["range"].get<double>(), r["location_error_m"]["azimuth"].get<double>(),
              r["resolution_m"]["range"].get<double>(), r["resolution_m"]["azimuth"].get<double>(),
              r["pslr_db"]["range"].get<double>(), r["pslr_db"]["azimuth"].get<double>(),
              r["islr_db"]["range"].get<double>(), r["islr_db"]["azimuth"].get<double>(), r["rcs_dbsm"].get<double>(),
              r["rcs_expected_dbsm"].get<double>(), r["calibration_offset_db"].get<double>(), r["scr_db"].get<double>(),
              r["hh_vv_ratio_db"].get<double>(), r["hh_vv_phase_deg"].get<double>(),
              r["cross_pol_isolation_db"].get<double>());
  // The file holds what the result holds.
  json written;
  std::ifstream(dir / "pta.json") >> written;
  EXPECT_EQ(written["reflectors"][0]["rcs_dbsm"], r["rcs_dbsm"]);
  // VV measured at its own peak: the trihedral is there too.
  PtaRequest vv = AlosRequest(dir);
  vv.polarization = "VV";
  vv.out_prefix = (dir / "vv").string();
  const PtaResult on_vv = RunPta(vv, "test");
  ASSERT_EQ(on_vv.measured, 1);
  EXPECT_LE(std::abs(on_vv.report["reflectors"][0]["location_error_px"]["azimuth"].get<double>()), 1.0);
}

// No target where the row says (30 lines before the reflector the brightest
// clutter sample is 10.6 dB above the background, below the 15 dB detection
// threshold): the result is written,
// "converged": false with the reason (exit status 3 at the CLI).
TEST(PtaTest, NoTargetIsANoResultWithItsReason) {
  const fs::path dir = MakeTempDir();
  const Eigen::Vector3d g = AlosPixel(25.0, 20.0);  // 30 lines before the reflector: clutter only
  std::ostringstream row;
  row << std::setprecision(15) << "trihedral," << g.x() << "," << g.y() << ",0,2.5,270,35.26\n";
  PtaRequest r = AlosRequest(dir);
  r.reflectors = WriteCsv(dir / "clutter.csv", row.str()).string();
  const PtaResult result = RunPta(r, "test");
  EXPECT_EQ(result.measured, 0);
  EXPECT_FALSE(result.report["converged"].get<bool>());
  const std::string reason = result.report["reason"].get<std::string>();
  EXPECT_NE(reason.find("dB above the background"), std::string::npos) << reason;
  EXPECT_NE(reason.find("row 1"), std::string::npos) << reason;
  EXPECT_FALSE(result.report["reflectors"][0]["found"].get<bool>());
  EXPECT_NEAR(result.report["reflectors"][0]["predicted_px"]["azimuth"].get<double>(), 20.0, 0.01);
  EXPECT_TRUE(fs::exists(dir / "pta.json"));
  EXPECT_TRUE(fs::exists(dir / "pta_irf.png"));
  std::printf("no target: %s\n", reason.c_str());
}

// Bad input: the exception names the problem and the input; nothing written.
TEST(PtaTest, BadInputNamesTheInput) {
  const fs::path dir = MakeTempDir();
  const fs::path out = dir / "out";
  fs::create_directories(out);
  auto request = [&] {
    PtaRequest r = AlosRequest(dir);
    r.out_prefix = (out / "pta").string();
    return r;
  };
  auto expect_error = [&](const PtaRequest& r, const std::string& what, const std::string& where, bool config) {
    try {
      RunPta(r, "test");
      ADD_FAILURE() << "no error for " << what;
    } catch (const Error& e) {
      EXPECT_EQ(dynamic_cast<const ConfigError*>(&e) != nullptr, config) << e.what();
      EXPECT_NE(e.message().find(what), std::string::npos) << e.what();
      EXPECT_NE(e.where().find(where), std::string::npos) << e.what();
    }
    EXPECT_TRUE(fs::is_empty(out)) << what;
  };
  PtaRequest unknown = request();
  unknown.polarization = "XX";
  expect_error(unknown, "unknown channel 'XX'", "--polarization", true);
  PtaRequest not_stored = request();
  not_stored.product = DataPath("uavsar/SanAnd_129.h5").string();
  not_stored.polarization = "HV";
  expect_error(not_stored, "(polarisations stored: HH)", "SanAnd_129.h5", false);
  const Eigen::Vector3d g = AlosPixel(25.0, 50.0);
  std::ostringstream rows;
  rows << std::setprecision(15) << "trihedral," << g.x() << "," << g.y() << ",0,2.5,270,35.26\n"
       << "trihedral," << g.x() + 0.05 << "," << g.y() << ",0,2.5,270,35.26\n";  // 5 km east: off the chip
  PtaRequest outside = request();
  outside.reflectors = WriteCsv(dir / "outside.csv", rows.str()).string();
  expect_error(outside, "reflector lies outside the product's radar grid", "outside.csv row 2", false);
  PtaRequest bad_type = request();
  bad_type.reflectors = WriteCsv(dir / "cube.csv", "cube,-68.17,-9.71,0,1,270,35\n").string();
  expect_error(bad_type, "cube", "cube.csv row 1", false);
  PtaRequest both = request();
  both.image = (dir / "x_slc.tif").string();
  expect_error(both, "give one of --product or --image", "--product/--image", true);
  PtaRequest upsampling = request();
  upsampling.upsampling = 1;
  expect_error(upsampling, "must be 2 to 64", "--upsampling", true);
  // An image that is not `gissar simulate --coherent`'s: no sidecar.
  geo::FloatRaster raster;
  raster.width = raster.height = 8;
  raster.bands = {std::vector<float>(64, 1.0f)};
  geo::WriteFloatGeoTiff(dir / "plain.tif", raster);
  PtaRequest plain = request();
  plain.product.clear();
  plain.image = (dir / "plain.tif").string();
  expect_error(plain, "cannot read the image's sidecar", "plain.json", false);
}

// Closed form through the whole chain: `gissar simulate --coherent` of a
// trihedral (a = 1 m, C band, boresight on the sensor) on dark flat ground,
// sigma0 output, an unweighted 5 m impulse response on 2 m pixels (a sampled
// sinc, B = 0.354 cycles/px); `pta --image PREFIX_slc.tif` predicts it with
// the simulation's own geometry and terrain, converts sigma0 back to beta0
// (1 / sin of the column's incidence) and integrates its energy. The
// 97 x 97 box (--chip-half-size 48) misses 1 / (pi^2 B 48) = 0.6 % of a
// sinc's energy per axis (-0.05 dB in all): the RCS is within 0.1 dB of
// 4 pi a^4 / (3 lambda^2) = 31.34 dBsm.
TEST(PtaTest, SimulatedCoherentTrihedralHasItsClosedFormRcs) {
  const fs::path dir = MakeTempDir();
  const char* tm = "+proj=tmerc +lat_0=43.7 +lon_0=7.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  const fs::path dem = dir / "flat.tif";
  geo::WriteDemGeoTiff(dem, std::vector<float>(101 * 101, 50.0f), 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, tm);
  const fs::path materials = dir / "dark.json";
  std::ofstream(materials) << R"({"default": {"sigma0_db": [[0, -80], [90, -80]]}})";
  std::vector<double> x{30.0}, y{-20.0};
  geo::CrsTransform(tm).ToLonLat(x, y);
  std::ostringstream row;
  row << std::setprecision(12) << "trihedral," << x[0] << "," << y[0] << ",0.4,1,270,40\n";
  const fs::path csv = WriteCsv(dir / "reflector.csv", row.str());
  constexpr double kC = 0.0555;
  SimulateRequest sim;
  sim.dem = dem.string();
  sim.vertical_datum = "ellipsoid";
  sim.materials = materials.string();
  sim.reflectors = csv.string();
  sim.coherent = true;
  sim.bounces = 1;
  sim.wavelength_m = kC;
  sim.radiometry = "sigma0";
  sim.geometry.heading_deg = 0.0;
  sim.geometry.depression_deg = 40.0;
  sim.geometry.range_spacing_m = sim.geometry.azimuth_spacing_m = 2.0;
  sim.range_resolution_m = sim.azimuth_resolution_m = 5.0;
  sim.out_prefix = (dir / "sim").string();
  RunSimulate(sim, "test");
  PtaRequest r;
  r.image = sim.out_prefix + "_slc.tif";
  r.reflectors = csv.string();
  r.chip_half_size_px = 48;
  r.upsampling = 8;
  r.out_prefix = (dir / "pta").string();
  const PtaResult result = RunPta(r, "test");
  ASSERT_EQ(result.measured, 1) << result.report.dump(2);
  const json& m = result.report["reflectors"][0];
  const double closed_form = 10.0 * std::log10(4.0 * M_PI / (3.0 * kC * kC));
  EXPECT_NEAR(m["rcs_expected_dbsm"].get<double>(), closed_form, 1e-6);  // the boresight looks at the sensor
  EXPECT_NEAR(m["rcs_dbsm"].get<double>(), closed_form, 0.1);
  EXPECT_LT(std::abs(m["location_error_px"]["range"].get<double>()), 0.05);
  EXPECT_LT(std::abs(m["location_error_px"]["azimuth"].get<double>()), 0.05);
  // 0.886 / B = 2.5 px = 5 m: the simulated resolution.
  EXPECT_NEAR(m["resolution_m"]["range"].get<double>(), 5.0, 0.1);
  EXPECT_NEAR(m["resolution_m"]["azimuth"].get<double>(), 5.0, 0.1);
  EXPECT_NEAR(m["pslr_db"]["range"].get<double>(), -13.26, 0.3);
  EXPECT_EQ(result.report["source"]["radiometry"], "sigma0");
  EXPECT_FALSE(result.report["quad_pol"].get<bool>());
  std::printf("simulated trihedral: RCS %.4f dBsm (closed form %.4f), location error %.4f / %.4f px, "
              "resolution %.3f / %.3f m, PSLR %.2f / %.2f dB\n",
              m["rcs_dbsm"].get<double>(), closed_form, m["location_error_px"]["range"].get<double>(),
              m["location_error_px"]["azimuth"].get<double>(), m["resolution_m"]["range"].get<double>(),
              m["resolution_m"]["azimuth"].get<double>(), m["pslr_db"]["range"].get<double>(),
              m["pslr_db"]["azimuth"].get<double>());
}

}  // namespace
}  // namespace gissar::pipeline
