#include "gissar/cli/cli.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>

#include <nlohmann/json.hpp>

#include "gissar/geo/raster_io.h"
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_fields.h"
#include "gissar/pipeline/mvg_fields.h"
#include "gissar/pipeline/polsar_fields.h"
#include "gissar/pipeline/simulate_fields.h"
#include "gissar/pipeline/validate_fields.h"
#include "gissar/pipeline/views_fields.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/cli/command.h"
#include "gissar/cli/corridor_command.h"
#include "gissar/util/testing.h"

namespace gissar::cli {
namespace {
namespace fs = std::filesystem;
using pipeline::EvaluateRequest;
using pipeline::SimulateRequest;

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
          "--range-spacing", "400", "--azimuth-spacing", "400", "--out", (out / "sim").string(),
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
      dir, "391 no-data cells inside (12 more on its border are left out of the scene)");
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
  ExpectCleanFailure(RunGissar(args), dir, "(--range-spacing)");
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

TEST(FmatrixCommandTest, DegenerateInputIsAClearError) {
  const fs::path dir = testing::MakeTempDir();
  auto csv = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  };
  struct Case {
    std::string file, needle;
  };
  const std::vector<Case> cases = {
      {csv("three.csv", "x1,y1,x2,y2\n1,2,3,4\n5,6,7,8\n9,1,2,3\n"), "at least 4 matches"},
      {csv("collinear.csv", "x1,y1,x2,y2\n0,0,0,0\n1,1,1,1\n2,2,2,2\n3,3,3,3\n4,4,4,4\n"), "degenerate"},
      {csv("nan.csv", "x1,y1,x2,y2\n1,2,3,4\n5,nan,7,8\n9,1,2,3\n4,4,5,5\n"), "nan.csv"},
      {csv("columns.csv", "x1,y1,x2\n1,2,3\n"), "columns.csv"},
  };
  for (const Case& c : cases) {
    const Outcome o = RunGissar({"fmatrix", "--matches", c.file, "--out", (dir / "out").string()});
    const std::string& err = o.err;
    EXPECT_EQ(o.status, 2) << c.file;
    EXPECT_EQ(err.rfind("gissar: error: ", 0), 0u) << err;
    EXPECT_NE(err.find(c.needle), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_FALSE(fs::exists(dir / "out.json"));
  }
}


// The real executable with a shell command line; stdout and stderr captured.
// Runs a shell command line, its stdout and stderr captured through files in `dir`.
Outcome RunShell(const std::string& command_line, const fs::path& dir) {
  const std::string command =
      command_line + " >" + (dir / "stdout.txt").string() + " 2>" + (dir / "stderr.txt").string();
  const int raw = std::system(command.c_str());
  Outcome o;
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  auto read = [](const fs::path& path) {
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
  };
  o.out = read(dir / "stdout.txt");
  o.err = read(dir / "stderr.txt");
  fs::remove(dir / "stdout.txt");
  fs::remove(dir / "stderr.txt");
  return o;
}

Outcome RunBinary(const std::string& arguments, const fs::path& dir) {
  return RunShell(std::string(GISSAR_CLI_BINARY) + " " + arguments, dir);
}

// `gissar corridor` is the Python package's command: the package is found
// beside the executable (build tree, then installed prefix), the arguments
// pass through unchanged, and the real binary answers --help through Python.
TEST(CorridorDoorTest, FindsThePackageBesideTheExecutableAndPassesTheArguments) {
  const fs::path dir = testing::MakeTempDir();
  fs::create_directories(dir / "build" / "bin");
  EXPECT_FALSE(PythonPackageDir(dir / "build" / "bin" / "gissar").has_value());
  fs::create_directories(dir / "prefix" / "bin");
  fs::create_directories(dir / "prefix" / "lib" / "python3" / "dist-packages" / "gissar");
  std::ofstream(dir / "prefix" / "lib" / "python3" / "dist-packages" / "gissar" / "corridor.py") << "\n";
  EXPECT_EQ(PythonPackageDir(dir / "prefix" / "bin" / "gissar"),
            fs::weakly_canonical(dir / "prefix" / "lib" / "python3" / "dist-packages"));
  fs::create_directories(dir / "build" / "python" / "gissar");
  std::ofstream(dir / "build" / "python" / "gissar" / "corridor.py") << "\n";
  EXPECT_EQ(PythonPackageDir(dir / "build" / "bin" / "gissar"), fs::weakly_canonical(dir / "build" / "python"));
  const char* argv[] = {"gissar", "corridor", "--route", "r.csv", "--help"};
  EXPECT_TRUE(IsCorridorCommand(5, argv));
  EXPECT_FALSE(IsCorridorCommand(1, argv));
  EXPECT_EQ(CorridorArguments("py", 5, argv),
            (std::vector<std::string>{"py", "-m", "gissar.corridor", "--route", "r.csv", "--help"}));
  EXPECT_NE(RunGissar({"--help"}).out.find("corridor"), std::string::npos);
  const Outcome help = RunBinary("corridor --help", dir);
  EXPECT_EQ(help.status, 0) << help.err;
  EXPECT_NE(help.out.find("--pose-step"), std::string::npos) << help.out;
  const Outcome bad = RunBinary("corridor --pose-stepp 100", dir);
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(bad.err.rfind("gissar: error: ", 0), 0u) << bad.err;
  EXPECT_EQ(CountLines(bad.err), 1u) << bad.err;
}

// `--out sim` (a prefix with no directory) writes in the working directory;
// the STAC Item's hrefs are then plain file names (this failed at the very
// end with "cannot make absolute path" before).
TEST(CliTest, OutPrefixWithoutADirectory) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path before = fs::current_path();
  fs::current_path(dir);
  const Outcome o = RunGissar({"simulate", "--dem", testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string(),
                               "--heading", "0", "--depression", "40", "--range-spacing", "400", "--azimuth-spacing",
                               "400", "--out", "sim", "--quiet"});
  fs::current_path(before);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_TRUE(fs::exists(dir / "sim.tif"));
  std::ifstream in(dir / "sim_stac.json");
  const nlohmann::json item = nlohmann::json::parse(in);
  EXPECT_EQ(item["assets"]["image"]["href"], "sim.tif") << item["assets"].dump();
}

