// Raster engine throughput (DEM cells per second after loading) on a DEM
// given by $GISSAR_BENCH_DEM (default: a 4096^2 fractal DEM written by
// scripts/bench.sh), the floor of its sampling on this machine (what any
// engine that splats as it does must spend, with nothing else), and a
// STREAM-like memory bandwidth figure (triad a = b + s c over arrays far
// larger than the caches) from the same run.
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

// A lower bound for any raster engine that samples the image as this one
// does (each triangle's power splatted bilinearly at its three edge
// midpoints: six splats per DEM cell), measured on the same DEM and image:
// the posts projected to (column, row) in a vectorised pass, each
// triangle's area and a cos^2 law (cheaper than a sigma0 table) in a
// vectorised pass per grid row, then the splats; no horizon, no shadow, no
// layover, no mask, no classes. Each thread splats half the grid into its
// own image (no chunking, no sharing). Argument: 0 the whole floor, 1 the
// projection only, 2 projection and per-triangle arithmetic (no splat): the
// splats cost 0 minus 2.
void BM_SplatFloor(benchmark::State& state) {
  const int stages = state.range(0);
  const Scene& s = LoadedScene();
  const auto& posts = s.terrain.mesh.vertices;
  const int w = s.width, h = s.height;
  const sensor::SarGeometry& g = *s.geometry;
  const Eigen::Vector3f xc = g.scene_centre().cast<float>(), fd = g.flight_direction().cast<float>(),
                        look = g.look_direction().cast<float>();
  const float inv_dr = static_cast<float>(1.0 / g.range_spacing_m());
  const float inv_da = static_cast<float>(1.0 / g.azimuth_spacing_m());
  const float u0 = static_cast<float>(g.u0()), v0 = static_cast<float>(g.v0());
  const int iw = g.width(), ih = g.height();
  const size_t n = posts.size();
  std::vector<float> px(n), py(n), pz(n), col(n), row(n);
  std::vector<std::vector<float>> images(2, std::vector<float>(size_t(iw) * ih));
  for (auto _ : state) {
    tbb::parallel_for(tbb::blocked_range<int>(0, h, 16), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y != r.end(); ++y) {
        const size_t i0 = size_t(y) * w;
        for (int x = 0; x < w; ++x) {
          const Eigen::Vector3f p = posts[i0 + x] - xc;
          px[i0 + x] = p.x();
          py[i0 + x] = p.y();
          pz[i0 + x] = p.z();
          col[i0 + x] = p.dot(look) * inv_dr + u0;
          row[i0 + x] = (p.x() * fd.x() + p.y() * fd.y()) * inv_da + v0;
        }
      }
    });
    if (stages == 1) continue;
    tbb::parallel_for(0, 2, [&](int k) {
      std::vector<float>& image = images[k];
      if (stages == 0) std::fill(image.begin(), image.end(), 0.0f);
      float* im = image.data();
      const int cells = w - 1;
      // Per grid row: two triangles per cell, three samples each.
      std::vector<float> sc(size_t(6) * cells), sr(size_t(6) * cells), sv(size_t(2) * cells);
      for (int y = k * (h - 1) / 2; y < (k + 1) * (h - 1) / 2; ++y) {
        const size_t i0 = size_t(y) * w;
        // Triangle (a, b, c) of cell x: samples at the three edge midpoints.
        auto triangle = [&](int x, int t, size_t a, size_t b, size_t c) {
          const float e1x = px[b] - px[a], e1y = py[b] - py[a], e1z = pz[b] - pz[a];
          const float e2x = px[c] - px[a], e2y = py[c] - py[a], e2z = pz[c] - pz[a];
          const float nx = e1y * e2z - e1z * e2y, ny = e1z * e2x - e1x * e2z, nz = e1x * e2y - e1y * e2x;
          const float twice_area = std::sqrt(nx * nx + ny * ny + nz * nz);
          const float cos_in = -(nx * look.x() + ny * look.y() + nz * look.z()) / twice_area;
          sv[2 * size_t(x) + t] = cos_in > 0.0f ? twice_area * cos_in * cos_in * (0.5f / 3.0f) : 0.0f;
          const float dc1 = 0.5f * (col[b] - col[a]), dc2 = 0.5f * (col[c] - col[a]);
          const float dr1 = 0.5f * (row[b] - row[a]), dr2 = 0.5f * (row[c] - row[a]);
          const size_t j = 6 * size_t(x) + 3 * t;
          sc[j] = col[a] + dc1;
          sr[j] = row[a] + dr1;
          sc[j + 1] = col[a] + dc2;
          sr[j + 1] = row[a] + dr2;
          sc[j + 2] = col[a] + dc1 + dc2;
          sr[j + 2] = row[a] + dr1 + dr2;
        };
        for (int x = 0; x < cells; ++x) {
          const size_t a = i0 + x;
          triangle(x, 0, a, a + 1, a + w);
          triangle(x, 1, a + 1, a + w + 1, a + w);
        }
        if (stages == 2) {
          // The row's samples count as used (no splat reads them here).
          benchmark::DoNotOptimize(sc.data());
          benchmark::DoNotOptimize(sr.data());
          benchmark::DoNotOptimize(sv.data());
          benchmark::ClobberMemory();
          continue;
        }
        for (size_t j = 0; j < sc.size(); ++j) {
          const float c = sc[j], r = sr[j], v = sv[j / 3];
          const int c0 = static_cast<int>(c), r0 = static_cast<int>(r);
          if (c0 < 0 || r0 < 0 || c0 >= iw - 1 || r0 >= ih - 1) continue;
          const float fc = c - float(c0), fr = r - float(r0);
          float* q = im + size_t(r0) * iw + c0;
          q[0] += v * (1.0f - fc) * (1.0f - fr);
          q[1] += v * fc * (1.0f - fr);
          q[iw] += v * (1.0f - fc) * fr;
          q[iw + 1] += v * fc * fr;
        }
      }
    });
    benchmark::DoNotOptimize(images[0].data());
  }
  state.counters["cells_per_s"] =
      benchmark::Counter(double(w - 1) * (h - 1), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_SplatFloor)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

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
