// `gissar simulate --product S1.SAFE` on the bundled Sentinel-1 annotations
// (data/sentinel1/, no image data): a trihedral placed at a point of the
// product's geolocation grid, on a flat DEM at that point's height, must
// peak on the grid point's pixel (converted into the simulated grid's own
// numbering) within 0.5 px, in an IW SLC burst and in the GRD. Each run
// renders a window of the product grid around the point (--product-window):
// a whole burst is ~1500 x 21600 pixels, a GRD 16700 x 25800.
#include "gissar/pipeline/sentinel1_simulate.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/orbit_file.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/sentinel1_testing.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/simulate_door.h"
#include "gissar/pipeline/pta.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/sensor/range_doppler.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

using geo::testing_s1::kIwGrd;
using geo::testing_s1::kIwSlc;
using geo::testing_s1::kSm;
using geo::testing_s1::Annotation;

const geo::Sentinel1GridPoint& GridPoint(const geo::Sentinel1Annotation& a, int line, int pixel) {
  for (const geo::Sentinel1GridPoint& g : a.geolocation_grid) {
    if (g.line == line && g.pixel == pixel) return g;
  }
  throw std::runtime_error("no grid point at line " + std::to_string(line) + ", pixel " + std::to_string(pixel));
}

// A flat DEM of ~10 m posts (EPSG:4326, heights used as ellipsoidal) at
// `height_m`, 2 half_m + 10 m wide, whose centre post is (lon, lat).
fs::path FlatDem(const fs::path& dir, double lon, double lat, double height_m, double half_m) {
  const double dlat = 10.0 / 111320.0, dlon = 10.0 / (111320.0 * std::cos(lat * M_PI / 180.0));
  const int half = static_cast<int>(std::ceil(half_m / 10.0)), n = 2 * half + 1;
  const fs::path path = dir / "flat.tif";
  geo::WriteDemGeoTiff(path, std::vector<float>(size_t(n) * n, static_cast<float>(height_m)), n, n,
                       {lon - (half + 0.5) * dlon, dlon, 0.0, lat + (half + 0.5) * dlat, 0.0, -dlat}, "EPSG:4326");
  return path;
}

// One 2 m trihedral whose apex (its phase centre) is on the ground at the
// grid point, boresight towards the sensor at the point's zero-Doppler time.
fs::path TrihedralAt(const fs::path& dir, const geo::Sentinel1Annotation& a, const geo::Sentinel1GridPoint& g) {
  const sensor::Orbit orbit(a.orbit.time_s, a.orbit.position_m, a.orbit.velocity_mps);
  const Eigen::Vector3d target = geo::LocalFrame::EcefFromGeodetic(g.longitude_deg, g.latitude_deg, g.height_m);
  const auto rc = sensor::Geo2Rdr(orbit, target, g.azimuth_time_s);
  if (!rc) throw std::runtime_error("geo2rdr failed");
  const Eigen::Vector3d sensor_llh = geo::LocalFrame::GeodeticFromEcef(orbit.Interpolate(rc->time_s).position_m);
  const geo::LocalFrame local(g.longitude_deg, g.latitude_deg, g.height_m);
  const Eigen::Vector3d to_sensor = local.EnuFromGeodetic(sensor_llh.x(), sensor_llh.y(), sensor_llh.z());
  const double azimuth = std::atan2(to_sensor.x(), to_sensor.y()) * 180.0 / M_PI;
  const double elevation = std::atan2(to_sensor.z(), std::hypot(to_sensor.x(), to_sensor.y())) * 180.0 / M_PI;
  const fs::path path = dir / "reflectors.csv";
  std::ofstream out(path);
  char row[256];
  std::snprintf(row, sizeof row, "trihedral,%.9f,%.9f,0,2,%.4f,%.4f\n", g.longitude_deg, g.latitude_deg, azimuth,
                elevation);
  out << "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n" << row;
  return path;
}