// Band 1 with no-data (NaN, outside the footprint) as -1, so that == compares
// two images pixel for pixel.
std::vector<float> FirstBand(const fs::path& tif) {
  std::vector<float> band = geo::ReadFloatRaster(tif).bands.at(0);
  for (float& v : band) if (std::isnan(v)) v = -1.0f;
  return band;
}

const std::string kSmallSimulate =
    "simulate --dem " + testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string() +
    " --heading 0 --depression 40 --range-spacing 400 --azimuth-spacing 400";

// RequestFlags::AddAll declares one flag per field with help, in the
// table's order (the locate table: --composite and --polish its older
// spellings, max_memory_bytes without help has none), and only the named
// fields are required.
TEST(RequestFlagsTest, AddAllDeclaresTheFieldsWithHelpInTableOrder) {
  CLI::App app;
  pipeline::LocateRequest request;
  RequestFlags<pipeline::LocateRequest> flags(&app, pipeline::LocateFields(), &request);
  flags.AddAll({"out"});
  std::vector<std::string> expected;
  for (const auto& field : pipeline::LocateFields().fields()) {
    if (!field.help.empty()) expected.push_back(field.Flag());
  }
  std::vector<std::string> declared, required;
  for (const CLI::Option* option : app.get_options()) {
    if (option->get_name() == "--help") continue;
    declared.push_back(option->get_name());
    if (option->get_required()) required.push_back(option->get_name());
  }
  EXPECT_EQ(declared, expected);
  EXPECT_EQ(expected.size(), pipeline::LocateFields().fields().size() - 1);  // all but max_memory_bytes
  EXPECT_NE(std::find(declared.begin(), declared.end(), "--composite"), declared.end());
  EXPECT_EQ(required, std::vector<std::string>{"--out"});
  ClearOptionKeyFlags();
}

// The rows added for the other commands' tables parse their text where the
// flags parsed it before: an integer list with its older spelling
// (polsar --looks), a three-number centre and an optional number (resect),
// simulate's rows reached through a member (validate's --dem, --burst) and
// the comparison's own (--radiometry, --looks); a malformed list names the
// flag and what it needs.
TEST(RequestFlagsTest, TablesOfTheOtherCommandsReadTheirFlags) {
  {
    CLI::App app;
    pipeline::PolsarRequest request;
    RequestFlags<pipeline::PolsarRequest> flags(&app, pipeline::PolsarFields(), &request);
    flags.AddAll({"multilook", "out_prefix"});
    app.parse("--looks 3,5 --matrix coherency --out x", false);
    pipeline::PolsarRequest resolved = request;
    flags.Apply(resolved);
    EXPECT_EQ(resolved.multilook, (std::vector<int>{3, 5}));
    EXPECT_EQ(resolved.matrix, image::PolarimetricMatrix::kCoherency);
    EXPECT_EQ(resolved.out_prefix, "x");
    CLI::App again;
    pipeline::PolsarRequest bad;
    RequestFlags<pipeline::PolsarRequest> bad_flags(&again, pipeline::PolsarFields(), &bad);
    bad_flags.AddAll({"multilook", "out_prefix"});
    again.parse("--multilook 3 --out x", false);
    try {
      bad_flags.Apply(bad);
      ADD_FAILURE() << "one look accepted";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.where(), "--multilook");
      EXPECT_NE(e.message().find("two integers R,A"), std::string::npos) << e.message();
    }
  }
  {
    CLI::App app;
    pipeline::ResectRequest request;
    RequestFlags<pipeline::ResectRequest> flags(&app, pipeline::ResectFields(), &request);
    flags.AddAll({"points"});
    app.parse("--points p.csv --center-enu 1,2,-3.5 --slant-range 8000 --out r", false);
    pipeline::ResectRequest resolved = request;
    flags.Apply(resolved);
    EXPECT_EQ(resolved.center_enu_m, Eigen::Vector3d(1, 2, -3.5));
    ASSERT_TRUE(resolved.slant_range_m.has_value());
    EXPECT_EQ(*resolved.slant_range_m, 8000.0);
    EXPECT_EQ(pipeline::ResectFields().ToJson(resolved)["center_enu_m"], nlohmann::json({1.0, 2.0, -3.5}));
  }
  {
    CLI::App app;
    pipeline::ValidateRequest request;
    RequestFlags<pipeline::ValidateRequest> flags(&app, pipeline::ValidateFields(), &request);
    flags.AddAll({"product", "out_prefix"});
    app.parse("--product p.h5 --dem d.tif --burst 2 --radiometry sigma0 --looks 2,4 --out v", false);
    pipeline::ValidateRequest resolved = request;
    flags.Apply(resolved);
    EXPECT_EQ(resolved.simulate.product, "p.h5");
    EXPECT_EQ(resolved.simulate.dem, "d.tif");
    EXPECT_EQ(resolved.simulate.burst, 2);
    EXPECT_EQ(resolved.radiometry, "sigma0");
    EXPECT_EQ(resolved.looks, (std::vector<int>{2, 4}));
    // The rows shared with simulate are simulate's: same key, flag and help.
    EXPECT_EQ(pipeline::ValidateFields().at("dem").help, pipeline::SimulateFields().at("dem").help);
    EXPECT_EQ(pipeline::ValidateFields().at("product_window_px").Flag(), "--product-window");
  }
  ClearOptionKeyFlags();
}

