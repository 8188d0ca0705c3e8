// Fuzzes the Sentinel-1 SAFE XML parsers (product annotation, calibration and
// noise annotations, geo/sentinel1_safe.h): any bytes must give a parsed
// document with finite values or a gissar::Error, never a crash or a hang.
// Seeds: the annotations of data/sentinel1/ (scripts/fuzz.sh).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "gissar/geo/sentinel1_safe.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  constexpr double kEpoch = 1617235200.0;  // 2021-04-01T00:00:00Z
  try {
    const gissar::geo::Sentinel1Annotation a = gissar::geo::ParseSentinel1Annotation(text, "fuzz.xml");
    for (const auto& g : a.geolocation_grid) {
      if (!std::isfinite(g.azimuth_time_s) || !std::isfinite(g.latitude_deg)) std::abort();  // promised finite
    }
    if (!a.range_conversion.empty()) (void)a.GroundRangeOfSlantRange(8e5, a.first_line_time_s);
    for (const auto& b : a.bursts) (void)a.BurstOfTime(b.azimuth_time_s);
  } catch (const gissar::Error&) {
  }
  try {
    const gissar::geo::Sentinel1Calibration c = gissar::geo::ParseSentinel1Calibration(text, "fuzz.xml", kEpoch);
    if (!std::isfinite(c.sigma0.At(0.0, 0.0))) std::abort();
  } catch (const gissar::Error&) {
  }
  try {
    const gissar::geo::Sentinel1Noise n = gissar::geo::ParseSentinel1Noise(text, "fuzz.xml", kEpoch);
    if (!std::isfinite(n.At(10.0, 10.0))) std::abort();
  } catch (const gissar::Error&) {
  }
  return 0;
}
