// Fuzzes the radar grid JSON reader (geo::ReadRadarGrid) and the product it
// makes with an orbit (geo::ProductFromOrbit, as `simulate --orbit
// --radar-grid` does): any bytes must give a grid with positive finite
// spacings, a size in [1, 2^20] and a parseable start time, then a product
// with finite increasing grids or a gissar::Error (the orbit does not cover
// it), never a crash, a hang or another exception.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.h"
#include "gissar/geo/orbit_file.h"
#include "gissar/util/error.h"
#include "gissar/util/utc_time.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  try {
    const gissar::geo::RadarGridSpec g = gissar::geo::ReadRadarGrid(file.path());
    auto positive = [](double x) { return std::isfinite(x) && x > 0.0; };
    if (!positive(g.starting_range_m) || !positive(g.range_spacing_m) || !positive(g.azimuth_time_interval_s) ||
        !positive(g.wavelength_m) || g.width < 1 || g.width > (1 << 20) || g.length < 1 || g.length > (1 << 20)) {
      std::abort();
    }
    // A low orbit around the grid's start: 10 vectors 10 s apart from 20 s
    // before it.
    const double start = gissar::ParseUtcSeconds(g.sensing_start_utc, "fuzz");
    if (!std::isfinite(start)) std::abort();
    gissar::geo::StateVectors v;
    v.format = "json";
    for (int i = 0; i < 10; ++i) {
      const double t = 10.0 * i;
      v.utc_s.push_back(start - 20.0 + t);
      v.position_m.emplace_back(7.0e6, 7.5e3 * t, 0.0);
      v.velocity_mps.emplace_back(0.0, 7.5e3, 0.0);
    }
    const gissar::geo::RslcProduct p = gissar::geo::ProductFromOrbit(v, "orbit.json", g, file.path());
    if (p.rows() != g.length || p.cols() != g.width || !std::isfinite(p.center_frequency_hz)) std::abort();
    for (int i = 0; i < p.rows(); ++i) {
      if (!std::isfinite(p.zero_doppler_time_s[i])) std::abort();
    }
    for (int j = 0; j < p.cols(); ++j) {
      if (!std::isfinite(p.slant_range_m[j])) std::abort();
    }
  } catch (const gissar::Error&) {
  }
  return 0;
}
