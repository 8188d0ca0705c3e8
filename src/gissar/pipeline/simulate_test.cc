#include "gissar/pipeline/image_probe_testing.h"
#include "gissar/pipeline/simulate_door.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/render/image_agreement.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iomanip>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/material/material.h"
#include "gissar/scene/scene_config.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

SimulateRequest AndorraOptions(const fs::path& out_dir, double heading) {
  SimulateRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_raw.tif").string();
  o.fill_nodata = true;
  o.geometry.heading_deg = heading;
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = 150.0;
  o.geometry.azimuth_spacing_m = 150.0;
  o.out_prefix = (out_dir / ("andorra_" + std::to_string(int(heading)))).string();
  return o;
}

TEST(SimulateTest, AndorraProducesEveryOutputWithProvenance) {
  const fs::path dir = testing::MakeTempDir();
  const SimulateRequest options = AndorraOptions(dir, 30.0);
  const SimulateResult result = RunSimulate(options, "gissar simulate (test)");
  ASSERT_EQ(result.outputs.size(), 6u);
  for (const auto& p : result.outputs) EXPECT_TRUE(fs::exists(p)) << p;
  // The annotated quicklook: the image plus axes (70 + 50 px), title (44 px)
  // and the dB colour bar (110 px).
  int qw = 0, qh = 0;
  geo::ReadByteRaster(options.out_prefix + "_quicklook.png", &qw, &qh);
  EXPECT_EQ(qw, result.width + 180);
  EXPECT_EQ(qh, result.height + 94);

  const geo::FloatRaster image = geo::ReadFloatRaster(options.out_prefix + ".tif");
  EXPECT_EQ(image.width, result.width);
  EXPECT_EQ(image.metadata.at("GISSAR_HEADING_DEG"), "30");
  EXPECT_EQ(image.metadata.at("GISSAR_PROJECTION_MODE"), "affine");
  // Three bounces traced (the default): the total, then single, double and
  // triple; no band for four or more (no path returns after four bounces).
  ASSERT_EQ(image.band_names, (std::vector<std::string>{"total", "single", "double", "triple"}));
  EXPECT_EQ(image.metadata.at("GISSAR_BANDS"), "1 total, 2 single, 3 double, 4 triple bounces");
  // Bare DEM (no mirror material): everything is single bounce.
  EXPECT_EQ(std::memcmp(image.bands[0].data(), image.bands[1].data(), image.bands[0].size() * sizeof(float)), 0);
  EXPECT_TRUE(image.nodata_nan);
  int w = 0, h = 0;
  const auto mask = geo::ReadByteRaster(options.out_prefix + "_mask.tif", &w, &h);
  EXPECT_EQ(w, image.width);
  // NaN exactly outside the imaged footprint (mask 255): the rotated DEM
  // leaves the image's corners without terrain; shadow inside it stays a
  // number (no return), told apart from no-data.
  int positive = 0, outside = 0, shadow = 0, layover = 0;
  for (size_t i = 0; i < mask.size(); ++i) {
    const float v = image.bands[0][i];
    if (mask[i] == render::kMaskOutside) {
      ASSERT_TRUE(std::isnan(v)) << i;
      ASSERT_TRUE(std::isnan(image.bands[3][i])) << i;
      ++outside;
      continue;
    }
    ASSERT_LE(mask[i], 3);
    ASSERT_TRUE(std::isfinite(v)) << i;
    ASSERT_GE(v, 0.0f);
    // Bare DEM: no double or triple bounce (zeros inside the footprint).
    ASSERT_EQ(image.bands[2][i], 0.0f) << i;
    ASSERT_EQ(image.bands[3][i], 0.0f) << i;
    positive += v > 0;
    shadow += (mask[i] & 2) != 0;
    layover += (mask[i] & 1) != 0;
  }
  EXPECT_GT(positive, image.width * image.height / 3);
  EXPECT_GT(outside, 0);
  EXPECT_TRUE(std::isnan(image.bands[0][0]));  // heading 30: the first corner sees no terrain
  // Pyrenean relief at 40 deg depression: slopes turned away steeper than
  // 40 deg cast shadows; slopes facing the radar fold over.
  EXPECT_GT(shadow, 0);
  EXPECT_GT(layover, 0);

  nlohmann::json provenance;
  std::ifstream(options.out_prefix + ".json") >> provenance;
  EXPECT_EQ(provenance["options"]["heading_deg"], 30.0);
  // 403 voids: 391 inside (filled), 12 on the border (left out of the scene).
  EXPECT_EQ(provenance["terrain"]["filled_nodata_cells"], 391);
  EXPECT_EQ(provenance["terrain"]["outside_posts"], 12);
  EXPECT_EQ(provenance["inputs"][0]["sha256"].get<std::string>().size(), 64u);
  EXPECT_EQ(provenance["stats"]["mask_pixels"]["shadow"].get<int>() +
                provenance["stats"]["mask_pixels"]["layover_and_shadow"].get<int>(),
            shadow);
  EXPECT_EQ(provenance["stats"]["mask_pixels"]["outside"].get<int>(), outside);
  EXPECT_TRUE(provenance["timings_s"].contains("trace"));
  EXPECT_NE(provenance["version"].get<std::string>().find("gissar"), std::string::npos);
}

// An image wider than kQuicklookMaxSidePx: PREFIX.png keeps every pixel, the
// annotated quicklook shows it multilooked by the smallest integer factor
// that fits; the sidecar says where the write phase's time went.
TEST(SimulateTest, LargeImagesGetAMultilookedAnnotatedQuicklook) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest options = AndorraOptions(dir, 0.0);
  options.engine = SimulateEngine::kRaster;
  options.geometry.range_spacing_m = 12.0;
  options.geometry.azimuth_spacing_m = 12.0;
  const SimulateResult result = RunSimulate(options, "gissar simulate (test)");
  const int side = std::max(result.width, result.height);
  ASSERT_GT(side, kQuicklookMaxSidePx);
  const int looks = (side + kQuicklookMaxSidePx - 1) / kQuicklookMaxSidePx;
  EXPECT_LE(std::max(result.width, result.height) / looks, kQuicklookMaxSidePx);
  int qw = 0, qh = 0, pw = 0, ph = 0;
  geo::ReadByteRaster(options.out_prefix + "_quicklook.png", &qw, &qh);
  EXPECT_EQ(qw, result.width / looks + 180);
  EXPECT_EQ(qh, result.height / looks + 94);
  geo::ReadByteRaster(options.out_prefix + ".png", &pw, &ph);
  EXPECT_EQ(pw, result.width);
  EXPECT_EQ(ph, result.height);
  nlohmann::json provenance;
  std::ifstream(options.out_prefix + ".json") >> provenance;
  const nlohmann::json& detail = provenance["timings_s"]["write_detail"];
  for (const char* part : {"georeference", "image", "quicklooks", "mask", "sidecars"}) {
    ASSERT_TRUE(detail.contains(part)) << part;
    EXPECT_GE(detail[part].get<double>(), 0.0);
  }
}

