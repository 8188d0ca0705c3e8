#include "gissar/geo/rslc_product.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <complex>
#include <fstream>
#include <numeric>
#include <random>

#include "gissar/geo/geoid.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::geo {
namespace {

using testing::DataPath;
using testing::MakeTempDir;

// Values checked against h5dump of the bundled chip (data/README.md).
TEST(RslcProductTest, ReadsWinnipegChip) {
  const RslcProduct p = ReadRslcProduct(DataPath("uavsar/winnipeg.h5"));
  EXPECT_EQ(p.rows(), 250);
  EXPECT_EQ(p.cols(), 250);
  EXPECT_TRUE(p.look_left);
  EXPECT_EQ(p.product_version, "0.3");
  EXPECT_EQ(p.epoch_utc, "2012-07-15 14:36:47");
  EXPECT_DOUBLE_EQ(p.center_frequency_hz, 1.243e9);
  EXPECT_NEAR(p.wavelength_m, 299792458.0 / 1.243e9, 1e-12);
  EXPECT_NEAR(p.range_spacing_m(), 6.24568, 1e-5);       // slantRangeSpacing
  EXPECT_NEAR(p.azimuth_spacing_s(), 0.0273291, 1e-7);   // zeroDopplerTimeSpacing
  EXPECT_DOUBLE_EQ(p.zero_doppler_time_s.front(), 172800.0);
  EXPECT_NEAR(p.slant_range_m.front(), 13150.0574, 1e-4);
  ASSERT_EQ(p.orbit.time_s.size(), 100u);
  EXPECT_NEAR(p.orbit.time_s.front(), 172621.185856, 1e-6);
  EXPECT_NEAR(p.orbit.position_m[0].x(), -528670.39051178, 1e-6);
  EXPECT_NEAR(p.orbit.velocity_mps[0].z(), 103.79241699, 1e-6);
  EXPECT_EQ(p.orbit.type, "POE");
  EXPECT_EQ(p.attitude.time_s.size(), 100u);
  ASSERT_EQ(p.amplitude.size(), 250u * 250u);
  const double mean = std::accumulate(p.amplitude.begin(), p.amplitude.end(), 0.0) / p.amplitude.size();
  EXPECT_NEAR(mean, 0.201874, 1e-5);  // mean |HH| by h5py
  ASSERT_EQ(p.polarizations.size(), 1u);
  EXPECT_EQ(p.polarizations[0], "HH");
}

TEST(RslcProductTest, ReadsSanAndrewsChipWithFourPolarizations) {
  const RslcProduct p = ReadRslcProduct(DataPath("uavsar/SanAnd_129.h5"));
  EXPECT_EQ(p.rows(), 150);
  EXPECT_EQ(p.cols(), 200);
  EXPECT_EQ(p.epoch_utc, "2018-10-09 22:42:03");
  EXPECT_EQ(p.polarizations, (std::vector<std::string>{"HH", "HV", "VH", "VV"}));
  EXPECT_NEAR(p.azimuth_spacing_s(), 0.0211786, 1e-7);
  EXPECT_THROW(ReadRslcProduct(DataPath("uavsar/SanAnd_129.h5"), {"A", "VV", true}), InputError);  // not stored
  EXPECT_THROW(ReadRslcProduct(DataPath("uavsar/SanAnd_129.h5"), {"C", "HH", true}), ConfigError);
}

// The ALOS-1 PALSAR quad-pol chip in NISAR RSLC layout (data/alos_rio_branco):
// sample values checked with gdal_translate of the HDF5 layers.
TEST(RslcProductTest, ReadsAlosQuadPolChipWithItsComplexLayersAndBeta0Lut) {
  const std::filesystem::path path = DataPath("alos_rio_branco/calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5");
  RslcReadOptions options;
  options.read_amplitude = false;
  options.read_complex = true;
  options.read_calibration = true;
  const RslcProduct p = ReadRslcProduct(path, options);
  EXPECT_EQ(p.rows(), 100);
  EXPECT_EQ(p.cols(), 50);
  EXPECT_EQ(p.mission, "ALOS");
  EXPECT_FALSE(p.look_left);
  EXPECT_EQ(p.stored_polarizations, (std::vector<std::string>{"HH", "HV", "VH", "VV"}));
  EXPECT_TRUE(p.amplitude.empty());
  ASSERT_EQ(p.slc.size(), 5000u);
  EXPECT_EQ(p.slc[0], std::complex<float>(-122.5625f, -411.5f));
  EXPECT_EQ(p.slc[1], std::complex<float>(-704.0f, 2.3046875f));
  EXPECT_EQ(p.slc[50 * 50 + 25], std::complex<float>(7356.0f, 20448.0f));  // the corner reflector
  ASSERT_TRUE(p.beta0_lut.has_value());
  EXPECT_EQ(p.beta0_lut->dataset, "/science/LSAR/RSLC/metadata/calibrationInformation/geometry/beta0");
  EXPECT_EQ(p.beta0_lut->time_s.size(), 2u);
  EXPECT_EQ(p.beta0_lut->slant_range_m.size(), 1u);
  EXPECT_DOUBLE_EQ(p.beta0_lut->At(p.zero_doppler_time_s[50], p.slant_range_m[25]), 1.0);
  // Without the flags: no LUT, amplitude only (the default behaviour).
  const RslcProduct q = ReadRslcProduct(path, {"A", "VV", true});
  EXPECT_FALSE(q.beta0_lut.has_value());
  EXPECT_TRUE(q.slc.empty());
  ASSERT_EQ(q.amplitude.size(), 5000u);
  EXPECT_NEAR(q.amplitude[50 * 50 + 25], std::abs(std::complex<float>(-1886.0f, 16432.0f)), 1e-2);
}

TEST(RslcProductTest, CalibrationLutIsBilinearAndClamped) {
  RslcCalibrationLut lut;
  lut.time_s = {0.0, 10.0};
  lut.slant_range_m = {100.0, 200.0, 300.0};
  lut.values = {1.0, 2.0, 3.0, 11.0, 12.0, 13.0};
  EXPECT_DOUBLE_EQ(lut.At(0.0, 100.0), 1.0);
  EXPECT_DOUBLE_EQ(lut.At(5.0, 150.0), 6.5);
  EXPECT_DOUBLE_EQ(lut.At(-5.0, 50.0), 1.0);     // clamped
  EXPECT_DOUBLE_EQ(lut.At(20.0, 1000.0), 13.0);  // clamped
  EXPECT_DOUBLE_EQ(lut.At(10.0, 250.0), 12.5);
}

// SanAnd lists four polarisations but the cropped file stores only HH.
TEST(RslcProductTest, MissingLayerNamesTheStoredOnes) {
  try {
    ReadRslcProduct(DataPath("uavsar/SanAnd_129.h5"), {"A", "HV", true});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("polarisations stored: HH"), std::string::npos) << e.what();
  }
}

