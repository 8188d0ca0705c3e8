// Sentinel-1 SAFE reader on the real annotations of data/sentinel1/ (copied
// from bopen/xarray-sentinel's tests/data, see data/sentinel1/PROVENANCE.md).
// Expected values are read off the XML files by eye (quoted in comments) and
// the interpolated LUT values are worked out by hand from them.
#include "gissar/geo/sentinel1_safe.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include <cpl_vsi.h>
#include <gtest/gtest.h>

#include "gissar/geo/sentinel1_testing.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::geo {
namespace {
namespace fs = std::filesystem;

using geo::testing_s1::kIwGrd;
using geo::testing_s1::kIwSlc;
using geo::testing_s1::kSm;
using geo::testing_s1::ErrorOf;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void Spit(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

// Copy of a bundled SAFE in a fresh directory (to break it).
fs::path CopySafe(const char* relative) {
  const fs::path src = testing::DataPath(relative);
  const fs::path dst = testing::MakeTempDir() / src.filename();
  fs::copy(src, dst, fs::copy_options::recursive);
  return dst;
}

TEST(Sentinel1Safe, ReadsTheManifestOfAnIwSlc) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kIwSlc));
  EXPECT_EQ(p.mission, "S1B");
  EXPECT_EQ(p.mode, "IW");
  EXPECT_EQ(p.product_type, "SLC");
  EXPECT_EQ(p.epoch_utc, "2021-04-01T00:00:00.000000Z");
  // The manifest lists IW1-IW3 x VH/VV; the bundled copy keeps three annotations.
  ASSERT_EQ(p.entries.size(), 6u);
  int present = 0;
  for (const Sentinel1Entry& e : p.entries) present += e.annotation_present;
  EXPECT_EQ(present, 3);
  const Sentinel1Entry& e = p.Entry("iw1", "vv");
  EXPECT_EQ(e.annotation_file, "annotation/s1b-iw1-slc-vv-20210401t052624-20210401t052649-026269-032297-004.xml");
  EXPECT_EQ(e.calibration_file,
            "annotation/calibration/calibration-s1b-iw1-slc-vv-20210401t052624-20210401t052649-026269-032297-004.xml");
  EXPECT_TRUE(e.annotation_present);
}

TEST(Sentinel1Safe, RecognisesSafePaths) {
  EXPECT_TRUE(IsSentinel1Path(testing::DataPath(kIwSlc)));
  EXPECT_TRUE(IsSentinel1Path(testing::DataPath(kIwSlc) / "manifest.safe"));
  EXPECT_TRUE(IsSentinel1Path("/nowhere/S1A_IW_GRDH_1SDV_X.zip"));
  EXPECT_FALSE(IsSentinel1Path(testing::DataPath("uavsar/winnipeg.h5")));
  EXPECT_FALSE(IsSentinel1Path(testing::DataPath("uavsar")));
}