TEST(SimulateTest, SameInputsGiveIdenticalImages) {
  const fs::path a = testing::MakeTempDir(), b = testing::MakeTempDir();
  RunSimulate(AndorraOptions(a, 0.0), "");
  RunSimulate(AndorraOptions(b, 0.0), "");
  const auto ia = geo::ReadFloatRaster(a / "andorra_0.tif");
  const auto ib = geo::ReadFloatRaster(b / "andorra_0.tif");
  // Bit for bit, no-data (NaN) included.
  ASSERT_EQ(ia.bands[0].size(), ib.bands[0].size());
  EXPECT_EQ(std::memcmp(ia.bands[0].data(), ib.bands[0].data(), ia.bands[0].size() * sizeof(float)), 0);
}

TEST(SimulateTest, FailureLeavesNoOutput) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest options = AndorraOptions(dir, 0.0);
  options.fill_nodata = false;  // the raw DEM has voids
  EXPECT_THROW(RunSimulate(options, ""), InputError);
  EXPECT_TRUE(fs::is_empty(dir));
}

// Bitwise equality of two float planes (NaN equal to NaN).
int DifferingPixels(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return -1;
  int differing = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i])))) ++differing;
  }
  return differing;
}

// PREFIX.tif holds the total, then the bounce counts up to the highest that
// can return in the run: the raster engine (single bounce) writes total and
// single; one bounce traced with a trihedral (three) writes up to triple,
// the double band between them zero inside the footprint.
TEST(SimulateTest, BandsStopAtTheHighestBounceCountThatCanReturn) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest raster = AndorraOptions(dir, 30.0);
  raster.engine = SimulateEngine::kRaster;
  raster.out_prefix = (dir / "raster").string();
  RunSimulate(raster, "test");
  const geo::FloatRaster single = geo::ReadFloatRaster(raster.out_prefix + ".tif");
  EXPECT_EQ(single.band_names, (std::vector<std::string>{"total", "single"}));
  EXPECT_EQ(single.metadata.at("GISSAR_BANDS"), "1 total, 2 single bounces");
  EXPECT_EQ(DifferingPixels(single.bands[0], single.bands[1]), 0);

  nlohmann::json provenance;
  std::ifstream(raster.out_prefix + ".json") >> provenance;
  const double lon = provenance["scene_centre"]["lon_deg"], lat = provenance["scene_centre"]["lat_deg"];
  const fs::path csv = dir / "reflectors.csv";
  std::ofstream(csv) << "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                     << "trihedral," << std::setprecision(12) << lon << "," << lat << ",0.5,3,300,40\n";
  SimulateRequest traced = AndorraOptions(dir, 30.0);
  traced.bounces = 1;
  traced.reflectors = csv.string();
  traced.out_prefix = (dir / "traced").string();
  RunSimulate(traced, "test");
  const geo::FloatRaster image = geo::ReadFloatRaster(traced.out_prefix + ".tif");
  ASSERT_EQ(image.band_names, (std::vector<std::string>{"total", "single", "double", "triple"}));
  EXPECT_EQ(image.metadata.at("GISSAR_BANDS"), "1 total, 2 single, 3 double, 4 triple bounces");
  float triple_peak = 0.0f;
  for (size_t i = 0; i < image.bands[0].size(); ++i) {
    if (std::isnan(image.bands[0][i])) {
      ASSERT_TRUE(std::isnan(image.bands[2][i])) << i;
      continue;
    }
    ASSERT_EQ(image.bands[2][i], 0.0f) << i;  // no double bounce: one bounce traced, no dihedral
    triple_peak = std::max(triple_peak, image.bands[3][i]);
  }
  EXPECT_GT(triple_peak, 1.0f);  // the 3 m trihedral: sigma0 about 12 in its pixel (test below)
}

TEST(SimulateTest, OutputMayNotOverwriteTheDem) {
  const fs::path dir = testing::MakeTempDir();
  fs::copy_file(testing::DataPath("andorra/andorra_srtm3_dem_filled.tif"), dir / "dem.tif");
  SimulateRequest options = AndorraOptions(dir, 0.0);
  options.dem = (dir / "dem.tif").string();
  options.out_prefix = (dir / "dem").string();
  EXPECT_THROW(options.Check(), ConfigError);
}

// Radiometry options: sidecar and band metadata carry the quantity and unit;
// a coherent run with a reflector writes the SLC, and the reflector is the
// brightest return; bad combinations and rows are errors naming the input.
TEST(SimulateTest, RadiometryReflectorsAndCoherentOutputs) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest base = AndorraOptions(dir, 30.0);
  base.radiometry = "gamma0";
  RunSimulate(base, "");
  nlohmann::json provenance;
  std::ifstream(base.out_prefix + ".json") >> provenance;
  EXPECT_EQ(provenance["radiometry"]["quantity"], "gamma0");
  EXPECT_EQ(provenance["radiometry"]["unit"], "m2/m2");
  EXPECT_EQ(provenance["radiometry"]["range_spacing_m"], 150.0);
  EXPECT_TRUE(provenance["sampling"].contains("empty_footprint_fraction"));
  EXPECT_LT(provenance["sampling"]["empty_footprint_fraction"].get<double>(), 0.01);
  const double lon = provenance["scene_centre"]["lon_deg"], lat = provenance["scene_centre"]["lat_deg"];

  // A 3 m trihedral at the centre, facing the sensor (heading 30, looking
  // right: the sensor lies towards bearing 300 deg, 40 deg up).
  const fs::path csv = dir / "reflectors.csv";
  std::ofstream(csv) << "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                     << "trihedral," << std::setprecision(12) << lon << "," << lat << ",0.5,3,300,40\n";
  SimulateRequest coherent = AndorraOptions(dir, 30.0);
  coherent.out_prefix = (dir / "coherent").string();
  coherent.coherent = true;
  coherent.reflectors = csv.string();
  coherent.db = true;
  const SimulateResult result = RunSimulate(coherent, "");
  EXPECT_EQ(result.outputs.size(), 7u);
  EXPECT_TRUE(fs::exists(dir / "coherent_slc.tif"));
  const geo::FloatRaster image = geo::ReadFloatRaster(coherent.out_prefix + ".tif");
  EXPECT_EQ(image.metadata.at("GISSAR_RADIOMETRY"), "sigma0");
  float peak = -1e9f;
  for (float v : image.bands[3]) peak = std::max(peak, std::isnan(v) ? -1e9f : v);  // triple bounce band, dB
  // sigma = 4 pi 3^4 / (3 lambda^2) = 3.531e5 m2 at X band (0.031 m) over
  // 150 m x 150 m pixels: beta0 15.69 in one pixel (no impulse response),
  // sigma0 = beta0 sin(50 deg) = 12.02: 10.80 dB.
  EXPECT_NEAR(peak, 10.80, 0.05);

  // The SLC: the complex total and one complex band per bounce count, named
  // as the detected image's bands, adding up to the total (no noise here).
  {
    const geo::ComplexRaster slc = geo::ReadComplexRaster(dir / "coherent_slc.tif");
    // Three bounces traced and a trihedral (three): no four-or-more band.
    ASSERT_EQ(slc.bands.size(), 4u);
    EXPECT_EQ(slc.band_names, (std::vector<std::string>{"total", "single", "double", "triple"}));
    EXPECT_EQ(slc.band_units[0], "sqrt(m2/m2)");
    EXPECT_TRUE(slc.nodata_nan);
    double worst = 0.0, triple_power = 0.0, single_power = 0.0;
    int64_t finite = 0;
    for (size_t k = 0; k < slc.bands[0].size(); k += 2) {
      const float re = slc.bands[0][k], im = slc.bands[0][k + 1];
      if (std::isnan(re)) {
        for (int b = 1; b < 4; ++b) EXPECT_TRUE(std::isnan(slc.bands[b][k]));
        continue;
      }
      ++finite;
      double sr = 0.0, si = 0.0;
      for (int b = 1; b < 4; ++b) {
        sr += slc.bands[b][k];
        si += slc.bands[b][k + 1];
      }
      worst = std::max(worst, std::hypot(sr - re, si - im) / (1.0 + std::hypot(re, im)));
      single_power += double(slc.bands[1][k]) * slc.bands[1][k] + double(slc.bands[1][k + 1]) * slc.bands[1][k + 1];
      triple_power += double(slc.bands[3][k]) * slc.bands[3][k] + double(slc.bands[3][k + 1]) * slc.bands[3][k + 1];
    }
    std::printf("SLC: %lld pixels, worst |sum of bounce bands - total| / (1 + |total|) = %.2e\n",
                static_cast<long long>(finite), worst);
    EXPECT_GT(finite, 0);
    EXPECT_LT(worst, 1e-5);
    EXPECT_GT(single_power, 0.0);
    EXPECT_GT(triple_power, 0.0);  // the trihedral
  }

  SimulateRequest bad = coherent;
  bad.speckle_looks = 4.0;
  EXPECT_THROW(bad.Check(), ConfigError);
  std::ofstream(csv) << "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
                     << "trihedral," << lon << "," << lat << ",0,1,300,40\n"
                     << "trihedral,0.0,0.0,0,1,300,40\n";
  try {
    RunSimulate(coherent, "");
    FAIL() << "a reflector off the DEM";
  } catch (const InputError& e) {
    EXPECT_NE(e.where().find("row 2"), std::string::npos) << e.what();
  }
  const fs::path materials = dir / "materials.json";
  std::ofstream(materials) << R"({"water": {"wind_speed_m_s": 5}})";
  SimulateRequest dem_materials = AndorraOptions(dir, 30.0);
  dem_materials.out_prefix = (dir / "m").string();
  dem_materials.materials = materials.string();
  EXPECT_THROW(RunSimulate(dem_materials, ""), ConfigError);
}