// The brightest pixel of band 1, refined to sub-pixel by a parabola through
// the dB values of it and its two neighbours along each axis.
struct Peak {
  double line = 0, pixel = 0, value = 0;
};
Peak FindPeak(const geo::FloatRaster& r) {
  const std::vector<float>& v = r.bands[0];
  size_t best = 0;
  for (size_t k = 0; k < v.size(); ++k) {
    if (std::isfinite(v[k]) && (!std::isfinite(v[best]) || v[k] > v[best])) best = k;
  }
  const int row = int(best / r.width), col = int(best % r.width);
  auto at = [&](int i, int j) { return 10.0 * std::log10(double(v[size_t(i) * r.width + j])); };
  auto vertex = [](double a, double b, double c) { return 0.5 * (a - c) / (a - 2.0 * b + c); };
  Peak p;
  p.value = v[best];
  EXPECT_TRUE(row > 0 && row + 1 < r.height && col > 0 && col + 1 < r.width) << row << " " << col;
  if (!(row > 0 && row + 1 < r.height && col > 0 && col + 1 < r.width)) return p;
  p.line = row + vertex(at(row - 1, col), at(row, col), at(row + 1, col));
  p.pixel = col + vertex(at(row, col - 1), at(row, col), at(row, col + 1));
  return p;
}