TEST(Sentinel1Safe, ReadsAnIwSlcAnnotation) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kIwSlc));
  const Sentinel1Annotation a = ReadSentinel1Annotation(p, p.Entry("IW1", "VV"));
  EXPECT_EQ(a.swath, "IW1");
  EXPECT_EQ(a.polarization, "VV");
  EXPECT_EQ(a.pass, "Descending");
  // productFirstLineUtcTime 2021-04-01T05:26:24.209990 = 5 h 26 min 24.209990 s after midnight.
  EXPECT_NEAR(a.first_line_time_s, 5 * 3600 + 26 * 60 + 24.209990, 1e-9);
  EXPECT_NEAR(a.azimuth_time_interval_s, 2.055556299999998e-03, 1e-18);
  EXPECT_NEAR(a.slant_range_time_s, 5.343035814454385e-03, 1e-18);
  EXPECT_EQ(a.number_of_samples, 21632);
  EXPECT_EQ(a.number_of_lines, 13509);
  // c / (2 x rangeSamplingRate 6.434523812571428e7 Hz) matches rangePixelSpacing 2.329562 m.
  EXPECT_NEAR(a.slant_range_spacing_m(), 2.329562, 5e-7);
  EXPECT_NEAR(a.range_pixel_spacing_m, 2.329562, 1e-12);
  // c / radarFrequency 5.405000454334350e9 Hz.
  EXPECT_NEAR(a.wavelength_m, 299792458.0 / 5.405000454334350e9, 1e-15);
  ASSERT_EQ(a.orbit.time_s.size(), 17u);
  EXPECT_NEAR(a.orbit.time_s.front(), 5 * 3600 + 25 * 60 + 19.0, 1e-9);  // 05:25:19.000000
  EXPECT_DOUBLE_EQ(a.orbit.position_m.front().x(), 4.299854769e6);
  EXPECT_DOUBLE_EQ(a.orbit.velocity_mps.front().y(), -9.1122756e1);
  // 9 bursts of 1501 lines; burst 1 valid on lines 19..1482 (19 leading and 18 trailing -1).
  ASSERT_EQ(a.bursts.size(), 9u);
  EXPECT_EQ(a.lines_per_burst, 1501);
  EXPECT_EQ(a.bursts[0].first_valid_line, 19);
  EXPECT_EQ(a.bursts[0].last_valid_line, 1482);
  EXPECT_EQ(a.bursts[0].first_valid_sample[19], 529);
  EXPECT_EQ(a.bursts[0].last_valid_sample[19], 20935);
  EXPECT_EQ(a.bursts[1].first_line, 1501);
  EXPECT_NEAR(a.bursts[1].azimuth_time_s, 5 * 3600 + 26 * 60 + 26.966491, 1e-9);
  EXPECT_EQ(a.Burst(2).number, 2);
  EXPECT_EQ(a.BurstOfTime(a.bursts[1].azimuth_time_s + 0.5), 2);
  // 210 grid points; the first at line 0 pixel 0, 47.09200435560957 N 12.42647347821595 E, 2322.000320347026 m.
  ASSERT_EQ(a.geolocation_grid.size(), 210u);
  const Sentinel1GridPoint& g = a.geolocation_grid.front();
  EXPECT_EQ(g.line, 0);
  EXPECT_EQ(g.pixel, 0);
  EXPECT_DOUBLE_EQ(g.latitude_deg, 4.709200435560957e+01);
  EXPECT_DOUBLE_EQ(g.longitude_deg, 1.242647347821595e+01);
  EXPECT_DOUBLE_EQ(g.height_m, 2.322000320347026e+03);
  EXPECT_NEAR(g.azimuth_time_s, 5 * 3600 + 26 * 60 + 24.209736, 1e-9);
  EXPECT_EQ(a.geolocation_grid.back().line, 13508);
  EXPECT_EQ(a.geolocation_grid.back().pixel, 21631);
  EXPECT_TRUE(a.range_conversion.empty());
}

