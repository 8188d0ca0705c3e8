// Driver of the bad-input catalogue (tests/bad_inputs/README.md): runs one
// case file against the real `gissar` binary, or checks the catalogue as a
// whole.
//
//   bad_inputs_driver --gissar BIN --case FILE.case [--help-cache DIR]
//   bad_inputs_driver --gissar BIN --catalogue CASES_DIR
//   bad_inputs_driver --catalogue CASES_DIR --export-seeds DIR   (fuzz seeds)
//
// A case passes when the command, given the case's inputs (generated here,
// never committed binaries), exits with the expected status (2 unless the
// case says otherwise) within the time limit, and
//  - for status 2: stderr is exactly one line starting "gissar: error: " that
//    contains every `error:` substring of the case, stdout is empty;
//  - for status 0: every stderr line starts "gissar: warning: " and contains
//    the case's `warning:` substrings, and every `output:` file exists;
//  - for status 3 (no result): the last stderr line starts "gissar: no result: "
//    and contains every `error:` substring, the others are warnings, every
//    `output:` file exists, and each `.json` output says "converged": false
//    with a non-empty "reason";
//  - in both: the case's input files are unchanged and no file appeared
//    beside them; for status 2 the output directories stay empty.
// A case whose command `gissar --help` does not list fails: nothing is
// skipped. Exit status 0 = pass, 1 = fail (the reasons on stderr).
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "gissar/geo/dem.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/scene/scene_io.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/testing.h"

namespace {
namespace fs = std::filesystem;

// ------------------------------------------------------------------ cases

struct Case {
  fs::path file;
  std::string name;
  std::vector<std::string> description;  // leading comment lines
  std::string run;                       // command line with {placeholders}
  int status = 2;
  std::vector<std::string> errors;    // substrings of the error line
  std::vector<std::string> warnings;  // substrings of the warning lines (status 0)
  std::vector<std::string> outputs;   // files expected in {out} (status 0)
  std::map<std::string, std::string> files;  // inline text inputs
};

[[noreturn]] void Die(const std::string& message) {
  std::cerr << "bad_inputs_driver: " << message << "\n";
  std::exit(1);
}

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

Case ParseCase(const fs::path& path) {
  std::ifstream in(path);
  if (!in) Die("cannot read case " + path.string());
  Case c;
  c.file = path;
  c.name = path.stem().string();
  std::string line;
  int number = 0;
  bool in_header = true;
  while (std::getline(in, line)) {
    ++number;
    const std::string where = path.filename().string() + ":" + std::to_string(number);
    if (line.empty() || line[0] == '#') {
      if (in_header && !line.empty()) c.description.push_back(Trim(line.substr(1)));
      continue;
    }
    in_header = false;
    const size_t colon = line.find(':');
    if (colon == std::string::npos) Die(where + ": expected 'key: value'");
    const std::string key = Trim(line.substr(0, colon));
    const std::string value = Trim(line.substr(colon + 1));
    if (key == "run") {
      if (!c.run.empty()) Die(where + ": a case has one 'run' line");
      c.run = value;
    } else if (key == "status") {
      c.status = std::atoi(value.c_str());
      if (c.status != 0 && c.status != 2 && c.status != 3) Die(where + ": status is 0, 2 or 3");
    } else if (key == "error") {
      c.errors.push_back(value);
    } else if (key == "warning") {
      c.warnings.push_back(value);
    } else if (key == "output") {
      c.outputs.push_back(value);
    } else if (key == "file") {
      std::string text, body;
      bool closed = false;
      while (std::getline(in, body)) {
        ++number;
        if (body == "end") {
          closed = true;
          break;
        }
        text += body + "\n";
      }
      if (!closed) Die(where + ": 'file: " + value + "' has no closing 'end' line");
      c.files[value] = text;
    } else {
      Die(where + ": unknown key '" + key + "'");
    }
  }
  if (c.run.empty()) Die(path.string() + ": no 'run' line");
  if (c.description.empty()) Die(path.string() + ": starts with no '#' line saying what it covers");
  if (c.status == 2 && c.errors.empty()) Die(path.string() + ": an error case needs 'error:' lines");
  if (c.status == 3 && (c.errors.empty() || c.outputs.empty())) {
    Die(path.string() + ": a no-result case needs 'error:' lines (the reason) and its 'output:' result file");
  }
  return c;
}

std::vector<std::string> SplitArgs(const std::string& text) {
  std::vector<std::string> args;
  std::string current;
  bool quoted = false, any = false;
  for (char ch : text) {
    if (ch == '\'') {
      quoted = !quoted;
      any = true;
    } else if (!quoted && (ch == ' ' || ch == '\t')) {
      if (any) args.push_back(current);
      current.clear();
      any = false;
    } else {
      current += ch;
      any = true;
    }
  }
  if (quoted) Die("unbalanced quote in: " + text);
  if (any) args.push_back(current);
  return args;
}

// Names of the {placeholders} in `text`: braces around a name of letters,
// digits, '_', '-' and '.' (other braces, as in JSON, are left alone).
std::vector<std::string> Placeholders(const std::string& text) {
  std::vector<std::string> names;
  size_t pos = 0;
  while ((pos = text.find('{', pos)) != std::string::npos) {
    size_t end = pos + 1;
    while (end < text.size() && (std::isalnum(static_cast<unsigned char>(text[end])) ||
                                 text[end] == '_' || text[end] == '-' || text[end] == '.')) {
      ++end;
    }
    if (end < text.size() && text[end] == '}' && end > pos + 1) {
      names.push_back(text.substr(pos + 1, end - pos - 1));
    }
    pos = end;
  }
  return names;
}

// ------------------------------------------------------------------ fixtures

// The fixture DEMs' heights are EGM96 (compound CRS, as SRTM): a DEM naming no
// vertical datum prints a warning, which an error case's one stderr line
// leaves no room for (simulate_dem_without_vertical_datum.case covers it).
const char* kUtm31 = "EPSG:32631+5773";
const char* kWgs84 = "EPSG:4326+5773";

std::vector<float> Hill(int w, int h) {
  std::vector<float> z(size_t(w) * h);
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const double dx = c - w / 2.0, dy = r - h / 2.0;
      z[size_t(r) * w + c] = static_cast<float>(1200.0 + 150.0 * std::exp(-(dx * dx + dy * dy) / 60.0));
    }
  }
  return z;
}

