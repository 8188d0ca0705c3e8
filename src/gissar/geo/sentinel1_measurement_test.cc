// Sentinel-1 measurement reading and calibration on the bundled SAFE folders
// (data/sentinel1, PROVENANCE.md). Their measurement TIFFs are real-format,
// full-size images whose pixels are constant placeholders (IW1 VV SLC: 2 + 0i,
// IW1 VH: 1 + 0i, IW2 VH: 0 + 1i, GRD VV: 1, S3 VH SLC: 0): fine for reading,
// windows and calibration arithmetic, not for image statistics. Expected LUT
// values are read off the XML by eye (quoted) and combined by hand.
#include "gissar/geo/sentinel1_measurement.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include <cpl_vsi.h>
#include <gdal.h>
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

constexpr const char* kIw1VvTiff = "measurement/s1b-iw1-slc-vv-20210401t052624-20210401t052649-026269-032297-004.tiff";

Sentinel1ImageOptions Options(const std::string& swath, const std::string& pol, int burst = 0,
                              Sentinel1Radiometry r = Sentinel1Radiometry::kNone, bool noise = false) {
  Sentinel1ImageOptions o;
  o.swath = swath;
  o.polarization = pol;
  o.burst = burst;
  o.radiometry = r;
  o.remove_noise = noise;
  return o;
}

// One pixel of an image (measurement numbering).
float At(const Sentinel1Image& image, int line, int sample) {
  return image.ReadFloat({line, sample, 1, 1}).front();
}

TEST(Sentinel1Measurement, OpensTheTiffsWithTheAnnotatedSize) {
  const Sentinel1Image slc = Sentinel1Image::Open(testing::DataPath(kIwSlc), Options("IW1", "VV"));
  EXPECT_TRUE(slc.measurement().is_complex());
  EXPECT_EQ(slc.measurement().lines(), 13509);  // numberOfLines = 9 bursts x 1501
  EXPECT_EQ(slc.measurement().samples(), 21632);
  EXPECT_EQ(slc.measurement().file(),
            std::string(fs::path(kIwSlc).filename().string()) + "/" + kIw1VvTiff);
  const Sentinel1Window all = slc.window();
  EXPECT_EQ(all.first_line, 0);
  EXPECT_EQ(all.lines, 13509);
  EXPECT_EQ(all.samples, 21632);
  // The placeholder's DN, as stored (no no-data rule): 2 + 0i everywhere.
  const std::vector<std::complex<float>> dn = slc.measurement().ReadDn({100, 200, 2, 3});
  ASSERT_EQ(dn.size(), 6u);
  for (const auto& v : dn) EXPECT_EQ(v, std::complex<float>(2.0f, 0.0f));

  const Sentinel1Image grd = Sentinel1Image::Open(testing::DataPath(kIwGrd), Options("IW", "VV"));
  EXPECT_FALSE(grd.measurement().is_complex());
  EXPECT_EQ(grd.measurement().lines(), 16685);
  EXPECT_EQ(grd.measurement().samples(), 25788);
  EXPECT_EQ(grd.measurement().ReadDn({16684, 25787, 1, 1}).front(), std::complex<float>(1.0f, 0.0f));
  EXPECT_EQ(At(grd, 8000, 12000), 1.0f);  // amplitude DN (radiometry none)

  const Sentinel1Image sm = Sentinel1Image::Open(testing::DataPath(kSm), Options("S3", "VH"));
  EXPECT_TRUE(sm.measurement().is_complex());
  EXPECT_EQ(sm.measurement().lines(), 36895);
  EXPECT_EQ(sm.measurement().samples(), 18998);
  EXPECT_EQ(sm.measurement().ReadDn({0, 0, 1, 1}).front(), std::complex<float>(0.0f, 0.0f));
  // DN 0 is ESA's fill value: no-data.
  EXPECT_TRUE(std::isnan(sm.ReadDn({0, 0, 1, 1}).front().real()));
  EXPECT_TRUE(std::isnan(At(sm, 20000, 9000)));
}

