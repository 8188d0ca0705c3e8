// Scene build (GIS scene issue): DEM window + polygons -> triangulation with
// classes (the cells the polygons touch through the constrained Delaunay
// triangulation, the others split directly). Synthetic rolling terrain (10 m
// posts, local transverse Mercator) with N random polygons of the water,
// forest and urban classes; sizes 1024^2, 2048^2 and 4096^2 posts with
// 5,000 polygons. Reports wall time, triangles, posts/s and peak RSS.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/scene/gis_scene.h"
#include "gissar/util/progress.h"

namespace {
namespace fs = std::filesystem;
using namespace gissar;

const char* kLocalTm =
    "+proj=tmerc +lat_0=42.5 +lon_0=1.6 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
constexpr double kSpacing = 10.0;

fs::path WorkDir() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("gissar-bench-scene-" + std::to_string(getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

// DEM of n x n posts and a GeoJSON of `polygons` random polygons over it;
// written once per size.
std::pair<std::string, std::string> Inputs(int n, int polygons) {
  static std::map<std::pair<int, int>, std::pair<std::string, std::string>> cache;
  const auto key = std::make_pair(n, polygons);
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  const double half = n * kSpacing / 2;
  std::vector<float> heights(size_t(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c)
      heights[size_t(r) * n + c] = static_cast<float>(
          500 + 120 * std::sin(c * 0.013) * std::cos(r * 0.011) + 40 * std::sin((c + 2 * r) * 0.05));
  const fs::path dem = WorkDir() / ("dem_" + std::to_string(n) + ".tif");
  geo::WriteDemGeoTiff(dem, heights, n, n, {-half, kSpacing, 0, half, 0, -kSpacing}, kLocalTm);

  std::mt19937 rng(42);
  std::uniform_real_distribution<double> pos(-half * 0.95, half * 0.95), radius(20, 150), jitter(0.7, 1.0);
  const geo::CrsTransform tm(kLocalTm);
  const char* classes[] = {"water", "forest", "urban"};
  std::ostringstream json;
  json.precision(10);
  json << R"({"type":"FeatureCollection","features":[)";
  for (int i = 0; i < polygons; ++i) {
    const double cx = pos(rng), cy = pos(rng), rad = radius(rng);
    std::vector<double> x, y;
    for (int k = 0; k <= 8; ++k) {
      const double a = 2 * M_PI * (k % 8) / 8;
      const double s = k == 8 ? 1.0 : jitter(rng);
      x.push_back(cx + rad * s * std::cos(a));
      y.push_back(cy + rad * s * std::sin(a));
    }
    x.back() = x.front();
    y.back() = y.front();
    tm.ToLonLat(x, y);
    json << (i ? "," : "") << R"({"type":"Feature","properties":{"kind":")" << classes[i % 3]
         << R"("},"geometry":{"type":"Polygon","coordinates":[[)";
    for (size_t k = 0; k < x.size(); ++k) json << (k ? "," : "") << "[" << x[k] << "," << y[k] << "]";
    json << "]]}}";
  }
  json << "]}";
  const fs::path vectors = WorkDir() / ("polygons_" + std::to_string(n) + "_" + std::to_string(polygons) + ".geojson");
  std::ofstream(vectors) << json.str();
  return cache[key] = {dem.string(), vectors.string()};
}

void BM_SceneBuild(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const int polygons = static_cast<int>(state.range(1));
  const auto [dem_path, vectors] = Inputs(n, polygons);
  scene::SceneConfig config;
  for (const auto& [name, id] : {std::pair{"water", scene::kClassWater}, {"forest", scene::kClassForest},
                                 {"urban", scene::kClassUrban}}) {
    scene::LayerSpec spec;
    spec.source = {vectors, "", std::string("kind = '") + name + "'"};
    spec.class_id = id;
    config.layers.push_back(spec);
  }
  size_t triangles = 0;
  double cdt_share = 0.0;
  for (auto _ : state) {
    const geo::Dem dem = geo::ReadDem(dem_path);
    const geo::GeoPoint centre = geo::ResolveSceneCentre(dem, std::nullopt, std::nullopt);
    const scene::GisScene built =
        scene::BuildGisScene(dem, geo::LocalFrame(centre.lon_deg, centre.lat_deg), config);
    triangles = built.mesh.triangle_count();
    cdt_share = double(built.stats.cdt_cells) / (double(n - 1) * (n - 1));
    benchmark::DoNotOptimize(triangles);
  }
  state.counters["posts"] = double(n) * n;
  state.counters["polygons"] = polygons;
  state.counters["triangles"] = double(triangles);
  state.counters["cdt_cell_share"] = cdt_share;  // cells through the CDT (the rest split directly)
  state.counters["posts_per_s"] = benchmark::Counter(double(n) * n, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["peak_rss_MiB"] = double(PeakResidentBytes()) / 1048576.0;
}

BENCHMARK(BM_SceneBuild)
    ->Args({1024, 5000})
    ->Args({2048, 5000})
    ->Args({4096, 5000})
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
