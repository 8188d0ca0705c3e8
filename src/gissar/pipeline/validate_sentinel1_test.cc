// The geometry proof on real Sentinel-1 annotations (data/sentinel1/): gissar's
// geo2rdr/rdr2geo against the geolocation grids ESA's processor computed,
// with the annotation orbit and with an EOF file written from it.
#include "gissar/pipeline/validate_sentinel1.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include <gtest/gtest.h>

#include "gissar/geo/sentinel1_testing.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"
#include "gissar/util/utc_time.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

using geo::testing_s1::kIwGrd;
using geo::testing_s1::kIwSlc;
using geo::testing_s1::kSm;
using geo::testing_s1::Annotation;

void ExpectWithinTargets(const GeolocationGridAgreement& r, size_t points) {
  SCOPED_TRACE(r.swath + "/" + r.polarization + " " + r.ToJson().dump());
  EXPECT_EQ(r.points, static_cast<int>(points));
  EXPECT_EQ(r.failures, 0);
  EXPECT_LE(r.range_rms_px, kGridRmsMaxPx);
  EXPECT_LE(r.azimuth_rms_px, kGridRmsMaxPx);
  EXPECT_LE(r.range_max_px, kGridMaxMaxPx);
  EXPECT_LE(r.azimuth_max_px, kGridMaxMaxPx);
  EXPECT_LE(r.ground_max_m, kGridGroundMaxM);
}

TEST(ValidateSentinel1, IwSlcGridAgreesInEverySwathAndPolarisation) {
  for (const auto& [swath, pol, points] : {std::tuple{"IW1", "VV", 210u}, {"IW1", "VH", 210u}, {"IW2", "VH", 231u}}) {
    const geo::Sentinel1Annotation a = Annotation(kIwSlc, swath, pol);
    ExpectWithinTargets(CheckGeolocationGrid(a), points);
  }
}

TEST(ValidateSentinel1, IwGrdGridAgreesInGroundRangePixels) {
  for (const char* pol : {"VV", "VH"}) {
    const GeolocationGridAgreement r = CheckGeolocationGrid(Annotation(kIwGrd, "IW", pol));
    ExpectWithinTargets(r, 210u);
    // gissar's ground-range pixel (nearest srgr record) against the grid's
    // pixel numbers: 0.008 px at most (a linear interpolation between records
    // would be up to 1.5 px off, geo/sentinel1_safe.h).
    EXPECT_LE(r.pixel_max_px, 0.01);
  }
}

TEST(ValidateSentinel1, StripmapGridAgreesEverywhere) {
  // The S1A stripmap grid (945 points). Its state vectors are not exactly each
  // other's derivatives (about 1 cm/s), and ESA's processor puts the
  // interpolated velocities in the Doppler equation: with the derivative of
  // the Hermite position cubic instead, gissar's zero-Doppler times were late
  // by up to 0.37 lines between vectors (0.259 rms; docs/sentinel1.md). With
  // the velocities interpolated (sensor::Orbit) the grid agrees within the
  // targets; measured 0.002 lines rms and 0.004 max.
  const GeolocationGridAgreement r = CheckGeolocationGrid(Annotation(kSm, "S3", "VH"));
  ExpectWithinTargets(r, 945u);
  EXPECT_LE(std::abs(r.azimuth_mean_px), 0.01);
  EXPECT_LE(r.ground_max_m, 1.0);
}

TEST(ValidateSentinel1, AnOrbitTimingErrorShowsAsItsAzimuthShift) {
  // Delaying every state vector by 1 ms makes each zero-Doppler time 1 ms
  // later: +1e-3 / azimuthTimeInterval (2.055556299999998e-3 s) = +0.4865 lines.
  geo::Sentinel1Annotation a = Annotation(kIwSlc, "IW1", "VV");
  const GeolocationGridAgreement before = CheckGeolocationGrid(a);
  for (double& t : a.orbit.time_s) t += 1e-3;
  const GeolocationGridAgreement after = CheckGeolocationGrid(a);
  EXPECT_NEAR(after.azimuth_mean_px - before.azimuth_mean_px, 1e-3 / 2.055556299999998e-3, 0.002);
  EXPECT_NEAR(after.range_mean_px, before.range_mean_px, 0.01);
}

