#include "gissar/sensor/sar_geometry.h"

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <array>
#include <cmath>
#include <sstream>
#include <string>

#include "gissar/util/error.h"

namespace gissar::sensor {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::string Num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

// A given side (`size` pixels of `spacing_m`, named `flag`) must not span
// more than kMaxImageExtentM: its footprint would leave the Earth.
void CheckGivenExtent(int size, double spacing_m, const char* flag, const char* spacing_flag) {
  const double extent_m = double(size) * spacing_m;
  if (size <= 0 || extent_m <= kMaxImageExtentM) return;
  std::ostringstream text;
  text << flag << " " << size << " at " << spacing_m << " m per pixel spans " << std::llround(extent_m / 1e3)
       << " km, beyond the Earth's radius (" << std::llround(kMaxImageExtentM / 1e3)
       << " km): the image's footprint would leave the Earth; use a smaller " << flag << " or a finer "
       << spacing_flag;
  throw ConfigError(text.str(), "--width/--height");
}

}  // namespace

Eigen::Vector3d FlightDirection(double heading_deg) {
  const double psi = heading_deg * kDegToRad;
  return {std::sin(psi), std::cos(psi), 0.0};
}

Eigen::Vector3d LookDirection(double heading_deg, double depression_deg, LookSide look_side) {
  const double psi = heading_deg * kDegToRad;
  const double dep = depression_deg * kDegToRad;
  Eigen::Vector3d r_h(std::cos(psi), -std::sin(psi), 0.0);
  if (look_side == LookSide::kLeft) r_h = -r_h;
  return std::cos(dep) * r_h - std::sin(dep) * Eigen::Vector3d::UnitZ();
}

LookSide ParseLookSide(const std::string& text, const std::string& option) {
  return kLookSides.Parse(text, option);
}

ProjectionMode ParseProjectionMode(const std::string& text, const std::string& option) {
  return kProjectionModes.Parse(text, option);
}

std::string ToString(LookSide side) { return std::string(kLookSides.Name(side)); }
std::string ToString(ProjectionMode mode) { return std::string(kProjectionModes.Name(mode)); }

void SarGeometryOptions::Check() const {
  // Bounds: a heading is an angle (headings drift past 360 in pose
  // searches, so a few turns are fine, but 1e300 is no direction); the
  // farthest SAR is geostationary (36,000 km): 1e8 m bounds any slant
  // range; 100 km bounds any pixel spacing.
  if (!std::isfinite(heading_deg) || std::abs(heading_deg) > kMaxAbsHeadingDeg) {
    throw ConfigError("heading must be within +-10000 degrees, got " + Num(heading_deg), "--heading");
  }
  if (!std::isfinite(depression_deg) || depression_deg <= 0.0 || depression_deg >= 90.0) {
    throw ConfigError("depression must be in (0, 90) degrees, got " + Num(depression_deg),
                      "--depression");
  }
  if (!std::isfinite(slant_range_m) || slant_range_m <= 0.0 || slant_range_m > kMaxSlantRangeM) {
    throw ConfigError("slant range must be in (0, 1e8] m, got " + Num(slant_range_m), "--slant-range");
  }
  if (!std::isfinite(range_spacing_m) || range_spacing_m <= 0.0 || range_spacing_m > kMaxPixelSpacingM) {
    throw ConfigError("range pixel spacing must be in (0, 1e5] m, got " + Num(range_spacing_m),
                      "--range-spacing");
  }
  if (!std::isfinite(azimuth_spacing_m) || azimuth_spacing_m <= 0.0 || azimuth_spacing_m > kMaxPixelSpacingM) {
    throw ConfigError("azimuth pixel spacing must be in (0, 1e5] m, got " + Num(azimuth_spacing_m),
                      "--azimuth-spacing");
  }
  if (width < 0 || height < 0) throw ConfigError("image size must not be negative", "--width/--height");
  // A given size: checked here, before anything projects its footprint.
  if (width > 0 && height > 0 && double(width) * double(height) > double(kMaxImagePixels)) {
    throw ConfigError("image of " + std::to_string(width) + " x " + std::to_string(height) + " pixels is over the " +
                          std::to_string(kMaxImagePixels) + "-pixel limit; use a smaller --width/--height",
                      "--width/--height");
  }
}

