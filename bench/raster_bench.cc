// Raster engine throughput (DEM cells per second after loading) on a DEM
// given by $GISSAR_BENCH_DEM (default: a 4096^2 fractal DEM written by
// scripts/bench.sh), and a STREAM-like memory bandwidth figure (triad
// a = b + s c over arrays far larger than the caches) from the same run.
#include <benchmark/benchmark.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstdlib>
#include <memory>
#include <vector>

#include "gissar/pipeline/simulate.h"
#include "gissar/render/raster_renderer.h"

namespace {
using namespace gissar;

struct Scene {
  pipeline::Terrain terrain;
  int width = 0, height = 0;
  std::unique_ptr<sensor::SarGeometry> geometry;
};

const Scene& LoadedScene() {
  static const Scene scene = [] {
    Scene s;
    pipeline::SimulateRequest o;
    const char* dem = std::getenv("GISSAR_BENCH_DEM");
    o.dem = dem != nullptr ? dem : "fractal_4096.tif";
    o.out_prefix = "unused";
    o.geometry.heading_deg = 30.0;
    o.geometry.depression_deg = 40.0;
    o.geometry.slant_range_m = 20000.0;
    s.terrain = pipeline::LoadTerrain(o);
    s.width = s.terrain.description["width"].get<int>();
    s.height = s.terrain.description["height"].get<int>();
    s.geometry = std::make_unique<sensor::SarGeometry>(sensor::SarGeometry::Covering(
        pipeline::ResolvedGeometry(o, s.terrain), s.terrain.centre_enu, s.terrain.mesh.vertices));
    return s;
  }();
  return scene;
}

void BM_RasterCells(benchmark::State& state) {
  const Scene& s = LoadedScene();
  for (auto _ : state) {
    render::SarImage image =
        render::RenderSarRaster(s.terrain.mesh.vertices, s.width, s.height, s.terrain.materials, *s.geometry);
    benchmark::DoNotOptimize(image.intensity.data());
  }
  const double cells = double(s.width - 1) * (s.height - 1);
  state.counters["cells"] = cells;
  state.counters["cells_per_s"] = benchmark::Counter(cells, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["image_pixels"] = double(s.geometry->width()) * s.geometry->height();
}
BENCHMARK(BM_RasterCells)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

// STREAM triad on 3 x 256 MiB arrays, on all threads (TBB, like the raster
// engine): bytes moved per second (2 reads and 1 write per element;
// write-allocate traffic not counted, as in STREAM).
void BM_StreamTriad(benchmark::State& state) {
  const size_t n = size_t(32) << 20;  // 32 Mi doubles = 256 MiB per array
  static std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  const size_t m = a.size();
  for (auto _ : state) {
    double* pa = a.data();
    const double* pb = b.data();
    const double* pc = c.data();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) pa[i] = pb[i] + 3.0 * pc[i];
    });
    benchmark::ClobberMemory();
  }
  state.counters["bytes_per_s"] =
      benchmark::Counter(3.0 * sizeof(double) * m, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_StreamTriad)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
