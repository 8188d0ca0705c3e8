#include "gissar/pipeline/pta.h"
#include "gissar/pipeline/simulate_door.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/geo/warp.h"
#include "gissar/pipeline/alos_testing.h"
#include "gissar/pipeline/pta_fields.h"
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

const char* kAlos = alos_testing::kProduct;
constexpr double kSpeedOfLight = 299792458.0;
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
// The pta table: a round trip through JSON, null keeping the default (the
// Python door's None), an unknown key named, the flags kept from before the
// table (--ground-height, --search, --out), and the Sentinel-1 selection
// refused with a NISAR product.
TEST(PtaFields, RoundTripNullAndFlags) {
  PtaRequest o;
  o.product = "S1B.SAFE";
  o.swath = "IW2";
  o.burst = 4;
  o.orbit = "orbit.EOF";
  o.reflectors = "r.csv";
  o.search_px = 12.0;
  o.out_prefix = "out/p";
  PtaRequest round;
  round.ApplyJson(o.ToJson(), "test");
  EXPECT_EQ(round.ToJson(), o.ToJson());
  EXPECT_EQ(round.burst, 4);
  PtaRequest kept;
  kept.ApplyJson({{"upsampling", nullptr}, {"frequency", nullptr}}, "test");
  EXPECT_EQ(kept.upsampling, PtaRequest().upsampling);
  EXPECT_EQ(kept.frequency, "A");
  try {
    kept.ApplyJson({{"bursts", 2}}, "opts.json");
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bursts"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("opts.json"), std::string::npos) << e.what();
  }
  EXPECT_EQ(PtaFields().at("ground_height_m").Flag(), "--ground-height");
  EXPECT_EQ(PtaFields().at("search_px").Flag(), "--search");
  EXPECT_EQ(PtaFields().at("chip_half_size_px").Flag(), "--chip-half-size");
  EXPECT_EQ(PtaFields().at("out_prefix").Flag(), "--out");
  PtaRequest nisar;
  nisar.product = "rslc.h5";
  nisar.reflectors = "r.csv";
  nisar.out_prefix = "p";
  nisar.Check();
  nisar.burst = 2;
  EXPECT_THROW(nisar.Check(), ConfigError);
  nisar.burst = 0;
  nisar.swath = "IW1";
  EXPECT_THROW(nisar.Check(), ConfigError);
}

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