SarGeometry::SarGeometry(const SarGeometryOptions& options, const Eigen::Vector3d& scene_centre,
                         double u0, double v0, int width, int height)
    : options_(options), xc_(scene_centre), u0_(u0), v0_(v0), width_(width), height_(height) {
  options_.Check();
  if (width <= 0 || height <= 0) throw ConfigError("image size must be positive", "--width/--height");
  h_ = FlightDirection(options.heading_deg);
  l_ = LookDirection(options.heading_deg, options.depression_deg, options.look_side);
  n_ = l_.cross(h_);
  options_.width = width;
  options_.height = height;
}

SarGeometry SarGeometry::Covering(const SarGeometryOptions& options,
                                  const Eigen::Vector3d& scene_centre,
                                  const std::vector<Eigen::Vector3f>& points, int margin_px,
                                  int64_t max_pixels) {
  options.Check();
  // A given size, with the spacings resolved: before anything projects its
  // footprint (a DEM window, a map projection).
  CheckGivenExtent(options.width, options.range_spacing_m, "--width", "--range-spacing");
  CheckGivenExtent(options.height, options.azimuth_spacing_m, "--height", "--azimuth-spacing");
  if (options.width > 0 && options.height > 0) {
    if (double(options.width) * double(options.height) > static_cast<double>(max_pixels)) {
      throw ConfigError("image of " + std::to_string(options.width) + " x " + std::to_string(options.height) +
                            " pixels is too large; use a smaller --width/--height",
                        "--width/--height");
    }
    return SarGeometry(options, scene_centre, (options.width - 1) / 2.0,
                       (options.height - 1) / 2.0, options.width, options.height);
  }
  // Project with a provisional frame (Xc at pixel 0,0), then shift. A
  // column grows with slant range and a row with the along-track coordinate
  // (ColumnOfRange and RowOfAlongTrack are monotonic in floating point too),
  // so the extent is that of the posts' slant ranges and along-track
  // coordinates, mapped once: the same columns and rows as projecting every
  // post, without the per-post pixel arithmetic.
  const SarGeometry probe(options, scene_centre, 0.0, 0.0, 1, 1);
  const bool affine = options.mode == ProjectionMode::kAffine;
  const double range0 = probe.options_.slant_range_m;
  // Extent of the slant ranges and along-track coordinates (in parallel: a
  // large DEM has tens of millions of posts); min and max do not depend on
  // the order; non-finite posts are skipped as std::min/max skip NaN.
  using Extent = std::array<double, 4>;  // slant range min, max, along-track min, max
  const Extent extent_m = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, points.size(), size_t(1) << 16), Extent{range0, range0, 0.0, 0.0},
      [&](const tbb::blocked_range<size_t>& range, Extent e) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
          const Eigen::Vector3d p = points[i].cast<double>();
          const double along = probe.AlongTrack(p);
          // SlantRange(p), with the along-track coordinate computed once.
          const double r = affine ? range0 + (p - probe.xc_).dot(probe.l_)
                                  : (p - probe.SensorPosition(along)).norm();
          e = {std::min(e[0], r), std::max(e[1], r), std::min(e[2], along), std::max(e[3], along)};
        }
        return e;
      },
      [](const Extent& a, const Extent& b) {
        return Extent{std::min(a[0], b[0]), std::max(a[1], b[1]), std::min(a[2], b[2]), std::max(a[3], b[3])};
      });
  const Extent extent = {probe.ColumnOfRange(extent_m[0]), probe.ColumnOfRange(extent_m[1]),
                         probe.RowOfAlongTrack(extent_m[2]), probe.RowOfAlongTrack(extent_m[3])};
  const double cmin = extent[0], cmax = extent[1], rmin = extent[2], rmax = extent[3];
  const double u0 = std::ceil(-cmin) + margin_px;
  const double v0 = std::ceil(-rmin) + margin_px;
  const double width_d = std::ceil(cmax + u0) + margin_px + 1;
  const double height_d = std::ceil(rmax + v0) + margin_px + 1;
  int width = options.width > 0 ? options.width : 0;
  int height = options.height > 0 ? options.height : 0;
  // The size of the image made: a given side replaces the covering one.
  const double final_width = width > 0 ? width : width_d, final_height = height > 0 ? height : height_d;
  if (final_width * final_height > static_cast<double>(max_pixels) || final_width > 1e9 || final_height > 1e9) {
    const bool given = width > 0 || height > 0;
    throw ConfigError("image of " + Num(final_width) + " x " + Num(final_height) + " pixels is too large; " +
                          (given ? "use a smaller --width/--height or coarser pixel spacing"
                                 : "use coarser pixel spacing or a smaller scene"),
                      given ? "--width/--height" : "--range-spacing/--azimuth-spacing");
  }
  return SarGeometry(options, scene_centre, width > 0 ? (width - 1) / 2.0 : u0,
                     height > 0 ? (height - 1) / 2.0 : v0,
                     width > 0 ? width : static_cast<int>(width_d),
                     height > 0 ? height : static_cast<int>(height_d));
}

