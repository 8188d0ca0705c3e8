// Fuzzes the DEM reader through GDAL on in-memory files (/vsimem/): any
// bytes (GeoTIFF, VRT, any format GDAL recognises) must give a valid DEM or
// a gissar::Error, and a valid DEM must turn into a mesh in its scene frame
// (centre, post spacing, ENU posts) or a gissar::Error. The memory budget is
// 64 MiB, as with --max-memory 64M. Only file-based DEM formats are enabled
// (see KeepDemDrivers).
#include <cpl_conv.h>
#include <cpl_vsi.h>
#include <gdal_priv.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <set>
#include <string>

#include "gissar/geo/dem.h"
#include "gissar/geo/gdal_env.h"
#include "gissar/geo/local_frame.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/error.h"

namespace {

// File-based raster formats DEMs come in; every other driver (network
// services such as WMS/WMTS/EEDA, heavy scientific formats) is deregistered
// so that no input makes the fuzzer reach for the network. /vsicurl/ sources
// of a VRT go to a closed loopback port.
void KeepDemDrivers() {
  const std::set<std::string> keep = {"GTiff", "VRT",   "AAIGrid", "SRTMHGT", "EHdr",
                                      "ENVI",  "USGSDEM", "XYZ",   "GSAG",    "GSBG",
                                      "GS7BG", "HFA",   "PNM",     "ISIS3",   "PDS4"};
  GDALDriverManager* manager = GetGDALDriverManager();
  for (int i = manager->GetDriverCount() - 1; i >= 0; --i) {
    GDALDriver* driver = manager->GetDriver(i);
    if (!keep.count(driver->GetDescription())) manager->DeregisterDriver(driver);
  }
  CPLSetConfigOption("GDAL_HTTP_PROXY", "127.0.0.1:9");
  CPLSetConfigOption("GDAL_HTTP_TIMEOUT", "1");
  CPLSetConfigOption("GDAL_DISABLE_READDIR_ON_OPEN", "EMPTY_DIR");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gissar::geo::EnsureGdal();
  KeepDemDrivers();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = "/vsimem/fuzz_dem";
  VSILFILE* f = VSIFileFromMemBuffer(path.c_str(), const_cast<GByte*>(data), size, FALSE);
  if (f == nullptr) return 0;
  VSIFCloseL(f);
  try {
    gissar::geo::DemReadOptions options;
    options.max_bytes = int64_t{64} << 20;
    options.bytes_per_post = 256;
    options.fill_nodata = size > 0 && (data[size - 1] & 1);
    const gissar::geo::Dem dem = gissar::geo::ReadDem(path, options);
    for (float h : dem.heights_m) {
      if (!std::isfinite(h)) std::abort();  // promised finite
    }
    const gissar::geo::GeoPoint centre = gissar::geo::ResolveSceneCentre(dem, std::nullopt, std::nullopt);
    const gissar::geo::LocalFrame frame(centre.lon_deg, centre.lat_deg, 0.0);
    const auto posts = gissar::geo::DemPostsInFrame(dem, frame);
    gissar::geo::DemPostSpacingMetres(dem, frame);
    gissar::scene::MeshFromGrid(posts, dem.width, dem.height);
  } catch (const gissar::Error&) {
  }
  VSIUnlink(path.c_str());
  return 0;
}
