// Small, fast end-to-end evaluation of `gissar locate` (issue 7): 5 Monte-
// Carlo trials on the bundled Andorra SRTM DEM (bare terrain, 30 m cells,
// 128 x 128 images; ~1 s per fix),
// and the real Sentinel-1 warp recovery.
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_door.h"
#include "gissar/pipeline/simulate_door.h"
#include "gissar/pipeline/locate_fields.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "gissar/pipeline/simulate.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {

TEST(Evaluate, SmallMonteCarloOnAndorraDem) {
  const auto dir = gissar::testing::MakeTempDir();
  EvaluateRequest o;
  o.dem = gissar::testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  o.trials = 5;
  o.seed = 3;
  o.spacing_m = 30.0;
  o.size_px = 128;
  o.compare_matchers = false;
  o.out_prefix = (dir / "eval").string();
  const nlohmann::json s = RunEvaluate(o, "test");
  // Measured (seed 3, 2026-11-27): 5/5 successes, median 0.28 cells (p95
  // 0.71), median heading error 0.049 deg.
  EXPECT_GE(s["success_rate"].get<double>(), 0.8);
  EXPECT_LT(s["position_error_cells"]["median"].get<double>(), 1.2);
  EXPECT_LT(s["heading_error_deg"]["median"].get<double>(), 0.15);
  EXPECT_TRUE(std::filesystem::exists(dir / "eval_trials.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir / "eval_hist.png"));
  // The automatic prior errors (negative defaults) are the ones the trials
  // draw from: +-200 m per horizontal axis, +-50 m vertical, +-3 deg.
  EXPECT_EQ(s["options"]["prior_error_horizontal_m"].get<double>(), 200.0);
  std::ifstream csv(dir / "eval_trials.csv");
  std::string line;
  std::getline(csv, line);
  const std::string column = "prior_position_error_m";
  const size_t at = line.find(column);
  ASSERT_NE(at, std::string::npos);
  const long index = std::count(line.begin(), line.begin() + static_cast<long>(at), ',');
  double largest = 0.0;
  while (std::getline(csv, line)) {
    std::stringstream fields(line);
    std::string field;
    for (long k = 0; k <= index; ++k) std::getline(fields, field, ',');
    largest = std::max(largest, std::stod(field));
  }
  EXPECT_GT(largest, 50.0);
}

// Trial k depends only on (seed, k): subsets of the trials, summarised in
// any order, give the table of all of them (but for the time per fix).
TEST(Evaluate, TrialSubsetsSummariseToTheWholeRun) {
  EvaluateRequest o;
  o.dem = gissar::testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  o.trials = 3;
  o.seed = 5;
  o.spacing_m = 60.0;
  o.size_px = 64;
  o.compare_matchers = false;
  o.prior_error_horizontal_m = 100.0;
  o.prior_error_vertical_m = 20.0;
  o.prior_error_heading_deg = 1.0;
  o.out_prefix = "(test)";
  const std::vector<nlohmann::json> all = EvaluateTrials(o);
  ASSERT_EQ(all.size(), 3u);
  EvaluateRequest last = o;
  last.trial_first = 2;
  last.trial_count = 1;
  EvaluateRequest first = o;
  first.trial_count = 2;
  std::vector<nlohmann::json> parts = EvaluateTrials(last);
  for (const nlohmann::json& r : EvaluateTrials(first)) parts.push_back(r);
  ASSERT_EQ(parts.size(), 3u);
  EXPECT_EQ(parts[0]["trial"], 2);
  for (size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(parts[(k + 1) % 3]["csv_row"].get<std::string>().substr(0, 60), all[k]["csv_row"].get<std::string>().substr(0, 60));
    EXPECT_EQ(parts[(k + 1) % 3]["position_error_m"], all[k]["position_error_m"]);
  }
  nlohmann::json a = SummariseTrials(o, all), b = SummariseTrials(o, parts);
  a.erase("seconds_per_fix");
  b.erase("seconds_per_fix");
  EXPECT_EQ(a, b);
  EXPECT_EQ(a["trials"], 3);
  EXPECT_THROW(SummariseTrials(o, {all[0], all[0]}), ConfigError);
  EvaluateRequest bad = o;
  bad.trial_first = 3;
  EXPECT_THROW(bad.Check(), ConfigError);
  bad.trial_first = 1;
  bad.trial_count = 3;
  EXPECT_THROW(bad.Check(), ConfigError);
  EvaluateRequest round;
  round.ApplyJson(o.ToJson(), "test");
  EXPECT_EQ(round.ToJson(), o.ToJson());
}

// `gissar simulate` an image of the Andorra DEM, then `locate` it from a
// prior 200 m and 2.5 deg off.
TEST(Locate, FixesASimulatedImageFromADriftedPrior) {
  const auto dir = gissar::testing::MakeTempDir();
  SimulateRequest so;
  so.dem = gissar::testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  so.fill_nodata = true;
  // No --center: the ENU frame of a DEM is centred on the DEM centre, as in `locate --dem`.
  so.geometry.heading_deg = 31.0;
  so.geometry.depression_deg = 40.0;
  so.geometry.slant_range_m = 10000.0;
  so.geometry.range_spacing_m = so.geometry.azimuth_spacing_m = 30.0;
  so.geometry.width = so.geometry.height = 128;
  so.bounces = 1;
  so.speckle_looks = 4.0;
  so.out_prefix = (dir / "obs").string();
  RunSimulate(so, "test");
  std::ifstream sidecar(dir / "obs.json");
  const nlohmann::json sim = nlohmann::json::parse(sidecar);
  const auto truth = sim["geometry"]["sensor_enu_m_at_centre"].get<std::vector<double>>();
  const nlohmann::json prior = {{"heading_deg", 33.5},
                                {"slant_range_m", 10000.0},
                                {"sensor_enu_m", {truth[0] - 170.0, truth[1] + 160.0, truth[2] - 40.0}}};
  std::ofstream(dir / "prior.json") << prior.dump();
  LocateRequest lo;
  lo.image = (dir / "obs.tif").string();
  lo.dem = so.dem;
  lo.prior = (dir / "prior.json").string();
  lo.out = (dir / "fix.json").string();
  const nlohmann::json r = RunLocate(lo, "test");
  const auto est = r["pose"]["sensor_enu_m"].get<std::vector<double>>();
  const double err = std::hypot(est[0] - truth[0], est[1] - truth[1], est[2] - truth[2]);
  EXPECT_TRUE(r["converged"].get<bool>());
  EXPECT_LT(err, 30.0);  // one resolution cell; measured 17.2 m (heading error 0.119 deg)
  std::printf("locate: position error %.2f m, heading error %.3f deg\n", err, r["pose"]["heading_deg"].get<double>() - 31.0);
  EXPECT_LT(std::abs(r["pose"]["heading_deg"].get<double>() - 31.0), 0.2);
  EXPECT_GT(r["similarity_ncc"].get<double>(), r["prior_similarity_ncc"].get<double>());

  // A prior at 20 km for an image made at 10 km (the image says so) is
  // refused, naming the key; 10.9 km (9 % off) is accepted as a prior.
  nlohmann::json far = prior;
  far["slant_range_m"] = 20000.0;
  std::ofstream(dir / "far.json") << far.dump();
  lo.prior = (dir / "far.json").string();
  lo.out = (dir / "far_fix.json").string();
  try {
    RunLocate(lo, "test");
    ADD_FAILURE() << "a prior 100 % off the image's slant range was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("10 %"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.where()).find("slant_range_m"), std::string::npos) << e.where();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "far_fix.json"));
}

TEST(MatchPair, RecoversKnownWarpOnSentinel1Dates) {
  const auto dir = gissar::testing::MakeTempDir();
  MatchPairRequest o;
  o.fixed = gissar::testing::DataPath("opera_10SGD/burst292320_IW2_2021-11-19_VV.tif").string();
  o.moving = gissar::testing::DataPath("opera_10SGD/burst292320_IW2_2021-11-25_VV.tif").string();
  o.out = (dir / "pair.json").string();
  const nlohmann::json r = RunMatchPair(o, "test");
  // Measured: ncc 0.052 px, chamfer 0.088 px, features 0.42 px RMS.
  EXPECT_LT(r["matchers"]["ncc"]["warp_rms_error_px"].get<double>(), 0.15);
  EXPECT_LT(r["matchers"]["chamfer"]["warp_rms_error_px"].get<double>(), 0.3);
  // Two years apart: ncc 0.074 px.
  o.moving = gissar::testing::DataPath("opera_10SGD/burst292320_IW2_2023-12-03_VV.tif").string();
  o.out = (dir / "pair2.json").string();
  const nlohmann::json r2 = RunMatchPair(o, "test");
  EXPECT_LT(r2["matchers"]["ncc"]["warp_rms_error_px"].get<double>(), 0.2);
}

TEST(Locate, DatabaseOptionsAreChecked) {
  auto message = [](const auto& request) {
    try {
      request.Check();
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  LocateRequest lo;
  lo.image = "obs.tif";
  lo.dem = "dem.tif";
  lo.prior = "prior.json";
  lo.out = "fix.json";
  lo.database = "db_catalog.json";
  EXPECT_EQ(message(lo), "");
  lo.database_fallback = "guess";
  EXPECT_NE(message(lo).find("--database-fallback"), std::string::npos);
  lo.database_fallback = "render";
  lo.database_heading_tolerance_deg = 0.0;
  EXPECT_NE(message(lo).find("--database-heading-tolerance"), std::string::npos);
  LocateRequest product;
  product.product = "p.h5";
  product.dem = "dem.tif";
  product.out = "fix.json";
  product.database = "db_catalog.json";
  EXPECT_NE(message(product).find("--database"), std::string::npos);
  EvaluateRequest ev;
  ev.dem = "dem.tif";
  ev.out_prefix = "ev";
  ev.database = "db_catalog.json";
  ev.database_fixes = "both";
  EXPECT_NE(message(ev).find("--database-fixes"), std::string::npos);
  // The request fields round-trip (the Python keywords).
  ev.database_fixes = "render";
  EvaluateRequest round;
  round.ApplyJson(ev.ToJson(), "test");
  EXPECT_EQ(round.database, "db_catalog.json");
  EXPECT_EQ(round.database_fixes, "render");
  LocateRequest applied;
  applied.ApplyJson({{"database", "db_catalog.json"}, {"database_fallback", "render"},
                     {"database_heading_tolerance_deg", 5.0}}, "test");
  EXPECT_EQ(applied.database_fallback, "render");
  EXPECT_EQ(applied.database_heading_tolerance_deg, 5.0);
}

// The locate request's table (locate_fields.cc): every field round-trips
// through JSON (the Python keywords), null keeps the default, and the track
// offset takes exactly three numbers, as JSON and as flag text.
TEST(LocateFields, RoundTripNullAndTrackOffset) {
  LocateRequest o;
  o.image = "obs.tif";
  o.prior = "prior.json";
  o.look = "left";
  o.search_px = 40;
  o.prior_offset_track = {-60.0, 30.0, 5.0};
  o.composite_png = "c.png";
  LocateRequest round;
  round.ApplyJson(o.ToJson(), "test");
  EXPECT_EQ(round.ToJson(), o.ToJson());
  EXPECT_EQ(round.prior_offset_track, (std::vector<double>{-60.0, 30.0, 5.0}));
  EXPECT_EQ(round.look, "left");
  LocateRequest kept;
  kept.ApplyJson({{"search_px", nullptr}, {"matcher", nullptr}}, "test");
  EXPECT_EQ(kept.search_px, LocateRequest().search_px);
  EXPECT_EQ(kept.matcher, "ncc");
  EXPECT_THROW(kept.ApplyJson({{"prior_offset_track", {1.0, 2.0}}}, "test"), ConfigError);
  EXPECT_THROW(kept.ApplyJson({{"serch_px", 3}}, "test"), ConfigError);
  const RequestField<LocateRequest>& offset = LocateFields().at("prior_offset_track");
  EXPECT_EQ(offset.Flag(), "--prior-offset-track");
  EXPECT_EQ(offset.from_text("0,30,-2.5", offset.Flag()), nlohmann::json({0.0, 30.0, -2.5}));
  for (const char* bad : {"0,30", "0,30,", "0,x,1", "1,2,3,4", ""}) {
    EXPECT_THROW(offset.from_text(bad, offset.Flag()), ConfigError) << bad;
  }
  EXPECT_EQ(LocateFields().at("composite_png").Flag(), "--composite");
}

TEST(Prior, UnknownKeyIsAConfigErrorNamingIt) {
  const nlohmann::json j = {{"heading_deg", 1.0}, {"slant_range_m", 5000.0}, {"sensor_enu_m", {0, 0, 3000}}, {"hedding", 2}};
  try {
    ParsePriorJson(j, "p.json");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("hedding"), std::string::npos);
  }
  EXPECT_THROW(ParsePriorJson({{"heading_deg", 1.0}, {"slant_range_m", 5000.0}}, "p.json"), ConfigError);
  const PriorPose p = ParsePriorJson({{"heading_deg", 1.0}, {"slant_range_m", 5000.0}, {"depression_deg", 40.0},
                                      {"centre_enu_m", {1, 2, 3}}}, "p.json");
  EXPECT_EQ(p.centre_enu->y(), 2.0);
}

}  // namespace
}  // namespace gissar::pipeline