// Every table's ToJson is read back by its ApplyJson unchanged (the keys a
// sidecar or an options file carries), and an unknown key is refused.
TEST(RequestFlagsTest, EveryTableRoundTripsThroughJson) {
  auto round_trip = [](const auto& table, auto request, const char* what) {
    const nlohmann::json written = table.ToJson(request);
    decltype(request) read;
    table.ApplyJson(read, written, "test");
    EXPECT_EQ(table.ToJson(read), written) << what;
    EXPECT_THROW(table.ApplyJson(read, nlohmann::json{{"no_such_key", 1}}, "test"), ConfigError) << what;
  };
  pipeline::PolsarRequest polsar;
  polsar.multilook = {2, 3};
  round_trip(pipeline::PolsarFields(), polsar, "polsar");
  pipeline::FmatrixRequest fmatrix;
  fmatrix.range_spacing_m = Eigen::Vector2d(1.5, 2.5);
  fmatrix.robust = false;
  round_trip(pipeline::FmatrixFields(), fmatrix, "fmatrix");
  pipeline::ResectRequest resect;
  resect.slant_range_m = 900.0;
  round_trip(pipeline::ResectFields(), resect, "resect");
  round_trip(pipeline::RegisterFields(), pipeline::RegisterRequest(), "register");
  round_trip(pipeline::EpipolarFields(), pipeline::EpipolarRequest(), "epipolar");
  round_trip(pipeline::CompositeFields(), pipeline::CompositeRequest(), "composite");
  pipeline::ValidateRequest validate;
  validate.simulate.dem = "d.tif";
  validate.looks = {2};
  round_trip(pipeline::ValidateFields(), validate, "validate");
  pipeline::SequenceRequest sequence;
  sequence.frames = 4;
  round_trip(pipeline::SequenceFields(), sequence, "sequence");
  round_trip(pipeline::OrthoFields(), pipeline::OrthoRequest(), "ortho");
  round_trip(pipeline::MatchPairFields(), pipeline::MatchPairRequest(), "matchpair");
}

// --options FILE.json: keys are the request's snake_case names; the same
// job as with flags gives the same image; flags on the command line win.
TEST(CommonFlagsTest, OptionsFileEqualsFlags) {
  const fs::path dir = testing::MakeTempDir();
  ASSERT_EQ(RunBinary(kSmallSimulate + " --quiet --out " + (dir / "flags").string(), dir).status, 0);
  std::ofstream(dir / "job.json") << "{\"dem\": \"" << testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string()
                                  << "\", \"heading_deg\": 30, \"depression_deg\": 40, \"range_spacing_m\": 400, "
                                     "\"azimuth_spacing_m\": 400, \"center_lonlat\": null, \"coherent\": false}";
  const Outcome o = RunBinary("simulate --options " + (dir / "job.json").string() + " --heading 0 --quiet --out " +
                                  (dir / "file").string(),
                              dir);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_EQ(FirstBand(dir / "flags.tif"), FirstBand(dir / "file.tif"));
  // The sidecar records the request under the same names.
  std::ifstream sidecar(dir / "file.json");
  const nlohmann::json provenance = nlohmann::json::parse(sidecar);
  EXPECT_EQ(provenance["options"]["heading_deg"].get<double>(), 0.0);
  EXPECT_EQ(provenance["options"]["range_spacing_m"].get<double>(), 400.0);
}

// A sidecar's options, fed back as an options file, redo the same job:
// every request field has its flag.
TEST(CommonFlagsTest, SidecarOptionsAreAnOptionsFile) {
  const fs::path dir = testing::MakeTempDir();
  ASSERT_EQ(RunBinary(kSmallSimulate + " --look left --mode exact --speckle-looks 3 --seed 7 --quiet --out " +
                          (dir / "first").string(), dir).status, 0);
  std::ifstream sidecar(dir / "first.json");
  const nlohmann::json options = nlohmann::json::parse(sidecar)["options"];
  const nlohmann::json defaults = SimulateRequest().ToJson();
  for (const auto& [key, value] : defaults.items()) {
    EXPECT_TRUE(options.contains(key)) << key;
  }
  std::ofstream(dir / "again.json") << options.dump();
  const Outcome o = RunBinary("simulate --options " + (dir / "again.json").string() + " --quiet --out " +
                                  (dir / "second").string(), dir);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_EQ(FirstBand(dir / "first.tif"), FirstBand(dir / "second.tif"));
}

// A switch that is on by default (overviews) is turned off by `false` in an
// options file (its --no- form) and back on by its flag on the command line.
TEST(CommonFlagsTest, OptionsFileTurnsOffADefaultOnSwitch) {
  const fs::path dir = testing::MakeTempDir();
  std::ofstream(dir / "switch.json") << R"({"overviews": false})";
  auto overviews = [&](const std::string& extra, const std::string& name) {
    const Outcome o = RunBinary(kSmallSimulate + " --options " + (dir / "switch.json").string() + extra +
                                    " --quiet --out " + (dir / name).string(), dir);
    EXPECT_EQ(o.status, 0) << o.err;
    std::ifstream sidecar(dir / (name + ".json"));
    return nlohmann::json::parse(sidecar)["options"]["overviews"].get<bool>();
  };
  EXPECT_FALSE(overviews("", "off"));
  EXPECT_TRUE(overviews(" --overviews", "on"));
}