// `simulate --dem` with --sea auto (the default), both engines: a DEM whose
// west half is at 0 m (connected to the border: sea) and east half at 1 m
// (land). Flat ground in a sigma0 image reads its class's law at the
// incidence 50 deg (depression 40): the sea's law (material `sea`) west,
// the bare terrain's (`default`) east. With --sea off both halves read
// `default`.
TEST(SimulateTest, DemSeaFallbackInBothEngines) {
  const fs::path dir = testing::MakeTempDir();
  const char* tm = "+proj=tmerc +lat_0=43.7 +lon_0=7.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  std::vector<float> heights(101 * 101);
  for (int r = 0; r < 101; ++r)
    for (int c = 0; c < 101; ++c) heights[size_t(r) * 101 + c] = c < 50 ? 0.0f : 1.0f;
  const fs::path dem = dir / "coast.tif";
  geo::WriteDemGeoTiff(dem, heights, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, tm);
  const double cos_inc = std::cos(50 * M_PI / 180);
  const double sea = material::DefaultMaterial(scene::kClassSea).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  const double land =
      material::DefaultMaterial(scene::kClassDefault).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  ASSERT_LT(sea, 0.5 * land);  // the two are told apart
  for (const std::string engine : {"trace", "raster"}) {
    for (const std::string mode : {"auto", "off"}) {
      SimulateRequest o;
      o.dem = dem.string();
      o.engine = kSimulateEngines.Parse(engine, "engine");
      o.sea = mode;
      o.bounces = 1;
      o.geometry.heading_deg = 0.0;
      o.geometry.depression_deg = 40.0;
      o.geometry.range_spacing_m = o.geometry.azimuth_spacing_m = 5.0;
      o.out_prefix = (dir / (engine + mode)).string();
      RunSimulate(o, "test");
      const geo::FloatRaster image = geo::ReadFloatRaster(dir / (engine + mode + ".tif"));
      auto mean = [&](double x_m, double y_m) { return MeanAroundGroundPoint(image, x_m, y_m, 40.0, 5.0); };
      SCOPED_TRACE(engine + " --sea " + mode);
      const double west = mode == "auto" ? sea : land;
      EXPECT_NEAR(mean(-250, 0), west, 0.03 * west);
      EXPECT_NEAR(mean(-250, 200), west, 0.03 * west);
      EXPECT_NEAR(mean(250, 0), land, 0.03 * land);
    }
  }
}

