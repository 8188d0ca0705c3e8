// Fuzzes the CSV readers of matches (x1,y1,x2,y2) and control points
// (X,Y,Z,x,y) used by fmatrix, resect, register and epipolar: any bytes must
// give finite points or a gissar::Error.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.h"
#include "gissar/mvg/match_io.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  try {
    for (const gissar::mvg::PointMatch& m : gissar::mvg::ReadMatchesCsv(file.path())) {
      if (!m.p1.allFinite() || !m.p2.allFinite()) std::abort();  // promised finite
    }
  } catch (const gissar::Error&) {
  }
  try {
    for (const gissar::mvg::ControlPoint& p : gissar::mvg::ReadControlPointsCsv(file.path())) {
      if (!p.world.allFinite() || !p.pixel.allFinite()) std::abort();
    }
  } catch (const gissar::Error&) {
  }
  return 0;
}