TEST(CommonFlagsTest, UnknownOptionsKeyNamesKeyAndFile) {
  const fs::path dir = testing::MakeTempDir();
  std::ofstream(dir / "bad.json") << "{\"heading_deg\": 0, \"headin_deg\": 3}";
  const Outcome o = RunBinary("simulate --options " + (dir / "bad.json").string() + " --out " + (dir / "x").string(), dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, "gissar: error: unknown key 'headin_deg' (" + (dir / "bad.json").string() + ")\n");
  EXPECT_EQ(CountEntries(dir), 1u);  // only bad.json
}

// Fuzzer finding (fuzz_options_json): a list flag's value nested 30,000
// [ ] deep made CLI11 expand it level by level (gigabytes); a JSON list
// nested as deep was dumped recursively. Both are ConfigErrors now.
TEST(CommonFlagsTest, DeeplyNestedOptionsValueIsAClearError) {
  const fs::path dir = testing::MakeTempDir();
  const std::string deep = std::string(30000, '[') + std::string(30000, ']');
  std::ofstream(dir / "text.json") << "{\"prior_offset_track\": \"" << deep << "\"}";
  std::ofstream(dir / "list.json") << "{\"prior_offset_track\": [" << deep << "]}";
  for (const char* name : {"text.json", "list.json"}) {
    const Outcome o = RunBinary("locate --options " + (dir / name).string() + " --out " + (dir / "x").string(), dir);
    EXPECT_EQ(o.status, 2) << name;
    EXPECT_NE(o.err.find("key 'prior_offset_track'"), std::string::npos) << o.err;
    EXPECT_NE(o.err.find(name), std::string::npos) << o.err;
  }
}

TEST(CommonFlagsTest, DeprecatedSpellingWorksWithAWarning) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  ASSERT_EQ(RunBinary(kSmallSimulate + " --quiet --out " + (dir / "new").string(), dir).status, 0);
  const Outcome o = RunBinary("simulate --dem " + dem + " --heading 0 --depression 40 --range-res 400 "
                              "--azimuth-res=400 --quiet --out " + (dir / "old").string(), dir);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_NE(o.err.find("gissar: warning: --range-res is deprecated and will be removed; use --range-spacing"),
            std::string::npos) << o.err;
  EXPECT_NE(o.err.find("use --azimuth-spacing"), std::string::npos) << o.err;
  EXPECT_EQ(FirstBand(dir / "new.tif"), FirstBand(dir / "old.tif"));
}

// evaluate's prior errors are spelled as in docs/conventions.md; the old
// spellings warn, naming the new flag (before the request's own check).
TEST(CommonFlagsTest, OldEvaluatePriorSpellingsWarn) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  const Outcome o = RunBinary("evaluate --dem " + dem + " --trials 0 --prior-vertical 10 --prior-heading=2 --out " +
                                  (dir / "e").string(),
                              dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("gissar: warning: --prior-vertical is deprecated and will be removed; use "
                       "--prior-error-vertical"),
            std::string::npos) << o.err;
  EXPECT_NE(o.err.find("use --prior-error-heading"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("gissar: error: must be in [1, 100000] (--trials)"), std::string::npos) << o.err;
}

