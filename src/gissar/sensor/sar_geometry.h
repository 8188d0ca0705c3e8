// SAR acquisition geometry and the projection of scene points (ENU metres)
// into the azimuth x slant-range image. Conventions (docs/geometry.md):
//  - heading psi: flight direction, degrees clockwise from true north;
//    h = [sin psi, cos psi, 0].
//  - right-looking: horizontal look r_h = [cos psi, -sin psi, 0] (left: -r_h);
//    line of sight to the scene centre l = cos(d) r_h - sin(d) z for the
//    depression angle d; n = l x h.
//  - pixel x (column) = slant range, increasing away from the radar;
//    pixel y (row) = azimuth, increasing along the flight. Pixel centres sit
//    at integer coordinates; the scene centre Xc projects to (u0, v0).
//  - affine mode: parallel rays along l; slant range = R + (X - Xc).l,
//    azimuth = (X - Xc).h. This is the camera P_SAR = C_SAR P_par G_perp.
//  - exact mode: straight, level flight line P(a) = Xc - R l + a h; a point is
//    imaged at its zero-Doppler position a = (X - Xc).h with its true slant
//    range |X - P(a)|; depression varies across the swath.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/look_side.h"
#include "gissar/util/enum_table.h"

namespace gissar::sensor {

using LookSide = geo::LookSide;  // geo/look_side.h: products read and write it too
using geo::kLookSides;
using geo::LookSideOf;
enum class ProjectionMode { kAffine, kExact };
inline constexpr auto kProjectionModes = util::MakeEnumTable<ProjectionMode>(
    "mode", {{ProjectionMode::kAffine, "affine"}, {ProjectionMode::kExact, "exact"}});

// The tables' Parse and Name: a name of the table, else ConfigError naming
// `option` and the choices.
LookSide ParseLookSide(const std::string& text, const std::string& option = "--look");
ProjectionMode ParseProjectionMode(const std::string& text, const std::string& option = "--mode");
std::string ToString(LookSide side);
std::string ToString(ProjectionMode mode);

// Flight (azimuth) direction h = [sin psi, cos psi, 0] of a heading in
// degrees clockwise from north (ENU).
Eigen::Vector3d FlightDirection(double heading_deg);
// Line of sight l = cos(d) r_h - sin(d) z to the scene centre for a heading,
// a depression d (degrees) and a look side (r_h = [cos psi, -sin psi, 0] for
// right-looking, its opposite for left-looking). No validation.
Eigen::Vector3d LookDirection(double heading_deg, double depression_deg, LookSide look_side);

// Bounds of SarGeometryOptions::Check (geostationary orbits are at 3.6e7 m).
inline constexpr double kMaxSlantRangeM = 1e8;
inline constexpr double kMaxAbsHeadingDeg = 1e4;
inline constexpr double kMaxPixelSpacingM = 1e5;
// Most pixels of an image (1024 Mpx: 64 GiB of simulation planes), whether
// its size is given or covers the scene.
inline constexpr int64_t kMaxImagePixels = int64_t{1} << 30;
// Largest extent of an image on either axis (size x pixel spacing): the
// Earth's mean radius. The image plane is tangent to the Earth at the scene
// centre; a footprint reaching this far from it leaves the Earth (its far
// range grazes the surface once the Earth has curved by the depression
// angle, i.e. within R x depression < R), so no map projection holds it.
inline constexpr double kMaxImageExtentM = 6.371e6;

struct SarGeometryOptions {
  double heading_deg = 0.0;       // flight direction, clockwise from north, |h| <= kMaxAbsHeadingDeg
  double depression_deg = 40.0;   // at the scene centre, in (0, 90)
  LookSide look_side = LookSide::kRight;
  double slant_range_m = 10000.0;  // sensor to scene centre, in (0, kMaxSlantRangeM]
  double range_spacing_m = 0.0;    // pixel spacing in slant range, in (0, kMaxPixelSpacingM]
  double azimuth_spacing_m = 0.0;  // pixel spacing along track, in (0, kMaxPixelSpacingM]
  ProjectionMode mode = ProjectionMode::kAffine;
  int width = 0;   // image columns (range); 0 = cover the whole scene
  int height = 0;  // image rows (azimuth); 0 = cover the whole scene