void WriteUtmDem(const fs::path& path, std::vector<float> z, int w, int h, double nodata = NAN) {
  gissar::geo::WriteDemGeoTiff(path, z, w, h, {380000.0, 30.0, 0.0, 4710000.0, 0.0, -30.0}, kUtm31,
                               nodata);
}

void WriteBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) Die("cannot write " + path.string());
}

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A valid 3x3-post scene (8 triangles) in a frame at (1.5 E, 42.5 N).
gissar::scene::SceneFile SmallScene() {
  gissar::scene::SceneFile scene;
  std::vector<Eigen::Vector3f> posts;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) posts.emplace_back(100.0f * (c - 1), 100.0f * (1 - r), 10.0f * c);
  }
  scene.mesh = gissar::scene::MeshFromGrid(posts, 3, 3);
  scene.origin_lon_deg = 1.5;
  scene.origin_lat_deg = 42.5;
  scene.centre_lon_deg = 1.5;
  scene.centre_lat_deg = 42.5;
  scene.centre_height_m = 10.0;
  scene.centre_enu = Eigen::Vector3d(0, 0, 10);
  scene.class_names = {"default", "water", "forest", "urban", "road", "building"};
  scene.provenance = {{"post_spacing_m", 100.0}};
  return scene;
}

// Writes the built-in input `name` into `dir`; false when there is none.
// Generic names: empty.EXT (0 bytes), random.EXT (4096 seeded random bytes).
bool MakeFixture(const std::string& name, const fs::path& dir) {
  const fs::path path = dir / name;
  const std::string stem = fs::path(name).stem().string();
  if (stem == "empty") {
    WriteBytes(path, "");
  } else if (stem == "random") {
    std::mt19937 rng(20261123);
    std::string bytes(4096, '\0');
    for (char& b : bytes) b = static_cast<char>(rng() & 0xff);
    WriteBytes(path, bytes);
  } else if (name == "dem.tif") {
    WriteUtmDem(path, Hill(32, 32), 32, 32);
  } else if (name == "product_no_orbit.h5") {
    // A NISAR-layout RSLC (4 lines x 3 bins) without its orbit group.
    gissar::geo::RslcProduct p;
    p.epoch_utc = "2020-01-02 03:04:05";
    p.zero_doppler_time_s = {10.0, 10.5, 11.0, 11.5};
    p.slant_range_m = {1000.0, 1002.0, 1004.0};
    p.center_frequency_hz = 1.243e9;
    p.look_left = true;
    p.amplitude.assign(12, 1.0f);
    gissar::geo::WriteRslcProduct(path, p);
  } else if (name == "product_libhdf5_crash.h5") {
    // A corrupt RSLC on which libhdf5 1.10.8 itself reads through a null
    // pointer (tests/data/hostile_hdf5, a fuzzer finding).
    WriteBytes(path, ReadBytes(gissar::testing::TestDataPath("hostile_hdf5/libhdf5_local_heap_segv.h5")));
  } else if (name == "dem_geo.tif") {
    gissar::geo::WriteDemGeoTiff(path, Hill(32, 32), 32, 32,
                                 {1.5, 1.0 / 1200, 0.0, 42.5, 0.0, -1.0 / 1200}, kWgs84);
  } else if (name == "dem_truncated.tif") {
    WriteUtmDem(dir / ".whole.tif", Hill(96, 96), 96, 96);
    const std::string whole = ReadBytes(dir / ".whole.tif");
    fs::remove(dir / ".whole.tif");
    WriteBytes(path, whole.substr(0, whole.size() * 6 / 10));
  } else if (name == "dem_header_only.tif") {
    WriteUtmDem(dir / ".whole.tif", Hill(96, 96), 96, 96);
    const std::string whole = ReadBytes(dir / ".whole.tif");
    fs::remove(dir / ".whole.tif");
    WriteBytes(path, whole.substr(0, 200));
  } else if (name == "dem_nan.tif") {
    std::vector<float> z = Hill(32, 32);
    z[5] = z[300] = z[1000] = std::numeric_limits<float>::quiet_NaN();
    WriteUtmDem(path, z, 32, 32);
  } else if (name == "dem_inf.tif") {
    std::vector<float> z = Hill(32, 32);
    // Inside the grid: no-data on the border would be left out of the scene.
    z[300] = std::numeric_limits<float>::infinity();
    z[301] = -std::numeric_limits<float>::infinity();
    WriteUtmDem(path, z, 32, 32);
  } else if (name == "dem_all_nodata.tif") {
    WriteUtmDem(path, std::vector<float>(32 * 32, -9999.0f), 32, 32, -9999.0);
  } else if (name == "dem_unmarked_nodata.tif") {
    std::vector<float> z = Hill(32, 32);
    for (int i = 100; i < 140; ++i) z[i] = -3.4028235e38f;
    WriteUtmDem(path, z, 32, 32);
  } else if (name == "dem_1x1.tif") {
    WriteUtmDem(path, {1200.0f}, 1, 1);
  } else if (name == "dem_1x40.tif") {
    WriteUtmDem(path, std::vector<float>(40, 1200.0f), 1, 40);
  } else if (name == "dem_pole.tif") {
    // Posts from 89.2 to 89.8 degrees north.
    gissar::geo::WriteDemGeoTiff(path, Hill(32, 32), 32, 32, {0.0, 0.02, 0.0, 89.81, 0.0, -0.02},
                                 kWgs84);
  } else if (name == "dem_beyond_pole.tif") {
    gissar::geo::WriteDemGeoTiff(path, Hill(32, 32), 32, 32, {0.0, 0.1, 0.0, 91.0, 0.0, -0.1},
                                 kWgs84);
  } else if (name == "dem_antimeridian.tif") {
    // Longitudes 179.95 .. 180.05.
    gissar::geo::WriteDemGeoTiff(path, Hill(32, 32), 32, 32,
                                 {179.95, 0.1 / 32, 0.0, 42.5, 0.0, -0.1 / 32}, kWgs84);
  } else if (name == "dem_65535_bands.tif") {
    // Fuzzer finding (fuzz_dem): 162 bytes declaring 1024 x 4 cells of
    // 65535 pixel-interleaved float bands; GDAL reads a block of all bands
    // at once (256 MiB). A hand-made classic TIFF: header, then one IFD.
    const uint16_t kShort = 3, kLong = 4;
    const std::vector<std::array<uint32_t, 4>> entries = {
        {256, kShort, 1, 1024}, {257, kShort, 1, 4},     {258, kShort, 1, 32},
        {259, kShort, 1, 1},    {262, kShort, 1, 1},     {273, kLong, 1, 8 + 2 + 11 * 12 + 4},
        {277, kShort, 1, 65535}, {278, kShort, 1, 4},    {279, kLong, 1, 16},
        {284, kShort, 1, 1},    {339, kShort, 1, 3}};
    std::string bytes = "II*";
    bytes += '\0';
    auto put = [&bytes](uint32_t value, int size) {
      for (int i = 0; i < size; ++i) bytes += static_cast<char>((value >> (8 * i)) & 0xff);
    };
    put(8, 4);
    put(static_cast<uint32_t>(entries.size()), 2);
    for (const auto& [tag, type, count, value] : entries) {
      put(tag, 2);
      put(type, 2);
      put(count, 4);
      put(value, 4);  // a SHORT value sits in the first 2 of the 4 bytes
    }
    put(0, 4);
    bytes += std::string(16, '\0');
    WriteBytes(path, bytes);
  } else if (name == "image_flat64.tif") {
    // Featureless: nothing for `locate` to match (a no-result, not a bad input).
    gissar::geo::FloatRaster raster;
    raster.width = raster.height = 64;
    raster.bands = {std::vector<float>(64 * 64, 0.1f)};
    raster.band_names = {"total"};
    gissar::geo::WriteFloatGeoTiff(path, raster);
  } else if (name == "image.tif") {
    gissar::geo::FloatRaster raster;
    raster.width = raster.height = 16;
    raster.bands = {std::vector<float>(256, 0.5f)};
    raster.band_names = {"total"};
    gissar::geo::WriteFloatGeoTiff(path, raster);
  } else if (name == "scene.gscene") {
    gissar::scene::WriteScene(path, SmallScene());
  } else if (name == "scene_truncated.gscene" || name == "scene_v9.gscene" ||
             name == "scene_bad_end.gscene" || name == "scene_bad_index.gscene" ||
             name == "scene_nan_vertex.gscene" || name == "scene_huge_count.gscene" ||
             name == "scene_bad_header.gscene" || name == "scene_bad_class.gscene") {
    gissar::scene::SceneFile scene = SmallScene();
    if (name == "scene_bad_index.gscene") scene.mesh.triangles[3] = Eigen::Vector3i(0, 1, 9);
    if (name == "scene_nan_vertex.gscene") scene.mesh.vertices[4].z() = NAN;
    if (name == "scene_bad_class.gscene") scene.mesh.classes[2] = 9;
    gissar::scene::WriteScene(dir / ".whole.gscene", scene);
    std::string bytes = ReadBytes(dir / ".whole.gscene");
    fs::remove(dir / ".whole.gscene");
    uint64_t json_bytes = 0;  // memcpy: the field is not 8-byte aligned in the buffer
    std::memcpy(&json_bytes, bytes.data() + 12, sizeof(json_bytes));
    const size_t counts = 20 + json_bytes;  // vertex count, then triangle count
    if (name == "scene_truncated.gscene") bytes.resize(bytes.size() * 2 / 3);
    if (name == "scene_v9.gscene") bytes[8] = 9;
    if (name == "scene_bad_end.gscene") bytes[bytes.size() - 1] = 'X';
    if (name == "scene_huge_count.gscene") {
      const uint64_t huge = uint64_t{1} << 62;
      std::memcpy(bytes.data() + counts + 8, &huge, sizeof(huge));
    }
    if (name == "scene_bad_header.gscene") bytes[20] = '[';
    WriteBytes(path, bytes);
  } else {
    return false;
  }
  return true;
}

