#include "gissar/cli/cli.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "gissar/util/testing.h"

namespace gissar::cli {
namespace {
namespace fs = std::filesystem;

struct Outcome {
  int status = -1;
  std::string out;
  std::string err;
};

Outcome RunGissar(std::vector<std::string> args) {
  args.insert(args.begin(), "gissar");
  std::vector<const char*> argv;
  for (const auto& a : args) argv.push_back(a.c_str());
  std::ostringstream out, err;
  Outcome o;
  o.status = RunCli(static_cast<int>(argv.size()), argv.data(), out, err);
  o.out = out.str();
  o.err = err.str();
  return o;
}

size_t CountLines(const std::string& text) {
  size_t n = 0;
  for (char c : text) n += c == '\n';
  return n;
}

size_t CountEntries(const fs::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

std::vector<std::string> SimulateArgs(const std::string& dem, const fs::path& out,
                                      const std::string& depression = "40") {
  return {"simulate", "--dem", dem, "--heading", "0", "--depression", depression,
          "--range-res", "400", "--azimuth-res", "400", "--out", (out / "sim").string(),
          "--quiet"};
}

// Every failure: status 2, exactly one line "gissar: error: ...", nothing written.
void ExpectCleanFailure(const Outcome& o, const fs::path& out_dir, const std::string& needle) {
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(CountLines(o.err), 1u) << o.err;
  EXPECT_EQ(o.err.rfind("gissar: error: ", 0), 0u) << o.err;
  EXPECT_NE(o.err.find(needle), std::string::npos) << o.err;
  EXPECT_EQ(CountEntries(out_dir), 0u);
}

TEST(CliTest, MissingDemFile) {
  const fs::path dir = testing::MakeTempDir();
  ExpectCleanFailure(RunGissar(SimulateArgs("/nonexistent/dem.tif", dir)), dir,
                     "DEM file does not exist (/nonexistent/dem.tif)");
}

TEST(CliTest, NonRasterFile) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path input = testing::MakeTempDir() / "dem.tif";
  std::ofstream(input) << "plain text, not a raster\n";
  ExpectCleanFailure(RunGissar(SimulateArgs(input.string(), dir)), dir, "not a raster GDAL can read");
}

TEST(CliTest, DemWithVoidsNeedsFill) {
  const fs::path dir = testing::MakeTempDir();
  ExpectCleanFailure(
      RunGissar(SimulateArgs(testing::DataPath("andorra/andorra_srtm3_dem_raw.tif").string(), dir)),
      dir, "403 no-data cells");
}

TEST(CliTest, DepressionOutsideOpenInterval) {
  const std::string dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  for (const std::string dep : {"0", "90", "-5", "95", "nan"}) {
    const fs::path dir = testing::MakeTempDir();
    ExpectCleanFailure(RunGissar(SimulateArgs(dem, dir, dep)), dir, "(--depression)");
  }
}

TEST(CliTest, OtherBadOptions) {
  const std::string dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  const fs::path dir = testing::MakeTempDir();
  auto args = SimulateArgs(dem, dir);
  args[4] = "nan";  // heading
  ExpectCleanFailure(RunGissar(args), dir, "(--heading)");
  args = SimulateArgs(dem, dir);
  args[8] = "-3";  // range spacing
  ExpectCleanFailure(RunGissar(args), dir, "(--range-res)");
  args = SimulateArgs(dem, dir);
  args.insert(args.end(), {"--mode", "fisheye"});
  ExpectCleanFailure(RunGissar(args), dir, "(--mode)");
  args = SimulateArgs(dem, dir);
  args.insert(args.end(), {"--center", "1.6"});
  ExpectCleanFailure(RunGissar(args), dir, "(--center)");
  ExpectCleanFailure(RunGissar(SimulateArgs(dem, dir / "missing")), dir, "output directory does not exist");
  ExpectCleanFailure(RunGissar({"simulate", "--dem", dem}), dir, "(command line)");
  ExpectCleanFailure(RunGissar({"frobnicate"}), dir, "(command line)");
}

TEST(CliTest, HelpAndVersionSucceed) {
  const Outcome help = RunGissar({"simulate", "--help"});
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.out.find("--depression"), std::string::npos);
  const Outcome version = RunGissar({"--version"});
  EXPECT_EQ(version.status, 0);
  EXPECT_NE(version.out.find("gissar 0."), std::string::npos);
}

// The real executable: exit status 2 and one stderr line.
TEST(CliTest, BinaryExitsWithStatusTwo) {
  const fs::path dir = testing::MakeTempDir();
  const std::string command = std::string(GISSAR_CLI_BINARY) +
                              " simulate --dem /nonexistent.tif --heading 0 --depression 40 --out " +
                              (dir / "x").string() + " 2>" + (dir / "stderr.txt").string();
  const int raw = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(raw));
  EXPECT_EQ(WEXITSTATUS(raw), 2);
  std::ifstream in(dir / "stderr.txt");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "gissar: error: DEM file does not exist (/nonexistent.tif)\n");
  EXPECT_EQ(CountEntries(dir), 1u);  // only the captured stderr
}

}  // namespace
}  // namespace gissar::cli