// Every key of an evaluate request (its sidecar's options) is an options-file
// key, those whose flag kept an older spelling (speckle_looks: --looks,
// compare_matchers: --compare, ...) included: the file below reaches the
// request's own check, not "unknown key".
TEST(CommonFlagsTest, EvaluateOptionsFileTakesEveryRequestKey) {
  const fs::path dir = testing::MakeTempDir();
  nlohmann::json options = EvaluateRequest().ToJson();
  options["dem"] = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  options["compare_matchers"] = false;
  options["speckle_looks"] = 2.0;
  options["trials"] = 0;
  options.erase("out_prefix");
  std::ofstream(dir / "evaluate.json") << options.dump();
  const Outcome o = RunBinary("evaluate --options " + (dir / "evaluate.json").string() + " --out " +
                                  (dir / "e").string(),
                              dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err.find("unknown key"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("must be in [1, 100000] (--trials)"), std::string::npos) << o.err;
}

// fmatrix --res1 R1,A1 --res2 R2,A2 = --range-spacing R1,R2 --azimuth-spacing
// A1,A2 (case 3: 1 m pixels in view 1, 0.75 m in view 2), resect
// --scene-centre = --center-enu; the old spellings warn, naming the new flags.
TEST(CommonFlagsTest, OldFmatrixAndResectSpellingsWorkWithAWarning) {
  const fs::path dir = testing::MakeTempDir();
  const std::string matches = testing::TestDataPath("affine/case3_dpsi30_dep40_45_res1_0.75_points.csv").string();
  Outcome o = RunGissar({"fmatrix", "--matches", matches, "--range-spacing", "1,0.75", "--azimuth-spacing",
                         "1,0.75", "--depressions", "40,45", "--out", (dir / "new").string()});
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_EQ(o.err.find("deprecated"), std::string::npos) << o.err;
  // The binary: warnings go to the process's stderr.
  o = RunBinary("fmatrix --matches " + matches + " --res1 1,1 --res2=0.75,0.75 --depressions 40,45 --out " +
                    (dir / "old").string(),
                dir);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_NE(o.err.find("gissar: warning: --res1 is deprecated and will be removed; use --range-spacing R1,R2 "
                       "--azimuth-spacing A1,A2"),
            std::string::npos) << o.err;
  EXPECT_NE(o.err.find("--res2 is deprecated"), std::string::npos) << o.err;
  nlohmann::json a, b;
  std::ifstream(dir / "new.json") >> a;
  std::ifstream(dir / "old.json") >> b;
  EXPECT_EQ(a["F_calibrated"], b["F_calibrated"]);
  EXPECT_EQ(a["heading_change_deg"], b["heading_change_deg"]);
  EXPECT_EQ(b["options"]["range_spacing_m"], nlohmann::json::array({1.0, 0.75}));
  EXPECT_EQ(b["options"]["azimuth_spacing_m"], nlohmann::json::array({1.0, 0.75}));
  // One old flag alone, or old and new together: exit 2.
  o = RunGissar({"fmatrix", "--matches", matches, "--res1", "1,1", "--out", (dir / "x").string()});
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("give both --res1 and --res2"), std::string::npos) << o.err;
  o = RunGissar({"fmatrix", "--matches", matches, "--res1", "1,1", "--res2", "1,1", "--range-spacing", "1,1",
                 "--azimuth-spacing", "1,1", "--out", (dir / "x").string()});
  EXPECT_EQ(o.status, 2);
  o = RunGissar({"fmatrix", "--matches", matches, "--range-spacing", "1,1", "--out", (dir / "x").string()});
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("give both --range-spacing"), std::string::npos) << o.err;
  EXPECT_FALSE(fs::exists(dir / "x.json"));

  const std::string points = testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree_points.csv").string();
  // resect reads X,Y,Z,x,y: the reference case's 3-D points with their image-1 pixels.
  std::ifstream in(points);
  std::string header, line;
  std::getline(in, header);
  std::vector<std::string> names;
  {
    std::istringstream h(header);
    for (std::string name; std::getline(h, name, ',');) names.push_back(name);
  }
  auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(names.begin(), names.end(), name) - names.begin());
  };
  std::ofstream csv(dir / "p.csv");
  csv << "X,Y,Z,x,y\n";
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::istringstream l(line);
    for (std::string cell; std::getline(l, cell, ',');) cells.push_back(cell);
    csv << cells[column("X")] << "," << cells[column("Y")] << "," << cells[column("Z")] << "," << cells[column("x1")]
        << "," << cells[column("y1")] << "\n";
  }
  csv.close();
  o = RunGissar({"resect", "--points", (dir / "p.csv").string(), "--center-enu", "0,0,0", "--out",
                 (dir / "rnew").string()});
  ASSERT_EQ(o.status, 0) << o.err;
  o = RunBinary("resect --points " + (dir / "p.csv").string() + " --scene-centre 0,0,0 --out " +
                    (dir / "rold").string(),
                dir);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_NE(o.err.find("gissar: warning: --scene-centre is deprecated and will be removed; use --center-enu"),
            std::string::npos) << o.err;
  std::ifstream(dir / "rnew.json") >> a;
  std::ifstream(dir / "rold.json") >> b;
  EXPECT_EQ(a["heading_deg"], b["heading_deg"]);
  EXPECT_EQ(b["options"]["center_enu_m"], nlohmann::json::array({0.0, 0.0, 0.0}));
}

TEST(CommonFlagsTest, MisspeltFlagOrCommandGetsASuggestion) {
  const fs::path dir = testing::MakeTempDir();
  Outcome o = RunGissar({"simulate", "--dem", "x.tif", "--heading", "0", "--depresion", "40", "--out", "y"});
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("did you mean --depression?"), std::string::npos) << o.err;
  EXPECT_EQ(CountLines(o.err), 1u);
  o = RunGissar({"simulat", "--dem", "x.tif"});
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("did you mean simulate?"), std::string::npos) << o.err;
  // An unknown command is an error even with --help (which alone succeeds).
  o = RunGissar({"evalute", "--help"});
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, "gissar: error: unknown command 'evalute'; did you mean evaluate? (`gissar --help` lists the "
                   "commands) (command line)\n");
  o = RunGissar({"scene", "biuld"});
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("did you mean build?"), std::string::npos) << o.err;
  EXPECT_EQ(RunGissar({"scene", "build", "--help"}).status, 0);
}

// --quiet: nothing on stderr for a clean run; by default information lines
// and, off a terminal, no progress bar (no carriage returns); --threads
// does not change the image; --log-level is checked.
TEST(CommonFlagsTest, QuietLogLevelAndThreads) {
  const fs::path dir = testing::MakeTempDir();
  Outcome o = RunBinary(kSmallSimulate + " --quiet --out " + (dir / "q").string(), dir);
  ASSERT_EQ(o.status, 0);
  EXPECT_EQ(o.err, "");
  EXPECT_EQ(CountLines(o.out), 6u);  // the six files written
  o = RunBinary(kSmallSimulate + " --threads 1 --out " + (dir / "t1").string(), dir);
  ASSERT_EQ(o.status, 0);
  EXPECT_NE(o.err.find("simulate: image "), std::string::npos) << o.err;
  EXPECT_EQ(o.err.find('\r'), std::string::npos);
  EXPECT_EQ(FirstBand(dir / "q.tif"), FirstBand(dir / "t1.tif"));
  o = RunBinary(kSmallSimulate + " --log-level loud --out " + (dir / "x").string(), dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("(--log-level)"), std::string::npos) << o.err;
  o = RunBinary(kSmallSimulate + " --log-level error --out " + (dir / "e").string(), dir);
  EXPECT_EQ(o.status, 0);
  EXPECT_EQ(o.err, "");
}