// Issue 17: reflectors in the raster engine. A flat DEM (50 m, 10 m posts,
// -80 dB ground) with a 100 m high ridge along x = -200 m: a trihedral
// (a = 1 m, C band) at (60, 40) m sees the sensor (west, 40 deg up), one at
// (-150, -80) m is hidden by the ridge (its line of sight is 92 m high at
// x = -200). Both engines keep one return; the visible one integrates to the
// same RCS within 0.5 dB and to 4 pi a^4 / (3 lambda^2) within 1.5 dB, at the
// same pixel.
TEST(SimulateTest, RasterEngineRendersReflectorsLikeTheTracer) {
  const fs::path dir = testing::MakeTempDir();
  const char* tm = "+proj=tmerc +lat_0=43.7 +lon_0=7.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  std::vector<float> heights(101 * 101, 50.0f);
  for (int r = 0; r < 101; ++r) heights[size_t(r) * 101 + 30] = 150.0f;  // x = -505 + 10 * 30 + 5 = -200
  const fs::path dem = dir / "ridge.tif";
  geo::WriteDemGeoTiff(dem, heights, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, tm);
  const fs::path materials = dir / "dark.json";
  std::ofstream(materials) << R"({"default": {"sigma0_db": [[0, -80], [90, -80]]}})";
  const fs::path csv = dir / "reflectors.csv";
  {
    const geo::CrsTransform local(tm);
    std::vector<double> x{60.0, -150.0}, y{40.0, -80.0};
    local.ToLonLat(x, y);
    std::ofstream out(csv);
    out << std::setprecision(12) << "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n"
        << "trihedral," << x[0] << "," << y[0] << ",0.4,1,270,40\n"
        << "trihedral," << x[1] << "," << y[1] << ",0.4,1,270,40\n";
  }
  constexpr double kC = 0.0555;
  const double closed_form_db = 10.0 * std::log10(4.0 * M_PI / (3.0 * kC * kC));
  double db[2] = {0, 0};
  size_t peak[2] = {0, 0};
  int k = 0;
  for (const std::string engine : {"trace", "raster"}) {
    SCOPED_TRACE(engine);
    SimulateRequest o;
    o.dem = dem.string();
    o.vertical_datum = "ellipsoid";
    o.engine = kSimulateEngines.Parse(engine, "engine");
    o.materials = materials.string();
    o.reflectors = csv.string();
    o.bounces = 1;
    o.wavelength_m = kC;
    o.radiometry = "beta0";
    o.geometry.heading_deg = 0.0;
    o.geometry.depression_deg = 40.0;
    o.geometry.range_spacing_m = o.geometry.azimuth_spacing_m = 2.0;
    o.range_resolution_m = o.azimuth_resolution_m = 5.0;
    o.out_prefix = (dir / engine).string();
    RunSimulate(o, "test");
    const geo::FloatRaster image = geo::ReadFloatRaster(o.out_prefix + ".tif");
    nlohmann::json sidecar;
    std::ifstream(o.out_prefix + ".json") >> sidecar;
    EXPECT_EQ(sidecar["radiometry"]["reflector_returns"], 1);  // the hidden one returns nothing
    const std::vector<float>& triple = image.bands[3];
    for (size_t i = 0; i < triple.size(); ++i) {
      if (!std::isnan(triple[i]) && !(triple[i] <= triple[peak[k]])) peak[k] = i;
    }
    const int pc = int(peak[k] % image.width), pr = int(peak[k] / image.width);
    double sum = 0.0;
    for (int r = std::max(0, pr - 40); r <= std::min(image.height - 1, pr + 40); ++r) {
      for (int c = std::max(0, pc - 40); c <= std::min(image.width - 1, pc + 40); ++c) {
        const float v = image.bands[0][size_t(r) * image.width + c];
        if (!std::isnan(v)) sum += v;
      }
    }
    db[k] = 10.0 * std::log10(sum * 4.0);
    std::printf("%s engine: trihedral a = 1 m, C band: %.3f dB m2 (closed form %.3f)\n", engine.c_str(), db[k],
                closed_form_db);
    EXPECT_NEAR(db[k], closed_form_db, 1.5);
    ++k;
  }
  EXPECT_NEAR(db[1], db[0], 0.5);
  EXPECT_EQ(peak[1], peak[0]);
}

// A flat 1 km square seen at heading 45 deg: its image is a rhombus of
// area 1000^2 cos(40 deg) / (5 x 5) = 30,642 pixels (flat ground: slant
// range = ground range x cos(depression)); measured 31,530 (tracer) and
// 31,503 (raster) with the edge pixels a splat reaches; every pixel outside is NaN,
// declared no-data, with mask 255 (kMaskOutside), in both engines.
// Issue 16, no bright column at the scene edge: a tilted plane
// (z = 100 + 0.2 x) inside a square rotated by 30 degrees, no-data outside
// (the collar of a reprojected DEM). The collar is outside the scene, so the
// first and last 5 % of the scene's range bins (the columns from the first
// to the last holding terrain) hold the plane as everywhere else:
// every pixel there whose 7 x 7 neighbourhood is inside the footprint is
// within 0.5 dB of the plane's level (the median of the image); the
// footprint's own boundary pixels (the valid area's edge follows the 10 m
// DEM cells) are partly covered and darker, never brighter.
TEST(SimulateTest, ReprojectionCollarLeavesNoBrightColumnAtTheEdges) {
  const fs::path dir = testing::MakeTempDir();
  const char* tm = "+proj=tmerc +lat_0=43.7 +lon_0=7.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  const double kNodata = -9999.0, angle = 30.0 * M_PI / 180.0;
  std::vector<float> heights(101 * 101);
  for (int r = 0; r < 101; ++r)
    for (int c = 0; c < 101; ++c) {
      const double x = -500.0 + 10 * c, y = 500.0 - 10 * r;
      const double u = std::cos(angle) * x + std::sin(angle) * y, v = -std::sin(angle) * x + std::cos(angle) * y;
      heights[size_t(r) * 101 + c] = std::abs(u) <= 350.0 && std::abs(v) <= 350.0 ? static_cast<float>(100.0 + 0.2 * x)
                                                                                   : static_cast<float>(kNodata);
    }
  const fs::path dem = dir / "collar.tif";
  geo::WriteDemGeoTiff(dem, heights, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, tm, kNodata);
  SceneBuildRequest build;
  build.dem = dem.string();
  build.out_prefix = (dir / "collar_scene").string();
  RunSceneBuild(build, "test");
  for (const std::string engine : {"scene", "trace", "raster"}) {
    // Looks along the square's sides (bearings 60 and 240 deg): the first and
    // last range bins run along a whole side; the plane faces the radar,
    // then turns away.
    for (const double heading : {330.0, 150.0}) {
      SCOPED_TRACE(engine + " heading " + std::to_string(heading));
      SimulateRequest o;
      if (engine == "scene") {
        o.scene = build.out_prefix + ".gscene";
      } else {
        o.dem = dem.string();
        o.engine = kSimulateEngines.Parse(engine, "engine");
      }
      o.bounces = 1;
      o.layers = true;
      o.geometry.heading_deg = heading;
      o.geometry.depression_deg = 40.0;
      o.geometry.range_spacing_m = o.geometry.azimuth_spacing_m = 5.0;
      o.out_prefix = (dir / (engine + std::to_string(int(heading)))).string();
      RunSimulate(o, "test");
      const geo::FloatRaster image = geo::ReadFloatRaster(o.out_prefix + ".tif");
      const int w = image.width, h = image.height;
      const std::vector<float>& v = image.bands[0];
      std::vector<float> finite;
      for (float x : v)
        if (std::isfinite(x) && x > 0) finite.push_back(x);
      ASSERT_GT(finite.size(), 1000u);
      std::nth_element(finite.begin(), finite.begin() + finite.size() / 2, finite.end());
      const double plane_db = 10.0 * std::log10(finite[finite.size() / 2]);
      // Terrain pixels: finite and non-zero (the collar returns nothing).
      auto terrain = [&](int x, int y) {
        const float p = v[size_t(y) * w + x];
        return std::isfinite(p) && p > 0.0f;
      };
      // The scene's range bins: the columns from the first to the last that
      // hold terrain; its edges are their first and last 5 %.
      int first = w, last = -1;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          if (terrain(x, y)) { first = std::min(first, x); last = std::max(last, x); }
      ASSERT_GT(last - first, 80);
      const int edge = static_cast<int>(std::lround(0.05 * (last - first + 1)));
      int interior_pixels = 0, off = 0, brighter = 0;
      double worst = 0.0, brightest = -1e9;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          if ((x >= first + edge && x <= last - edge) || !terrain(x, y)) continue;
          const double d = 10.0 * std::log10(v[size_t(y) * w + x]) - plane_db;
          brightest = std::max(brightest, d);
          if (d > 0.5) ++brighter;  // any pixel, the footprint's boundary included
          bool interior = x > 2 && y > 2 && x + 3 < w && y + 3 < h;
          for (int dy = -3; dy <= 3 && interior; ++dy)
            for (int dx = -3; dx <= 3; ++dx)
              if (!terrain(x + dx, y + dy)) interior = false;
          if (!interior) continue;
          ++interior_pixels;
          worst = std::max(worst, std::abs(d));
          if (std::abs(d) > 0.5) ++off;
        }
      // The terrain layers (the raster engine triangulates its posts, the
      // collar's non-finite): the plane's local incidence at the footprint's
      // middle, to first order 50 deg minus its 11.31 deg slope times the
      // cosine between the look bearing and the uphill bearing (90 deg):
      // 40.2 deg at heading 330, 59.8 deg at heading 150.
      const geo::FloatRaster layers = geo::ReadFloatRaster(o.out_prefix + "_layers.tif");
      const size_t middle = size_t(h / 2) * w + (first + last) / 2;
      const double slope_deg = std::atan(0.2) * 180.0 / M_PI;
      const double look_from_uphill = (heading + 90.0 - 90.0) * M_PI / 180.0;
      EXPECT_NEAR(layers.bands[0][middle], 50.0 - slope_deg * std::cos(look_from_uphill), 1.0);
      std::printf("%s heading %.0f: plane %.2f dB; edge bins: %d interior pixels, %d beyond 0.5 dB (worst %.2f dB), "
                  "%d brighter by 0.5 dB (brightest %+.2f dB)\n",
                  engine.c_str(), heading, plane_db, interior_pixels, off, worst, brighter, brightest);
      EXPECT_GT(interior_pixels, 30);
      EXPECT_EQ(off, 0) << "worst " << worst << " dB";
      EXPECT_EQ(brighter, 0) << "brightest " << brightest << " dB";
    }
  }
}