// ------------------------------------------------------------------ running

struct Outcome {
  int status = -1;        // exit status, or -1
  int signal = 0;         // terminating signal, or 0
  bool timed_out = false;
  std::string out, err;
  double seconds = 0.0;
};

// Runs `args` (args[0] = binary) with stdout/stderr captured; kills it after
// `timeout_s`. `unprivileged`: drop to uid/gid 65534 first (when root), so
// that directory permissions apply.
Outcome Run(const std::vector<std::string>& args, const fs::path& capture_dir, double timeout_s,
            bool unprivileged) {
  const fs::path out_path = capture_dir / "stdout", err_path = capture_dir / "stderr";
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) Die("fork failed");
  if (pid == 0) {
    const int out_fd = open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err_fd = open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int null_fd = open("/dev/null", O_RDONLY);
    if (out_fd < 0 || err_fd < 0 || null_fd < 0) _exit(120);
    dup2(null_fd, 0);
    dup2(out_fd, 1);
    dup2(err_fd, 2);
    if (unprivileged && geteuid() == 0) {
      if (setgid(65534) != 0 || setuid(65534) != 0) _exit(121);
    }
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(122);
  }
  Outcome o;
  int raw = 0;
  while (true) {
    const pid_t done = waitpid(pid, &raw, WNOHANG);
    if (done == pid) break;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (elapsed > timeout_s) {
      kill(pid, SIGKILL);
      waitpid(pid, &raw, 0);
      o.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (WIFEXITED(raw)) o.status = WEXITSTATUS(raw);
  if (WIFSIGNALED(raw)) o.signal = WTERMSIG(raw);
  o.out = ReadBytes(out_path);
  o.err = ReadBytes(err_path);
  if (o.status == 121 || o.status == 122) {
    // The child never reached the binary: say why instead of a bare status.
    o.err += std::string("bad_inputs driver: could not ") +
             (o.status == 121 ? "drop to uid/gid 65534" : "execute " + args[0]) +
             (unprivileged ? " as uid 65534 (every directory above the build tree must be "
                             "world-searchable, e.g. chmod 0755 on a mktemp directory)\n"
                           : "\n");
  }
  return o;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

// Subcommands listed in the "Subcommands:" section of `help`.
std::set<std::string> ListedSubcommands(const std::string& help) {
  std::set<std::string> names;
  bool in_section = false;
  for (const std::string& line : Lines(help)) {
    if (line.rfind("Subcommands:", 0) == 0) {
      in_section = true;
    } else if (in_section) {
      if (line.empty() || line[0] != ' ') {
        in_section = false;
        continue;
      }
      std::istringstream words(line);
      std::string name;
      if (words >> name) names.insert(name);
    }
  }
  return names;
}

// `--help-cache DIR`: help texts shared by the cases of one build (each case
// otherwise starts the binary once more per command level just to read its
// help; under the sanitizers that start-up is most of a case's time). Keyed
// by the binary's path, size and modification time, so a rebuilt binary is
// asked again; written to a temporary name and renamed (cases run in
// parallel). Without it, or when the cache cannot be written, the help is
// simply run.
fs::path g_help_cache;

std::string HelpText(const std::vector<std::string>& with_help, const fs::path& capture_dir) {
  fs::path cached;
  if (!g_help_cache.empty()) {
    struct stat st {};
    if (stat(with_help[0].c_str(), &st) == 0) {
      std::string key = with_help[0] + "|" + std::to_string(st.st_size) + "|" +
                        std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
      for (const std::string& a : with_help) key += "|" + a;
      std::ostringstream name;
      name << "help-" << std::hex << std::hash<std::string>{}(key) << ".txt";
      cached = g_help_cache / name.str();
      std::ifstream in(cached, std::ios::binary);
      if (in) return std::string(std::istreambuf_iterator<char>(in), {});
    }
  }
  const Outcome help = Run(with_help, capture_dir, 60.0, false);
  if (!cached.empty() && help.status == 0 && !help.timed_out) {
    std::error_code ec;
    fs::create_directories(g_help_cache, ec);
    const fs::path tmp = cached.string() + ".tmp." + std::to_string(getpid());
    {
      std::ofstream out(tmp, std::ios::binary);
      out << help.out;
    }
    fs::rename(tmp, cached, ec);
    if (ec) fs::remove(tmp, ec);
  }
  return help.out;
}

// The command path of `args` (e.g. {"scene", "build"}), checked against the
// help of the binary; returns an error message, or "" when listed.
std::string CheckCommandListed(const std::string& gissar, const std::vector<std::string>& args,
                               const fs::path& capture_dir, std::vector<std::string>* path) {
  static std::map<std::vector<std::string>, std::set<std::string>> cache;
  std::vector<std::string> help_args = {gissar};
  for (size_t i = 0; i < args.size(); ++i) {
    if (!cache.count(help_args)) {
      std::vector<std::string> with_help = help_args;
      with_help.push_back("--help");
      cache[help_args] = ListedSubcommands(HelpText(with_help, capture_dir));
    }
    const std::set<std::string> listed = cache[help_args];
    if (listed.empty()) return "";  // a leaf command: the rest are its arguments
    if (!listed.count(args[i])) {
      std::string joined;
      for (size_t k = 1; k < help_args.size(); ++k) joined += help_args[k] + " ";
      return "command '" + joined + args[i] + "' is not listed by `gissar " + joined + "--help`";
    }
    help_args.push_back(args[i]);
    path->push_back(args[i]);
  }
  return "";
}

std::map<std::string, std::string> Snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    const std::string rel = fs::relative(entry.path(), dir).string();
    files[rel] = entry.is_regular_file() ? ReadBytes(entry.path()) : std::string("<dir>");
  }
  return files;
}