// The old spelling --json FILE of fmatrix and resect names the JSON file
// itself, as it did: `--json OUT_kvd.png --plot OUT` once wrote the KvD
// picture over the fit (exit 0); the collision check sees the file --json
// resolves to (exit 2, the warning and one error line, nothing written).
TEST(CommonFlagsTest, OldJsonSpellingNamesTheFileAndCollides) {
  const fs::path dir = testing::MakeTempDir();
  const std::string matches = testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree_points.csv").string();
  Outcome o = RunBinary("fmatrix --matches " + matches + " --json " + (dir / "OUT_kvd.png").string() + " --plot " +
                            (dir / "OUT").string(),
                        dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, "gissar: warning: --json is deprecated and will be removed; use --out\n"
                   "gissar: error: --json and --plot name the same file " + (dir / "OUT_kvd.png").string() +
                       " (--json/--plot)\n");
  EXPECT_EQ(o.out, "");
  EXPECT_EQ(CountEntries(dir), 0u);
  // The file itself, without an extension added; with --plot elsewhere, both.
  o = RunBinary("fmatrix --matches " + matches + " --json " + (dir / "fit").string() + " --plot " +
                    (dir / "OUT").string() + " --quiet",
                dir);
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_EQ(o.out.rfind((dir / "fit").string() + "\n" + (dir / "OUT_kvd.png").string() + "\n", 0), 0u) << o.out;
  nlohmann::json fit;
  std::ifstream(dir / "fit") >> fit;
  EXPECT_TRUE(fit["converged"].get<bool>());
  EXPECT_EQ(fit["num_matches"].get<int>(), 50);
  EXPECT_TRUE(fs::exists(dir / "OUT_kvd.png"));
  EXPECT_FALSE(fs::exists(dir / "fit.json"));
  // Both spellings at once, or neither: exit 2.
  o = RunBinary("fmatrix --matches " + matches + " --json " + (dir / "a.json").string() + " --out " +
                    (dir / "b").string() + " --log-level error",
                dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, "gissar: error: give the output once, as --out (--json/--out)\n");
  o = RunBinary("fmatrix --matches " + matches, dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, "gissar: error: an output file is required (--out)\n");
  // resect: --json naming its input is refused like --out.
  o = RunBinary("resect --points " + matches + " --json " + matches + " --log-level error", dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(o.err, "gissar: error: output would overwrite the input " + matches + " (" + matches + ")\n");
  EXPECT_EQ(CountEntries(dir), 2u);  // fit and OUT_kvd.png
  // Commands that never had --json do not take it.
  o = RunBinary(kSmallSimulate + " --json " + (dir / "s").string(), dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_EQ(CountEntries(dir), 2u);
}

// A full disk, for real: a 16 KiB tmpfs in a user and mount namespace
// (skipped where unshare cannot make one). simulate and scene build exit 2
// with one line saying there is no space, naming the output (never its
// temporary), and leave nothing on the file system.
TEST(FullDiskTest, SimulateAndSceneBuildSayNoSpaceNamingTheOutput) {
  const fs::path dir = testing::MakeTempDir();
  fs::create_directories(dir / "disk");
  const std::string probe = "unshare --user --map-root-user --mount sh -c 'mount -t tmpfs -o size=16k tmpfs " +
                            (dir / "disk").string() + "' >/dev/null 2>&1";
  if (std::system(probe.c_str()) != 0) GTEST_SKIP() << "cannot mount a tmpfs in a user namespace here";
  const std::string dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  const fs::path disk = dir / "disk";
  for (const auto& [command, output] :
       std::vector<std::pair<std::string, std::string>>{{kSmallSimulate + " --out " + (disk / "sim").string(), "sim."},
                                                        {"scene build --dem " + dem + " --out " + (disk / "scene").string(),
                                                         "scene."}}) {
    // The command, then what is left on the tmpfs, in the namespace that holds it.
    const std::string script = "mount -t tmpfs -o size=16k tmpfs " + disk.string() + " || exit 99; " +
                               GISSAR_CLI_BINARY + " " + command + " --quiet; status=$?; ls -A " + disk.string() +
                               " >" + (dir / "left.txt").string() + "; exit $status";
    const Outcome o = RunShell("unshare --user --map-root-user --mount sh -c '" + script + "'", dir);
    EXPECT_EQ(o.status, 2) << command;
    EXPECT_EQ(CountLines(o.err), 1u) << o.err;
    EXPECT_EQ(o.err.rfind("gissar: error: failed writing ", 0), 0u) << o.err;
    EXPECT_NE(o.err.find(": no space left on the device holding " + disk.string() + " (" + (disk / output).string()),
              std::string::npos)
        << o.err;
    EXPECT_EQ(o.err.find(".gs-"), std::string::npos) << o.err;
    std::ifstream left(dir / "left.txt");
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(left), {}), "") << command;
  }
}

