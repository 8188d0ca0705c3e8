#include "gissar/sensor/georeference.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::sensor {
namespace {

// GDAL's (RPC00B) order of the 20 cubic terms in (L = lon, P = lat, H = height).
std::array<double, 20> RpcTerms(double L, double P, double H) {
  return {1.0,       L,         P,         H,         L * P,     L * H,     P * H,
          L * L,     P * P,     H * H,     P * L * H, L * L * L, L * P * P, L * H * H,
          L * L * P, P * P * P, P * H * H, L * L * H, P * P * H, H * H * H};
}

std::string Coefficients(const Eigen::VectorXd& c) {
  std::string out;
  char buf[40];
  for (int i = 0; i < c.size(); ++i) {
    std::snprintf(buf, sizeof(buf), "%s%.17g", i ? " " : "", c[i]);
    out += buf;
  }
  return out;
}

std::string Number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

}  // namespace

Eigen::Vector2d LatticePixel(const SarGeometry& geometry, int grid, int i, int j) {
  return Eigen::Vector2d((geometry.width() - 1) * double(i) / (grid - 1),
                         (geometry.height() - 1) * double(j) / (grid - 1));
}

namespace {

// What the loci of all lattice nodes share: the height band searched
// (the terrain's +-margin) and the march's quarter-pixel step, the range
// plane's upward normal and the horizontal look direction.
struct LocusFrame {
  const SarGeometry& geometry;
  double z_top = 0.0, z_bottom = 0.0;
  double step_m = 0.0;
  Eigen::Vector3d up{0.0, 0.0, 1.0};
  Eigen::Vector3d n_up;  // the range plane's normal, pointing up
  Eigen::Vector3d r_h;   // the look direction projected on the horizontal, unit