RslcProduct Synthetic() {
  RslcProduct p;
  p.epoch_utc = "2020-01-02 03:04:05";
  for (int i = 0; i < 4; ++i) p.zero_doppler_time_s.push_back(10.0 + 0.5 * i);
  for (int j = 0; j < 3; ++j) p.slant_range_m.push_back(1000.0 + 2.0 * j);
  p.center_frequency_hz = 5.405e9;
  p.look_left = false;
  for (int k = 0; k < 5; ++k) {
    p.orbit.time_s.push_back(8.0 + k);
    p.orbit.position_m.emplace_back(7e6 + k, 1.0, 2.0);
    p.orbit.velocity_mps.emplace_back(1.0, 7500.0, 0.0);
  }
  for (int k = 0; k < 12; ++k) p.amplitude.push_back(0.5f * k);
  return p;
}

TEST(RslcProductTest, WriterRoundTrip) {
  const auto dir = MakeTempDir();
  const RslcProduct p = Synthetic();
  WriteRslcProduct(dir / "p.h5", p);
  const RslcProduct q = ReadRslcProduct(dir / "p.h5");
  EXPECT_EQ(q.rows(), 4);
  EXPECT_EQ(q.cols(), 3);
  EXPECT_FALSE(q.look_left);
  EXPECT_EQ(q.epoch_utc, p.epoch_utc);
  EXPECT_EQ(q.orbit.time_s, p.orbit.time_s);
  EXPECT_EQ(q.amplitude, p.amplitude);
  EXPECT_NEAR(q.wavelength_m, 0.0554658, 1e-7);
}