TEST(Sentinel1Safe, CalibrationLutIsBilinearInLineAndPixel) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kIwSlc));
  const Sentinel1Calibration c = ReadSentinel1Calibration(p, p.Entry("IW1", "VV"));
  EXPECT_DOUBLE_EQ(c.absolute_calibration_constant, 1.393);
  ASSERT_EQ(c.sigma0.line.size(), 30u);
  // Vector 1: line -1042, pixels 0 40 ..., sigmaNought 331.9230 331.8600; vector 2: line -556,
  // sigmaNought 331.9099 331.8470.
  EXPECT_EQ(c.sigma0.line[0], -1042);
  EXPECT_EQ(c.sigma0.line[1], -556);
  EXPECT_DOUBLE_EQ(c.sigma0.At(-1042, 0), 331.9230);               // node
  EXPECT_DOUBLE_EQ(c.sigma0.At(-1042, 40), 331.8600);              // node
  EXPECT_NEAR(c.sigma0.At(-1042, 20), (331.9230 + 331.8600) / 2, 1e-9);  // between pixels
  EXPECT_NEAR(c.sigma0.At(-799, 0), (331.9230 + 331.9099) / 2, 1e-9);    // between lines
  EXPECT_NEAR(c.sigma0.At(-799, 20), (331.9230 + 331.8600 + 331.9099 + 331.8470) / 4, 1e-9);
  // A quarter of the way: line -1042 + 486/4, pixel 10.
  const double top = 331.9230 + 0.25 * (331.8600 - 331.9230), bottom = 331.9099 + 0.25 * (331.8470 - 331.9099);
  EXPECT_NEAR(c.sigma0.At(-1042 + 121.5, 10), 0.75 * top + 0.25 * bottom, 1e-9);
  EXPECT_DOUBLE_EQ(c.sigma0.At(-5000, 0), 331.9230);  // clamped before the first vector
  EXPECT_DOUBLE_EQ(c.beta0.At(-1042, 0), 236.9867);
  EXPECT_NEAR(c.gamma0.At(-1042, 20), (307.8685 + 307.7896) / 2, 1e-9);
  EXPECT_DOUBLE_EQ(c.dn.At(-1042, 0), 200.7929);
}

TEST(Sentinel1Safe, NoiseIsRangeTimesAzimuthLut) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kIwSlc));
  const Sentinel1Noise n = ReadSentinel1Noise(p, p.Entry("IW1", "VV"));
  ASSERT_EQ(n.range.line.size(), 10u);
  ASSERT_EQ(n.azimuth.size(), 1u);
  EXPECT_EQ(n.azimuth[0].last_azimuth_line, 13508);
  EXPECT_EQ(n.azimuth[0].last_range_sample, 21631);
  // noiseRangeVector at line 0: pixels 0 40, LUT 508.1391 505.1812; noiseAzimuthLut at lines 0 10:
  // 1.156654 1.152112.
  EXPECT_NEAR(n.At(0, 0), 508.1391 * 1.156654, 1e-9);
  EXPECT_NEAR(n.At(0, 20), (508.1391 + 505.1812) / 2 * 1.156654, 1e-9);
  EXPECT_NEAR(n.range.At(-1501, 40), 507.7135, 1e-9);
}

TEST(Sentinel1Safe, ReadsAGrdWithItsRangePolynomials) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kIwGrd));
  EXPECT_EQ(p.product_type, "GRD");
  const Sentinel1Annotation a = ReadSentinel1Annotation(p, p.Entry("", "VV"));
  EXPECT_TRUE(a.is_grd());
  EXPECT_EQ(a.swath, "IW");
  EXPECT_DOUBLE_EQ(a.range_pixel_spacing_m, 10.0);
  ASSERT_EQ(a.range_conversion.size(), 28u);
  const Sentinel1RangeConversion& c = a.range_conversion.front();
  EXPECT_DOUBLE_EQ(c.sr0_m, 8.009428521087262e+05);
  EXPECT_EQ(c.srgr.size(), 9u);
  // At the first record's time and R = sr0, ground range = srgr[0] = 0.03469 m; G = 0 gives R = grsr[0].
  EXPECT_NEAR(a.GroundRangeOfSlantRange(c.sr0_m, c.azimuth_time_s), 3.469352441607043e-02, 1e-9);
  EXPECT_NEAR(a.SlantRangeOfGroundRange(0.0, c.azimuth_time_s), 8.009428521087262e+05, 1e-6);
  // The two polynomials invert each other to a few centimetres over the swath (250 km).
  for (double g : {0.0, 50e3, 150e3, 250e3}) {
    const double r = a.SlantRangeOfGroundRange(g, c.azimuth_time_s + 0.5);
    EXPECT_NEAR(a.GroundRangeOfSlantRange(r, c.azimuth_time_s + 0.5), g, 0.05) << g;
  }
  EXPECT_EQ(ErrorOf([&] { a.Burst(1); }).find("a GRD product has no bursts"), 0u);
  EXPECT_NE(ErrorOf([&] { a.Burst(1); }).find("--burst"), std::string::npos);
}

