// GeoTIFF output throughput (issue 18, "fast output"): 24 Mpx x 4 float32
// bands (the 4096^2, 3-bounce simulate's image: total and three bounce layers) through
// geo::WriteFloatGeoTiff, the writer `simulate` uses: a Cloud-Optimized
// GeoTIFF, 512-pixel ZSTD tiles with the floating-point predictor, and its
// AVERAGE overviews. The pixels are 4-look speckle over a smooth field with a
// NaN collar, and the multiple-bounce bands are sparse (what a simulated SAR
// image compresses like: about 100 MB, as the fractal 4096^2 simulate's).
// With $GISSAR_BENCH_IMAGE set (scripts/bench.sh: the 4096^2 fractal DEM's
// 3-bounce simulate output), that image's bands are written instead.
// Each iteration writes the file anew into $TMPDIR (or /tmp) and deletes it.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "gissar/geo/raster_io.h"

namespace {
using namespace gissar;

constexpr int kWidth = 4292, kHeight = 5601;  // the 4096^2 fractal DEM's image

geo::FloatRaster& Image() {
  static geo::FloatRaster raster = [] {
    if (const char* image = std::getenv("GISSAR_BENCH_IMAGE")) {
      geo::FloatRaster r = geo::ReadFloatRaster(image);
      r.georeference = {};
      r.metadata.clear();
      return r;
    }
    geo::FloatRaster r;
    r.width = kWidth;
    r.height = kHeight;
    r.nodata_nan = true;
    r.band_names = {"total", "single", "double", "triple"};
    std::mt19937 rng(1);
    std::gamma_distribution<float> speckle(4.0f, 0.25f);
    std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
    // Bands 3-4 (double, triple bounces) return from a few per cent of the
    // pixels and are zero elsewhere, as on real terrain.
    const float occupied[4] = {1.0f, 1.0f, 0.03f, 0.01f};
    const float scale[4] = {1.0f, 0.95f, 0.5f, 0.2f};
    for (int b = 0; b < 4; ++b) {
      std::vector<float> band(size_t(kWidth) * kHeight);
      for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
          // A NaN collar: the rotated footprint leaves the corners empty.
          const bool outside = x + y < 600 || (kWidth - x) + (kHeight - y) < 600;
          const float field = 0.2f * (1.5f + std::sin(0.01f * x) * std::cos(0.013f * y));
          float v = 0.0f;
          if (outside) v = std::numeric_limits<float>::quiet_NaN();
          else if (b < 2 || uniform(rng) < occupied[b]) v = scale[b] * field * speckle(rng);
          band[size_t(y) * kWidth + x] = v;
        }
      }
      r.bands.push_back(std::move(band));
    }
    return r;
  }();
  return raster;
}

// state.range(0): 1 with the COG's internal overviews (simulate's default),
// 0 without (simulate --no-overviews, the issue-18 benchmark's outputs).
void BM_WriteFloatCog(benchmark::State& state) {
  geo::FloatRaster& raster = Image();
  raster.overviews = state.range(0) != 0;
  const char* tmp = std::getenv("TMPDIR");
  const std::filesystem::path path =
      std::filesystem::path(tmp != nullptr ? tmp : "/tmp") / "gissar_write_bench.tif";
  for (auto _ : state) {
    geo::WriteFloatGeoTiff(path, raster);
    state.PauseTiming();
    state.counters["file_MB"] = double(std::filesystem::file_size(path)) / 1e6;
    std::filesystem::remove(path);
    state.ResumeTiming();
  }
  const double bytes = double(raster.width) * raster.height * raster.bands.size() * sizeof(float);
  state.SetBytesProcessed(static_cast<int64_t>(bytes * state.iterations()));
  state.counters["megapixels"] = double(raster.width) * raster.height / 1e6;
  state.counters["bands"] = double(raster.bands.size());
  state.counters["overviews"] = double(state.range(0));
}
BENCHMARK(BM_WriteFloatCog)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