TEST(Sentinel1Measurement, BurstWindowsAndLineTimes) {
  const Sentinel1Image b1 = Sentinel1Image::Open(testing::DataPath(kIwSlc), Options("IW1", "VV", 1));
  const Sentinel1Annotation& a = b1.annotation();
  EXPECT_EQ(b1.window().first_line, 0);
  EXPECT_EQ(b1.window().lines, 1501);  // linesPerBurst
  EXPECT_EQ(b1.window().first_sample, 0);
  EXPECT_EQ(b1.window().samples, 21632);
  const Sentinel1Window w2 = Sentinel1BurstWindow(a, 2);
  EXPECT_EQ(w2.first_line, 1501);
  EXPECT_EQ(w2.lines, 1501);
  const Sentinel1Window w9 = Sentinel1BurstWindow(a, 9);
  EXPECT_EQ(w9.first_line, 12008);  // 8 x 1501
  EXPECT_EQ(w9.first_line + w9.lines, 13509);
  EXPECT_NE(ErrorOf([&] { Sentinel1BurstWindow(a, 10); }).find("burst 10 does not exist; swath IW1 has bursts 1-9"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { Sentinel1BurstWindow(a, 0); }).find("| --burst"), std::string::npos);
  // Line times: burst 2's first line at its azimuthTime 05:26:26.966491, the next one azimuthTimeInterval later;
  // the last line of burst 1 (1500 intervals after 05:26:24.209990) is later than burst 2's first (overlap).
  EXPECT_NEAR(Sentinel1LineTime(a, 1501), 5 * 3600 + 26 * 60 + 26.966491, 1e-9);
  // (near 20000 s a double keeps ~4e-12 s)
  EXPECT_NEAR(Sentinel1LineTime(a, 1502) - Sentinel1LineTime(a, 1501), 2.055556299999998e-03, 1e-11);
  EXPECT_NEAR(Sentinel1LineTime(a, 0), 5 * 3600 + 26 * 60 + 24.209990, 1e-9);
  EXPECT_NEAR(Sentinel1LineTime(a, 1500), 5 * 3600 + 26 * 60 + 24.209990 + 1500 * 2.055556299999998e-03, 1e-9);
  // A window outside the burst is refused.
  EXPECT_NE(ErrorOf([&] { b1.ReadFloat({1500, 0, 2, 1}); }).find("is outside lines 0-1500"), std::string::npos);

  // Products without bursts.
  const Sentinel1Image grd = Sentinel1Image::Open(testing::DataPath(kIwGrd), Options("IW", "VV"));
  EXPECT_NE(ErrorOf([&] { Sentinel1BurstWindow(grd.annotation(), 1); }).find("a GRD product has no bursts"),
            std::string::npos);
  EXPECT_NEAR(Sentinel1LineTime(grd.annotation(), 10),
              grd.annotation().first_line_time_s + 10 * 1.498376640333055e-03, 1e-9);
  EXPECT_NE(ErrorOf([&] { Sentinel1Image::Open(testing::DataPath(kSm), Options("S3", "VH", 1)); })
                .find("has no bursts"),
            std::string::npos);
}

TEST(Sentinel1Measurement, NoDataOutsideTheBurstsValidWindow) {
  const Sentinel1Image b1 = Sentinel1Image::Open(testing::DataPath(kIwSlc), Options("IW1", "VV", 1));
  // Burst 1: lines 0-18 have no valid sample; line 19 is valid on samples 529-20935.
  EXPECT_TRUE(std::isnan(At(b1, 18, 10000)));
  EXPECT_TRUE(std::isnan(At(b1, 19, 528)));
  EXPECT_EQ(At(b1, 19, 529), 2.0f);  // |DN|
  EXPECT_EQ(At(b1, 19, 20935), 2.0f);
  EXPECT_TRUE(std::isnan(At(b1, 19, 20936)));
  const std::vector<std::complex<float>> dn = b1.ReadDn({19, 528, 1, 2});
  EXPECT_TRUE(std::isnan(dn[0].real()) && std::isnan(dn[0].imag()));
  EXPECT_EQ(dn[1], std::complex<float>(2.0f, 0.0f));
  EXPECT_FALSE(Sentinel1SampleValid(b1.annotation(), 13509, 529));    // beyond the bursts
}