TEST(SimulateTest, FlatSquareIsNoDataOutsideItsFootprint) {
  const fs::path dir = testing::MakeTempDir();
  const char* tm = "+proj=tmerc +lat_0=43.7 +lon_0=7.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  const std::vector<float> heights(101 * 101, 0.0f);
  const fs::path dem = dir / "flat.tif";
  geo::WriteDemGeoTiff(dem, heights, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, tm);
  const double expected = 1000.0 * 1000.0 * std::cos(40.0 * M_PI / 180.0) / 25.0;
  for (const std::string engine : {"trace", "raster"}) {
    SCOPED_TRACE(engine);
    SimulateRequest o;
    o.dem = dem.string();
    o.engine = kSimulateEngines.Parse(engine, "engine");
    o.bounces = 1;
    o.geometry.heading_deg = 45.0;
    o.geometry.depression_deg = 40.0;
    o.geometry.range_spacing_m = o.geometry.azimuth_spacing_m = 5.0;
    o.out_prefix = (dir / engine).string();
    o.layers = true;
    RunSimulate(o, "test");
    const geo::FloatRaster image = geo::ReadFloatRaster(o.out_prefix + ".tif");
    EXPECT_TRUE(image.nodata_nan);
    // --layers: flat ground, local incidence 50 deg and 5 x 5 / sin 50 =
    // 32.64 m2 of terrain in every interior pixel; NaN where the image is.
    const geo::FloatRaster layers = geo::ReadFloatRaster(o.out_prefix + "_layers.tif");
    ASSERT_EQ(layers.bands.size(), 2u);
    EXPECT_EQ(layers.band_names[1], "projected_area");
    const size_t middle = size_t(image.height / 2) * image.width + image.width / 2;
    EXPECT_NEAR(layers.bands[0][middle], 50.0, 1e-3);
    EXPECT_NEAR(layers.bands[1][middle], 25.0 / std::sin(50.0 * M_PI / 180.0), 1e-3);
    EXPECT_TRUE(std::isnan(layers.bands[1][0]));
    EXPECT_FALSE(geo::ReadGeoreference(o.out_prefix + "_layers.tif").gcps.empty());
    int w = 0, h = 0;
    const auto mask = geo::ReadByteRaster(o.out_prefix + "_mask.tif", &w, &h);
    ASSERT_EQ(mask.size(), image.bands[0].size());
    int finite = 0;
    for (size_t i = 0; i < mask.size(); ++i) {
      const bool nan = std::isnan(image.bands[0][i]);
      ASSERT_EQ(nan, mask[i] == render::kMaskOutside) << i;
      for (size_t b = 1; b < image.bands.size(); ++b) ASSERT_EQ(std::isnan(image.bands[b][i]), nan) << b;
      if (!nan) {
        ++finite;
        EXPECT_GT(image.bands[0][i], 0.0f) << i;  // flat lit ground: a return in every footprint pixel
      }
    }
    // Pixel centres on the rhombus (diagonals 1414 m / 5 m = 282.8 px in
    // azimuth, 1414 cos 40 / 5 = 216.7 px in range; perimeter 712.5 px),
    // plus the edge pixels a ray's splat reaches (at most 1.5 px beyond it).
    const double perimeter = 4.0 * std::hypot(282.84 / 2, 216.67 / 2);
    EXPECT_GE(finite, expected - 0.5 * perimeter);
    EXPECT_LE(finite, expected + 1.5 * perimeter);
    // The corners of the image see no terrain; its centre does.
    EXPECT_TRUE(std::isnan(image.bands[0][0]));
    EXPECT_TRUE(std::isnan(image.bands[0][size_t(h) * w - 1]));
    EXPECT_FALSE(std::isnan(image.bands[0][size_t(h / 2) * w + w / 2]));
  }
}

