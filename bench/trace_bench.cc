// Ray tracer throughput against its limit on a DEM given by
// $GISSAR_BENCH_DEM (scripts/bench.sh passes each fractal DEM), in the
// geometry of `gissar simulate --heading 30 --depression 40 --slant-range 20000`
// with $GISSAR_BENCH_RAYS_PER_CELL (default 4) rays per cell:
//   BM_RawEmbreeStream: the primary rays of the tracer, intersected 16 at a
//     time (rtcIntersect16, coherent flag) and nothing else: the limit;
//   BM_TracerPrimary: RenderSar with one bounce, timed over its tracing
//     phase (ray generation, intersection, shading, splatting, merging the
//     image bands; not the layover/shadow mask, which is not primary rays);
//   BM_BvhBuild: the BVH at low and medium quality, time and memory;
// the two throughput benchmarks run with argument 0 on Embree's BVH over
// the DEM's triangles and with 1 on the height field (render/heightfield.h,
// no BVH over the terrain; `bvh_build_s` and `bvh_added_MiB` are then the
// height field's).
// $GISSAR_BENCH_BVH (low, medium, high; default automatic) sets the quality
// of the BVH the two throughput benchmarks use.
// Both report rays_per_s; scripts/bench.sh takes their ratio. The BVH is
// built once, before either runs.
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "gissar/pipeline/simulate.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"

namespace {
using namespace gissar;

struct Scene {
  pipeline::Terrain terrain;
  std::unique_ptr<render::EmbreeScene> embree;
  std::unique_ptr<render::EmbreeScene> heightfield;
  std::unique_ptr<sensor::SarGeometry> geometry;
  double rays_per_cell = 4.0;
  double bvh_seconds = 0.0;    // build of `embree`
  double bvh_added_bytes = 0;  // resident memory it added
  double heightfield_seconds = 0.0;    // build of `heightfield`
  double heightfield_added_bytes = 0;  // resident memory it added
  const render::EmbreeScene& Traced(int64_t heightfield_arg) const { return heightfield_arg ? *heightfield : *embree; }
};

double ResidentBytes();

const Scene& LoadedScene() {
  static const Scene scene = [] {
    Scene s;
    pipeline::SimulateRequest o;
    const char* dem = std::getenv("GISSAR_BENCH_DEM");
    o.dem = dem != nullptr ? dem : "fractal_1024.tif";
    o.out_prefix = "unused";
    o.geometry.heading_deg = 30.0;
    o.geometry.depression_deg = 40.0;
    o.geometry.slant_range_m = 20000.0;
    if (const char* r = std::getenv("GISSAR_BENCH_RAYS_PER_CELL")) s.rays_per_cell = std::stod(r);
    s.terrain = pipeline::LoadTerrain(o);
    render::BvhQuality quality = render::BvhQuality::kAuto;
    if (const char* q = std::getenv("GISSAR_BENCH_BVH")) {
      quality = std::string(q) == "low" ? render::BvhQuality::kLow
                : std::string(q) == "high" ? render::BvhQuality::kHigh : render::BvhQuality::kMedium;
    }
    const double before = ResidentBytes();
    s.embree = std::make_unique<render::EmbreeScene>(s.terrain.mesh, quality);
    s.bvh_added_bytes = ResidentBytes() - before;
    s.bvh_seconds = s.embree->build_seconds();
    const double before_heightfield = ResidentBytes();
    s.heightfield = std::make_unique<render::EmbreeScene>(
        s.terrain.mesh, render::TerrainGrid{s.terrain.grid_width, s.terrain.grid_height}, quality);
    s.heightfield->Build();  // (a height field alone is otherwise built by its first query)
    s.heightfield_added_bytes = ResidentBytes() - before_heightfield;
    s.heightfield_seconds = s.heightfield->build_seconds();
    s.geometry = std::make_unique<sensor::SarGeometry>(sensor::SarGeometry::Covering(
        pipeline::ResolvedGeometry(o, s.terrain), s.terrain.centre_enu, s.terrain.mesh.vertices));
    return s;
  }();
  return scene;
}

void BM_RawEmbreeStream(benchmark::State& state) {
  const Scene& s = LoadedScene();
  int64_t rays = 0, hits = 0;
  for (auto _ : state) {
    rays = render::IntersectPrimaryRaysOnly(s.Traced(state.range(0)), s.terrain.mesh, *s.geometry, s.rays_per_cell, &hits);
    benchmark::DoNotOptimize(hits);
  }
  state.counters["rays"] = double(rays);
  state.counters["hits"] = double(hits);
  state.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsIterationInvariantRate);
  // The BVH both throughput benchmarks use (automatic quality unless
  // $GISSAR_BENCH_BVH): its build time and memory.
  state.counters["bvh_build_s"] = state.range(0) ? s.heightfield_seconds : s.bvh_seconds;
  state.counters["bvh_added_MiB"] = (state.range(0) ? s.heightfield_added_bytes : s.bvh_added_bytes) / 1048576.0;
  state.counters["triangles"] = double(s.terrain.mesh.triangle_count());
  const render::BvhQuality q = s.embree->quality();
  state.SetLabel(state.range(0) ? "heightfield"
                 : q == render::BvhQuality::kLow ? "low" : q == render::BvhQuality::kHigh ? "high" : "medium");
}

void BM_TracerPrimary(benchmark::State& state) {
  const Scene& s = LoadedScene();
  render::RenderOptions o;
  o.rays_per_cell = s.rays_per_cell;
  o.max_bounces = 1;
  int64_t rays = 0, hits = 0;
  for (auto _ : state) {
    const render::SarImage image = render::RenderSar(s.Traced(state.range(0)), s.terrain.mesh, s.terrain.materials, *s.geometry, o);
    state.SetIterationTime(image.stats.trace_seconds);
    rays = image.stats.rays;
    hits = image.stats.hits;
  }
  state.counters["rays"] = double(rays);
  state.counters["hits"] = double(hits);
  state.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["triangles"] = double(s.terrain.mesh.triangle_count());
  state.SetLabel(state.range(0) ? "heightfield" : "bvh");
}

// Resident memory now (bytes), from /proc/self/statm.
double ResidentBytes() {
  long pages = 0, resident = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return double(resident) * double(sysconf(_SC_PAGESIZE));
}

// BVH build of the scene's mesh at each quality: seconds and the memory it
// adds (resident set before and after, the mesh copy into Embree included).
void BM_BvhBuild(benchmark::State& state) {
  const Scene& s = LoadedScene();
  const auto quality = static_cast<render::BvhQuality>(state.range(0));
  double added = 0;
  for (auto _ : state) {
    const double before = ResidentBytes();
    render::EmbreeScene embree(s.terrain.mesh, quality);
    added = ResidentBytes() - before;
    benchmark::DoNotOptimize(&embree);
  }
  state.counters["triangles"] = double(s.terrain.mesh.triangle_count());
  state.counters["added_MiB"] = added / 1048576.0;
  state.SetLabel(quality == render::BvhQuality::kLow ? "low (Morton)" : quality == render::BvhQuality::kMedium ? "medium (binned SAH)" : "high (SAH, spatial splits)");
}
BENCHMARK(BM_BvhBuild)
    ->Arg(int(render::BvhQuality::kLow))
    ->Arg(int(render::BvhQuality::kMedium))
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);

// Alternating, so that both see the same load on a shared machine.
BENCHMARK(BM_RawEmbreeStream)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);
BENCHMARK(BM_TracerPrimary)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(2);

}  // namespace

BENCHMARK_MAIN();