// --force lifts the memory budget: a job refused under a tiny --max-memory runs.
TEST(CommonFlagsTest, ForceLiftsTheMemoryBudget) {
  const fs::path dir = testing::MakeTempDir();
  Outcome o = RunBinary(kSmallSimulate + " --max-memory 1M --quiet --out " + (dir / "a").string(), dir);
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--max-memory"), std::string::npos) << o.err;
  o = RunBinary(kSmallSimulate + " --max-memory 1M --force --quiet --out " + (dir / "b").string(), dir);
  EXPECT_EQ(o.status, 0) << o.err;
}
// The leaf commands of `gissar --help` (and `gissar scene --help`).
std::vector<std::vector<std::string>> LeafCommands() {
  std::vector<std::vector<std::string>> leaves;
  std::function<void(std::vector<std::string>)> walk = [&](std::vector<std::string> path) {
    std::vector<std::string> args = path;
    args.push_back("--help");
    const Outcome help = RunGissar(args);
    EXPECT_EQ(help.status, 0);
    const size_t at = help.out.find("Subcommands:");
    if (at == std::string::npos) {
      leaves.push_back(path);
      return;
    }
    std::istringstream lines(help.out.substr(at));
    std::string line;
    std::getline(lines, line);
    while (std::getline(lines, line)) {
      std::istringstream words(line);
      std::string name;
      if (line.rfind("  ", 0) != 0 || !(words >> name)) continue;
      // `corridor` is the Python package's command (the executable hands over
      // before this parser runs): its flags are checked against simulate's by
      // python/tests/test_corridor.py.
      if (path.empty() && (name == "corridor" || name == "view")) continue;
      std::vector<std::string> child = path;
      child.push_back(name);
      walk(child);
    }
  };
  walk({});
  return leaves;
}

// The help line of `flag` ("  --flag TYPE   description"), or "".
std::string FlagLine(const std::string& help, const std::string& flag) {
  std::istringstream lines(help);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream words(line);
    std::string first;
    words >> first;
    if (first == flag || first.rfind(flag + ",", 0) == 0) return line;
  }
  return "";
}

// Every command's --help lists the shared flags with the same spelling,
// type and meaning (their help lines are identical to simulate's), and
// every command that writes files takes --out as an output prefix.
TEST(HelpWalkTest, EveryCommandHasTheSharedFlagsWithOneMeaning) {
  const std::vector<std::vector<std::string>> leaves = LeafCommands();
  ASSERT_GE(leaves.size(), 15u);  // simulate, scene build/info, ..., geocode
  const std::string reference = RunGissar({"simulate", "--help"}).out;
  // `scene info` prints and writes no file.
  const std::vector<std::string> no_files = {"scene info"};
  for (const auto& leaf : leaves) {
    std::string name;
    for (const auto& w : leaf) name += (name.empty() ? "" : " ") + w;
    std::vector<std::string> args = leaf;
    args.push_back("--help");
    const std::string help = RunGissar(args).out;
    for (const char* flag : {"--quiet", "--log-level", "--threads", "--force", "--options"}) {
      const std::string line = FlagLine(help, flag);
      EXPECT_FALSE(line.empty()) << name << " lacks " << flag;
      EXPECT_EQ(line, FlagLine(reference, flag)) << name << " " << flag;
    }
    const std::string out = FlagLine(help, "--out");
    if (std::find(no_files.begin(), no_files.end(), name) != no_files.end()) {
      EXPECT_EQ(out, "") << name;
    } else {
      EXPECT_NE(out.find("Output prefix: PREFIX"), std::string::npos) << name << ": " << out;
    }
    // Every command that reads a DEM takes its vertical datum, with simulate's help line.
    if (!FlagLine(help, "--dem").empty()) {
      EXPECT_NE(FlagLine(help, "--vertical-datum"), "") << name << " reads a DEM but lacks --vertical-datum";
      EXPECT_EQ(FlagLine(help, "--vertical-datum"), FlagLine(reference, "--vertical-datum")) << name;
    }
    // Old spellings are not listed as flags of their own.
    for (const char* old : {"--range-res", "--azimuth-res", "--range", "--json", "--res1", "--res2", "--scene-centre"}) {
      EXPECT_EQ(FlagLine(help, old), "") << name << " " << old;
    }
  }
}

// A mistyped flag gets "did you mean" on every command: the shared --quiet,
// and the command's own first flag with one letter dropped.
TEST(HelpWalkTest, EveryCommandSuggestsTheFlagMeant) {
  for (const auto& leaf : LeafCommands()) {
    std::string name;
    for (const auto& w : leaf) name += (name.empty() ? "" : " ") + w;
    std::vector<std::string> args = leaf;
    args.push_back("--qiuet");
    Outcome o = RunGissar(args);
    EXPECT_EQ(o.status, 2) << name;
    EXPECT_NE(o.err.find("did you mean --quiet?"), std::string::npos) << name << ": " << o.err;
    EXPECT_EQ(CountLines(o.err), 1u) << name;
    // The command's own first flag after --help.
    std::vector<std::string> help_args = leaf;
    help_args.push_back("--help");
    std::istringstream lines(RunGissar(help_args).out);
    std::string line, own;
    while (std::getline(lines, line)) {
      std::istringstream words(line);
      std::string first;
      words >> first;
      if (first.rfind("--", 0) == 0 && first != "--help" && first.size() >= 6) {
        own = first.substr(0, first.find(','));
        break;
      }
    }
    ASSERT_FALSE(own.empty()) << name;
    args = leaf;
    args.push_back(own.substr(0, 3) + own.substr(4));  // one letter dropped
    o = RunGissar(args);
    EXPECT_EQ(o.status, 2) << name;
    EXPECT_NE(o.err.find("did you mean " + own + "?"), std::string::npos) << name << ": " << o.err;
  }
}