std::vector<std::string> Entries(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) names.push_back(entry.path().filename().string());
  return names;
}

std::string Replace(std::string text, const std::map<std::string, std::string>& values) {
  for (const auto& [name, value] : values) {
    const std::string key = "{" + name + "}";
    size_t pos = 0;
    while ((pos = text.find(key, pos)) != std::string::npos) {
      text.replace(pos, key.size(), value);
      pos += value.size();
    }
  }
  return text;
}

double TimeoutSeconds() {
  const char* env = std::getenv("GISSAR_CASE_TIMEOUT");
  return env != nullptr && std::atof(env) > 0 ? std::atof(env) : 120.0;
}

int RunCase(const std::string& gissar, const fs::path& case_file) {
  const Case c = ParseCase(case_file);
  char pattern[] = "/tmp/gissar-bad-input-XXXXXX";
  if (mkdtemp(pattern) == nullptr) Die("mkdtemp failed");
  const fs::path root = pattern;
  const fs::path work = root / "work", out = root / "out", capture = root / "capture";
  fs::create_directories(work);
  fs::create_directories(out);
  fs::create_directories(capture);
  // Readable by the unprivileged user of {readonly} cases.
  for (const fs::path& d : {root, work, out}) fs::permissions(d, fs::perms(0755));

  std::map<std::string, std::string> values = {{"out", out.string()}, {"work", work.string()},
                                               {"missing", (work / "missing-dir").string()}};
  bool unprivileged = false;
  std::vector<std::string> failures;
  std::vector<std::string> used = Placeholders(c.run);
  for (const auto& [name, text] : c.files) {
    for (const std::string& inner : Placeholders(text)) used.push_back(inner);
  }
  for (const auto& [name, text] : c.files) values[name] = (work / name).string();
  for (const std::string& name : used) {
    if (values.count(name)) continue;
    if (name == "readonly") {
      const fs::path ro = root / "readonly";
      fs::create_directories(ro);
      fs::permissions(ro, fs::perms(0555));
      values[name] = ro.string();
      unprivileged = true;
    } else if (MakeFixture(name, work)) {
      values[name] = (work / name).string();
    } else {
      Die(case_file.string() + ": no inline file or built-in input named {" + name + "}");
    }
  }
  for (const auto& [name, text] : c.files) {
    fs::create_directories((work / name).parent_path());
    WriteBytes(work / name, Replace(text, values));
  }

  std::vector<std::string> args = SplitArgs(Replace(c.run, values));
  if (args.empty()) Die(case_file.string() + ": empty command");
  std::vector<std::string> command;
  const std::string unlisted = CheckCommandListed(gissar, args, capture, &command);
  if (!unlisted.empty()) failures.push_back(unlisted);

  const auto before = Snapshot(work);
  args.insert(args.begin(), gissar);
  const Outcome o = failures.empty() ? Run(args, capture, TimeoutSeconds(), unprivileged) : Outcome{};
  const std::vector<std::string> err_lines = Lines(o.err);
  if (failures.empty()) {
    if (o.timed_out) failures.push_back("timed out after " + std::to_string(o.seconds) + " s (a hang)");
    if (o.signal != 0) failures.push_back("killed by signal " + std::to_string(o.signal) + " (a crash)");
    if (o.status != c.status) {
      failures.push_back("exit status " + std::to_string(o.status) + ", expected " + std::to_string(c.status));
    }
    if (c.status == 2) {
      if (err_lines.size() != 1) {
        failures.push_back("stderr has " + std::to_string(err_lines.size()) + " lines, expected 1");
      }
      const std::string first = err_lines.empty() ? "" : err_lines[0];
      if (first.rfind("gissar: error: ", 0) != 0) failures.push_back("stderr does not start with 'gissar: error: '");
      for (const std::string& e : c.errors) {
        const std::string want = Replace(e, values);
        if (first.find(want) == std::string::npos) failures.push_back("error line lacks '" + want + "'");
      }
      if (!o.out.empty()) failures.push_back("stdout is not empty");
      for (const fs::path& dir : {out, root / "readonly"}) {
        for (const std::string& name : Entries(dir)) failures.push_back("left behind: " + (dir / name).string());
      }
      if (fs::exists(work / "missing-dir")) failures.push_back("created the missing directory");
    } else {
      const bool no_result = c.status == 3;
      for (size_t i = 0; i < err_lines.size(); ++i) {
        const std::string& line = err_lines[i];
        if (no_result && i + 1 == err_lines.size()) continue;
        if (line.rfind("gissar: warning: ", 0) != 0) failures.push_back("stderr line is not a warning: " + line);
      }
      if (no_result) {
        const std::string last = err_lines.empty() ? "" : err_lines.back();
        if (last.rfind("gissar: no result: ", 0) != 0) {
          failures.push_back("the last stderr line does not start with 'gissar: no result: '");
        }
        for (const std::string& e : c.errors) {
          const std::string want = Replace(e, values);
          if (last.find(want) == std::string::npos) failures.push_back("no-result line lacks '" + want + "'");
        }
        for (const std::string& name : c.outputs) {
          if (fs::path(name).extension() != ".json" || !fs::is_regular_file(out / name)) continue;
          const std::string text = ReadBytes(out / name);
          if (text.find("\"converged\": false") == std::string::npos) {
            failures.push_back(name + " does not say \"converged\": false");
          }
          if (text.find("\"reason\": \"") == std::string::npos || text.find("\"reason\": \"\"") != std::string::npos) {
            failures.push_back(name + " gives no reason");
          }
        }
      }
      for (const std::string& w : c.warnings) {
        if (o.err.find(Replace(w, values)) == std::string::npos) failures.push_back("no warning with '" + w + "'");
      }
      for (const std::string& name : c.outputs) {
        if (!fs::is_regular_file(out / name)) failures.push_back("missing output " + name);
      }
      for (const std::string& name : Entries(out)) {
        if (!name.empty() && name[0] == '.') failures.push_back("temporary left behind: " + name);
      }
    }
    const auto after = Snapshot(work);
    for (const auto& [name, bytes] : before) {
      auto it = after.find(name);
      if (it == after.end()) failures.push_back("input removed: " + name);
      else if (it->second != bytes) failures.push_back("input modified: " + name);
    }
    for (const auto& [name, bytes] : after) {
      if (!before.count(name)) failures.push_back("file appeared beside the inputs: " + name);
    }
  }

  std::cout << "case " << c.name << ": " << (c.description.empty() ? "" : c.description[0]) << "\n"
            << "  run: " << c.run << "\n  status " << o.status << " in " << o.seconds << " s\n";
  for (const std::string& line : err_lines) std::cout << "  stderr: " << line << "\n";
  std::error_code ec;
  fs::permissions(root / "readonly", fs::perms(0755), ec);
  if (failures.empty()) {
    fs::remove_all(root, ec);
    std::cout << "PASS\n";
    return 0;
  }
  for (const std::string& f : failures) std::cout << "  FAIL: " << f << "\n";
  std::cout << "  (inputs kept in " << work.string() << ")\n";
  return 1;
}

