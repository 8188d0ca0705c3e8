#include "gissar/pipeline/polsar.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::DataPath;
using testing::MakeTempDir;

const char* kAlos = "alos_rio_branco/calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5";

PolsarRequest AlosRequest(const fs::path& dir) {
  PolsarRequest r;
  r.product = DataPath(kAlos).string();
  r.multilook = {5, 5};
  r.out_prefix = (dir / "pol").string();
  return r;
}

// The ALOS-1 quad-pol chip (50 x 100): C3 bands named in storage order,
// H in [0, 1], A in [0, 1], alpha in [0, 90], GCPs on the ellipsoid, the
// multilooked grid in the metadata, the stretch in the sidecar.
TEST(PolsarTest, AlosQuadPolChipWritesNamedBandsAndHAalpha) {
  const fs::path dir = MakeTempDir();
  const PolsarResult result = RunPolsar(AlosRequest(dir), "test");
  EXPECT_EQ(result.width, 10);
  EXPECT_EQ(result.height, 20);
  for (const char* name : {"pol_C3.tif", "pol_HAalpha.tif", "pol_pauli.png", "pol.json"}) {
    EXPECT_TRUE(fs::exists(dir / name)) << name;
  }
  const geo::FloatRaster c3 = geo::ReadFloatRaster(dir / "pol_C3.tif");
  EXPECT_EQ(c3.band_names, (std::vector<std::string>{"C11", "C22", "C33", "C12_real", "C12_imag", "C13_real",
                                                     "C13_imag", "C23_real", "C23_imag"}));
  EXPECT_EQ(c3.width, 10);
  EXPECT_EQ(c3.height, 20);
  EXPECT_TRUE(c3.nodata_nan);
  EXPECT_EQ(c3.metadata.at("GISSAR_MULTILOOK"), "5,5");
  EXPECT_EQ(c3.metadata.at("GISSAR_LOOK_SIDE"), "right");
  EXPECT_NEAR(std::stod(c3.metadata.at("GISSAR_RANGE_SPACING_M")), 5 * 8.9224, 1e-3);
  ASSERT_EQ(c3.band_units.size(), 9u);
  for (float v : c3.bands[0]) EXPECT_GT(v, 0.0f);  // C11 = <|S_HH|^2>
  const geo::FloatRaster hal = geo::ReadFloatRaster(dir / "pol_HAalpha.tif");
  EXPECT_EQ(hal.band_names, (std::vector<std::string>{"entropy", "anisotropy", "alpha_deg"}));
  EXPECT_EQ(hal.band_units, (std::vector<std::string>{"1", "1", "deg"}));
  for (size_t k = 0; k < hal.bands[0].size(); ++k) {
    EXPECT_TRUE(hal.bands[0][k] >= 0.0f && hal.bands[0][k] <= 1.0f) << hal.bands[0][k];
    EXPECT_TRUE(hal.bands[1][k] >= 0.0f && hal.bands[1][k] <= 1.0f) << hal.bands[1][k];
    EXPECT_TRUE(hal.bands[2][k] >= 0.0f && hal.bands[2][k] <= 90.0f) << hal.bands[2][k];
  }
  const geo::Georeference g = geo::ReadGeoreference(dir / "pol_HAalpha.tif");
  ASSERT_EQ(g.gcps.size(), 36u);
  // The chip's corner (row 0, column 0) lies next to the product's
  // geolocationGrid corner at h = 0: -68.1776 E, -9.7158 N.
  EXPECT_NEAR(g.gcps[0].lon_deg, -68.18, 0.02);
  EXPECT_NEAR(g.gcps[0].lat_deg, -9.71, 0.02);
  EXPECT_EQ(g.gcps[0].height_m, 0.0);
  const json& report = result.report;
  EXPECT_EQ(report["command"], "polsar");
  EXPECT_EQ(report["looks"]["range"], 5);
  EXPECT_EQ(report["looks"]["azimuth"], 5);
  EXPECT_LT(report["stretch"]["low_db"].get<double>(), report["stretch"]["high_db"].get<double>());
  EXPECT_EQ(report["inputs"][0]["sha256"].get<std::string>().size(), 64u);
  EXPECT_TRUE(result.mean_entropy > 0.0 && result.mean_entropy < 1.0);
  EXPECT_TRUE(result.mean_alpha_deg > 0.0 && result.mean_alpha_deg < 90.0);
  std::printf("ALOS chip, 5 x 5 looks: mean H %.3f, A %.3f, alpha %.2f deg; Pauli stretch %.1f .. %.1f dB\n",
              result.mean_entropy, result.mean_anisotropy, result.mean_alpha_deg,
              report["stretch"]["low_db"].get<double>(), report["stretch"]["high_db"].get<double>());
  // The coherency gives the same H/A/alpha (T3 = U C3 U^T).
  PolsarRequest t3 = AlosRequest(dir);
  t3.matrix = image::PolarimetricMatrix::kCoherency;
  t3.out_prefix = (dir / "t3").string();
  const PolsarResult coherency = RunPolsar(t3, "test");
  EXPECT_EQ(geo::ReadFloatRaster(dir / "t3_T3.tif").band_names[0], "T11");
  EXPECT_NEAR(coherency.mean_entropy, result.mean_entropy, 1e-4);
  EXPECT_NEAR(coherency.mean_alpha_deg, result.mean_alpha_deg, 1e-2);
}