// Exact mode with the sensor 10 km away at 5 deg depression over Andorra:
// it flies at about 0.87 km above the DEM centre (~2 km), below the 3 km
// peaks: refused before rendering, nothing written. A grazing depression
// in affine mode is only a warning.
// --incidence-band (a field of the request's table, nothing else declared
// by hand): PREFIX.tif gains a last band "local_incidence" in degrees; on
// flat ground seen at 35 deg depression it is 90 - 35 = 55 deg in every
// imaged pixel, NaN outside; the other bands are those of a run without it.
TEST(SimulateTest, IncidenceBandIsTheLastBandOfTheImage) {
  const fs::path dir = testing::MakeTempDir();
  const char* tm = "+proj=tmerc +lat_0=43.7 +lon_0=7.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  const std::vector<float> heights(81 * 81, 0.0f);
  const fs::path dem = dir / "flat.tif";
  geo::WriteDemGeoTiff(dem, heights, 81, 81, {-405.0, 10.0, 0.0, 405.0, 0.0, -10.0}, tm);
  SimulateRequest o;
  o.ApplyJson({{"dem", dem.string()}, {"heading_deg", 20.0}, {"depression_deg", 35.0}, {"bounces", 1},
               {"range_spacing_m", 10.0}, {"azimuth_spacing_m", 10.0}, {"out_prefix", (dir / "plain").string()}},
              "test");
  RunSimulate(o, "test");
  o.ApplyJson({{"incidence_band", true}, {"out_prefix", (dir / "with").string()}}, "test");
  EXPECT_EQ(o.ToJson()["incidence_band"], true);
  RunSimulate(o, "test");
  const geo::FloatRaster plain = geo::ReadFloatRaster(dir / "plain.tif");
  const geo::FloatRaster with = geo::ReadFloatRaster(dir / "with.tif");
  ASSERT_EQ(with.bands.size(), plain.bands.size() + 1);
  EXPECT_EQ(with.band_names.back(), "local_incidence");
  ASSERT_EQ(with.band_units.size(), with.bands.size());
  EXPECT_EQ(with.band_units.back(), "deg");
  EXPECT_EQ(with.band_units.front(), plain.band_units.front());
  for (size_t b = 0; b < plain.bands.size(); ++b) {
    ASSERT_EQ(with.bands[b].size(), plain.bands[b].size());
    for (size_t i = 0; i < plain.bands[b].size(); ++i) {
      const float p = plain.bands[b][i], w = with.bands[b][i];
      ASSERT_TRUE(p == w || (std::isnan(p) && std::isnan(w))) << "band " << b << " pixel " << i;
    }
  }
  const std::vector<float>& incidence = with.bands.back();
  int imaged = 0;
  for (size_t i = 0; i < incidence.size(); ++i) {
    if (std::isnan(plain.bands[0][i])) continue;
    ++imaged;
    // The "flat" DEM follows the ellipsoid: d metres from the centre the
    // ground is tilted by d / R (570 m at the corners: 0.005 deg).
    if (!std::isnan(incidence[i])) {
      ASSERT_NEAR(incidence[i], 55.0, 0.006) << i;
    }
  }
  EXPECT_GT(imaged, 1000);
  const size_t middle = size_t(with.height / 2) * with.width + with.width / 2;
  EXPECT_NEAR(incidence[middle], 55.0, 1e-3);
  EXPECT_TRUE(std::isnan(incidence[0]));
}

TEST(SimulateTest, SensorBelowThePeaksIsRefusedAndGrazingWarned) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest o = AndorraOptions(dir, 0.0);
  o.geometry.mode = sensor::ProjectionMode::kExact;
  o.geometry.depression_deg = 5.0;
  o.geometry.slant_range_m = 10000.0;
  try {
    RunSimulate(o, "test");
    ADD_FAILURE() << "accepted a sensor below the terrain";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("not above the terrain"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(o.out_prefix + ".tif"));

  struct Collect : Reporter {
    std::vector<std::string> warnings;
    void Warn(const std::string& line) override { warnings.push_back(line); }
  } collect;
  o = AndorraOptions(dir, 0.0);
  o.geometry.depression_deg = 2.0;
  o.bounces = 1;
  RunSimulate(o, "test", collect);
  int grazing = 0;
  for (const std::string& w : collect.warnings) grazing += w.find("depression 2 deg is grazing") != std::string::npos;
  EXPECT_EQ(grazing, 1);
}

TEST(SimulateTest, ParsesNumberPairs) {
  EXPECT_EQ(ParseNumberPair("1.6,42.5", "--center"), Eigen::Vector2d(1.6, 42.5));
  EXPECT_THROW(ParseNumberPair("1.6", "--center"), ConfigError);
  EXPECT_THROW(ParseNumberPair("1.6,42.5,3", "--center"), ConfigError);
  EXPECT_THROW(ParseNumberPair("a,b", "--center"), ConfigError);
}

// ApplyJson reads every key ToJson writes (the options-file and Python
// names of every field), and the round trip changes nothing.
TEST(SimulateRequestTest, JsonRoundTripCoversEveryField) {
  SimulateRequest changed;
  changed.dem = "a.tif";
  changed.geometry.heading_deg = 12.5;
  changed.geometry.look_side = sensor::LookSide::kLeft;
  changed.center_lonlat = Eigen::Vector2d(1.5, 42.5);
  changed.nesz_db = -20.0;
  changed.seed = 99;
  changed.layers = true;
  SimulateRequest read;
  read.ApplyJson(changed.ToJson(), "test");
  EXPECT_EQ(read.ToJson(), changed.ToJson());
  SimulateRequest defaults;
  defaults.ApplyJson(SimulateRequest().ToJson(), "test");
  EXPECT_EQ(defaults.ToJson(), SimulateRequest().ToJson());
  EXPECT_THROW(defaults.ApplyJson(nlohmann::json{{"heading", 3}}, "test"), ConfigError);
  EXPECT_THROW(defaults.ApplyJson(nlohmann::json{{"heading_deg", "north"}}, "test"), ConfigError);
}


// --- DEM windows (PlanDemWindow): a fixed-size image reads only the DEM it
// needs and equals the image of the whole DEM.

// A 512 x 512 UTM DEM (30 m posts) of smooth hills from 100 to ~1300 m.
fs::path WriteHillsDem(const fs::path& dir) {
  const int n = 512;
  std::vector<float> h(size_t(n) * n);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      h[size_t(r) * n + c] = static_cast<float>(700.0 + 300.0 * std::sin(c * 0.031) * std::cos(r * 0.023) +
                                                250.0 * std::sin((c + 2 * r) * 0.011) + 40.0 * std::cos(c * 0.17 + r * 0.05));
    }
  }
  const fs::path path = dir / "hills.tif";
  geo::WriteDemGeoTiff(path, h, n, n, {400000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0}, "EPSG:32631");
  return path;
}

