// The EGM96 geoid (PROJ's egm96_15.gtx grid, 15' posts): undulation N of the
// geoid above the WGS84 ellipsoid, so that ellipsoidal height h = H + N for
// an orthometric (EGM96) height H such as SRTM's.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace gissar::geo {

class Egm96Geoid {
 public:
  // Loads the grid from `path`, or when empty from the first of
  // $PROJ_DATA, $PROJ_LIB, /usr/share/proj, /usr/local/share/proj holding
  // egm96_15.gtx (Debian package proj-data). Throws InputError naming the
  // places searched when it is not found or unreadable.
  explicit Egm96Geoid(const std::filesystem::path& path = {});

  // Undulation N in metres at WGS84 (lon_deg, lat_deg), bilinear between
  // the grid posts (longitude wraps around). Latitude is clamped to
  // [-90, 90].
  double UndulationM(double lon_deg, double lat_deg) const;

  const std::string& source() const { return source_; }

 private:
  std::string source_;
  int width_ = 0, height_ = 0;
  double lon0_ = 0.0, lat0_ = 0.0, dlon_ = 0.0, dlat_ = 0.0;  // post (0,0) and spacing
  std::vector<float> n_m_;
};

}  // namespace gissar::geo

namespace gissar::geo {
struct Dem;
// Converts a DEM's heights from orthometric (EGM96, as SRTM) to ellipsoidal:
// h = H + N(lon, lat) at every post (any CRS: posts are transformed to
// WGS84 first). Throws InputError as Egm96Geoid and CrsTransform do.
void Egm96ToEllipsoidal(Dem& dem, const Egm96Geoid& geoid);
}  // namespace gissar::geo