// Every built-in input, for --export-seeds.
const char* kFixtureNames[] = {
    "empty.tif", "random.tif", "empty.gscene", "random.gscene", "empty.csv", "random.csv",
    "empty.json", "random.json", "dem.tif", "dem_geo.tif", "dem_truncated.tif",
    "dem_header_only.tif", "dem_nan.tif", "dem_inf.tif", "dem_all_nodata.tif",
    "dem_unmarked_nodata.tif", "dem_1x1.tif", "dem_1x40.tif", "dem_pole.tif",
    "dem_beyond_pole.tif", "dem_antimeridian.tif", "scene.gscene", "scene_truncated.gscene",
    "scene_v9.gscene", "scene_bad_end.gscene", "scene_bad_index.gscene",
    "scene_nan_vertex.gscene", "scene_huge_count.gscene", "scene_bad_header.gscene",
    "scene_bad_class.gscene", "dem_65535_bands.tif", "image_flat64.tif"};

// Seed corpora of the fuzzers (fuzz/): the built-in inputs and the inline
// files of every case, sorted by the reader they feed: DIR/dem (.tif, .vrt,
// .asc), DIR/scene_file (.gscene), DIR/scene_config (.json), DIR/points_csv
// (.csv).
int ExportSeeds(const fs::path& cases_dir, const fs::path& out_dir) {
  const std::map<std::string, std::string> kind_of = {
      {".tif", "dem"}, {".vrt", "dem"}, {".asc", "dem"}, {".gscene", "scene_file"},
      {".json", "scene_config"}, {".csv", "points_csv"}};
  for (const auto& [ext, kind] : kind_of) fs::create_directories(out_dir / kind);
  int written = 0;
  auto place = [&](const std::string& name, const std::string& bytes) {
    auto it = kind_of.find(fs::path(name).extension().string());
    if (it == kind_of.end()) return;
    WriteBytes(out_dir / it->second / name, bytes);
    ++written;
  };
  const fs::path scratch = out_dir / ".scratch";
  fs::create_directories(scratch);
  for (const char* name : kFixtureNames) {
    if (!MakeFixture(name, scratch)) Die(std::string("no fixture ") + name);
    place(std::string("fixture_") + name, ReadBytes(scratch / name));
  }
  fs::remove_all(scratch);
  for (const auto& entry : fs::directory_iterator(cases_dir)) {
    if (entry.path().extension() != ".case") continue;
    const Case c = ParseCase(entry.path());
    for (const auto& [name, text] : c.files) place(c.name + "_" + name, text);
  }
  std::cout << written << " seeds in " << out_dir.string() << "\n";
  return 0;
}

