// Fuzzes the orbit readers (geo::ReadStateVectors: CSV, JSON and ESA EOF
// XML): any bytes must give at least kMinStateVectors finite state vectors
// with strictly increasing times, or a gissar::Error, never a crash, a hang
// or another exception. The first byte chooses how the format is picked:
// by content (no extension: the reader's sniffing of the first character)
// or by the extension .csv, .json, .EOF or .xml. Seeds: tests/data/orbits/
// and the catalogue's orbit files (scripts/fuzz.sh).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_support.h"
#include "gissar/geo/orbit_file.h"
#include "gissar/util/error.h"

namespace {

void Check(const gissar::geo::StateVectors& v) {
  const size_t n = v.utc_s.size();
  if (n < size_t(gissar::geo::kMinStateVectors) || v.position_m.size() != n || v.velocity_mps.size() != n) std::abort();
  if (v.format != "csv" && v.format != "json" && v.format != "eof") std::abort();
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(v.utc_s[i]) || !v.position_m[i].allFinite() || !v.velocity_mps[i].allFinite()) std::abort();
    if (i > 0 && !(v.utc_s[i] > v.utc_s[i - 1])) std::abort();  // promised strictly increasing
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const char* const kNames[] = {"", "orbit.csv", "orbit.json", "orbit.EOF", "orbit.xml"};
  const unsigned choice = data[0] % 5;
  ++data, --size;
  try {
    if (choice == 0) {
      const gissar::fuzz::MemoryFile file(data, size);
      Check(gissar::geo::ReadStateVectors(file.path()));
    } else {
      const gissar::fuzz::NamedFile file(data, size, kNames[choice]);
      Check(gissar::geo::ReadStateVectors(file.path()));
    }
  } catch (const gissar::Error&) {
  }
  return 0;
}