  LocusFrame(const SarGeometry& g, double z_min_m, double z_max_m, double margin_m) : geometry(g) {
    z_top = z_max_m + margin_m;
    z_bottom = z_min_m - margin_m;
    step_m = 0.25 * std::min(g.range_spacing_m(), g.azimuth_spacing_m());
    n_up = g.range_plane_normal();
    if (n_up.z() < 0) n_up = -n_up;
    const Eigen::Vector3d& l = g.look_direction();
    r_h = Eigen::Vector3d(l.x(), l.y(), 0.0);
    r_h.normalize();
  }
};

// The locus of a pixel as a curve point(s), s from the top (s_top) down
// (s_bottom) in steps of ds: the affine model's line along n_up, or exact
// mode's iso-range circle in the zero-Doppler plane (s the angle below the
// horizontal).
struct PixelLocus {
  std::function<Eigen::Vector3d(double)> point;
  double s_top = 0.0, s_bottom = 0.0, ds = 0.0;
  double along = 0.0;  // the pixel's along-track position, m
  double range = 0.0;  // its slant range, m
};

PixelLocus LocusOfPixel(const LocusFrame& lf, const Eigen::Vector2d& pixel) {
  const SarGeometry& geometry = lf.geometry;
  const Eigen::Vector3d& l = geometry.look_direction();
  const Eigen::Vector3d& h = geometry.flight_direction();
  PixelLocus locus;
  const double col = pixel.x(), row = pixel.y();
  const double along = (row - geometry.v0()) * geometry.azimuth_spacing_m();
  const double range = geometry.slant_range_m() + (col - geometry.u0()) * geometry.range_spacing_m();
  locus.along = along;
  locus.range = range;
  if (geometry.mode() == ProjectionMode::kAffine) {
    const Eigen::Vector3d base = geometry.scene_centre() +
                                 (range - geometry.slant_range_m()) * l + along * h;
    const Eigen::Vector3d n_up = lf.n_up;
    locus.point = [base, n_up](double t) -> Eigen::Vector3d { return base + t * n_up; };
    locus.s_top = (lf.z_top - base.z()) / n_up.z();
    locus.s_bottom = (lf.z_bottom - base.z()) / n_up.z();
    locus.ds = -lf.step_m;
  } else {
    const Eigen::Vector3d sensor = geometry.SensorPosition(along);
    const Eigen::Vector3d r_h = lf.r_h, up = lf.up;
    locus.point = [sensor, r_h, up, range](double phi) -> Eigen::Vector3d {
      return sensor + range * (std::cos(phi) * r_h - std::sin(phi) * up);
    };
    auto angle = [&](double z) { return std::asin(std::clamp((sensor.z() - z) / range, -1.0, 1.0)); };
    locus.s_top = angle(lf.z_top);
    locus.s_bottom = angle(lf.z_bottom);
    locus.ds = lf.step_m / range;
  }
  return locus;
}

// Only the part of the locus over the surface's plan box can meet it:
// the locus moves horizontally along a line xy = o + lambda u
// (lambda = s for affine, range cos(s) for exact, s in [0, pi / 2]).
// Narrows [s_top, s_bottom] to it; false when the locus never passes over
// the surface.
bool ClipLocusToPlan(const LocusFrame& lf, const Eigen::AlignedBox2d& plan, PixelLocus& locus) {
  const SarGeometry& geometry = lf.geometry;
  double& s_top = locus.s_top;
  double& s_bottom = locus.s_bottom;
  const double range = locus.range;
  const Eigen::Vector2d lo = plan.min().array() - 1.0, hi = plan.max().array() + 1.0;
  Eigen::Vector2d o, u;
  const bool affine = geometry.mode() == ProjectionMode::kAffine;
  if (affine) {
    o = locus.point(0.0).head<2>();
    u = lf.n_up.head<2>();
  } else {
    o = geometry.SensorPosition(locus.along).head<2>();
    u = lf.r_h.head<2>();
  }
  double lambda_lo = -std::numeric_limits<double>::infinity(), lambda_hi = -lambda_lo;
  for (int k = 0; k < 2; ++k) {
    if (std::abs(u[k]) < 1e-12) {
      if (o[k] < lo[k] || o[k] > hi[k]) lambda_hi = lambda_lo - 1.0;
      continue;
    }
    double a = (lo[k] - o[k]) / u[k], b = (hi[k] - o[k]) / u[k];
    if (a > b) std::swap(a, b);
    lambda_lo = std::max(lambda_lo, a);
    lambda_hi = std::min(lambda_hi, b);
  }
  if (!(lambda_lo <= lambda_hi)) return false;  // the locus never passes over the surface
  if (affine) {
    // s runs down from s_top to s_bottom.
    s_top = std::min(s_top, lambda_hi);
    s_bottom = std::max(s_bottom, lambda_lo);
    if (!(s_top > s_bottom)) return false;
  } else if (s_top >= 0.0 && s_bottom <= 0.5 * M_PI) {
    // s (the angle below the horizontal) runs up from s_top; lambda
    // falls as s grows.
    const double s_near = std::acos(std::clamp(lambda_hi / range, -1.0, 1.0));
    const double s_far = std::acos(std::clamp(lambda_lo / range, -1.0, 1.0));
    s_top = std::max(s_top, s_near);
    s_bottom = std::min(s_bottom, s_far);
    if (!(s_top < s_bottom)) return false;
  }
  return true;
}

// The first point of the locus, from the top, where it meets the surface:
// marched in steps and bisected; nullopt when it never does.
std::optional<Eigen::Vector3d> MarchToFirstCrossing(const LocusFrame& lf, const PixelLocus& locus,
                                                    const SurfaceHeight& surface, double max_gradient) {
  const auto& point = locus.point;
  const double s_top = locus.s_top, s_bottom = locus.s_bottom, ds = locus.ds, range = locus.range;
  const Eigen::Vector3d& n_up = lf.n_up;
  auto above = [&](double s, bool* valid) {
    const Eigen::Vector3d p = point(s);
    const double zs = surface(p.x(), p.y());
    *valid = std::isfinite(zs);
    return p.z() - zs;
  };
  // How fast the height above the terrain, f(s), can fall per unit of s
  // where the surface is defined: the locus point moves at unit speed
  // along n_up (affine), or `range` metres per radian with vertical and
  // horizontal parts at most `range` (exact), and the surface rises at
  // most max_gradient per horizontal metre. A point f above the terrain
  // is then at least f / rate from the first crossing, which a step of
  // 0.9 f / rate cannot pass; below a quarter pixel the march takes its
  // fixed steps, so the crossing is bracketed as before.
  const double rate = lf.geometry.mode() == ProjectionMode::kAffine
                          ? n_up.z() + max_gradient * n_up.head<2>().norm()
                          : range * (1.0 + max_gradient);
  const bool leap = std::isfinite(rate) && rate > 0.0;
  const double direction = ds > 0.0 ? 1.0 : -1.0, fixed = std::abs(ds);
  double prev_s = s_top;
  bool prev_valid = false;
  double prev_f = above(prev_s, &prev_valid);
  while (direction * (s_bottom - prev_s) > 0.0) {
    double s = prev_s + direction * fixed;
    bool valid = false;
    double f;
    const double stride = leap && prev_valid && prev_f > 0.0 ? 0.9 * prev_f / rate : 0.0;
    if (stride > fixed) {
      s = prev_s + direction * stride;
      f = above(s, &valid);
      if (!valid) {  // left the surface's domain: the bound says nothing there
        s = prev_s + direction * fixed;
        f = above(s, &valid);
      }
    } else {
      f = above(s, &valid);
    }
    if (valid && prev_valid && prev_f > 0 && f <= 0) {
      // Bisection to 2^-26 of the bracket (a 60th of a micrometre for
      // 10 m pixels).
      double a = prev_s, b = s;
      for (int it = 0; it < 26; ++it) {
        const double m = 0.5 * (a + b);
        bool v = false;
        const double fm = above(m, &v);
        if (!v || fm > 0) a = m; else b = m;
      }
      return point(0.5 * (a + b));
    }
    prev_s = s;
    prev_f = f;
    prev_valid = valid;
  }
  return std::nullopt;
}

// The GCP of terrain point `p` (ENU): its pixel (GDAL's convention, the
// first pixel's corner at 0) and geodetic position.
geo::GroundControlPoint GcpOfPoint(const SarGeometry& geometry, const geo::LocalFrame& frame,
                                   const Eigen::Vector3d& p) {
  const Eigen::Vector3d g = frame.GeodeticFromEnu(p);
  const Eigen::Vector2d px = geometry.Project(p);
  return geo::GroundControlPoint{px.x() + 0.5, px.y() + 0.5, g.x(), g.y(), g.z()};
}

// The RPC metadata, fitted to geometry.Project() on a 15 x 15 x 7 lattice
// over the GCPs' footprint (grown by 10 %) and their heights +-margin_m;
// the fit's residuals go to `report`.
geo::Metadata FitRpc(const SarGeometry& geometry, const geo::LocalFrame& frame,
                     const std::vector<geo::GroundControlPoint>& gcps, double margin_m, GeoreferenceReport* report) {
  double lon_min = 1e9, lon_max = -1e9, lat_min = 1e9, lat_max = -1e9, h_min = 1e9, h_max = -1e9;
  for (const auto& g : gcps) {
    lon_min = std::min(lon_min, g.lon_deg);
    lon_max = std::max(lon_max, g.lon_deg);
    lat_min = std::min(lat_min, g.lat_deg);
    lat_max = std::max(lat_max, g.lat_deg);
    h_min = std::min(h_min, g.height_m);
    h_max = std::max(h_max, g.height_m);
  }
  const double lon_off = 0.5 * (lon_min + lon_max), lat_off = 0.5 * (lat_min + lat_max);
  const double h_off = 0.5 * (h_min + h_max);
  const double lon_scale = std::max(0.55 * (lon_max - lon_min), 1e-6);
  const double lat_scale = std::max(0.55 * (lat_max - lat_min), 1e-6);
  const double h_scale = 0.5 * (h_max - h_min) + margin_m;
  const double samp_off = 0.5 * (geometry.width() - 1), line_off = 0.5 * (geometry.height() - 1);
  const double samp_scale = std::max(0.5 * geometry.width(), 1.0);
  const double line_scale = std::max(0.5 * geometry.height(), 1.0);
  const int nl = 15, nh = 7;
  const int n = nl * nl * nh;
  Eigen::MatrixXd A(n, 20);
  Eigen::VectorXd bs(n), bl(n);
  int k = 0;
  for (int a = 0; a < nh; ++a) {
    for (int b = 0; b < nl; ++b) {
      for (int c = 0; c < nl; ++c, ++k) {
        const double H = -1.0 + 2.0 * a / (nh - 1);
        const double P = -1.0 + 2.0 * b / (nl - 1);
        const double L = -1.0 + 2.0 * c / (nl - 1);
        const Eigen::Vector3d enu = frame.EnuFromGeodetic(lon_off + L * lon_scale,
                                                          lat_off + P * lat_scale, h_off + H * h_scale);
        const Eigen::Vector2d px = geometry.Project(enu);
        const auto terms = RpcTerms(L, P, H);
        for (int t = 0; t < 20; ++t) A(k, t) = terms[t];
        bs[k] = (px.x() - samp_off) / samp_scale;
        bl[k] = (px.y() - line_off) / line_scale;
      }
    }
  }
  const auto qr = A.colPivHouseholderQr();
  const Eigen::VectorXd cs = qr.solve(bs), cl = qr.solve(bl);
  const Eigen::VectorXd rs = (A * cs - bs) * samp_scale, rl = (A * cl - bl) * line_scale;
  double max_err = 0.0, sum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double e = std::hypot(rs[i], rl[i]);
    max_err = std::max(max_err, e);
    sum2 += e * e;
  }
  Eigen::VectorXd den = Eigen::VectorXd::Zero(20);
  den[0] = 1.0;
  geo::Metadata rpc = {{"LINE_OFF", Number(line_off)},     {"SAMP_OFF", Number(samp_off)},
                       {"LAT_OFF", Number(lat_off)},       {"LONG_OFF", Number(lon_off)},
                       {"HEIGHT_OFF", Number(h_off)},      {"LINE_SCALE", Number(line_scale)},
                       {"SAMP_SCALE", Number(samp_scale)}, {"LAT_SCALE", Number(lat_scale)},
                       {"LONG_SCALE", Number(lon_scale)},  {"HEIGHT_SCALE", Number(h_scale)},
                       {"LINE_NUM_COEFF", Coefficients(cl)}, {"LINE_DEN_COEFF", Coefficients(den)},
                       {"SAMP_NUM_COEFF", Coefficients(cs)}, {"SAMP_DEN_COEFF", Coefficients(den)},
                       {"MIN_LONG", Number(lon_off - lon_scale)}, {"MAX_LONG", Number(lon_off + lon_scale)},
                       {"MIN_LAT", Number(lat_off - lat_scale)},  {"MAX_LAT", Number(lat_off + lat_scale)},
                       {"ERR_BIAS", Number(-1.0)}, {"ERR_RAND", Number(-1.0)}};
  if (report != nullptr) {
    report->gcp_count = static_cast<int>(gcps.size());
    report->rpc_max_error_px = max_err;
    report->rpc_rms_error_px = std::sqrt(sum2 / n);
  }
  return rpc;
}

}  // namespace