TEST(Sentinel1Measurement, CalibrationIsDnSquaredOverTheBilinearLutSquared) {
  const fs::path safe = testing::DataPath(kIwSlc);
  const Sentinel1Image s = Sentinel1Image::Open(safe, Options("IW1", "VV", 1, Sentinel1Radiometry::kSigma0));
  // sigmaNought vectors (calibration-s1b-iw1-slc-vv-...-004.xml): line 91, pixels 480 520 560:
  // 330.8047 330.7431 330.6816; line 577: 330.7421 330.6806 330.6192. |DN|^2 = 4.
  // A grid node (line 577, pixel 560).
  EXPECT_FLOAT_EQ(At(s, 577, 560), static_cast<float>(4.0 / (330.6192 * 330.6192)));
  // Between nodes: line 334 is half-way from 91 to 577, pixel 540 half-way from 520 to 560.
  const double mid = (330.7431 + 330.6816 + 330.6806 + 330.6192) / 4;
  EXPECT_FLOAT_EQ(At(s, 334, 540), static_cast<float>(4.0 / (mid * mid)));
  // A quarter of the way in both: line 91 + 486/4 = 212.5 (not a line; take 213 = 91 + 122), pixel 530.
  const double w = 122.0 / 486.0;
  const double top = 330.7431 + 0.25 * (330.6816 - 330.7431), bottom = 330.6806 + 0.25 * (330.6192 - 330.6806);
  const double q = (1 - w) * top + w * bottom;
  EXPECT_FLOAT_EQ(At(s, 213, 530), static_cast<float>(4.0 / (q * q)));

  // betaNought is 236.9867 everywhere in this product; gamma at the node (577, 600) is 306.1540.
  const Sentinel1Image b = Sentinel1Image::Open(safe, Options("IW1", "VV", 1, Sentinel1Radiometry::kBeta0));
  EXPECT_FLOAT_EQ(At(b, 700, 12345), static_cast<float>(4.0 / (236.9867 * 236.9867)));
  const Sentinel1Image g = Sentinel1Image::Open(safe, Options("IW1", "VV", 1, Sentinel1Radiometry::kGamma0));
  EXPECT_FLOAT_EQ(At(g, 577, 600), static_cast<float>(4.0 / (306.1540 * 306.1540)));

  // A whole row of the fast evaluation equals Sentinel1LineVectors::At sample by sample, before, inside and
  // after the table (lines -2000, 334, 20000; samples beyond the last pixel 21631 included).
  const Sentinel1LineVectors& lut = s.calibration()->sigma0;
  for (double line : {-2000.0, 334.0, 20000.0}) {
    const std::vector<double> row = Sentinel1LutRow(lut, line, -5, 21650);
    for (int k = 0; k < 21650; k += 7) ASSERT_EQ(row[size_t(k)], lut.At(line, k - 5)) << line << " " << k;
  }
}

