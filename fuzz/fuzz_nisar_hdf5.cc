// Fuzzes the NISAR RSLC reader (geo::ReadRslcProduct: HDF5 through the
// HDF5 C library, which needs a real file: the input is written to a
// temporary file, as HDF5 resolves /proc/self/fd/N to the memfd's name and
// cannot open that)
// with the amplitude, the complex layer and the beta0 calibration LUT read,
// under a 64 MiB --max-memory budget: any bytes must give a product whose
// grids are finite and strictly increasing, whose orbit, layers
// and LUT have consistent sizes and finite values, or a gissar::Error,
// never a crash, a hang or another exception. The last byte (not the first:
// it is the HDF5 signature's) chooses the polarization asked for (HH or HV)
// and whether the calibration is read.
// Seeds: data/uavsar/SanAnd_129.h5 and data/alos_rio_branco/*.h5 (read
// whole: -max_len 262144 in scripts/fuzz.sh) and fuzz/seeds/nisar_hdf5/.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/util/error.h"

namespace {

void CheckIncreasing(const std::vector<double>& v) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i]) || (i > 0 && !(v[i] > v[i - 1]))) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::NamedFile file(data, size, "product.h5");
  gissar::geo::RslcReadOptions options;
  options.max_bytes = int64_t{64} << 20;
  options.read_complex = true;
  const uint8_t last = size > 0 ? data[size - 1] : 0;
  options.read_calibration = (last & 2) == 0;
  if ((last & 1) != 0) options.polarization = "HV";
  try {
    const gissar::geo::RslcProduct p = gissar::geo::ReadRslcProduct(file.path(), options);
    const size_t pixels = size_t(p.rows()) * size_t(p.cols());
    if (p.rows() < 1 || p.cols() < 1 || p.amplitude.size() != pixels || p.slc.size() != pixels) std::abort();
    CheckIncreasing(p.zero_doppler_time_s);
    CheckIncreasing(p.slant_range_m);
    if (!std::isfinite(p.wavelength_m) || !(p.wavelength_m > 0.0) || !std::isfinite(p.center_frequency_hz)) {
      std::abort();
    }
    if (!std::isfinite(p.azimuth_spacing_s()) || !std::isfinite(p.range_spacing_m())) std::abort();
    const size_t n = p.orbit.time_s.size();
    if (n < 4 || p.orbit.position_m.size() != n || p.orbit.velocity_mps.size() != n) std::abort();
    CheckIncreasing(p.orbit.time_s);
    for (size_t i = 0; i < n; ++i) {
      if (!p.orbit.position_m[i].allFinite() || !p.orbit.velocity_mps[i].allFinite()) std::abort();
    }
    if (p.beta0_lut) {
      const gissar::geo::RslcCalibrationLut& lut = *p.beta0_lut;
      if (lut.values.size() != lut.time_s.size() * lut.slant_range_m.size() || lut.values.empty()) std::abort();
      CheckIncreasing(lut.time_s);
      CheckIncreasing(lut.slant_range_m);
      for (double x : lut.values) {
        if (!std::isfinite(x) || !(x > 0.0)) std::abort();
      }
      if (!std::isfinite(lut.At(p.zero_doppler_time_s[0], p.slant_range_m[0]))) std::abort();
    }
  } catch (const gissar::Error&) {
  }
  return 0;
}
