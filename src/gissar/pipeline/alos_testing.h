// Test fixture shared by the pipeline tests on the bundled ALOS-1 PALSAR
// quad-pol chip with its surveyed trihedral (data/alos_rio_branco,
// PROVENANCE.md): the chip, its reflector CSV, and the flat Amazon ground
// under it as a DEM at the reflector's height (the ellipsoid: the survey's
// apex is -2e-5 m above it) with the vertical datum and sea settings that
// keep it there. Test code only (gtest-free, header only).
#pragma once

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gissar/geo/dem.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline::alos_testing {

inline constexpr const char* kProduct = "alos_rio_branco/calib_RSLC_ALPSRP025826990_RIO_BRANCO_CR.h5";
inline constexpr const char* kReflectors = "alos_rio_branco/rio_branco_reflector.csv";
inline constexpr double kReflectorLon = -68.1728216904995;
inline constexpr double kReflectorLat = -9.71311741457592;
// The DEM's heights are ellipsoidal (--vertical-datum ellipsoid) and the
// ellipsoid lies below EGM96 sea level here: with --sea auto the whole DEM
// would be the `sea` class, so the fixture's users pass --sea off.
inline constexpr const char* kVerticalDatum = "ellipsoid";
inline constexpr const char* kSea = "off";

inline std::filesystem::path ProductPath() { return gissar::testing::DataPath(kProduct); }
inline std::filesystem::path ReflectorsPath() { return gissar::testing::DataPath(kReflectors); }

// Writes DIR/flat.tif: 3 km x 3 km at 15 m (201 x 201 posts) on a
// transverse Mercator centred on the reflector, every post `height_m`.
inline std::filesystem::path WriteFlatDem(const std::filesystem::path& dir, float height_m = 0.0f) {
  const std::string tm = "+proj=tmerc +lat_0=" + std::to_string(kReflectorLat) + " +lon_0=" +
                         std::to_string(kReflectorLon) + " +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
  const std::filesystem::path dem = dir / "flat.tif";
  geo::WriteDemGeoTiff(dem, std::vector<float>(201 * 201, height_m), 201, 201,
                       {-1507.5, 15.0, 0.0, 1507.5, 0.0, -15.0}, tm);
  return dem;
}

// Writes DIR/dark.json: the default class at `sigma0_db` at every angle.
inline std::filesystem::path WriteDarkMaterials(const std::filesystem::path& dir, double sigma0_db) {
  const std::filesystem::path path = dir / "dark.json";
  std::ofstream(path) << "{\"default\": {\"sigma0_db\": [[0, " << sigma0_db << "], [90, " << sigma0_db << "]]}}";
  return path;
}

}  // namespace gissar::pipeline::alos_testing