TEST(Sentinel1Measurement, NoiseRemovalSubtractsRangeTimesAzimuthLutBeforeDividing) {
  const Sentinel1Image s =
      Sentinel1Image::Open(testing::DataPath(kIwSlc), Options("IW1", "VV", 1, Sentinel1Radiometry::kSigma0, true));
  ASSERT_NE(s.noise(), nullptr);
  // noiseRangeLut at line 0, pixels 520 560: 473.6920 471.3990; at line 1501: 493.5479 490.9916;
  // noiseAzimuthLut at lines 330 340: 1.045198 1.042902. At (334, 540):
  const double wl = 334.0 / 1501.0;
  const double range = (1 - wl) * (473.6920 + 471.3990) / 2 + wl * (493.5479 + 490.9916) / 2;
  const double azimuth = 1.045198 + 0.4 * (1.042902 - 1.045198);
  const double noise = range * azimuth;  // 498.05 |DN|^2
  EXPECT_NEAR(s.noise()->At(334, 540), noise, 1e-9);
  EXPECT_NEAR(Sentinel1NoiseRow(*s.noise(), 334, 540, 1).front(), noise, 1e-9);
  // The placeholder's |DN|^2 = 4 is below the noise: clipped to NaN (not 0).
  EXPECT_TRUE(std::isnan(At(s, 334, 540)));
  // A DN of 40 (|DN|^2 = 1600) above it: (1600 - N) / A^2 with A as in the test above.
  const double a = (330.7431 + 330.6816 + 330.6806 + 330.6192) / 4;
  const std::vector<float> v =
      CalibrateSentinel1({{40.0f, 0.0f}, {0.0f, 40.0f}, {2.0f, 0.0f}}, {334, 540, 1, 3}, s.calibration()->sigma0,
                         s.noise());
  EXPECT_FLOAT_EQ(v[0], static_cast<float>((1600.0 - noise) / (a * a)));
  EXPECT_NEAR(v[0], 0.0101, 1e-4);
  EXPECT_GT(v[1], 0.0f);  // the next pixel, same |DN|
  EXPECT_TRUE(std::isnan(v[2]));

  // A hand-made table: A = 10 everywhere, noise range LUT 4 (pixels 0-9), azimuth blocks 0.5 on pixels 0-4
  // and 2 on pixels 5-9 (lines 0-100).
  Sentinel1LineVectors flat;
  flat.line = {0};
  flat.pixel = {{0, 9}};
  flat.values = {{10.0, 10.0}};
  Sentinel1Noise n;
  n.range = flat;
  n.range.values = {{4.0, 4.0}};
  n.azimuth.push_back({"IW1", 0, 100, 0, 4, {0, 100}, {0.5, 0.5}});
  n.azimuth.push_back({"IW1", 0, 100, 5, 9, {0, 100}, {2.0, 2.0}});
  const std::vector<float> h = CalibrateSentinel1(
      {{1.0f, 1.0f}, {3.0f, 4.0f}, {2.0f, 0.0f}, {3.0f, 0.0f}, {0.0f, 0.0f}}, {50, 3, 1, 5}, flat, &n);
  EXPECT_EQ(h[0], 0.0f);                           // pixel 3: |1 + i|^2 - 4 x 0.5 = 0 exactly: kept, not NaN
  EXPECT_FLOAT_EQ(h[1], (25.0f - 2.0f) / 100.0f);  // pixel 4: |3 + 4i|^2 = 25
  EXPECT_TRUE(std::isnan(h[2]));                   // pixel 5: N = 4 x 2 = 8 > 4
  EXPECT_FLOAT_EQ(h[3], (9.0f - 8.0f) / 100.0f);   // pixel 6
  EXPECT_TRUE(std::isnan(h[4]));                   // pixel 7: 0 - 8
  // Without noise: |DN|^2 / A^2.
  EXPECT_FLOAT_EQ(CalibrateSentinel1({{3.0f, 4.0f}}, {50, 3, 1, 1}, flat, nullptr)[0], 0.25f);
}