// The processed bandwidths (swaths/frequencyA/processedRangeBandwidth and
// processedAzimuthBandwidth, Hz) where a product states them, NaN where it
// does not; the writer keeps them. Values as gdalmdiminfo prints them:
// SanAnd 20000000 and 40.5514151995046532; the ALOS chip 20000000 and 1200.
TEST(RslcProductTest, ProcessedBandwidthsWhereTheProductStatesThem) {
  const RslcProduct sanand = ReadRslcProduct(DataPath("uavsar/SanAnd_129.h5"), {"A", "HH", false});
  std::printf("[ measured ] SanAnd processed bandwidths: range %.6f Hz, azimuth %.16g Hz\n",
              sanand.processed_range_bandwidth_hz, sanand.processed_azimuth_bandwidth_hz);
  EXPECT_EQ(sanand.processed_range_bandwidth_hz, 20000000.0);
  EXPECT_NEAR(sanand.processed_azimuth_bandwidth_hz, 40.5514151995046532, 1e-12);
  const RslcProduct alos =
      ReadRslcProduct(DataPath("alos_rio_branco/calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5"), {"A", "HH", false});
  std::printf("[ measured ] ALOS chip processed bandwidths: range %.6f Hz, azimuth %.6f Hz\n",
              alos.processed_range_bandwidth_hz, alos.processed_azimuth_bandwidth_hz);
  EXPECT_EQ(alos.processed_range_bandwidth_hz, 20000000.0);
  EXPECT_EQ(alos.processed_azimuth_bandwidth_hz, 1200.0);
  const auto dir = MakeTempDir();
  RslcProduct p = Synthetic();
  WriteRslcProduct(dir / "none.h5", p);
  const RslcProduct none = ReadRslcProduct(dir / "none.h5");
  EXPECT_TRUE(std::isnan(none.processed_range_bandwidth_hz));
  EXPECT_TRUE(std::isnan(none.processed_azimuth_bandwidth_hz));
  p.processed_range_bandwidth_hz = 14e6;
  p.processed_azimuth_bandwidth_hz = 1100.0;
  WriteRslcProduct(dir / "stated.h5", p);
  const RslcProduct stated = ReadRslcProduct(dir / "stated.h5");
  EXPECT_EQ(stated.processed_range_bandwidth_hz, 14e6);
  EXPECT_EQ(stated.processed_azimuth_bandwidth_hz, 1100.0);
}

// A product over the memory budget is refused from its shape, before the
// SLC is read, as `gissar validate` (and `simulate --product`) read it (400
// B per pixel): the message names only flags those commands have,
// --max-memory and --force.
TEST(RslcProductTest, ProductOverTheBudgetNamesRealFlags) {
  const auto dir = MakeTempDir();
  WriteRslcProduct(dir / "p.h5", Synthetic());
  RslcReadOptions options;
  options.max_bytes = 1024;
  options.bytes_per_pixel = 400.0;
  try {
    ReadRslcProduct(dir / "p.h5", options);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.where(), "--max-memory");
    EXPECT_EQ(e.message(), "product grid of 4 x 3 pixels (" + (dir / "p.h5").string() +
                               ") needs about 4.7 KiB, over the memory limit of 1.0 KiB; crop the product, raise "
                               "--max-memory, or run it anyway with --force");
  }
  options.max_bytes = 4800;  // 4 x 3 x 400 B: just enough
  EXPECT_EQ(ReadRslcProduct(dir / "p.h5", options).rows(), 4);
}