// The same channels in a complex GeoTIFF with bands named HH, HV, VH, VV
// (any order) give the same matrices.
TEST(PolsarTest, ImageWithFourNamedBandsMatchesTheProduct) {
  const fs::path dir = MakeTempDir();
  std::vector<std::vector<float>> re(4), im(4);
  const char* order[4] = {"VV", "HH", "VH", "hv"};
  int width = 0, height = 0;
  for (int c = 0; c < 4; ++c) {
    geo::RslcReadOptions options;
    options.polarization = std::string(order[c]) == "hv" ? "HV" : order[c];
    options.read_amplitude = false;
    options.read_complex = true;
    const geo::RslcProduct p = geo::ReadRslcProduct(DataPath(kAlos), options);
    width = p.cols();
    height = p.rows();
    for (const auto& s : p.slc) {
      re[c].push_back(s.real());
      im[c].push_back(s.imag());
    }
  }
  std::vector<geo::ComplexBand> bands;
  for (int c = 0; c < 4; ++c) bands.push_back({&re[c], &im[c], order[c]});
  geo::WriteComplexGeoTiff(dir / "quad.tif", bands, width, height, {}, "DN");
  PolsarRequest r;
  r.image = (dir / "quad.tif").string();
  r.multilook = {5, 5};
  r.out_prefix = (dir / "image").string();
  const PolsarResult from_image = RunPolsar(r, "test");
  const PolsarResult from_product = RunPolsar(AlosRequest(dir), "test");
  const geo::FloatRaster a = geo::ReadFloatRaster(dir / "image_C3.tif");
  const geo::FloatRaster b = geo::ReadFloatRaster(dir / "pol_C3.tif");
  ASSERT_EQ(a.bands.size(), b.bands.size());
  for (size_t band = 0; band < a.bands.size(); ++band) EXPECT_EQ(a.bands[band], b.bands[band]) << band;
  EXPECT_EQ(a.band_units[0], "(DN)^2");
  EXPECT_DOUBLE_EQ(from_image.mean_entropy, from_product.mean_entropy);
}

// SanAnd_129.h5 lists HH, HV, VH, VV but the cropped file stores only HH;
// an image without the four named bands; bad options: errors naming the
// input and the missing channel, nothing written.
TEST(PolsarTest, MissingChannelsAndBadOptionsNameTheInput) {
  const fs::path dir = MakeTempDir();
  const fs::path out = dir / "out";
  fs::create_directories(out);
  auto expect_error = [&](const PolsarRequest& r, const std::string& what, const std::string& where, bool config) {
    try {
      RunPolsar(r, "test");
      ADD_FAILURE() << "no error for " << what;
    } catch (const Error& e) {
      EXPECT_EQ(dynamic_cast<const ConfigError*>(&e) != nullptr, config) << e.what();
      EXPECT_NE(e.message().find(what), std::string::npos) << e.what();
      EXPECT_NE(e.where().find(where), std::string::npos) << e.what();
    }
    EXPECT_TRUE(fs::is_empty(out)) << what;
  };
  PolsarRequest sanand;
  sanand.product = DataPath("uavsar/SanAnd_129.h5").string();
  sanand.multilook = {5, 5};
  sanand.out_prefix = (out / "sanand").string();
  expect_error(sanand, "quad needs four channels: frequency A has no HV, VH, VV layer (stored: HH", "SanAnd_129.h5",
               false);
  // The complex image of `gissar simulate --coherent`: bands total, single, ...
  std::vector<float> plane(64, 1.0f);
  geo::WriteComplexGeoTiff(dir / "sim_slc.tif", {{&plane, &plane, "total"}, {&plane, &plane, "single"}}, 8, 8, {});
  PolsarRequest single = sanand;
  single.product.clear();
  single.image = (dir / "sim_slc.tif").string();
  expect_error(single, "quad needs four channels: no band named HH, HV, VH, VV (bands: total, single)",
               "sim_slc.tif", false);
  PolsarRequest looks = AlosRequest(out);
  looks.multilook = {0, 5};
  expect_error(looks, "looks must be integers in [1, 1024]", "--multilook", true);
  PolsarRequest big = AlosRequest(out);
  big.multilook = {51, 5};
  expect_error(big, "exceed the 50 x 100 image", "RIO_BRANCO_CR.h5", false);
  // An unknown matrix is refused where the name is read (options file,
  // Python keyword; the CLI parses --matrix with the same table).
  PolsarRequest matrix = AlosRequest(out);
  try {
    matrix.ApplyJson({{"matrix", "mueller"}}, "opts.json");
    ADD_FAILURE() << "no error for matrix mueller";
  } catch (const ConfigError& e) {
    EXPECT_NE(e.message().find("must be covariance or coherency"), std::string::npos) << e.what();
    EXPECT_NE(e.where().find("--matrix"), std::string::npos) << e.what();
  }
  PolsarRequest both = AlosRequest(out);
  both.image = single.image;
  expect_error(both, "give one of --image or --product", "--image/--product", true);
}

}  // namespace
}  // namespace gissar::pipeline