  // Throws ConfigError naming the option when a value is out of range or
  // not finite (spacings must already be resolved to positive values), and
  // for --width/--height when a given size exceeds kMaxImagePixels (which
  // the spacings do not change: callers may check options whose spacings
  // are placeholders).
  void Check() const;
};

class SarGeometry {
 public:
  // `scene_centre`: Xc in ENU metres; (u0, v0): its pixel; image size
  // `width` x `height`. Calls options.Check().
  SarGeometry(const SarGeometryOptions& options, const Eigen::Vector3d& scene_centre, double u0,
              double v0, int width, int height);

  // The geometry whose image just covers every point of `points` (plus
  // `margin_px` on each side); with options.width/height set, that size
  // centred on Xc instead. Throws ConfigError when the image would exceed
  // `max_pixels` (naming --width/--height when a size was given, else the
  // spacings), and first, for --width/--height, when a given side spans
  // more than kMaxImageExtentM at its spacing (width x range spacing,
  // height x azimuth spacing).
  static SarGeometry Covering(const SarGeometryOptions& options,
                              const Eigen::Vector3d& scene_centre,
                              const std::vector<Eigen::Vector3f>& points, int margin_px = 2,
                              int64_t max_pixels = kMaxImagePixels);

  const SarGeometryOptions& options() const { return options_; }
  ProjectionMode mode() const { return options_.mode; }
  const Eigen::Vector3d& scene_centre() const { return xc_; }
  double u0() const { return u0_; }
  double v0() const { return v0_; }
  int width() const { return width_; }
  int height() const { return height_; }
  double range_spacing_m() const { return options_.range_spacing_m; }
  double azimuth_spacing_m() const { return options_.azimuth_spacing_m; }
  double slant_range_m() const { return options_.slant_range_m; }

  // Unit vectors of the geometry (ENU).
  const Eigen::Vector3d& flight_direction() const { return h_; }   // h
  const Eigen::Vector3d& look_direction() const { return l_; }     // l
  const Eigen::Vector3d& range_plane_normal() const { return n_; } // n = l x h

  // Sensor position at along-track coordinate `along_track_m` (exact mode's
  // flight line; in affine mode the nominal sensor position at that time).
  Eigen::Vector3d SensorPosition(double along_track_m) const;

  // Along-track (azimuth) coordinate of a point, metres from Xc.
  double AlongTrack(const Eigen::Vector3d& p) const { return (p - xc_).dot(h_); }
  // Slant range of a point, metres (see the modes above).
  double SlantRange(const Eigen::Vector3d& p) const;
  // Continuous pixel (column = range, row = azimuth) of a point.
  Eigen::Vector2d Project(const Eigen::Vector3d& p) const;
  // Unit direction of the radar ray that reaches `p` (sensor -> p).
  Eigen::Vector3d RayDirectionTo(const Eigen::Vector3d& p) const;
  // Normal of the slant-range plane through `p`, oriented so that its dot
  // product with up (+z) is positive. A surface whose normal has a negative
  // dot product with it is imaged flipped: the layover condition.
  Eigen::Vector3d UpwardRangePlaneNormal(const Eigen::Vector3d& p) const;

  // Ellipsoid incidence angle theta_i (degrees from the vertical) of image
  // column `col` (docs/radiometry.md): affine mode 90 deg - depression for
  // every column; exact mode the angle at the point of the reference plane
  // through the scene centre (the ellipsoid's tangent plane, curvature
  // neglected) at the column's slant range from the flight line:
  // 90 deg - asin(R sin(d) / r); 0 where r <= R sin(d) (below the sensor).
  double IncidenceDeg(double col) const;

  // Column of a slant range and row of an along-track coordinate.
  double ColumnOfRange(double slant_range_m) const;
  double RowOfAlongTrack(double along_track_m) const;

  // All parameters as "GISSAR_*" key/value strings for image metadata.
  std::map<std::string, std::string> ToMetadata() const;

 private:
  SarGeometryOptions options_;
  Eigen::Vector3d xc_;
  double u0_, v0_;
  int width_, height_;
  Eigen::Vector3d h_, l_, n_;
};

}  // namespace gissar::sensor