TEST(RslcProductTest, RejectsBadProducts) {
  const auto dir = MakeTempDir();
  EXPECT_THROW(ReadRslcProduct(dir / "missing.h5"), InputError);
  {
    std::ofstream out(dir / "random.h5", std::ios::binary);
    std::mt19937 rng(1);
    for (int k = 0; k < 4096; ++k) out.put(static_cast<char>(rng()));
  }
  EXPECT_THROW(ReadRslcProduct(dir / "random.h5"), InputError);
  RslcProduct no_orbit = Synthetic();
  no_orbit.orbit = {};
  WriteRslcProduct(dir / "no_orbit.h5", no_orbit);
  try {
    ReadRslcProduct(dir / "no_orbit.h5");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no orbit"), std::string::npos) << e.what();
  }
  RslcProduct short_orbit = Synthetic();
  short_orbit.orbit.time_s = {11.0, 12.0, 13.0, 14.0};  // starts after the first line
  short_orbit.orbit.position_m.resize(4);
  short_orbit.orbit.velocity_mps.resize(4);
  WriteRslcProduct(dir / "short.h5", short_orbit);
  EXPECT_THROW(ReadRslcProduct(dir / "short.h5"), InputError);
  RslcProduct uneven = Synthetic();
  uneven.slant_range_m[2] = 1003.0;
  WriteRslcProduct(dir / "uneven.h5", uneven);
  EXPECT_THROW(ReadRslcProduct(dir / "uneven.h5"), InputError);
}

// PROJ's own vgridshift (cct +proj=vgridshift +grids=egm96_15.gtx) gives
// -26.4587 m at (-97.625, 49.5), midway between two posts; at a post the
// grid value itself (gdallocationinfo: -26.2163 m at (-97.75, 49.5)).
TEST(Egm96GeoidTest, MatchesProjAtWinnipeg) {
  const Egm96Geoid geoid;
  EXPECT_NEAR(geoid.UndulationM(-97.625, 49.5), -26.4587, 1e-3);
  EXPECT_NEAR(geoid.UndulationM(-97.75, 49.5), -26.2163, 1e-3);
  EXPECT_NEAR(geoid.UndulationM(180.0, 0.0), geoid.UndulationM(-180.0, 0.0), 1e-9);  // wraps
  EXPECT_THROW(Egm96Geoid("/nonexistent/egm96_15.gtx"), InputError);
}

// Hostile files (tests/data/hostile_hdf5, found by fuzz_nisar_hdf5): each a
// clear InputError naming the file, never a crash of the caller or an
// allocation outside the budget. The message of the read, or "" when none.
std::string HostileReadMessage(const std::string& name) {
  RslcReadOptions options;
  options.max_bytes = int64_t{64} << 20;
  options.read_complex = true;
  options.read_calibration = true;
  const std::filesystem::path path = gissar::testing::TestDataPath("hostile_hdf5/" + name);
  try {
    ReadRslcProduct(path, options);
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    return e.what();
  }
  return "";
}

TEST(RslcProductTest, LibHdf5CrashOnCorruptLocalHeapIsAnInputError) {
  // libhdf5 1.10.8 reads through a null pointer under H5Lexists on this file:
  // the probe process dies (SIGSEGV, or exit 1 with a sanitizer's report).
  const std::string message = HostileReadMessage("libhdf5_local_heap_segv.h5");
  EXPECT_NE(message.find("HDF5 library crashed"), std::string::npos) << message;
  EXPECT_NE(message.find("corrupt HDF5 file"), std::string::npos) << message;
}

TEST(RslcProductTest, LibHdf5CrashInAMutatedAlosChipIsAnInputError) {
  const std::string message = HostileReadMessage("libhdf5_local_heap_segv_alos.h5");
  EXPECT_NE(message.find("HDF5 library crashed"), std::string::npos) << message;
}

TEST(RslcProductTest, HugeStringCountIsRefusedBeforeAllocating) {
  // A string attribute declaring 4 GiB of strings in a 15 KB file.
  const std::string message = HostileReadMessage("oom_string_4gib.h5");
  EXPECT_NE(message.find("over 64 MiB"), std::string::npos) << message;
}

TEST(RslcProductTest, HugeNumberElementSizeIsRefusedBeforeAllocating) {
  // A numeric dataset whose element size is gigabytes (libhdf5 converts
  // through a buffer of stored values).
  const std::string message = HostileReadMessage("oom_number_size.h5");
  EXPECT_NE(message.find("-byte numbers"), std::string::npos) << message;
}

TEST(RslcProductTest, HugeMetadataCacheEntryIsAnInputError) {
  // libhdf5 asks malloc for 378 GB for a metadata-cache entry: glibc returns
  // NULL and the read fails (a sanitizer's allocator aborts the probe
  // instead): an InputError either way.
  EXPECT_FALSE(HostileReadMessage("libhdf5_huge_metadata_allocation.h5").empty());
}

}  // namespace
}  // namespace gissar::geo