Eigen::Vector3d SarGeometry::SensorPosition(double along_track_m) const {
  return xc_ - options_.slant_range_m * l_ + along_track_m * h_;
}

double SarGeometry::SlantRange(const Eigen::Vector3d& p) const {
  if (options_.mode == ProjectionMode::kAffine) {
    return options_.slant_range_m + (p - xc_).dot(l_);
  }
  return (p - SensorPosition(AlongTrack(p))).norm();
}

Eigen::Vector2d SarGeometry::Project(const Eigen::Vector3d& p) const {
  return {ColumnOfRange(SlantRange(p)), RowOfAlongTrack(AlongTrack(p))};
}

Eigen::Vector3d SarGeometry::RayDirectionTo(const Eigen::Vector3d& p) const {
  if (options_.mode == ProjectionMode::kAffine) return l_;
  return (p - SensorPosition(AlongTrack(p))).normalized();
}

Eigen::Vector3d SarGeometry::UpwardRangePlaneNormal(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d n = RayDirectionTo(p).cross(h_);
  return n.z() >= 0.0 ? n : Eigen::Vector3d(-n);
}

double SarGeometry::IncidenceDeg(double col) const {
  const double d = options_.depression_deg * M_PI / 180.0;
  if (options_.mode == ProjectionMode::kAffine) return 90.0 - options_.depression_deg;
  const double height = options_.slant_range_m * std::sin(d);
  const double r = options_.slant_range_m + (col - u0_) * options_.range_spacing_m;
  if (!(r > height)) return 0.0;
  return 90.0 - std::asin(height / r) * 180.0 / M_PI;
}

double SarGeometry::ColumnOfRange(double slant_range_m) const {
  return (slant_range_m - options_.slant_range_m) / options_.range_spacing_m + u0_;
}

double SarGeometry::RowOfAlongTrack(double along_track_m) const {
  return along_track_m / options_.azimuth_spacing_m + v0_;
}

std::map<std::string, std::string> SarGeometry::ToMetadata() const {
  const Eigen::Vector3d sensor = SensorPosition(0.0);
  return {
      {"GISSAR_PROJECTION_MODE", ToString(options_.mode)},
      {"GISSAR_HEADING_DEG", Num(options_.heading_deg)},
      {"GISSAR_DEPRESSION_DEG", Num(options_.depression_deg)},
      {"GISSAR_LOOK_SIDE", ToString(options_.look_side)},
      {"GISSAR_SLANT_RANGE_M", Num(options_.slant_range_m)},
      {"GISSAR_RANGE_SPACING_M", Num(options_.range_spacing_m)},
      {"GISSAR_AZIMUTH_SPACING_M", Num(options_.azimuth_spacing_m)},
      {"GISSAR_U0", Num(u0_)},
      {"GISSAR_V0", Num(v0_)},
      {"GISSAR_SCENE_CENTRE_ENU", Num(xc_.x()) + "," + Num(xc_.y()) + "," + Num(xc_.z())},
      {"GISSAR_SENSOR_ENU_AT_CENTRE", Num(sensor.x()) + "," + Num(sensor.y()) + "," + Num(sensor.z())},
      {"GISSAR_PIXEL_CONVENTION",
       "x=column=slant range away from radar, y=row=azimuth along flight, pixel centres at "
       "integers"},
  };
}

}  // namespace gissar::sensor