// --out is a prefix for the single-file commands too: PREFIX.png.
TEST(HelpWalkTest, SingleFileOutputIsAPrefix) {
  EXPECT_EQ(PrefixedOutput("dir/pair", ".png"), "dir/pair.png");
  EXPECT_EQ(PrefixedOutput("dir/pair.png", ".png"), "dir/pair.png");  // the older spelling: the file itself
  EXPECT_EQ(PrefixedOutput("fix", ".json"), "fix.json");
  const fs::path dir = testing::MakeTempDir();
  const std::vector<float> a(16, 1.0f);
  geo::WriteFloatGeoTiff(dir / "a.tif", geo::FloatRaster{4, 4, {a}, {"total"}, {}});
  const Outcome o = RunGissar({"composite", "--green", (dir / "a.tif").string(), "--magenta",
                               (dir / "a.tif").string(), "--out", (dir / "pair").string(), "--quiet"});
  ASSERT_EQ(o.status, 0) << o.err;
  EXPECT_TRUE(fs::exists(dir / "pair.png"));
  EXPECT_EQ(o.out, (dir / "pair.png").string() + "\n");
}

}  // namespace
}  // namespace gissar::cli

#include "gissar/cli/headline.h"

namespace gissar::cli {
namespace {

// The headlines read the result JSON the commands write (the keys of
// pipeline/locate.cc, product_locate.cc, mvg_commands.cc, product_simulate.cc).
TEST(HeadlineTest, EachCommandStatesItsResultInOneLine) {
  const nlohmann::json fmatrix = {{"heading_change_deg", 29.996}, {"heading_change_candidates", {29.996, -29.996}},
                                  {"inliers", {0, 1, 2, 4}}, {"num_matches", 5}, {"rms_gs_px", 0.1234},
                                  {"kvd", {{"s", 1.0}, {"theta_deg", 23.2}, {"phi_deg", 11.6}}}};
  EXPECT_EQ(FmatrixHeadline(fmatrix),
            "fmatrix: heading change 30.00 deg (candidates 30.00, -30.00), 4 of 5 matches inliers, Gold Standard "
            "rms 0.123 px; KvD s 1.0000, theta 23.20 deg, phi 11.60 deg");
  const nlohmann::json locate = {{"converged", false},
                                 {"reason", "too few matches"},
                                 {"pose", {{"heading_deg", 30.0}, {"depression_deg", 40.0},
                                           {"sensor_enu_m", {3.0, 4.0, 0.0}}, {"sensor_lon_lat_h", {1.5, 42.5, 6000.0}}}},
                                 {"prior", {{"sensor_enu_m", {0.0, 0.0, 0.0}}}},
                                 {"inliers", 12}};
  EXPECT_EQ(LocateHeadline(locate),
            "locate: fix heading 30.000 deg, depression 40.000 deg, sensor lon 1.500000, lat 42.500000, h 6000.0 m; "
            "5.0 m from the prior, 12 inliers; not converged: too few matches");
  const nlohmann::json product_fix = {
      {"converged", true}, {"cell_m", 10.0},
      {"fix", {{"time_utc", "2018-10-11T22:46:39Z"},
               {"frame", {{"sensor_lon_lat_height", {-118.4, 34.05, 12495.0}}}},
               {"correction", {{"along_m", 40.0}, {"cross_m", -20.0}, {"up_m", 0.5}}},
               {"error_against_annotated_track", {{"position_error_m", 21.5}, {"prior_position_error_m", 67.1}}}}}};
  EXPECT_EQ(LocateHeadline(product_fix),
            "locate: fix sensor lon -118.400000, lat 34.050000, h 12495.0 m at 2018-10-11T22:46:39Z, correction "
            "along 40.0 m, cross -20.0 m, up 0.5 m; error against the annotated track 21.5 m (prior 67.1 m), 2.15 "
            "cells; converged");
  const nlohmann::json evaluate = {
      {"trials", 20}, {"success_rate", 0.95}, {"success_cells", 2.0},
      {"position_error_cells", {{"median", 0.6}, {"p95", 1.9}}}, {"position_error_m", {{"median", 13.2}}},
      {"covariance_check", {{"along_m", {{"error_mean", -17.0}, {"error_sd", 7.0}}},
                            {"cross_m", {{"error_mean", 2.0}, {"error_sd", 3.0}}}}},
      {"seconds_per_fix", {{"median", 0.5}}}};
  EXPECT_EQ(EvaluateHeadline(evaluate),
            "evaluate: 19 of 20 trials succeeded (95.0 %, <= 2.000 cells), median error 0.60 cells (13.2 m), p95 "
            "1.90 cells; bias along -17.0 m (sd 7.0), cross 2.0 m (sd 3.0); 0.50 s per fix");
  const nlohmann::json validate = {{"correlation", {{{"looks", 1}, {"r_db", 0.5}}, {{"looks", 3}, {"r_db", 0.71}}}},
                                   {"pixels_geolocated", 100}};
  EXPECT_EQ(ValidateHeadline(validate),
            "validate: simulated vs real dB correlation r 0.500 at 1x1 looks, r 0.710 at 3x3 looks; 100 pixels "
            "geolocated");
  EXPECT_EQ(GeocodeHeadline({{"width", 10}, {"height", 20}, {"pixel_size_m", 30.0}, {"crs", "EPSG:32631"},
                             {"valid_pixels", 150}}),
            "geocode: 10 x 20 px of 30.000 m in EPSG:32631, 150 pixels with a value");
  EXPECT_EQ(ResectHeadline({{"heading_deg", 30.0}, {"depression_deg", 40.0}, {"range_spacing_m", 1.0},
                            {"azimuth_spacing_m", 1.0}, {"rms_px", 0.0}, {"converged", true},
                            {"sigma", {{"heading_deg", 0.001}, {"depression_deg", 0.002}}}}),
            "resect: heading 30.000 +- 0.001 deg, depression 40.000 +- 0.002 deg, spacings 1.000 x 1.000 m (range x "
            "azimuth), rms 0.000 px");
}

}  // namespace
}  // namespace gissar::cli
