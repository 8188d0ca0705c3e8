// Determinism (docs/robustness.md): the same inputs and seed give
// bit-identical output files across runs and thread counts. Only the JSON
// sidecars differ, in the fields that record the run itself (time stamp,
// timings, peak memory, output paths), which are removed before comparing.
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <fstream>
#include <sstream>

#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/simulate_door.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

std::string Bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << path;
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A JSON sidecar without the fields that describe the run, not the result.
json StableJson(const fs::path& path) {
  json j = json::parse(Bytes(path));
  for (const char* key : {"created_utc", "timings_s", "total_seconds", "peak_rss_bytes", "outputs",
                          "command_line"}) {
    j.erase(key);
  }
  if (j.contains("options")) {
    j["options"].erase("out_prefix");
    j["options"].erase("contributions");
  }
  if (j.contains("stats")) j["stats"].erase("build_seconds");
  return j;
}

// Runs `job` in an arena of `threads` worker threads.
template <typename Job>
void WithThreads(int threads, Job job) {
  tbb::task_arena arena(threads);
  arena.execute(job);
}

void ExpectSameFiles(const fs::path& a_prefix, const fs::path& b_prefix,
                     const std::vector<std::string>& binary_suffixes, const std::string& label) {
  for (const std::string& suffix : binary_suffixes) {
    const std::string a = Bytes(a_prefix.string() + suffix), b = Bytes(b_prefix.string() + suffix);
    EXPECT_FALSE(a.empty()) << label << suffix;
    EXPECT_TRUE(a == b) << label << ": " << suffix << " differs";
  }
  EXPECT_EQ(StableJson(a_prefix.string() + ".json"), StableJson(b_prefix.string() + ".json")) << label;
}

SimulateRequest DemJob(const fs::path& out_prefix) {
  SimulateRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  o.geometry.heading_deg = 30.0;
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = 90.0;
  o.geometry.azimuth_spacing_m = 90.0;
  o.rays_per_cell = 9.0;
  o.bounces = 3;
  o.range_resolution_m = 150.0;
  o.azimuth_resolution_m = 150.0;
  o.psf_window = "hamming";
  o.speckle_looks = 4.0;
  o.nesz_db = -25.0;
  o.seed = 7;
  o.out_prefix = out_prefix.string();
  o.contributions = out_prefix.string() + "_contributions.csv";
  return o;
}

TEST(DeterminismTest, SimulateIsBitIdenticalAcrossThreadCounts) {
  const fs::path dir = testing::MakeTempDir();
  for (int threads : {1, 2, 4}) {
    WithThreads(threads, [&] { RunSimulate(DemJob(dir / ("t" + std::to_string(threads))), "test"); });
  }
  const std::vector<std::string> files = {".tif", "_mask.tif", ".png", "_contributions.csv"};
  ExpectSameFiles(dir / "t1", dir / "t2", files, "1 vs 2 threads");
  ExpectSameFiles(dir / "t1", dir / "t4", files, "1 vs 4 threads");
}

TEST(DeterminismTest, CoherentExactModeIsBitIdenticalAcrossRuns) {
  const fs::path dir = testing::MakeTempDir();
  for (const char* name : {"a", "b"}) {
    SimulateRequest o = DemJob(dir / name);
    o.coherent = true;
    o.speckle_looks = 0.0;  // coherent mode forms its own speckle
    o.geometry.mode = sensor::ProjectionMode::kExact;
    o.contributions.clear();
    WithThreads(name[0] == 'a' ? 1 : 2, [&] { RunSimulate(o, "test"); });
  }
  ExpectSameFiles(dir / "a", dir / "b", {".tif", "_mask.tif", ".png"}, "coherent exact");
}

TEST(DeterminismTest, SceneBuildAndSceneSimulationAreBitIdentical) {
  const fs::path dir = testing::MakeTempDir();
  for (const char* name : {"a", "b"}) {
    SceneBuildRequest o;
    o.dem = testing::DataPath("monaco/monaco_srtm3_dem.tif").string();
    o.osm = testing::DataPath("monaco/monaco.osm.gz").string();
    o.fill_nodata = true;
    o.out_prefix = (dir / name).string();
    WithThreads(name[0] == 'a' ? 1 : 2, [&] { RunSceneBuild(o, "test"); });
  }
  ExpectSameFiles(dir / "a", dir / "b", {".gscene", ".ply", "_classes.png"}, "scene build");

  for (int threads : {1, 2}) {
    SimulateRequest o;
    o.scene = (dir / "a.gscene").string();
    o.geometry.heading_deg = 0.0;
    o.geometry.depression_deg = 35.0;
    o.geometry.range_spacing_m = 10.0;
    o.geometry.azimuth_spacing_m = 10.0;
    o.bounces = 4;
    o.out_prefix = (dir / ("sim" + std::to_string(threads))).string();
    WithThreads(threads, [&] { RunSimulate(o, "test"); });
  }
  ExpectSameFiles(dir / "sim1", dir / "sim2", {".tif", "_mask.tif", ".png"}, "scene simulation");
}

}  // namespace
}  // namespace gissar::pipeline