TEST(Sentinel1Safe, ReadsStripmap) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kSm));
  const Sentinel1Annotation a = ReadSentinel1Annotation(p, p.Entry("S3", "VH"));
  EXPECT_EQ(p.mode, "SM");  // manifest instrumentMode
  EXPECT_EQ(a.mode, "S3");  // the annotation's adsHeader/mode names the stripmap beam
  EXPECT_TRUE(a.bursts.empty());
  EXPECT_EQ(a.geolocation_grid.size(), 945u);
  EXPECT_EQ(a.number_of_lines, 36895);
  EXPECT_NE(ErrorOf([&] { a.Burst(1); }).find("has no bursts"), std::string::npos);
  const Sentinel1Calibration c = ReadSentinel1Calibration(p, p.Entry("S3", "VH"));
  EXPECT_FALSE(c.sigma0.line.empty());
}

TEST(Sentinel1Safe, ReadsAZipThroughVsizip) {
  const fs::path src = testing::DataPath(kIwGrd);
  const std::string zip = (testing::MakeTempDir() / "S1B_IW_GRDH_test.zip").string();
  for (const auto& entry : fs::recursive_directory_iterator(src)) {
    if (!entry.is_regular_file()) continue;
    const std::string inside = src.filename().string() + "/" + fs::relative(entry.path(), src).generic_string();
    const std::string text = Slurp(entry.path());
    VSILFILE* f = VSIFOpenL(("/vsizip/" + zip + "/" + inside).c_str(), "wb");
    ASSERT_NE(f, nullptr) << inside;
    ASSERT_EQ(VSIFWriteL(text.data(), 1, text.size(), f), text.size());
    VSIFCloseL(f);
  }
  const Sentinel1Product p = OpenSentinel1(zip);
  EXPECT_EQ(p.name, src.filename().string());
  const Sentinel1Annotation a = ReadSentinel1Annotation(p, p.Entry("IW", "VH"));
  EXPECT_EQ(a.polarization, "VH");
  EXPECT_EQ(a.geolocation_grid.size(), 210u);
}