// An ESA Earth Explorer orbit file holding `a`'s state vectors.
void WriteEof(const fs::path& path, const geo::Sentinel1Annotation& a, double epoch_unix_s, double shift_s = 0.0) {
  std::ofstream out(path);
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Earth_Explorer_File>\n<Data_Block type=\"xml\">\n"
      << "<List_of_OSVs count=\"" << a.orbit.time_s.size() << "\">\n";
  char buffer[512];
  for (size_t i = 0; i < a.orbit.time_s.size(); ++i) {
    std::string utc = FormatUtc(epoch_unix_s + a.orbit.time_s[i] + shift_s);
    utc.pop_back();  // the trailing Z
    const auto& p = a.orbit.position_m[i];
    const auto& v = a.orbit.velocity_mps[i];
    std::snprintf(buffer, sizeof buffer,
                  "<OSV><UTC>UTC=%s</UTC><X unit=\"m\">%.6f</X><Y unit=\"m\">%.6f</Y><Z unit=\"m\">%.6f</Z>"
                  "<VX unit=\"m/s\">%.9f</VX><VY unit=\"m/s\">%.9f</VY><VZ unit=\"m/s\">%.9f</VZ></OSV>\n",
                  utc.c_str(), p.x(), p.y(), p.z(), v.x(), v.y(), v.z());
    out << buffer;
  }
  out << "</List_of_OSVs>\n</Data_Block>\n</Earth_Explorer_File>\n";
}

TEST(ValidateSentinel1, RunWritesTheReportWithTheAnnotationOrbitAndAnEof) {
  const fs::path dir = testing::MakeTempDir();
  Sentinel1ValidateRequest request;
  request.product = testing::DataPath(kIwSlc).string();
  request.out_prefix = (dir / "s1").string();
  const Sentinel1ValidateResult with_annotation = RunSentinel1Validate(request, "test");
  ASSERT_EQ(with_annotation.outputs.size(), 1u);
  EXPECT_TRUE(fs::exists(dir / "s1.json"));
  const nlohmann::json& j = with_annotation.report;
  EXPECT_TRUE(j["passed"].get<bool>()) << j.dump(1);
  EXPECT_EQ(j["geolocation_grid"]["points"], 210 + 210 + 231);
  EXPECT_EQ(j["swaths"].size(), 3u);
  EXPECT_EQ(j["absent_annotations"].size(), 3u);  // the bundled copy lacks IW2 VV, IW3 VH, IW3 VV
  EXPECT_EQ(j["swaths"][0]["bursts"], 9);

  // The same vectors through an EOF file: the same figures.
  const geo::Sentinel1Product p = geo::OpenSentinel1(request.product);
  const geo::Sentinel1Annotation a = geo::ReadSentinel1Annotation(p, p.Entry("IW1", "VV"));
  request.orbit = (dir / "S1B_OPER_AUX_TEST.EOF").string();
  WriteEof(request.orbit, a, p.epoch_unix_s);
  request.out_prefix = (dir / "s1_eof").string();
  const nlohmann::json e = RunSentinel1Validate(request, "test").report;
  EXPECT_TRUE(e["passed"].get<bool>());
  EXPECT_EQ(e["orbit"], request.orbit);
  for (const char* axis : {"range_px", "azimuth_px"}) {
    EXPECT_NEAR(e["geolocation_grid"][axis]["rms"].get<double>(), j["geolocation_grid"][axis]["rms"].get<double>(),
                1e-6)
        << axis;
  }
  EXPECT_NEAR(e["geolocation_grid"]["ground_m"]["max"].get<double>(),
              j["geolocation_grid"]["ground_m"]["max"].get<double>(), 1e-3);
}

TEST(ValidateSentinel1, BadInputsAreErrorsAndWriteNothing) {
  const fs::path dir = testing::MakeTempDir();
  Sentinel1ValidateRequest request;
  request.product = testing::DataPath(kIwGrd).string();
  request.out_prefix = (dir / "bad").string();
  request.swath = "IW7";
  EXPECT_THROW(RunSentinel1Validate(request, "test"), InputError);
  request.swath = "";
  // An EOF an hour late does not cover the product.
  const geo::Sentinel1Annotation a = Annotation(kIwGrd, "IW", "VV");
  const geo::Sentinel1Product p = geo::OpenSentinel1(request.product);
  request.orbit = (dir / "late.EOF").string();
  WriteEof(request.orbit, a, p.epoch_unix_s, 3600.0);
  try {
    RunSentinel1Validate(request, "test");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("does not cover"), std::string::npos) << e.what();
    EXPECT_EQ(e.where(), request.orbit);
  }
  request.orbit = "";
  request.out_prefix = "";
  EXPECT_THROW(RunSentinel1Validate(request, "test"), ConfigError);
  EXPECT_FALSE(fs::exists(dir / "bad.json"));
}

}  // namespace
}  // namespace gissar::pipeline