TEST(Sentinel1Measurement, ErrorsNameTheFileAndField) {
  // A missing measurement TIFF.
  const fs::path src = testing::DataPath(kIwSlc);
  const fs::path safe = testing::MakeTempDir() / src.filename();
  fs::create_directories(safe);
  fs::copy(src / "manifest.safe", safe / "manifest.safe");
  fs::copy(src / "annotation", safe / "annotation", fs::copy_options::recursive);
  std::string e = ErrorOf([&] { Sentinel1Image::Open(safe, Options("IW1", "VV")); });
  EXPECT_NE(e.find("measurement file does not exist (the manifest lists it; this SAFE lacks it) | " +
                   src.filename().string() + "/" + kIw1VvTiff),
            std::string::npos)
      << e;
  // A measurement of the wrong size and type.
  fs::create_directories(safe / "measurement");
  GDALDatasetH small = GDALCreate(GDALGetDriverByName("GTiff"), (safe / kIw1VvTiff).c_str(), 10, 10, 1, GDT_CInt16,
                                  nullptr);
  ASSERT_NE(small, nullptr);
  GDALClose(small);
  e = ErrorOf([&] { Sentinel1Image::Open(safe, Options("IW1", "VV")); });
  EXPECT_NE(e.find("the measurement is 10 x 10 samples x lines, the annotation states 21632 x 13509"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("numberOfSamples, numberOfLines"), std::string::npos) << e;
  small = GDALCreate(GDALGetDriverByName("GTiff"), (safe / kIw1VvTiff).c_str(), 10, 10, 1, GDT_Float32, nullptr);
  GDALClose(small);
  e = ErrorOf([&] { Sentinel1Image::Open(safe, Options("IW1", "VV")); });
  EXPECT_NE(e.find("data type Float32, expected CInt16 for an SLC"), std::string::npos) << e;

  // The GRD's calibration annotation is listed by its manifest but not bundled.
  e = ErrorOf(
      [&] { Sentinel1Image::Open(testing::DataPath(kIwGrd), Options("IW", "VV", 0, Sentinel1Radiometry::kSigma0)); });
  EXPECT_NE(e.find("calibration annotation does not exist (the manifest lists it; this SAFE lacks it) | "
                   "S1B_IW_GRDH_1SDV_20210401T052623_20210401T052648_026269_032297_ECC8.SAFE/annotation/calibration/"
                   "calibration-s1b-iw-grd-vv-"),
            std::string::npos)
      << e;
  // Noise removal needs a radiometry; the stripmap copy has no noise annotation.
  e = ErrorOf([&] { Sentinel1Image::Open(src, Options("IW1", "VV", 0, Sentinel1Radiometry::kNone, true)); });
  EXPECT_NE(e.find("thermal noise removal needs a radiometry (sigma0, beta0 or gamma0) | --noise-removal"),
            std::string::npos)
      << e;
  e = ErrorOf([&] {
    Sentinel1Image::Open(testing::DataPath(kSm), Options("S3", "VH", 0, Sentinel1Radiometry::kSigma0, true));
  });
  EXPECT_NE(e.find("noise annotation does not exist"), std::string::npos) << e;
  // A product that is not there; a radiometry that does not exist.
  e = ErrorOf([&] { Sentinel1Image::Open(src.parent_path() / "S1X_nothing.SAFE", Options("", "")); });
  EXPECT_NE(e.find("product does not exist | "), std::string::npos) << e;
  EXPECT_EQ(ParseSentinel1Radiometry("SIGMA0", "--radiometry"), Sentinel1Radiometry::kSigma0);
  EXPECT_EQ(ParseSentinel1Radiometry("", "--radiometry"), Sentinel1Radiometry::kNone);
  EXPECT_THROW(ParseSentinel1Radiometry("sigma_0", "--radiometry"), ConfigError);
  EXPECT_NE(ErrorOf([] { ParseSentinel1Radiometry("sigma_0", "--radiometry"); }).find("| --radiometry"),
            std::string::npos);
}

TEST(Sentinel1Measurement, ReadsTheMeasurementInsideAZip) {
  const fs::path src = testing::DataPath(kIwGrd);
  const std::string zip = (testing::MakeTempDir() / "S1B_IW_GRDH_test.zip").string();
  for (const auto& entry : fs::recursive_directory_iterator(src)) {
    if (!entry.is_regular_file()) continue;
    const std::string inside = src.filename().string() + "/" + fs::relative(entry.path(), src).generic_string();
    std::ifstream in(entry.path(), std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string bytes = ss.str();
    VSILFILE* f = VSIFOpenL(("/vsizip/" + zip + "/" + inside).c_str(), "wb");
    ASSERT_NE(f, nullptr) << inside;
    ASSERT_EQ(VSIFWriteL(bytes.data(), 1, bytes.size(), f), bytes.size());
    VSIFCloseL(f);
  }
  const Sentinel1Image grd = Sentinel1Image::Open(zip, Options("IW", "VV"));
  EXPECT_EQ(grd.measurement().lines(), 16685);
  EXPECT_EQ(At(grd, 0, 0), 1.0f);
}

}  // namespace
}  // namespace gissar::geo