TEST(Sentinel1Safe, ErrorsNameTheFileAndField) {
  // A swath or polarisation that does not exist.
  const Sentinel1Product slc = OpenSentinel1(testing::DataPath(kIwSlc));
  EXPECT_NE(ErrorOf([&] { slc.Entry("IW4", "VV"); }).find("swath IW4 does not exist"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { slc.Entry("IW4", "VV"); }).find("| --swath"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { slc.Entry("IW1", "HH"); }).find("| --polarization"), std::string::npos);
  // Listed by the manifest but absent from the SAFE (the bundled copy lacks IW3).
  const std::string missing = ErrorOf([&] { ReadSentinel1Annotation(slc, slc.Entry("IW3", "VV")); });
  EXPECT_NE(missing.find("file not found | S1B_IW_SLC__1SDV_20210401T052622_20210401T052650_026269_032297_EFA4.SAFE/"
                         "annotation/s1b-iw3-slc-vv"),
            std::string::npos)
      << missing;
  // A burst that does not exist.
  const Sentinel1Annotation iw1 = ReadSentinel1Annotation(slc, slc.Entry("IW1", "VV"));
  EXPECT_NE(ErrorOf([&] { iw1.Burst(10); }).find("burst 10 does not exist; swath IW1 has bursts 1-9"),
            std::string::npos);

  // Truncated and malformed annotations.
  const fs::path safe = CopySafe(kIwGrd);
  const fs::path vv = safe / "annotation/s1b-iw-grd-vv-20210401t052623-20210401t052648-026269-032297-001.xml";
  const std::string text = Slurp(vv);
  Spit(vv, text.substr(0, text.size() / 2));
  const Sentinel1Product grd = OpenSentinel1(safe);
  std::string e = ErrorOf([&] { ReadSentinel1Annotation(grd, grd.Entry("IW", "VV")); });
  EXPECT_NE(e.find("malformed or truncated XML"), std::string::npos) << e;
  EXPECT_NE(e.find("annotation/s1b-iw-grd-vv-"), std::string::npos) << e;

  std::string bad = text;
  bad.replace(bad.find("<azimuthTimeInterval>") + 21, 5, "x.abc");
  Spit(vv, bad);
  e = ErrorOf([&] { ReadSentinel1Annotation(grd, grd.Entry("IW", "VV")); });
  EXPECT_NE(e.find("not a finite number"), std::string::npos) << e;
  EXPECT_NE(e.find("imageAnnotation/imageInformation/azimuthTimeInterval"), std::string::npos) << e;

  bad = text;
  const size_t at = bad.find("<orbitList");
  bad.replace(at, 10, "<orbitLost");
  bad.replace(bad.find("</orbitList>"), 12, "</orbitLost>");
  Spit(vv, bad);
  e = ErrorOf([&] { ReadSentinel1Annotation(grd, grd.Entry("IW", "VV")); });
  EXPECT_NE(e.find("missing element <orbitList> | "), std::string::npos) << e;
  EXPECT_NE(e.find(": generalAnnotation/orbitList"), std::string::npos) << e;

  // The SAFE without its annotation directory.
  fs::remove_all(safe / "annotation");
  const Sentinel1Product bare = OpenSentinel1(safe);
  e = ErrorOf([&] { ReadSentinel1Annotation(bare, bare.Entry("IW", "VH")); });
  EXPECT_NE(e.find("file not found"), std::string::npos) << e;

  // No manifest; not Sentinel-1.
  fs::remove(safe / "manifest.safe");
  EXPECT_NE(ErrorOf([&] { OpenSentinel1(safe); }).find("file not found"), std::string::npos);
  Spit(safe / "manifest.safe",
       "<?xml version=\"1.0\"?><xfdu:XFDU xmlns:xfdu=\"urn:ccsds:schema:xfdu:1\" xmlns:safe=\"x\"><metadataSection>"
       "<safe:familyName>SENTINEL-2</safe:familyName></metadataSection></xfdu:XFDU>");
  e = ErrorOf([&] { OpenSentinel1(safe); });
  EXPECT_NE(e.find("not a Sentinel-1 product"), std::string::npos) << e;
  EXPECT_NE(e.find("familyName"), std::string::npos) << e;
  EXPECT_NE(ErrorOf([&] { OpenSentinel1(safe / "nothing.SAFE"); }).find("not found"), std::string::npos);
}

TEST(Sentinel1Safe, ExternalOrbitMustCoverTheProduct) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(kIwGrd));
  Sentinel1Annotation a = ReadSentinel1Annotation(p, p.Entry("IW", "VV"));
  StateVectors v;
  v.format = "eof";
  for (size_t i = 0; i < a.orbit.time_s.size(); ++i) {
    v.utc_s.push_back(p.epoch_unix_s + a.orbit.time_s[i] + 3600.0);  // an hour late
    v.position_m.push_back(a.orbit.position_m[i]);
    v.velocity_mps.push_back(a.orbit.velocity_mps[i]);
  }
  const std::string e = ErrorOf([&] { ReplaceSentinel1Orbit(a, p, v, "late.EOF"); });
  EXPECT_NE(e.find("the orbit does not cover the product's time 2021-04-01T05:26:23"), std::string::npos) << e;
  EXPECT_NE(e.find("| late.EOF"), std::string::npos) << e;
  for (double& t : v.utc_s) t -= 3600.0;
  ReplaceSentinel1Orbit(a, p, v, "ok.EOF");
  EXPECT_EQ(a.orbit.type, "eof");
  EXPECT_GE(a.orbit.time_s.size(), 4u);
}

}  // namespace
}  // namespace gissar::geo