nlohmann::json Sidecar(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Issue 48: a reflector at a geolocation grid point of IW1 lands on the grid
// point's pixel in burst 2's own grid. Grid line 3002 is burst 3's first line
// (the grid's lines run across the concatenated bursts); bursts overlap in
// time, so the same point lies in burst 2 at line (burst 3's azimuthTime -
// burst 2's) / azimuthTimeInterval = ~1341, inside its valid lines.
TEST(Sentinel1SimulateTest, IwSlcBurstReflectorLandsOnTheGridPoint) {
  const fs::path dir = testing::MakeTempDir();
  const geo::Sentinel1Annotation a = Annotation(kIwSlc, "IW1", "VV");
  const geo::Sentinel1GridPoint& g = GridPoint(a, 3002, 10820);
  const int burst = 2;
  const geo::Sentinel1Burst& holder = a.bursts[size_t(g.line / a.lines_per_burst)];
  const double line_in_burst =
      (holder.azimuth_time_s + (g.line - holder.first_line) * a.azimuth_time_interval_s -
       a.Burst(burst).azimuth_time_s) / a.azimuth_time_interval_s;
  ASSERT_GT(line_in_burst, a.Burst(burst).first_valid_line);
  ASSERT_LT(line_in_burst, a.Burst(burst).last_valid_line);
  const std::array<int, 4> window{static_cast<int>(std::lround(line_in_burst)) - 24, g.pixel - 96, 48, 192};

  SimulateRequest o;
  o.product = testing::DataPath(kIwSlc).string();
  o.swath = "iw1";  // case does not matter
  o.burst = burst;
  o.polarization = "VV";
  o.dem = FlatDem(dir, g.longitude_deg, g.latitude_deg, g.height_m, 800.0).string();
  o.vertical_datum = "ellipsoid";
  o.reflectors = TrihedralAt(dir, a, g).string();
  o.product_window_px = window;
  o.bounces = 1;
  o.out_prefix = (dir / "burst").string();
  const SimulateResult result = RunSimulate(o, "test");
  EXPECT_EQ(result.width, 192);
  EXPECT_EQ(result.height, 48);

  const geo::FloatRaster r = geo::ReadFloatRaster(dir / "burst.tif");
  const Peak peak = FindPeak(r);
  const double d_line = peak.line - (line_in_burst - window[0]), d_pixel = peak.pixel - (g.pixel - window[1]);
  // The grid point's own azimuth time sits a little before its line number.
  const double line_of_time = (g.azimuth_time_s - a.Burst(burst).azimuth_time_s) / a.azimuth_time_interval_s;
  std::printf("[ measured ] IW1 burst 2, grid point line %d pixel %d (burst line %.3f): peak - grid = %+.3f lines, "
              "%+.3f pixels (peak - the point's azimuthTime: %+.3f lines)\n",
              g.line, g.pixel, line_in_burst, d_line, d_pixel, peak.line + window[0] - line_of_time);
  EXPECT_LE(std::abs(d_line), 0.5);
  EXPECT_LE(std::abs(d_pixel), 0.5);

  // The grid and the selection in the metadata and the sidecar.
  EXPECT_EQ(r.metadata.at("GISSAR_SENTINEL1_BURST"), "2");
  EXPECT_EQ(r.metadata.at("GISSAR_SENTINEL1_SWATH"), "IW1");
  const double first_range = std::stod(r.metadata.at("GISSAR_FIRST_RANGE_M"));
  EXPECT_NEAR(first_range, a.SlantRangeOfTime(a.slant_range_time_s) + window[1] * a.slant_range_spacing_m(), 1e-5);
  const nlohmann::json side = Sidecar(dir / "burst.json");
  const nlohmann::json& s1 = side["product"]["sentinel1"];
  EXPECT_EQ(s1["product"], fs::path(kIwSlc).filename().string());
  EXPECT_EQ(s1["swath"], "IW1");
  EXPECT_EQ(s1["burst"], 2);
  EXPECT_EQ(s1["polarization"], "VV");
  EXPECT_EQ(s1["grid"]["window"]["first_line"], window[0]);
  EXPECT_EQ(s1["orbit"]["source"], "annotation");
  EXPECT_NE(s1["real_image"].get<std::string>().find("none"), std::string::npos);
  EXPECT_EQ(side["impulse_response"]["range_resolution_source"], "processedRangeBandwidth");
  EXPECT_EQ(side["inputs"][0]["kind"], "Sentinel-1 SAFE");
  EXPECT_EQ(side["inputs"][1]["path"], fs::absolute(o.dem).lexically_normal().string());

  // Coherent: `gissar pta` measures the complex burst on its own grid (the
  // sidecar names the SAFE, swath, burst and window it re-reads).
  o.coherent = true;
  o.out_prefix = (dir / "coherent").string();
  RunSimulate(o, "test");
  PtaRequest pta;
  pta.image = (dir / "coherent_slc.tif").string();
  pta.reflectors = o.reflectors;
  pta.out_prefix = (dir / "pta").string();
  const PtaResult measured = RunPta(pta, "test");
  ASSERT_EQ(measured.measured, 1) << measured.report.dump(2);
  const nlohmann::json& error = measured.report["reflectors"][0]["location_error_px"];
  std::printf("[ measured ] pta on the coherent burst: location error %+.3f range, %+.3f azimuth px\n",
              error["range"].get<double>(), error["azimuth"].get<double>());
  EXPECT_LE(std::abs(error["range"].get<double>()), 0.1);
  EXPECT_LE(std::abs(error["azimuth"].get<double>()), 0.1);
}

// The GRD: rendered in slant range and resampled to its 10 m ground-range
// pixels with its own grsr polynomials; the reflector at grid point (line
// 8012, pixel 12900) peaks on that pixel of the GRD's own numbering.
TEST(Sentinel1SimulateTest, GrdReflectorLandsOnTheGridPoint) {
  const fs::path dir = testing::MakeTempDir();
  const geo::Sentinel1Annotation a = Annotation(kIwGrd, "IW", "VV");
  const geo::Sentinel1GridPoint& g = GridPoint(a, 8012, 12900);
  const std::array<int, 4> window{g.line - 20, g.pixel - 40, 40, 80};

  SimulateRequest o;
  o.product = testing::DataPath(kIwGrd).string();
  o.dem = FlatDem(dir, g.longitude_deg, g.latitude_deg, g.height_m, 1000.0).string();
  o.vertical_datum = "ellipsoid";
  o.reflectors = TrihedralAt(dir, a, g).string();
  o.product_window_px = window;
  o.bounces = 1;
  o.db = true;
  o.out_prefix = (dir / "grd").string();
  const SimulateResult result = RunSimulate(o, "test");
  EXPECT_EQ(result.width, 80);
  EXPECT_EQ(result.height, 40);

  geo::FloatRaster r = geo::ReadFloatRaster(dir / "grd.tif");
  for (float& v : r.bands[0]) v = std::pow(10.0f, v / 10.0f);  // dB -> linear for FindPeak
  const Peak peak = FindPeak(r);
  const double d_line = peak.line - (g.line - window[0]), d_pixel = peak.pixel - (g.pixel - window[1]);
  std::printf("[ measured ] IW GRD, grid point line %d pixel %d: peak - grid = %+.3f lines, %+.3f pixels\n", g.line,
              g.pixel, d_line, d_pixel);
  EXPECT_LE(std::abs(d_line), 0.5);
  EXPECT_LE(std::abs(d_pixel), 0.5);

  EXPECT_EQ(r.metadata.at("GISSAR_GROUND_RANGE_SPACING_M"), "10");
  EXPECT_EQ(r.metadata.count("GISSAR_FIRST_RANGE_M"), 0u);
  EXPECT_EQ(r.metadata.count("GISSAR_SENTINEL1_BURST"), 0u);
  // The ground points of the GRD pixels: the grid point's pixel is the
  // point itself (flat ground at its height), within a ground pixel.
  const size_t k = size_t(g.line - window[0]) * r.width + (g.pixel - window[1]);
  const geo::LocalFrame local(g.longitude_deg, g.latitude_deg, g.height_m);
  const Eigen::Vector3d d = local.EnuFromGeodetic(r.bands[5][k], r.bands[6][k], r.bands[7][k]);
  EXPECT_LT(std::hypot(d.x(), d.y()), 10.0);
  const nlohmann::json side = Sidecar(dir / "grd.json");
  const nlohmann::json& s1 = side["product"]["sentinel1"];
  EXPECT_EQ(s1["product_type"], "GRD");
  EXPECT_TRUE(s1["burst"].is_null());
  EXPECT_EQ(s1["grid"]["ground_range_spacing_m"], 10.0);
  EXPECT_GT(s1["ground_range"]["rendered_slant_grid"]["samples"].get<int>(), 80);
  EXPECT_NE(s1["impulse_response_bandwidths"].get<std::string>().find("lookBandwidth of IW2"), std::string::npos);
}

SimulateRequest Selection(const char* safe) {
  SimulateRequest o;
  o.product = testing::DataPath(safe).string();
  o.dem = "unused.tif";
  o.out_prefix = "/nonexistent/out";
  return o;
}

// The grids without rendering: a burst's times and ranges, a stripmap
// swath, the slant samples covering a GRD window, and --orbit replacing the
// annotation's vectors (same grid, the file named as the source).
TEST(Sentinel1SimulateTest, GridsOfABurstAStripmapSwathAndAGrdWindow) {
  const geo::Sentinel1Annotation a = Annotation(kIwSlc, "IW1", "VV");
  SimulateRequest o = Selection(kIwSlc);
  o.swath = "IW1";
  o.burst = 3;
  const Sentinel1Source burst = ReadSentinel1Source(o);
  EXPECT_EQ(burst.burst, 3);
  EXPECT_EQ(burst.grid.rows(), a.lines_per_burst);
  EXPECT_EQ(burst.grid.cols(), a.samples_per_burst);
  EXPECT_DOUBLE_EQ(burst.grid.zero_doppler_time_s.front(), a.bursts[2].azimuth_time_s);
  EXPECT_NEAR(burst.grid.azimuth_spacing_s(), a.azimuth_time_interval_s, 1e-12);
  EXPECT_NEAR(burst.grid.range_spacing_m(), a.slant_range_spacing_m(), 1e-9);
  EXPECT_FALSE(burst.grid.look_left);
  EXPECT_NEAR(burst.grid.wavelength_m, a.wavelength_m, 1e-12);
  EXPECT_GT(burst.grid.processed_range_bandwidth_hz, 5e7);

  SimulateRequest sm = Selection(kSm);
  sm.polarization = "VH";
  const Sentinel1Source swath = ReadSentinel1Source(sm);
  EXPECT_EQ(swath.burst, 0);
  EXPECT_EQ(swath.grid.rows(), swath.annotation.number_of_lines);
  EXPECT_EQ(swath.grid.cols(), swath.annotation.number_of_samples);

  SimulateRequest grd = Selection(kIwGrd);
  grd.product_window_px = std::array<int, 4>{100, 2000, 50, 300};
  const Sentinel1Source ground = ReadSentinel1Source(grd);
  EXPECT_TRUE(ground.ground_range);
  EXPECT_EQ(ground.grid.rows(), 50);
  for (int i : {0, 49}) {
    const double t = ground.grid.zero_doppler_time_s[size_t(i)];
    EXPECT_LT(ground.grid.slant_range_m.front(), ground.annotation.SlantRangeOfGroundRange(2000 * 10.0, t));
    EXPECT_GT(ground.grid.slant_range_m.back(), ground.annotation.SlantRangeOfGroundRange(2299 * 10.0, t));
  }

  // --orbit: the annotation's own vectors as a CSV file give the same grid.
  const fs::path dir = testing::MakeTempDir();
  geo::StateVectors vectors;
  vectors.format = "csv";
  for (size_t k = 0; k < a.orbit.time_s.size(); ++k) {
    vectors.utc_s.push_back(burst.product.epoch_unix_s + a.orbit.time_s[k]);
    vectors.position_m.push_back(a.orbit.position_m[k]);
    vectors.velocity_mps.push_back(a.orbit.velocity_mps[k]);
  }
  geo::WriteStateVectorsCsv(dir / "orbit.csv", vectors);
  o.orbit = (dir / "orbit.csv").string();
  const Sentinel1Source replaced = ReadSentinel1Source(o);
  EXPECT_EQ(replaced.orbit_source, o.orbit);
  EXPECT_EQ(replaced.grid.orbit.type, "csv");
  EXPECT_EQ(replaced.grid.zero_doppler_time_s, burst.grid.zero_doppler_time_s);
  // (only the vectors within 60 s of the product's lines are kept)
  EXPECT_LE(replaced.grid.orbit.time_s.size(), burst.grid.orbit.time_s.size());
  const sensor::Orbit from_file(replaced.grid.orbit.time_s, replaced.grid.orbit.position_m,
                                replaced.grid.orbit.velocity_mps);
  const sensor::Orbit from_annotation(burst.grid.orbit.time_s, burst.grid.orbit.position_m,
                                      burst.grid.orbit.velocity_mps);
  const double mid = burst.grid.zero_doppler_time_s[size_t(burst.grid.rows() / 2)];
  EXPECT_LT((from_file.Interpolate(mid).position_m - from_annotation.Interpolate(mid).position_m).norm(), 1e-3);
  EXPECT_NO_THROW(o.Check());
}

// --product-window cuts a NISAR product's grid too (and its amplitude).
TEST(Sentinel1SimulateTest, ProductWindowCutsANisarGrid) {
  SimulateRequest o;
  o.product = testing::DataPath("uavsar/winnipeg.h5").string();
  const geo::RslcProduct whole = ReadProductGeometry(o, true);
  o.product_window_px = std::array<int, 4>{10, 20, 30, 40};
  const geo::RslcProduct part = ReadProductGeometry(o, true);
  ASSERT_EQ(part.rows(), 30);
  ASSERT_EQ(part.cols(), 40);
  EXPECT_EQ(part.zero_doppler_time_s.front(), whole.zero_doppler_time_s[10]);
  EXPECT_EQ(part.slant_range_m.front(), whole.slant_range_m[20]);
  EXPECT_EQ(part.amplitude[size_t(29) * 40 + 39], whole.amplitude[size_t(39) * whole.cols() + 59]);
  o.product_window_px = std::array<int, 4>{0, whole.cols() - 1, 2, 2};
  EXPECT_THROW(ReadProductGeometry(o, false), ConfigError);
}

// Bad selections: each a clear error naming the flag (the bad-input
// catalogue runs the same through the binary, simulate_s1_*.case).
TEST(Sentinel1SimulateTest, BadSelectionsNameTheirFlag) {
  auto message_of = [](const SimulateRequest& o) {
    try {
      ReadSentinel1Source(o);
    } catch (const Error& e) {
      return e.message() + " (" + e.where() + ")";
    }
    return std::string("no error");
  };
  SimulateRequest o = Selection(kIwSlc);
  o.swath = "IW1";
  EXPECT_NE(message_of(o).find("one burst at a time: give --burst N (IW1 has bursts 1-9)"), std::string::npos)
      << message_of(o);
  o.burst = 12;
  EXPECT_NE(message_of(o).find("burst 12 does not exist; swath IW1 has bursts 1-9"), std::string::npos);
  o.burst = 1;
  o.swath = "IW4";
  EXPECT_NE(message_of(o).find("swath IW4 does not exist"), std::string::npos);
  o.swath = "";
  EXPECT_NE(message_of(o).find("has swaths IW1, IW2, IW3: give one with --swath"), std::string::npos)
      << message_of(o);
  o.swath = "IW1";
  o.product_window_px = std::array<int, 4>{1500, 0, 10, 10};
  EXPECT_NE(message_of(o).find("outside burst 1 of IW1 (1501 lines x 21632 pixels"), std::string::npos)
      << message_of(o);

  SimulateRequest grd = Selection(kIwGrd);
  grd.burst = 1;
  EXPECT_NE(message_of(grd).find("a GRD product has no bursts (--burst"), std::string::npos) << message_of(grd);
  grd.burst = 0;
  grd.coherent = true;
  EXPECT_THROW(ReadSentinel1Source(grd), ConfigError);

  // A SAFE's own rules, checked where it is opened, before any of its files
  // is read (generic Check() does not tell products apart).
  SimulateRequest f = Selection(kIwSlc);
  f.frequency = "A";
  EXPECT_NO_THROW(f.Check());
  EXPECT_EQ(message_of(f), "a Sentinel-1 product has no frequency band (A/B are NISAR's): choose with --swath and "
                           "--polarization (--frequency)");
  f.frequency = "";
  f.radar_grid = "grid.json";
  EXPECT_EQ(message_of(f), "a Sentinel-1 product fixes the radar grid (--product/--radar-grid)");
  SimulateRequest plain;
  plain.dem = "dem.tif";
  plain.out_prefix = "/nonexistent/out";
  plain.swath = "IW1";
  EXPECT_THROW(plain.Check(), ConfigError);
  EXPECT_THROW(ParseProductWindow("1,2,3"), ConfigError);
  EXPECT_THROW(ParseProductWindow("1,2,1,5"), ConfigError);
  EXPECT_EQ(ParseProductWindow("10,20,30,40"), (std::array<int, 4>{10, 20, 30, 40}));
}

// The selection fields are request fields like any other (options files,
// Python keywords, sidecars): ToJson / ApplyJson round trip.
TEST(Sentinel1SimulateTest, SelectionFieldsRoundTripThroughJson) {
  SimulateRequest o = Selection(kIwSlc);
  o.swath = "IW2";
  o.burst = 4;
  o.product_window_px = std::array<int, 4>{1, 2, 30, 40};
  SimulateRequest read;
  read.ApplyJson(o.ToJson(), "test");
  EXPECT_EQ(read.ToJson(), o.ToJson());
  EXPECT_EQ(o.ToJson()["product_window_px"], nlohmann::json({1, 2, 30, 40}));
  EXPECT_THROW(read.ApplyJson(nlohmann::json{{"product_window_px", {1, 2, 3}}}, "test"), ConfigError);
  read.ApplyJson(nlohmann::json{{"product_window_px", nullptr}}, "test");
  EXPECT_FALSE(read.product_window_px.has_value());
}

}  // namespace
}  // namespace gissar::pipeline