// The message of the gissar::Error that RunSimulate(o) throws; empty when
// it succeeds.
std::string SimulateError(const SimulateRequest& o) {
  try {
    RunSimulate(o, "test");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

SimulateRequest HillsWindowRequest(const fs::path& dem, const fs::path& out) {
  SimulateRequest o;
  o.dem = dem.string();
  o.sea = "off";
  o.geometry.heading_deg = 20.0;
  o.geometry.depression_deg = 35.0;
  o.geometry.range_spacing_m = 20.0;
  o.geometry.azimuth_spacing_m = 20.0;
  o.geometry.width = 64;
  o.geometry.height = 64;
  // Off the DEM centre (lon, lat of UTM 31N (404000, 4694000)).
  o.center_map = Eigen::Vector2d(404000.0, 4694000.0);
  o.out_prefix = out.string();
  return o;
}

void ExpectSameBands(const SimulatedImage& a, const SimulatedImage& b) {
  ASSERT_EQ(a.image.width, b.image.width);
  ASSERT_EQ(a.image.height, b.image.height);
  const size_t n = a.image.intensity.size();
  ASSERT_EQ(b.image.intensity.size(), n);
  EXPECT_EQ(std::memcmp(a.image.intensity.data(), b.image.intensity.data(), n * sizeof(float)), 0);
  EXPECT_EQ(a.image.mask, b.image.mask);
  EXPECT_EQ(a.image.footprint, b.image.footprint);
  int differing = 0, lit = 0;
  for (size_t i = 0; i < n; ++i) lit += a.image.intensity[i] > 0.0f;
  EXPECT_GT(lit, int(n) / 2);  // terrain fills the image
  for (size_t i = 0; i < n; ++i) {
    const float x = a.image.intensity[i], y = b.image.intensity[i];
    if (!(x == y || (std::isnan(x) && std::isnan(y)))) ++differing;
  }
  EXPECT_EQ(differing, 0);
}

TEST(SimulateTest, DemWindowEqualsTheWholeDem) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path dem = WriteHillsDem(dir);
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    SimulateRequest o = HillsWindowRequest(dem, dir / "w");
    o.geometry.mode = mode;
    o.range_resolution_m = 30.0;  // PSF and speckle too: they act on the image only
    o.azimuth_resolution_m = 30.0;
    o.speckle_looks = 4.0;
    const DemWindowPlan plan = PlanDemWindow(o);
    ASSERT_TRUE(plan.applies);
    ASSERT_TRUE(plan.read_window) << plan.reason;
    // 64 x 64 pixels of 20 m: about 45 x 60 posts on the ground, plus the
    // layover/shadow halo of 1200 m of relief at 35 deg (~1.7 km = 57
    // posts) and margins: far smaller than the 512 x 512 DEM.
    EXPECT_LT(double(plan.window[2]) * plan.window[3], 0.1 * 512 * 512);
    EXPECT_GT(plan.window[2], 45);
    const SimulatedImage windowed = SimulateImage(o);
    EXPECT_EQ(windowed.terrain.dem_window["read"], "window");
    EXPECT_EQ(windowed.terrain.grid_width, plan.window[2]);
    o.dem_window = "off";
    const SimulatedImage whole = SimulateImage(o);
    EXPECT_EQ(whole.terrain.dem_window["read"], "whole");
    EXPECT_EQ(whole.terrain.grid_width, 512);
    EXPECT_EQ(windowed.terrain.centre_enu, whole.terrain.centre_enu);
    EXPECT_EQ(windowed.terrain.post_spacing_m, whole.terrain.post_spacing_m);
    ExpectSameBands(windowed, whole);
  }
}

TEST(SimulateTest, DemWindowFitsAMemoryBudgetTheWholeDemDoesNot) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path dem = WriteHillsDem(dir);
  SimulateRequest o = HillsWindowRequest(dem, dir / "m");
  // 512^2 posts at 128 B each (the height field's estimate) need 32 MiB;
  // the window about a tenth.
  o.max_memory_bytes = int64_t{24} << 20;
  const SimulateResult result = RunSimulate(o, "test");
  EXPECT_EQ(result.width, 64);
  nlohmann::json sidecar;
  std::ifstream(o.out_prefix + ".json") >> sidecar;
  EXPECT_EQ(sidecar["dem_window"]["read"], "window");
  EXPECT_GT(sidecar["dem_window"]["cols"].get<int>(), 0);
  EXPECT_EQ(sidecar["options"]["dem_window"], "auto");
  o.dem_window = "off";
  o.out_prefix = (dir / "m_off").string();
  const std::string error = SimulateError(o);
  EXPECT_NE(error.find("--max-memory"), std::string::npos) << "the whole DEM fits the budget: " << error;
}

// The memory budget's estimate per image pixel is higher in coherent mode
// (the complex planes of the total and of every bounce count: 98 B per
// pixel measured with three bounces, against 26 B incoherent): a budget
// that holds the detected image refuses the coherent one before rendering.
TEST(SimulateTest, CoherentModeNeedsMoreOfTheMemoryBudget) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path dem = WriteHillsDem(dir);
  SimulateRequest o;
  o.dem = dem.string();
  o.sea = "off";
  o.geometry.heading_deg = 20.0;
  o.geometry.depression_deg = 35.0;
  o.geometry.range_spacing_m = 15.0;  // half the post spacing: about 4 pixels per post
  o.geometry.azimuth_spacing_m = 15.0;
  o.rays_per_cell = 1.0;
  o.out_prefix = (dir / "unbounded").string();
  const SimulateResult unbounded = RunSimulate(o, "test");
  const double pixels = double(unbounded.width) * unbounded.height;
  const double posts = 512.0 * 512.0;
  ASSERT_GT(pixels, 3.0 * posts);
  // Between the two estimates (64 and 160 B per pixel, plus 3x the mesh: 12
  // to 32 B per post here), above the DEM's 128 B per post.
  o.max_memory_bytes = static_cast<int64_t>(100.0 * pixels + 96.0 * posts);
  o.out_prefix = (dir / "detected").string();
  const SimulateResult detected = RunSimulate(o, "test");
  EXPECT_EQ(detected.width, unbounded.width);
  o.coherent = true;
  o.out_prefix = (dir / "coherent").string();
  const std::string error = SimulateError(o);
  EXPECT_NE(error.find("--max-memory"), std::string::npos) << "the coherent image fits the budget: " << error;
  EXPECT_NE(error.find("pixels"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir / "coherent.tif"));
}

TEST(SimulateTest, DemWindowFallsBackToTheWholeDemWithAReason) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path dem = WriteHillsDem(dir);
  SimulateRequest o = HillsWindowRequest(dem, dir / "s");
  o.sea = "auto";
  o.sea_level_m = 400.0;  // the hills reach below it: the sea needs the whole border
  DemWindowPlan plan = PlanDemWindow(o);
  EXPECT_TRUE(plan.applies);
  EXPECT_FALSE(plan.read_window);
  EXPECT_NE(plan.reason.find("--sea"), std::string::npos);
  o.sea_level_m = 0.0;  // no post that low: windowed
  EXPECT_TRUE(PlanDemWindow(o).read_window);
  o.geometry.width = 0;  // the image covers the DEM
  plan = PlanDemWindow(o);
  EXPECT_FALSE(plan.applies);
  EXPECT_NE(plan.reason.find("--width"), std::string::npos);
  o.geometry.width = 64;
  o.engine = SimulateEngine::kRaster;
  EXPECT_FALSE(PlanDemWindow(o).applies);
  SimulateRequest bad = o;
  bad.dem_window = "sometimes";
  EXPECT_THROW(bad.Check(), ConfigError);
}

TEST(SimulateTest, DemWindowOfAGeographicDemEqualsTheWholeDem) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  o.geometry.heading_deg = 200.0;
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = 60.0;
  o.geometry.azimuth_spacing_m = 60.0;
  o.geometry.width = 48;
  o.geometry.height = 40;
  o.center_lonlat = Eigen::Vector2d(1.50, 42.52);
  o.out_prefix = (dir / "a").string();
  const DemWindowPlan plan = PlanDemWindow(o);
  ASSERT_TRUE(plan.read_window) << plan.reason;
  EXPECT_LT(plan.window[2], plan.source_width);
  EXPECT_LT(plan.window[3], plan.source_height);
  const SimulatedImage windowed = SimulateImage(o);
  o.dem_window = "off";
  const SimulatedImage whole = SimulateImage(o);
  EXPECT_EQ(windowed.terrain.centre_enu, whole.terrain.centre_enu);
  ExpectSameBands(windowed, whole);
}

}  // namespace
}  // namespace gissar::pipeline