// Issue 44: `gissar simulate --product --coherent` on the ALOS-1 Rio Branco
// chip (its orbit, zero-Doppler grid and L-band wavelength) over flat ground
// at the ellipsoid (sigma0 -80 dB: clutter far below the reflector), with
// the surveyed trihedral of its CSV (2.5 m, seen 32 deg off its boresight)
// and an unweighted impulse response of ALOS PLR's resolutions (14 MHz:
// 0.886 c / 2B = 9.49 m slant range; 4.5 m azimuth); `pta --image
// PREFIX_slc.tif` predicts it on the simulation's terrain by geo2rdr on the
// product's orbit, converts the per-pixel sigma0 back to beta0 and measures
// it: at its prediction, with the physical-optics RCS of its pattern and
// the sinc's -13.26 dB sidelobes in both cuts.
TEST(PtaTest, SimulatedTrihedralOnTheAlosProductGrid) {
  const fs::path dir = MakeTempDir();
  const char* csv = alos_testing::kReflectors;
  const fs::path dem = alos_testing::WriteFlatDem(dir);  // 3 km x 3 km at 15 m, 0 m above the ellipsoid
  const fs::path materials = alos_testing::WriteDarkMaterials(dir, -80.0);
  SimulateRequest sim;
  sim.product = DataPath(kAlos).string();
  sim.dem = dem.string();
  sim.vertical_datum = alos_testing::kVerticalDatum;
  sim.sea = alos_testing::kSea;  // the ellipsoid lies below EGM96 sea level here: not the `sea` class, the dark default
  sim.materials = materials.string();
  sim.reflectors = DataPath(csv).string();
  sim.coherent = true;
  sim.bounces = 1;
  sim.radiometry = "sigma0";
  sim.range_resolution_m = 0.886 * kSpeedOfLight / (2.0 * 14e6);
  sim.azimuth_resolution_m = 4.5;
  sim.psf_window = "none";
  sim.out_prefix = (dir / "sim").string();
  const SimulateResult simulated = RunSimulate(sim, "test");
  EXPECT_EQ(simulated.width, 50);
  EXPECT_EQ(simulated.height, 100);
  const geo::ComplexRaster slc = geo::ReadComplexRaster(dir / "sim_slc.tif");
  ASSERT_EQ(slc.bands.size(), 5u);
  EXPECT_EQ(slc.width, 50);
  EXPECT_EQ(slc.height, 100);
  EXPECT_EQ(slc.band_names[0], "total");
  EXPECT_EQ(slc.band_names[3], "triple");
  EXPECT_TRUE(fs::exists(dir / "sim.json"));
  // The SLC is located by PREFIX.tif's geolocation arrays (GEOLOCATION
  // X_DATASET/Y_DATASET): GDAL's transformer maps its pixel centres to
  // bands 6/7 of sim.tif; and it carries GCPs.
  const geo::FloatRaster detected = geo::ReadFloatRaster(dir / "sim.tif");
  ASSERT_EQ(detected.bands.size(), 8u);
  std::vector<Eigen::Vector2d> pixels, want;
  for (int row = 5; row < 100; row += 17) {
    for (int col = 3; col < 50; col += 11) {
      const size_t k = size_t(row) * 50 + col;
      if (!std::isfinite(detected.bands[5][k])) continue;
      pixels.emplace_back(col + 0.5, row + 0.5);
      want.emplace_back(detected.bands[5][k], detected.bands[6][k]);
    }
  }
  ASSERT_GE(pixels.size(), 10u);
  const auto got = geo::PixelsToLonLat(dir / "sim_slc.tif", {"METHOD=GEOLOC_ARRAY"}, pixels);
  for (size_t i = 0; i < pixels.size(); ++i) {
    EXPECT_NEAR(got[i].x(), want[i].x(), 1e-5) << i;
    EXPECT_NEAR(got[i].y(), want[i].y(), 1e-5) << i;
  }
  const auto by_gcps = geo::PixelsToLonLat(dir / "sim_slc.tif", {"METHOD=GCP_TPS"}, pixels);
  for (size_t i = 0; i < pixels.size(); ++i) {
    EXPECT_NEAR(by_gcps[i].x(), want[i].x(), 1e-4) << i;  // ~10 m: a spline through 64 points
    EXPECT_NEAR(by_gcps[i].y(), want[i].y(), 1e-4) << i;
  }
  PtaRequest r;
  r.image = (dir / "sim_slc.tif").string();
  r.reflectors = DataPath(csv).string();
  r.out_prefix = (dir / "pta").string();
  const PtaResult result = RunPta(r, "test");
  ASSERT_EQ(result.measured, 1) << result.report.dump(2);
  const json& m = result.report["reflectors"][0];
  EXPECT_EQ(result.report["source"]["kind"], "gissar simulate --coherent complex image on a product's radar grid");
  // The prediction is the real reflector's (pta --product on the real chip
  // puts it at column 25, row 50).
  EXPECT_NEAR(m["predicted_px"]["range"].get<double>(), 25.0, 1.0);
  EXPECT_NEAR(m["predicted_px"]["azimuth"].get<double>(), 50.0, 1.0);
  const double dr = m["location_error_px"]["range"].get<double>();
  const double da = m["location_error_px"]["azimuth"].get<double>();
  const double rcs = m["rcs_dbsm"].get<double>(), expected = m["rcs_expected_dbsm"].get<double>();
  const double pslr_r = m["pslr_db"]["range"].get<double>(), pslr_a = m["pslr_db"]["azimuth"].get<double>();
  std::printf("[ measured ] simulated trihedral on the ALOS grid: location error %.4f / %.4f px (%.3f / %.3f m); "
              "RCS %.3f dBsm, physical optics %.3f dBsm (%+.3f dB; peak %.2f dBsm, %.1f deg off boresight); "
              "PSLR %.2f / %.2f dB; ISLR %.2f / %.2f dB; resolution %.2f / %.2f m; SCR %.1f dB\n",
              dr, da, m["location_error_m"]["range"].get<double>(), m["location_error_m"]["azimuth"].get<double>(),
              rcs, expected, rcs - expected, m["expected"]["peak_rcs_dbsm"].get<double>(),
              m["expected"]["off_boresight_deg"].get<double>(), pslr_r, pslr_a, m["islr_db"]["range"].get<double>(),
              m["islr_db"]["azimuth"].get<double>(), m["resolution_m"]["range"].get<double>(),
              m["resolution_m"]["azimuth"].get<double>(), m["scr_db"].get<double>());
  EXPECT_LE(std::abs(dr), 0.05);
  EXPECT_LE(std::abs(da), 0.05);
  EXPECT_NEAR(rcs, expected, 0.3);
  EXPECT_NEAR(pslr_r, -13.3, 0.3);
  EXPECT_NEAR(pslr_a, -13.3, 0.3);
  EXPECT_NEAR(m["resolution_m"]["range"].get<double>(), sim.range_resolution_m, 0.3);
  EXPECT_NEAR(m["resolution_m"]["azimuth"].get<double>(), sim.azimuth_resolution_m, 0.3);
}

}  // namespace
}  // namespace gissar::pipeline
