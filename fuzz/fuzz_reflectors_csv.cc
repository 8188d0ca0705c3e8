// Fuzzes the reflectors CSV reader (material::ReadReflectorsCsv, the
// `--reflectors` of scene build, simulate, pta and locate): any bytes must
// give reflectors with finite values in the documented ranges (size > 0,
// latitude and elevation in [-90, 90], roll in [-360, 360]) or a
// gissar::Error, never a crash, a hang or another exception.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.h"
#include "gissar/material/reflector.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  try {
    int last_row = 0;
    for (const gissar::material::ReflectorSpec& r : gissar::material::ReadReflectorsCsv(file.path())) {
      const double values[] = {r.lon_deg, r.lat_deg, r.apex_height_m, r.size_m, r.boresight_azimuth_deg,
                               r.boresight_elevation_deg, r.roll_deg};
      for (double x : values) {
        if (!std::isfinite(x)) std::abort();  // promised finite
      }
      if (!(r.size_m > 0.0) || std::abs(r.lat_deg) > 90.0 || std::abs(r.boresight_elevation_deg) > 90.0 ||
          std::abs(r.roll_deg) > 360.0 || r.row <= last_row) {
        std::abort();
      }
      last_row = r.row;
      (void)gissar::material::ToString(r.type);
      if (!gissar::material::BoresightVector(r.boresight_azimuth_deg, r.boresight_elevation_deg).allFinite()) {
        std::abort();
      }
    }
  } catch (const gissar::Error&) {
  }
  return 0;
}