// The catalogue as a whole: at least 40 error cases, every case parses, and
// every command `gissar --help` lists has at least one error case.
int CheckCatalogue(const std::string& gissar, const fs::path& dir) {
  std::vector<std::string> failures;
  int error_cases = 0, accepted_cases = 0;
  std::map<std::string, int> per_command;
  char pattern[] = "/tmp/gissar-bad-input-XXXXXX";
  if (mkdtemp(pattern) == nullptr) Die("mkdtemp failed");
  const fs::path capture = pattern;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".case") continue;
    const Case c = ParseCase(entry.path());
    (c.status == 2 ? error_cases : accepted_cases)++;
    std::vector<std::string> args = SplitArgs(c.run), command;
    const std::string unlisted = CheckCommandListed(gissar, args, capture, &command);
    if (!unlisted.empty()) failures.push_back(entry.path().filename().string() + ": " + unlisted);
    std::string joined;
    for (const std::string& w : command) joined += (joined.empty() ? "" : " ") + w;
    if (c.status == 2) per_command[joined]++;
  }
  // Every command the binary lists (one level of nesting: `scene build`).
  const Outcome top = Run({gissar, "--help"}, capture, 60.0, false);
  for (const std::string& name : ListedSubcommands(top.out)) {
    const Outcome sub = Run({gissar, name, "--help"}, capture, 60.0, false);
    const std::set<std::string> children = ListedSubcommands(sub.out);
    if (children.empty()) {
      if (!per_command.count(name)) failures.push_back("command '" + name + "' has no error case");
    }
    for (const std::string& child : children) {
      if (!per_command.count(name + " " + child)) {
        failures.push_back("command '" + name + " " + child + "' has no error case");
      }
    }
  }
  if (error_cases < 40) failures.push_back("only " + std::to_string(error_cases) + " error cases, want >= 40");
  fs::remove_all(capture);
  std::cout << error_cases << " error cases, " << accepted_cases << " accepted-input cases\n";
  for (const auto& [command, n] : per_command) std::cout << "  " << command << ": " << n << "\n";
  for (const std::string& f : failures) std::cout << "FAIL: " << f << "\n";
  return failures.empty() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  std::string gissar, case_file, catalogue, seeds;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--gissar") gissar = argv[i + 1];
    else if (flag == "--case") case_file = argv[i + 1];
    else if (flag == "--catalogue") catalogue = argv[i + 1];
    else if (flag == "--export-seeds") seeds = argv[i + 1];
    else if (flag == "--help-cache") g_help_cache = argv[i + 1];
    else Die("unknown flag " + flag);
  }
  if (!seeds.empty() && !catalogue.empty()) return ExportSeeds(catalogue, seeds);
  if (gissar.empty() || case_file.empty() == catalogue.empty()) {
    Die("usage: bad_inputs_driver --gissar BIN (--case FILE.case | --catalogue DIR)");
  }
  return case_file.empty() ? CheckCatalogue(gissar, catalogue) : RunCase(gissar, case_file);
}
