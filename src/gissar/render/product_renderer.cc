#include "gissar/render/product_renderer.h"

#include "gissar/render/splat.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <optional>

#include "gissar/material/scattering.h"
#include "gissar/util/error.h"

namespace gissar::render {

using Eigen::Vector3d;

sensor::HeightFunction SceneHeightFunction(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                           const geo::LocalFrame& frame) {
  const Eigen::AlignedBox3d box = mesh.Bounds();
  // Geodetic heights exceed ENU z (Earth curvature): start well above.
  const double top = box.max().z() + 1000.0, bottom = box.min().z() - 100.0;
  return [&embree, frame, top, bottom](double lon, double lat) -> std::optional<double> {
    const Vector3d a = frame.EnuFromGeodetic(lon, lat, top);
    const Vector3d b = frame.EnuFromGeodetic(lon, lat, bottom);
    const Vector3d dir = (b - a).normalized();
    const auto hit = embree.Intersect(a.cast<float>(), dir.cast<float>(), 0.0f, static_cast<float>((b - a).norm()));
    if (!hit) return std::nullopt;
    return top - double(hit->t);  // along the ellipsoid normal, metres
  };
}

namespace {

// SplitMix64 of (seed, return index, pixel): the micro-phase of a rough-
// surface return in one pixel of the product grid, uniform in [0, 2 pi).
double MicroPhase(uint64_t seed, uint64_t index, uint64_t pixel) {
  uint64_t z = (seed ^ (0x632be59bd9b4e019ULL * (pixel + 1))) + 0x9e3779b97f4a7c15ULL * (index + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return 2.0 * M_PI * (double(z >> 11) * 0x1.0p-53);
}

// The SplitMix64 finaliser.
uint64_t Mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Polarimetric passes: phase `which` (0: phi1, 1: phi2, 2: phi3 of RenderSar's
// "Polarimetric passes") of the rough-surface return (ray_id, phase_key) in
// product pixel `pixel`, uniform in [0, 2 pi). Keyed by the return's ray and
// key, which every pass of the set records alike, so that the passes draw
// the same phases for the same return and pixel.
double PolarimetricMicroPhase(uint64_t seed, int which, uint64_t ray_id, uint64_t phase_key, uint64_t pixel) {
  static constexpr uint64_t kKeys[3] = {0x632be59bd9b4e019ULL, 0x9e6c63d0676a9a99ULL, 0xd6e8feb86659fd93ULL};
  uint64_t z = Mix64((seed ^ (kKeys[which] * (pixel + 1))) + 0x9e3779b97f4a7c15ULL * (ray_id + 1));
  z = Mix64(z + 0x9e3779b97f4a7c15ULL * (phase_key + 1));
  return 2.0 * M_PI * (double(z >> 11) * 0x1.0p-53);
}

// The unit micro-phasor of a polarimetric pass's rough-surface return in
// product pixel `pixel` (RenderSar, "Polarimetric passes"): HH exp(j phi1),
// VV conj(rho) exp(j phi1) + sqrt(1 - |rho|^2) exp(j phi2), HV and VH
// exp(j phi3); rho = the contribution's recorded HH-VV correlation.
std::complex<double> PolarimetricMicroPhasor(const Contribution& c, material::Polarization pol, uint64_t seed,
                                             uint64_t pixel) {
  auto e = [&](int which) { return std::polar(1.0, PolarimetricMicroPhase(seed, which, c.ray_id, c.phase_key, pixel)); };
  switch (pol) {
    case material::Polarization::kHH: return e(0);
    case material::Polarization::kVV: {
      const std::complex<double> rho(c.channel_amplitude);
      return std::conj(rho) * e(0) + std::sqrt(std::max(0.0, 1.0 - std::norm(rho))) * e(1);
    }
    default: return e(2);
  }
}

// Adds the phasor `value` at fractional pixel (col, row) to the complex
// total (image.real/imag) and to bounce layer `layer`'s complex planes,
// split over the four
// neighbouring pixel centres with the square roots of the bilinear weights
// (the power splits as the bilinear weights). With `random`, every pixel's
// share is multiplied by its own unit micro-phasor micro(pixel) (single
// channel: exp(j MicroPhase(seed, index, pixel))): independent parts, so the
// expected power of every pixel is its bilinear share, also after any
// linear filter (the complex impulse response).
template <class MicroPhasor>
void SplatPhasor(SarImage& image, int layer, double col, double row, std::complex<double> value, bool random,
                 const MicroPhasor& micro) {
  const int width = image.width, height = image.height;
  const double c0f = std::floor(col), r0f = std::floor(row);
  const int c0 = static_cast<int>(c0f), r0 = static_cast<int>(r0f);
  const double fc = col - c0f, fr = row - r0f;
  const double w[2][2] = {{(1 - fr) * (1 - fc), (1 - fr) * fc}, {fr * (1 - fc), fr * fc}};
  for (int dr = 0; dr < 2; ++dr) {
    const int r = r0 + dr;
    if (r < 0 || r >= height) continue;
    for (int dc = 0; dc < 2; ++dc) {
      const int c = c0 + dc;
      if (c < 0 || c >= width || w[dr][dc] <= 0.0) continue;
      const size_t k = size_t(r) * width + c;
      std::complex<double> z = value * std::sqrt(w[dr][dc]);
      if (random) z *= micro(uint64_t(k));
      const float re = static_cast<float>(z.real()), im = static_cast<float>(z.imag());
      image.real[k] += re;
      image.imag[k] += im;
      image.bounce_real[layer][k] += re;
      image.bounce_imag[layer][k] += im;
    }
  }
}

Vector3d EcefOfEnu(const geo::LocalFrame& frame, const Vector3d& enu) {
  const Vector3d llh = frame.GeodeticFromEnu(enu);
  return geo::LocalFrame::EcefFromGeodetic(llh.x(), llh.y(), llh.z());
}

Vector3d EnuOfEcef(const geo::LocalFrame& frame, const Vector3d& ecef) {
  const Vector3d llh = geo::LocalFrame::GeodeticFromEcef(ecef);
  return frame.EnuFromGeodetic(llh.x(), llh.y(), llh.z());
}

}  // namespace

namespace {

// The product grid's view of the scene: the real orbit and grid, and the
// frame of the scene's ENU coordinates.
struct ProductView {
  const geo::LocalFrame& frame;
  const sensor::Orbit& orbit;
  const sensor::RadarGrid& grid;
};

// 1. Geolocation of every pixel (rdr2geo on the scene surface), into out's
// lon/lat/height planes (NaN where none) and out.geolocated.
void GeolocateGrid(const EmbreeScene& embree, const scene::TriangleMesh& mesh, const ProductView& view,
                   ProductImage& out) {
  const geo::LocalFrame& frame = view.frame;
  const sensor::RadarGrid& grid = view.grid;
  const int width = grid.cols, height = grid.rows;
  const size_t n = size_t(width) * height;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  out.lon_deg.assign(n, nan);
  out.lat_deg.assign(n, nan);
  out.height_m.assign(n, nan);
  out.lon_deg_exact.assign(n, std::numeric_limits<double>::quiet_NaN());
  out.lat_deg_exact.assign(n, std::numeric_limits<double>::quiet_NaN());

  const sensor::HeightFunction surface = SceneHeightFunction(embree, mesh, frame);
  const Eigen::AlignedBox3d box = mesh.Bounds();
  const double mean_height = frame.GeodeticFromEnu(box.center()).z();
  tbb::parallel_for(tbb::blocked_range<int>(0, height, 4), [&](const tbb::blocked_range<int>& rows) {
    for (int i = rows.begin(); i != rows.end(); ++i) {
      sensor::Rdr2GeoOptions o;
      o.initial_height_m = mean_height;
      for (int j = 0; j < width; ++j) {
        const auto llh = sensor::Rdr2Geo(view.orbit, grid.TimeOfRow(i), grid.RangeOfCol(j), grid.look_side, surface, o);
        if (!llh) continue;
        const size_t k = size_t(i) * width + j;
        out.lon_deg_exact[k] = llh->x();
        out.lat_deg_exact[k] = llh->y();
        out.lon_deg[k] = static_cast<float>(llh->x());
        out.lat_deg[k] = static_cast<float>(llh->y());
        out.height_m[k] = static_cast<float>(llh->z());
        o.initial_height_m = llh->z();  // next pixel starts from here
      }
    }
  });
  for (size_t k = 0; k < n; ++k) out.geolocated += std::isfinite(out.height_m[k]) ? 1 : 0;
  if (out.geolocated == 0) throw InputError("no pixel of the product reaches the terrain (product outside the DEM?)", "--product");
}

// The straight tracing geometry and how it maps to the real one.
struct TangentGeometry {
  sensor::SarGeometry geometry;
  double t_c = 0.0;           // zero-Doppler time of the scene centre, s
  double ground_speed = 0.0;  // speed of the zero-Doppler footprint along the ground at the scene, m/s
};

// 2. The straight tracing geometry, tangent to the orbit at the scene
// centre: the geolocated pixel nearest to the grid centre.
TangentGeometry TangentTracingGeometry(const ProductView& view, ProductImage& out) {
  const geo::LocalFrame& frame = view.frame;
  const sensor::RadarGrid& grid = view.grid;
  const int width = grid.cols, height = grid.rows;
  size_t centre_k = 0;
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i < height; ++i) {
    for (int j = 0; j < width; ++j) {
      const size_t k = size_t(i) * width + j;
      const double d = std::hypot(i - 0.5 * (height - 1), j - 0.5 * (width - 1));
      if (std::isfinite(out.height_m[k]) && d < best) {
        best = d;
        centre_k = k;
      }
    }
  }
  const int ci = int(centre_k / width), cj = int(centre_k % width);
  const double t_c = grid.TimeOfRow(ci);
  const Vector3d xc = frame.EnuFromGeodetic(out.lon_deg_exact[centre_k], out.lat_deg_exact[centre_k],
                                            out.height_m[centre_k]);
  const sensor::OrbitState state = view.orbit.Interpolate(t_c);
  const Vector3d sensor_enu = EnuOfEcef(frame, state.position_m);
  const Vector3d v_enu = EnuOfEcef(frame, state.position_m + state.velocity_mps) - sensor_enu;
  const Vector3d look = (xc - sensor_enu).normalized();
  const double range_c = (xc - sensor_enu).norm();
  const Vector3d xc_ecef = EcefOfEnu(frame, xc);
  // Speed of the zero-Doppler footprint along the ground at the scene.
  const double ground_speed = state.velocity_mps.norm() * xc_ecef.norm() / state.position_m.norm();
  const int margin = 8;
  sensor::SarGeometryOptions g;
  g.heading_deg = std::atan2(v_enu.x(), v_enu.y()) * 180.0 / M_PI;
  g.depression_deg = std::asin(std::clamp(-look.z(), -1.0, 1.0)) * 180.0 / M_PI;
  g.look_side = grid.look_side;
  g.slant_range_m = range_c;
  g.range_spacing_m = grid.dr_m;
  g.azimuth_spacing_m = ground_speed * grid.dt_s;
  g.mode = sensor::ProjectionMode::kExact;
  g.width = width + 2 * margin;
  g.height = height + 2 * margin;
  out.tracing_geometry = g;
  return {sensor::SarGeometry(g, xc, cj + margin, ci + margin, g.width, g.height), t_c, ground_speed};
}

// 3. Trace with the unchanged tracer, recording every return.
SarImage TraceReturns(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                      const material::MaterialTable& materials, const sensor::SarGeometry& geometry,
                      const RenderOptions& options) {
  RenderOptions trace_options = options;
  trace_options.record_contributions = true;
  // Every return, wherever the tracing geometry's image ends.
  trace_options.image_rays_only = false;
  // The phasors are formed on the product grid (step 4) from the recorded
  // returns: the tracer's own coherent planes (straight-line ranges) are
  // not needed.
  trace_options.coherent = false;
  return RenderSar(embree, mesh, materials, geometry, trace_options);
}

// The zeroed planes of a width x height product image (complex ones in
// coherent mode).
void AllocateImage(int width, int height, bool coherent, SarImage& image) {
  const size_t n = size_t(width) * height;
  image.width = width;
  image.height = height;
  image.intensity.assign(n, 0.0f);
  for (auto& layer : image.bounce_layers) layer.assign(n, 0.0f);
  if (coherent) {
    image.real.assign(n, 0.0f);
    image.imag.assign(n, 0.0f);
    for (int layer = 0; layer < kBounceLayers; ++layer) {
      image.bounce_real[layer].assign(n, 0.0f);
      image.bounce_imag[layer].assign(n, 0.0f);
    }
  }
}

// Where a return lands on the product grid.
struct Landing {
  double col = 0, row = 0;
  double range_m = 0;  // true range of the last hit plus the tracer's path excess
  bool ok = false;
};

// 4a. Re-projects every return with the real geometry: the hit's true
// zero-Doppler time and range, plus the path and azimuth offsets the
// tracer gave the return relative to that hit (multi-bounce).
std::vector<Landing> LandReturns(const std::vector<Contribution>& cs, const TangentGeometry& tangent,
                                 const ProductView& view) {
  const sensor::SarGeometry& geometry = tangent.geometry;
  const double t_c = tangent.t_c, ground_speed = tangent.ground_speed;
  std::vector<Landing> landing(cs.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cs.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t k = r.begin(); k != r.end(); ++k) {
      const Contribution& c = cs[k];
      const Vector3d hit = c.hit_enu.cast<double>();
      const double along = geometry.AlongTrack(hit);
      const auto rc = sensor::Geo2Rdr(view.orbit, EcefOfEnu(view.frame, hit), t_c + along / ground_speed);
      if (!rc) continue;
      const double range = c.range_m + (rc->range_m - geometry.SlantRange(hit));
      const double time = rc->time_s + (c.azimuth_m - along) / ground_speed;
      landing[k] = {view.grid.ColOfRange(range), view.grid.RowOfTime(time), range, true};
    }
  });
  return landing;
}

// 4b. Splats the landed returns, in order (deterministic sums): intensity
// and bounce layers, and in coherent mode their phasors; returns how many
// landed.
int64_t SplatReturns(const std::vector<Contribution>& cs, const std::vector<Landing>& landing,
                     const RenderOptions& options, SarImage& image) {
  const bool coherent = options.coherent;
  const int width = image.width, height = image.height;
  int64_t splatted = 0;
  for (size_t k = 0; k < cs.size(); ++k) {  // in order: deterministic sums
    if (!landing[k].ok) continue;
    const Contribution& c = cs[k];
    const Landing& at = landing[k];
    const int layer = std::min<int>(c.bounces, kBounceLayers) - 1;
    SplatBilinear(image.intensity, width, height, at.col, at.row, c.intensity);
    SplatBilinear(image.bounce_layers[layer], width, height, at.col, at.row, c.intensity);
    if (coherent) {
      // Phase of the true two-way path, exp(-j 4 pi R / lambda); a rough-
      // surface (single-bounce) return adds its seeded micro-phase per
      // pixel (its expected power stays the incoherent one); a later
      // bounce stands for its path and the reversed one in phase
      // (RenderSar): twice the amplitude of the one path, whose power is
      // half of c.intensity.
      //
      // Polarimetric passes: the channel of the return's scattering matrix
      // as RenderSar forms it: a first bounce's micro-phasor drawn jointly
      // across the passes (PolarimetricMicroPhasor), a later bounce's
      // recorded sqrt(P) (S_c + S^T_c).
      const std::complex<double> phasor = material::PathPhase(2.0 * at.range_m, options.wavelength_m);
      if (options.polarimetric) {
        const std::complex<double> value =
            c.bounces == 1 ? std::sqrt(double(c.intensity)) * phasor
                           : std::complex<double>(c.channel_amplitude) * phasor;
        SplatPhasor(image, layer, at.col, at.row, value, c.bounces == 1, [&](uint64_t pixel) {
          return PolarimetricMicroPhasor(c, options.polarization, options.seed, pixel);
        });
      } else {
        const double amplitude =
            c.bounces == 1 ? std::sqrt(double(c.intensity)) : 2.0 * std::sqrt(0.5 * double(c.intensity));
        SplatPhasor(image, layer, at.col, at.row, amplitude * phasor, c.bounces == 1,
                    [&](uint64_t pixel) { return std::polar(1.0, MicroPhase(options.seed, k, pixel)); });
      }
    }
    ++splatted;
  }
  if (coherent) {  // the total is the detected complex sum
    const size_t n = size_t(width) * height;
    for (size_t k = 0; k < n; ++k) image.intensity[k] = image.real[k] * image.real[k] + image.imag[k] * image.imag[k];
  }
  return splatted;
}

// 5. Mask through each pixel's ground point: the tracing geometry's mask
// code where the point projects, and the footprint (pixels with a ground
// point on the terrain).
void MaskFromTracing(const ProductImage& out, const sensor::SarGeometry& geometry, const SarImage& traced,
                     const geo::LocalFrame& frame, SarImage& image) {
  const size_t n = out.height_m.size();
  image.mask.assign(n, kMaskNone);
  image.footprint.assign(n, 0);  // pixels with a ground point on the terrain
  for (size_t k = 0; k < n; ++k) {
    if (!std::isfinite(out.height_m[k])) continue;
    image.footprint[k] = 1;
    const Vector3d p = frame.EnuFromGeodetic(out.lon_deg_exact[k], out.lat_deg_exact[k], out.height_m[k]);
    const Eigen::Vector2d q = geometry.Project(p);
    const int c = static_cast<int>(std::lround(q.x())), r = static_cast<int>(std::lround(q.y()));
    if (c >= 0 && c < geometry.width() && r >= 0 && r < geometry.height()) {
      image.mask[k] = traced.mask[size_t(r) * geometry.width() + c];
    }
  }
}

// 6. Canonical reflectors: RCS, pattern and visibility as in the tracing
// geometry (RenderSar), the phase centre placed with the real geometry:
// its pixel and its range (the coherent phase) from geo2rdr.
void PlaceReflectors(const EmbreeScene& embree, const TangentGeometry& tangent, const ProductView& view,
                     const RenderOptions& options, SarImage& image) {
  const sensor::SarGeometry& geometry = tangent.geometry;
  for (const SceneReflector& r : options.reflectors) {
    const std::vector<PointReturn> seen =
        ReflectorReturns(embree, {r}, geometry, options.wavelength_m,
                         options.polarimetric ? std::optional<material::Polarization>(options.polarization)
                                              : std::nullopt);
    if (seen.empty()) continue;
    const double along = geometry.AlongTrack(r.apex_enu);
    const auto rc = sensor::Geo2Rdr(view.orbit, EcefOfEnu(view.frame, r.apex_enu),
                                    tangent.t_c + along / tangent.ground_speed);
    if (!rc) continue;
    PointReturn p = seen.front();
    p.col = view.grid.ColOfRange(rc->range_m);
    p.row = view.grid.RowOfTime(rc->time_s);
    p.range_m = rc->range_m;
    image.points.push_back(p);
  }
}

}  // namespace

ProductImage RenderProduct(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                           const material::MaterialTable& materials, const geo::LocalFrame& frame,
                           const sensor::Orbit& orbit, const sensor::RadarGrid& grid,
                           const RenderOptions& options) {
  options.Check();
  if (options.coherent && !(options.wavelength_m > 0.0 && std::isfinite(options.wavelength_m))) {
    throw ConfigError("coherent mode needs a positive wavelength", "--wavelength");
  }
  const ProductView view{frame, orbit, grid};
  ProductImage out;
  GeolocateGrid(embree, mesh, view, out);
  const TangentGeometry tangent = TangentTracingGeometry(view, out);
  const SarImage traced = TraceReturns(embree, mesh, materials, tangent.geometry, options);
  AllocateImage(grid.cols, grid.rows, options.coherent, out.image);
  const std::vector<Landing> landing = LandReturns(traced.contributions, tangent, view);
  out.contributions = SplatReturns(traced.contributions, landing, options, out.image);
  MaskFromTracing(out, tangent.geometry, traced, frame, out.image);
  PlaceReflectors(embree, tangent, view, options, out.image);
  out.image.stats = traced.stats;
  return out;
}

}  // namespace gissar::render
