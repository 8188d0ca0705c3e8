// Test-only: the bundled Sentinel-1 products (data/sentinel1, from
// xarray-sentinel's test data; annotations only), as paths relative to the
// data directory (testing::DataPath).
#pragma once

#include <string>

#include "gissar/geo/sentinel1_safe.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::geo::testing_s1 {

inline constexpr const char* kIwSlc =
    "sentinel1/S1B_IW_SLC__1SDV_20210401T052622_20210401T052650_026269_032297_EFA4.SAFE";
inline constexpr const char* kIwGrd =
    "sentinel1/S1B_IW_GRDH_1SDV_20210401T052623_20210401T052648_026269_032297_ECC8.SAFE";
inline constexpr const char* kSm =
    "sentinel1/S1A_S3_SLC__1SDV_20210401T152855_20210401T152914_037258_04638E_6001.SAFE";

// One swath/polarisation's annotation of a bundled product.
inline Sentinel1Annotation Annotation(const char* safe, const std::string& swath, const std::string& pol) {
  const Sentinel1Product p = OpenSentinel1(testing::DataPath(safe));
  return ReadSentinel1Annotation(p, p.Entry(swath, pol));
}

// "message | where" of the project error `f` throws, or "(no error)".
template <typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const Error& e) {
    return e.message() + " | " + e.where();
  }
  return "(no error)";
}

}  // namespace gissar::geo::testing_s1
