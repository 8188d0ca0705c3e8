#include "gissar/geo/local_frame.h"

#include <ogr_spatialref.h>

#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace {

constexpr double kWgs84A = 6378137.0;
constexpr double kWgs84F = 1.0 / 298.257223563;
constexpr double kWgs84E2 = kWgs84F * (2.0 - kWgs84F);
constexpr double kDegToRad = M_PI / 180.0;

}  // namespace

LocalFrame::LocalFrame(double lon_deg, double lat_deg, double height_m)
    : lon0_deg_(lon_deg), lat0_deg_(lat_deg), h0_m_(height_m) {
  if (!std::isfinite(lon_deg) || !std::isfinite(lat_deg) || !std::isfinite(height_m)) {
    throw ConfigError("scene centre must be finite", "lon/lat/height");
  }
  if (lat_deg < -90.0 || lat_deg > 90.0) {
    throw ConfigError("scene centre latitude must be in [-90, 90] degrees",
                      std::to_string(lat_deg));
  }
  origin_ecef_ = EcefFromGeodetic(lon_deg, lat_deg, height_m);
  const double lam = lon_deg * kDegToRad, phi = lat_deg * kDegToRad;
  enu_from_ecef_ << -std::sin(lam), std::cos(lam), 0.0,                              //
      -std::sin(phi) * std::cos(lam), -std::sin(phi) * std::sin(lam), std::cos(phi),  //
      std::cos(phi) * std::cos(lam), std::cos(phi) * std::sin(lam), std::sin(phi);
}

Eigen::Vector3d LocalFrame::EcefFromGeodetic(double lon_deg, double lat_deg, double height_m) {
  const double lam = lon_deg * kDegToRad, phi = lat_deg * kDegToRad;
  const double s = std::sin(phi), c = std::cos(phi);
  const double n = kWgs84A / std::sqrt(1.0 - kWgs84E2 * s * s);
  return {(n + height_m) * c * std::cos(lam), (n + height_m) * c * std::sin(lam),
          (n * (1.0 - kWgs84E2) + height_m) * s};
}

Eigen::Vector3d LocalFrame::GeodeticFromEcef(const Eigen::Vector3d& ecef) {
  const double p = std::hypot(ecef.x(), ecef.y());
  const double lam = std::atan2(ecef.y(), ecef.x());
  double phi = std::atan2(ecef.z(), p * (1.0 - kWgs84E2));
  double h = 0.0;
  for (int i = 0; i < 8; ++i) {
    const double s = std::sin(phi);
    const double n = kWgs84A / std::sqrt(1.0 - kWgs84E2 * s * s);
    // Height form that stays well conditioned near the poles.
    h = p * std::cos(phi) + ecef.z() * s - kWgs84A * std::sqrt(1.0 - kWgs84E2 * s * s);
    phi = std::atan2(ecef.z(), p * (1.0 - kWgs84E2 * n / (n + h)));
  }
  return {lam / kDegToRad, phi / kDegToRad, h};
}

Eigen::Vector3d LocalFrame::EnuFromGeodetic(double lon_deg, double lat_deg,
                                            double height_m) const {
  return enu_from_ecef_ * (EcefFromGeodetic(lon_deg, lat_deg, height_m) - origin_ecef_);
}

Eigen::Vector3d LocalFrame::GeodeticFromEnu(const Eigen::Vector3d& enu) const {
  return GeodeticFromEcef(origin_ecef_ + enu_from_ecef_.transpose() * enu);
}

struct CrsTransform::Impl {
  OGRCoordinateTransformation* to_lonlat = nullptr;
  OGRCoordinateTransformation* from_lonlat = nullptr;
  ~Impl() {
    OGRCoordinateTransformation::DestroyCT(to_lonlat);
    OGRCoordinateTransformation::DestroyCT(from_lonlat);
  }
};

namespace {

// The transformations found for a CRS definition, kept for the process: PROJ's
// search for the operation to WGS84 takes 10-15 ms (its database), a clone of
// the operation found 0.1-0.4 ms, and a run builds one CrsTransform per
// thread and step (DemPostsInFrame's blocks among them). Never destroyed (no
// ordering problem with GDAL's own clean-up at exit); at most kMaxPrototypes
// definitions, the oldest dropped first.
struct Prototype {
  std::string definition;
  std::unique_ptr<OGRCoordinateTransformation> to_lonlat, from_lonlat;
  bool geographic = false;
};
constexpr size_t kMaxPrototypes = 16;
std::mutex& PrototypeMutex() {
  static std::mutex* mutex = new std::mutex;
  return *mutex;
}
std::deque<Prototype>& Prototypes() {
  static auto* prototypes = new std::deque<Prototype>;
  return *prototypes;
}

}  // namespace

