// Vertical datum of DEM heights (--vertical-datum): which surface the heights
// are measured from, and their conversion to WGS84 ellipsoidal heights (what
// the local frame uses, local_frame.h).
//
// Names: "ellipsoid" (WGS84 ellipsoidal heights, e.g. EPSG:4979), "egm96"
// (EGM96 height, EPSG:5773: SRTM), "egm2008" (EGM2008 height, EPSG:3855) and
// "EPSG:<n>" for any other vertical CRS PROJ knows (e.g. EPSG:5703, NAVD88).
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace gissar::geo {

struct Dem;

// The canonical name of a --vertical-datum value: "" stays "" (from the
// file), "ellipsoid", "egm96", "egm2008" (any case), "EPSG:n" of a vertical
// CRS ("EPSG:5773" -> "egm96", "EPSG:3855" -> "egm2008") or of a 3-D
// geographic CRS ("EPSG:4979" -> "ellipsoid"). Throws ConfigError naming
// `flag` for anything else (e.g. "egm97", or "EPSG:4326" which is not
// vertical).
std::string CanonicalVerticalDatum(const std::string& value, const std::string& flag = "--vertical-datum");

// The datum a raster's CRS (WKT or any definition OGR accepts) gives its
// heights: the vertical part of a compound CRS (EPSG:5773 -> "egm96",
// EPSG:3855 -> "egm2008", another code -> "EPSG:<n>"), "ellipsoid" for a 3-D
// geographic CRS (EPSG:4979), else "" (the CRS says nothing: 2-D, or a
// vertical CRS without an EPSG code). `driver` "SRTMHGT" (.hgt tiles,
// EGM96 by definition) gives "egm96" when the CRS says nothing.
std::string VerticalDatumOfCrs(const std::string& crs_definition, const std::string& driver = "");

// A resolved datum and where it came from: "flag" (--vertical-datum), "file"
// (the raster's vertical CRS, or its driver) or "assumed" (the file says
// nothing: ellipsoid).
struct VerticalDatumChoice {
  std::string datum;
  std::string source;
};

// `flag_value` (canonical, may be "") else the file's datum else
// {"ellipsoid", "assumed"}.
VerticalDatumChoice ResolveVerticalDatum(const std::string& flag_value, const std::string& file_datum);

// The one-line warning for an assumed datum, naming the file and the flag.
std::string AssumedDatumWarning(const std::string& file);

// Ellipsoidal height of the datum's zero level (the geoid undulation N, m) at
// WGS84 lon/lat points, so that h = H + N. "ellipsoid": 0; "egm96": PROJ's
// egm96_15.gtx read directly (Egm96Geoid, bilinear); "egm2008" and
// "EPSG:n": PROJ through OGR (compound EPSG:4326 + the vertical CRS to
// EPSG:4979, no ballpark transformation), so that a missing geoid grid is an
// InputError naming the grid (e.g. us_nga_egm08_25.tif) and where to put it,
// never a silent zero shift. `where` names the DEM in errors.
std::vector<double> GeoidUndulationsM(const std::string& datum, const std::vector<double>& lon_deg,
                                      const std::vector<double>& lat_deg, const std::string& where);
// As above through PROJ whatever the datum (also egm96): the reference the
// fast egm96 path is checked against.
std::vector<double> GeoidUndulationsViaProjM(const std::string& datum, const std::vector<double>& lon_deg,
                                             const std::vector<double>& lat_deg, const std::string& where);

// Converts a DEM's heights (metres, in `datum`) to WGS84 ellipsoidal heights:
// h = H + N(lon, lat) at every post (posts transformed to WGS84 first).
// Throws as GeoidUndulationsM.
void ToEllipsoidalHeights(Dem& dem, const std::string& datum);

}  // namespace gissar::geo