geo::Georeference SlantRangeGeoreference(const SarGeometry& geometry, const geo::LocalFrame& frame,
                                         const SurfaceHeight& surface, double z_min_m,
                                         double z_max_m, int grid, GeoreferenceReport* report,
                                         const SurfaceLimits& limits,
                                         const std::vector<KnownLatticePoint>* known) {
  if (grid < 2) throw ConfigError("GCP grid must be at least 2 x 2", "georeference");
  GISSAR_CHECK(known == nullptr || known->size() == size_t(grid) * grid);
  const double margin_m = 100.0;
  const LocusFrame lf(geometry, z_min_m, z_max_m, margin_m);

  // Lattice nodes in parallel (the surface is read-only), kept in lattice
  // order: the GCPs are the same whatever the thread count.
  std::vector<std::optional<geo::GroundControlPoint>> found(size_t(grid) * grid);
  tbb::parallel_for(tbb::blocked_range<int>(0, grid * grid, 8), [&](const tbb::blocked_range<int>& nodes) {
    for (int node = nodes.begin(); node < nodes.end(); ++node) {
      if (known != nullptr && (*known)[size_t(node)].known) {
        if (const auto& p = (*known)[size_t(node)].enu) found[size_t(node)] = GcpOfPoint(geometry, frame, *p);
        continue;
      }
      PixelLocus locus = LocusOfPixel(lf, LatticePixel(geometry, grid, node % grid, node / grid));
      if (!limits.plan.isEmpty() && !ClipLocusToPlan(lf, limits.plan, locus)) continue;
      if (const auto p = MarchToFirstCrossing(lf, locus, surface, limits.max_gradient)) {
        found[size_t(node)] = GcpOfPoint(geometry, frame, *p);
      }
    }
  });
  geo::Georeference out;
  for (const auto& gcp : found) {
    if (gcp) out.gcps.push_back(*gcp);
  }
  if (out.gcps.size() < 3) {
    throw ConfigError("fewer than 3 image pixels see the terrain; no georeferencing possible",
                      "georeference");
  }
  out.rpc = FitRpc(geometry, frame, out.gcps, margin_m, report);
  return out;
}

}  // namespace gissar::sensor