CrsTransform::CrsTransform(const std::string& crs_definition) : impl_(std::make_unique<Impl>()) {
  EnsureGdal();
  if (crs_definition.empty()) {
    throw InputError("raster has no coordinate reference system", "");
  }
  {
    // Clones in this thread's PROJ context, under the lock (the prototype's
    // objects are read by one thread at a time).
    const std::lock_guard<std::mutex> lock(PrototypeMutex());
    for (const Prototype& p : Prototypes()) {
      if (p.definition != crs_definition) continue;
      impl_->to_lonlat = p.to_lonlat->Clone();
      impl_->from_lonlat = p.from_lonlat->Clone();
      if (impl_->to_lonlat != nullptr && impl_->from_lonlat != nullptr) {
        source_is_geographic_ = p.geographic;
        return;
      }
      OGRCoordinateTransformation::DestroyCT(impl_->to_lonlat);
      OGRCoordinateTransformation::DestroyCT(impl_->from_lonlat);
      impl_->to_lonlat = impl_->from_lonlat = nullptr;
      break;
    }
  }
  OGRSpatialReference source, wgs84;
  if (source.SetFromUserInput(crs_definition.c_str()) != OGRERR_NONE) {
    throw InputError("cannot parse coordinate reference system", crs_definition.substr(0, 80));
  }
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs84.SetWellKnownGeogCS("WGS84");
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  source_is_geographic_ = source.IsGeographic();
  impl_->to_lonlat = OGRCreateCoordinateTransformation(&source, &wgs84);
  // The inverse of the operation found (no second search); a new search
  // where it has none.
  if (impl_->to_lonlat != nullptr) impl_->from_lonlat = impl_->to_lonlat->GetInverse();
  if (impl_->from_lonlat == nullptr) impl_->from_lonlat = OGRCreateCoordinateTransformation(&wgs84, &source);
  if (impl_->to_lonlat == nullptr || impl_->from_lonlat == nullptr) {
    throw InputError("no transformation from the raster's CRS to WGS84: " + LastGdalMessage(),
                     crs_definition.substr(0, 80));
  }
  Prototype p{crs_definition, std::unique_ptr<OGRCoordinateTransformation>(impl_->to_lonlat->Clone()),
              std::unique_ptr<OGRCoordinateTransformation>(impl_->from_lonlat->Clone()), source_is_geographic_};
  if (!p.to_lonlat || !p.from_lonlat) return;
  const std::lock_guard<std::mutex> lock(PrototypeMutex());
  std::deque<Prototype>& prototypes = Prototypes();
  for (const Prototype& q : prototypes) {
    if (q.definition == crs_definition) return;  // another thread was first
  }
  if (prototypes.size() >= kMaxPrototypes) prototypes.pop_front();
  prototypes.push_back(std::move(p));
}

CrsTransform::~CrsTransform() = default;

namespace {

void TransformInPlace(OGRCoordinateTransformation* ct, std::vector<double>& x,
                      std::vector<double>& y) {
  if (x.size() != y.size()) throw InputError("coordinate arrays differ in length", "");
  if (x.empty()) return;
  std::vector<int> ok(x.size(), 0);
  if (!ct->Transform(x.size(), x.data(), y.data(), nullptr, ok.data())) {
    throw InputError("coordinate transformation failed: " + LastGdalMessage(), "");
  }
  for (size_t i = 0; i < ok.size(); ++i) {
    if (!ok[i] || !std::isfinite(x[i]) || !std::isfinite(y[i])) {
      throw InputError("coordinate transformation failed for a point", "point " + std::to_string(i));
    }
  }
}

}  // namespace

void CrsTransform::ToLonLat(std::vector<double>& x, std::vector<double>& y) const {
  TransformInPlace(impl_->to_lonlat, x, y);
}

void CrsTransform::FromLonLat(std::vector<double>& lon, std::vector<double>& lat) const {
  TransformInPlace(impl_->from_lonlat, lon, lat);
}

std::vector<Eigen::Vector3d> ApplyProjPipeline(const std::string& pipeline,
                                               const std::vector<Eigen::Vector3d>& points) {
  EnsureGdal();
  OGRCoordinateTransformationOptions options;
  if (!options.SetCoordinateOperation(pipeline.c_str(), false)) {
    throw InputError("PROJ rejects the pipeline: " + LastGdalMessage(), pipeline);
  }
  std::unique_ptr<OGRCoordinateTransformation> transform(
      OGRCreateCoordinateTransformation(nullptr, nullptr, options));
  if (!transform) throw InputError("cannot build the PROJ pipeline: " + LastGdalMessage(), pipeline);
  std::vector<double> x, y, z;
  for (const auto& p : points) {
    x.push_back(p.x());
    y.push_back(p.y());
    z.push_back(p.z());
  }
  std::vector<int> ok(points.size(), 0);
  if (!points.empty() && !transform->Transform(points.size(), x.data(), y.data(), z.data(), nullptr, ok.data())) {
    throw InputError("PROJ pipeline failed on a point", pipeline);
  }
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < points.size(); ++i) out.emplace_back(x[i], y[i], z[i]);
  return out;
}

}  // namespace gissar::geo
