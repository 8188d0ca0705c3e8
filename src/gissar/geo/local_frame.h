// Local metric frame of a scene: a local East-North-Up (ENU) tangent frame on
// the WGS84 ellipsoid, with its origin at the scene centre (longitude,
// latitude) at ellipsoidal height 0. x = East, y = North (true north at the
// origin), z = Up, metres. Earth curvature is kept: a point 15 km from the
// origin at height 0 lies ~17.6 m below the tangent plane, as a real sensor
// sees it. Heights are WGS84 ellipsoidal: DEM heights in another vertical
// datum are converted first (vertical_datum.h, docs/geometry.md).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace gissar::geo {

class LocalFrame {
 public:
  // Origin at geodetic (lon_deg, lat_deg, height_m) on WGS84. Throws
  // ConfigError when the latitude is outside [-90, 90] or any value is not
  // finite.
  LocalFrame(double lon_deg, double lat_deg, double height_m = 0.0);

  double origin_lon_deg() const { return lon0_deg_; }
  double origin_lat_deg() const { return lat0_deg_; }
  double origin_height_m() const { return h0_m_; }

  // WGS84 geodetic (degrees, metres above the ellipsoid) -> ENU metres.
  Eigen::Vector3d EnuFromGeodetic(double lon_deg, double lat_deg, double height_m) const;
  // ENU metres -> (lon_deg, lat_deg, height_m).
  Eigen::Vector3d GeodeticFromEnu(const Eigen::Vector3d& enu) const;

  // ENU metres <-> ECEF metres (the frame's rigid transform: origin and
  // rotation; exact, no geodetic round trip).
  Eigen::Vector3d EcefFromEnu(const Eigen::Vector3d& enu) const { return origin_ecef_ + enu_from_ecef_.transpose() * enu; }
  Eigen::Vector3d EnuFromEcef(const Eigen::Vector3d& ecef) const { return enu_from_ecef_ * (ecef - origin_ecef_); }
  // An ECEF direction (a velocity, a line of sight) in ENU components.
  Eigen::Vector3d EnuVectorFromEcef(const Eigen::Vector3d& v) const { return enu_from_ecef_ * v; }

  // WGS84 geodetic -> Earth-centred Earth-fixed metres, and back.
  static Eigen::Vector3d EcefFromGeodetic(double lon_deg, double lat_deg, double height_m);
  static Eigen::Vector3d GeodeticFromEcef(const Eigen::Vector3d& ecef);

 private:
  double lon0_deg_, lat0_deg_, h0_m_;
  Eigen::Vector3d origin_ecef_;
  Eigen::Matrix3d enu_from_ecef_;  // rows: east, north, up unit vectors
};

// Transforms coordinates of a CRS (given as WKT or any string OGR accepts)
// to WGS84 longitude/latitude in degrees, and back, through PROJ. Axis order
// is always (x/easting/longitude, y/northing/latitude).
// Applies a PROJ pipeline string ("+proj=pipeline +step ...") to points,
// coordinates in the pipeline's own units (e.g. the ENU -> WGS84 degrees
// pipeline of a mesh sidecar). Throws InputError when PROJ rejects it or a
// point fails.
std::vector<Eigen::Vector3d> ApplyProjPipeline(const std::string& pipeline,
                                               const std::vector<Eigen::Vector3d>& points);

class CrsTransform {
 public:
  // Throws InputError when the CRS cannot be parsed or no transformation
  // exists.
  explicit CrsTransform(const std::string& crs_definition);
  ~CrsTransform();
  CrsTransform(const CrsTransform&) = delete;
  CrsTransform& operator=(const CrsTransform&) = delete;

  bool source_is_geographic() const { return source_is_geographic_; }

  // In place: map x,y -> lon,lat (degrees). Throws InputError if any point
  // fails to transform.
  void ToLonLat(std::vector<double>& x, std::vector<double>& y) const;
  // In place: lon,lat -> map x,y.
  void FromLonLat(std::vector<double>& lon, std::vector<double>& lat) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  bool source_is_geographic_ = false;
};

}  // namespace gissar::geo