namespace gissar::pipeline {
namespace {

// The height field against Embree's BVH over the same triangles, on the
// geographic Andorra DEM (EPSG:4326 posts: curved rows in ENU) with three
// bounces: the images agree (issue 18: r >= 0.999 of dB, mean difference
// <= 0.05 dB; measured r = 0.9999999, mean difference 1e-5 dB; distances
// differ in their last bits, and a ridge grazed in float by Embree may be
// hit or passed in double by the height field).
TEST(SimulateTest, HeightfieldAndBvhImagesAgreeOnAGeographicDem) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest o = AndorraOptions(dir, 135.0);
  o.bounces = 3;
  o.rays_per_cell = 4;
  const SimulatedImage heightfield = SimulateImage(o);
  o.heightfield = false;
  const SimulatedImage bvh = SimulateImage(o);
  ASSERT_EQ(heightfield.image.width, bvh.image.width);
  ASSERT_EQ(heightfield.image.intensity.size(), bvh.image.intensity.size());
  const render::IntensityAgreement agreement =
      render::CompareIntensities(bvh.image.intensity, heightfield.image.intensity);
  EXPECT_EQ(agreement.one_sided_zero, 0);
  ASSERT_GT(agreement.compared_pixels, 10000);
  EXPECT_GE(agreement.db_pearson, 0.999);
  EXPECT_LE(std::abs(agreement.mean_db_difference), 0.05);
  // The same triangles: distances differ in their last bits, pixels by far
  // less than 0.1 dB almost everywhere.
  std::vector<double> diff;
  for (size_t k = 0; k < bvh.image.intensity.size(); ++k) {
    const double a = heightfield.image.intensity[k], b = bvh.image.intensity[k];
    if (a > 0.0 && b > 0.0) diff.push_back(std::abs(10.0 * std::log10(a / b)));
  }
  std::sort(diff.begin(), diff.end());
  // Measured: 99 % of the pixels within 0.0002 dB, 99.9 % within 0.003 dB.
  EXPECT_LE(diff[diff.size() * 99 / 100], 0.01);
}

// --- Polarimetric channels (--polarization HH,VV | quad).


TEST(SimulateTest, SeveralChannelsGiveNamedBandsEqualToSingleChannelRuns) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path dem = WriteHillsDem(dir);
  // Detected: HH and VV, each channel's total first, then the bounce bands.
  SimulateRequest o = HillsWindowRequest(dem, dir / "dual");
  o.polarization = "hh,VV";
  RunSimulate(o, "test");
  const geo::FloatRaster dual = geo::ReadFloatRaster(dir / "dual.tif");
  // Three bounces traced: each channel's single, double and triple bands.
  ASSERT_EQ(dual.bands.size(), 8u);
  EXPECT_EQ(dual.band_names, (std::vector<std::string>{"HH", "VV", "HH_single", "HH_double", "HH_triple", "VV_single",
                                                        "VV_double", "VV_triple"}));
  EXPECT_EQ(dual.metadata.at("GISSAR_POLARIZATIONS"), "HH,VV");
  // Bare terrain has no mirror paths: each polarimetric pass's detected image
  // is the single-channel run of its channel, bit for bit.
  for (const std::string channel : {"HH", "VV"}) {
    SimulateRequest single = HillsWindowRequest(dem, dir / channel);
    single.polarization = channel;
    RunSimulate(single, "test");
    const geo::FloatRaster one = geo::ReadFloatRaster(dir / (channel + ".tif"));
    const int band = channel == "HH" ? 0 : 1;
    EXPECT_EQ(DifferingPixels(dual.bands[band], one.bands[0]), 0) << channel;
    EXPECT_EQ(DifferingPixels(dual.bands[2 + 3 * band], one.bands[1]), 0) << channel << " single bounce";
  }
  nlohmann::json provenance;
  std::ifstream(dir / "dual.json") >> provenance;
  EXPECT_EQ(provenance["radiometry"]["channels"], nlohmann::json({"HH", "VV"}));
  EXPECT_DOUBLE_EQ(provenance["polarimetry"]["bounce_shares"]["HH"]["single"].get<double>(), 1.0);
  nlohmann::json stac;
  std::ifstream(dir / "dual_stac.json") >> stac;
  EXPECT_EQ(stac["properties"]["sar:polarizations"], nlohmann::json({"HH", "VV"}));
}

TEST(SimulateTest, CoherentQuadWritesFourComplexChannelsAndAPauliQuicklook) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path dem = WriteHillsDem(dir);
  SimulateRequest o = HillsWindowRequest(dem, dir / "quad");
  o.coherent = true;
  o.polarization = "quad";
  const SimulateResult result = RunSimulate(o, "test");
  EXPECT_TRUE(fs::exists(dir / "quad_pauli.png"));
  EXPECT_NE(std::find(result.outputs.begin(), result.outputs.end(), dir / "quad_pauli.png"), result.outputs.end());
  const geo::ComplexRaster slc = geo::ReadComplexRaster(dir / "quad_slc.tif");
  ASSERT_EQ(slc.bands.size(), 4u + 4u * 3u);  // four totals, then three bounce bands per channel
  EXPECT_EQ(slc.band_names[0], "HH");
  EXPECT_EQ(slc.band_names[1], "HV");
  EXPECT_EQ(slc.band_names[2], "VH");
  EXPECT_EQ(slc.band_names[3], "VV");
  EXPECT_EQ(slc.band_names[4], "HH_single");
  // Reciprocity: VH is the HV pass (no thermal noise here).
  EXPECT_EQ(DifferingPixels(slc.bands[1], slc.bands[2]), 0);
  // The HH pass of a polarimetric run keeps the single-channel micro-phases:
  // its complex total equals a coherent HH run's.
  SimulateRequest hh = HillsWindowRequest(dem, dir / "hh");
  hh.coherent = true;
  hh.polarization = "HH";
  RunSimulate(hh, "test");
  const geo::ComplexRaster single = geo::ReadComplexRaster(dir / "hh_slc.tif");
  EXPECT_EQ(DifferingPixels(slc.bands[0], single.bands[0]), 0);
  // HH and VV of a rough surface are partly correlated (rho < 1), not equal.
  EXPECT_GT(DifferingPixels(slc.bands[0], slc.bands[3]), 0);
  nlohmann::json provenance;
  std::ifstream(dir / "quad.json") >> provenance;
  EXPECT_EQ(provenance["polarimetry"]["channels"], nlohmann::json({"HH", "HV", "VH", "VV"}));
  EXPECT_TRUE(provenance["polarimetry"].contains("pauli_quicklook"));
  EXPECT_EQ(provenance["polarimetry"]["bounce_shares"].size(), 4u);
}

TEST(SimulateTest, UnknownOrRepeatedChannelsAreRefused) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest o = AndorraOptions(dir, 0.0);
  o.polarization = "HH,XX";
  try {
    o.Check();
    ADD_FAILURE() << "an unknown channel was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown channel 'XX'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--polarization"), std::string::npos) << e.what();
  }
  o.polarization = "VV,vv";
  EXPECT_THROW(o.Check(), ConfigError);
  o.polarization = "Quad";
  EXPECT_NO_THROW(o.Check());
}

}  // namespace
}  // namespace gissar::pipeline
