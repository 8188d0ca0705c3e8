#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/field_names.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <cstdio>
#include <sstream>

#include "gissar/geo/dem.h"
#include "gissar/geo/geoid.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/sentinel1_safe.h"
#include "gissar/image/impulse_response.h"
#include "gissar/image/radiometry.h"
#include "gissar/material/material.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/raster_renderer.h"
#include "gissar/scene/gis_scene.h"
#include "gissar/scene/scene_io.h"
#include "gissar/scene/triangle_mesh.h"
#include <limits>
#include "gissar/util/atomic_output.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;

std::string ToString(SimulateEngine engine) { return std::string(kSimulateEngines.Name(engine)); }

namespace {

// The rules Check applies when the request renders on a product's radar
// grid (`product`, or `orbit` with `radar_grid`): the trace engine, no
// idealised-geometry options (--center, --center-map, --width, --height,
// --range-spacing, --azimuth-spacing) and no --contributions. Throws
// ConfigError naming the option. Coherent mode is allowed
// (render::RenderProduct forms the phasors on the product grid).
void CheckProductOptions(const SimulateRequest& o) {
  const bool sentinel1 = !o.product.empty() && geo::IsSentinel1Path(o.product);
  if (sentinel1) {
    // A SAFE fixes its grid; --orbit replaces its annotation's orbit.
    if (!o.radar_grid.empty()) throw ConfigError("a Sentinel-1 product fixes the radar grid", "--product/--radar-grid");
    if (!o.frequency.empty()) {
      throw ConfigError("a Sentinel-1 product has no frequency band (A/B are NISAR's): choose with --swath and "
                        "--polarization",
                        "--frequency");
    }
  } else {
    if (!o.product.empty() && (!o.orbit.empty() || !o.radar_grid.empty())) {
      throw ConfigError("give a product or an orbit with a radar grid, not both", "--product/--orbit");
    }
    if (o.product.empty() && (o.orbit.empty() || o.radar_grid.empty())) {
      throw ConfigError("an orbit needs a radar grid and a radar grid an orbit", "--orbit/--radar-grid");
    }
    if (!o.swath.empty()) throw ConfigError("only for a Sentinel-1 product (--product S1.SAFE)", "--swath");
    if (o.burst != 0) throw ConfigError("only for a Sentinel-1 product (--product S1.SAFE)", "--burst");
    if (!o.frequency.empty()) {
      if (o.product.empty()) throw ConfigError("only for a NISAR product (--product FILE.h5)", "--frequency");
      if (o.frequency != "A" && o.frequency != "B") {
        throw ConfigError("expected A or B, got '" + o.frequency + "'", "--frequency");
      }
    }
  }
  if (o.burst < 0) throw ConfigError("bursts are numbered from 1, got " + std::to_string(o.burst), "--burst");
  if (o.product_window_px) {
    const auto& w = *o.product_window_px;
    if (w[0] < 0 || w[1] < 0 || w[2] < 2 || w[3] < 2) {
      throw ConfigError("expected LINE,PIXEL,LINES,PIXELS with LINE, PIXEL >= 0 and at least 2 lines and 2 pixels",
                        "--product-window");
    }
  }
  // The option that fixes the geometry, for the messages below.
  const std::string fixed_by = o.product.empty() ? "--orbit" : "--product";
  if (o.engine != SimulateEngine::kTrace) throw ConfigError("the radar grid needs the trace engine", fixed_by + "/--engine");
  if (!o.contributions.empty()) {
    throw ConfigError("contributions are not recorded on a radar grid", fixed_by + "/--contributions");
  }
  if (o.center_lonlat || o.center_map) {
    throw ConfigError("the radar grid fixes the scene centre", fixed_by + "/--center");
  }
  if (o.geometry.width != 0 || o.geometry.height != 0) {
    throw ConfigError("the radar grid fixes the image size", fixed_by + "/--width/--height");
  }
  if (o.geometry.range_spacing_m != 0.0 || o.geometry.azimuth_spacing_m != 0.0) {
    throw ConfigError("the radar grid fixes the pixel spacing", fixed_by + "/--range-spacing/--azimuth-spacing");
  }
}

}  // namespace

void SimulateRequest::Check() const {
  if (dem.empty() == scene.empty()) {
    throw ConfigError("give exactly one terrain: a DEM or a scene", "--dem/--scene");
  }
  if (out_prefix.empty()) throw ConfigError("an output prefix is required", "--out");
  geo::CanonicalVerticalDatum(vertical_datum, "--vertical-datum");
  CheckVerticalUnits(vertical_units);
  if (!vertical_units.empty() && !scene.empty()) {
    throw ConfigError("a scene keeps the heights it was built with", "--vertical-units");
  }
  if (dem_oversample < 1 || dem_oversample > geo::kMaxDemOversample) {
    throw ConfigError("DEM oversampling must be in [1, " + std::to_string(geo::kMaxDemOversample) + "], got " +
                          std::to_string(dem_oversample),
                      "--dem-oversample");
  }
  if (sea != "auto" && sea != "off") throw ConfigError("expected auto or off, got '" + sea + "'", "--sea");
  if (dem_window != "auto" && dem_window != "off") {
    throw ConfigError("expected auto or off, got '" + dem_window + "'", "--dem-window");
  }
  if (!std::isfinite(sea_level_m)) throw ConfigError("sea level must be finite", "--sea-level");
  if (dem_oversample != 1 && !scene.empty()) {
    throw ConfigError("a scene keeps the posts it was built with", "--dem-oversample");
  }
  if (UsesProductGeometry()) {
    CheckProductOptions(*this);
  } else {
    for (const auto& [given, flag] : {std::pair{!frequency.empty(), "--frequency"}, {!swath.empty(), "--swath"},
                                      {burst != 0, "--burst"}, {product_window_px.has_value(), "--product-window"}}) {
      if (given) throw ConfigError("selects a part of a product: only with --product", flag);
    }
  }
  if (engine == SimulateEngine::kRaster) {
    if (!scene.empty()) throw ConfigError("the raster engine renders DEMs only (--dem)", "--engine");
    if (coherent) throw ConfigError("the raster engine is incoherent only", "--engine/--coherent");
    if (!contributions.empty()) {
      throw ConfigError("the raster engine records no contributions", "--engine/--contributions");
    }
  }
  if (center_lonlat && center_map) {
    throw ConfigError("give the scene centre once: --center or --center-map", "--center");
  }
  sensor::SarGeometryOptions probe = geometry;
  if (probe.range_spacing_m == 0.0) probe.range_spacing_m = 1.0;
  if (probe.azimuth_spacing_m == 0.0) probe.azimuth_spacing_m = 1.0;
  probe.Check();
  RenderOptionsOf(*this).Check();
  // NaN: not set (none, or a product's stated bandwidths).
  if (!std::isnan(range_resolution_m) && (!(range_resolution_m >= 0.0) || !std::isfinite(range_resolution_m))) {
    throw ConfigError("range resolution must be >= 0 metres", "--range-resolution");
  }
  if (!std::isnan(azimuth_resolution_m) &&
      (!(azimuth_resolution_m >= 0.0) || !std::isfinite(azimuth_resolution_m))) {
    throw ConfigError("azimuth resolution must be >= 0 metres", "--azimuth-resolution");
  }
  image::ParseSpectralWindow(psf_window, "--psf-window");
  if (!(speckle_looks == 0.0 || (speckle_looks >= 1.0 && std::isfinite(speckle_looks)))) {
    throw ConfigError("speckle looks must be 0 (off) or >= 1", "--speckle-looks");
  }
  // NaN = no thermal noise; otherwise [-100, 60] dB keeps 10^(NESZ/10) a finite float.
  if (!std::isnan(nesz_db) && !(nesz_db >= kMinNeszDb && nesz_db <= kMaxNeszDb)) {
    throw ConfigError("NESZ must be in [-100, 60] dB", "--nesz");
  }
  image::ParseRadiometry(radiometry, "--radiometry");
  // Radar wavelengths run from Ka band (8 mm) to VHF (10 m); [1 mm, 100 m]
  // keeps every band and refuses nonsense such as 1e-30 m.
  if (!(wavelength_m >= 1e-3 && wavelength_m <= 100.0)) {
    throw ConfigError("wavelength must be in [0.001, 100] m", "--wavelength");
  }
  material::ParsePolarizationList(polarization, "--polarization");
  if (coherent && speckle_looks > 0.0) {
    throw ConfigError("coherent mode forms its own speckle; do not add simulated speckle",
                      "--coherent/--speckle-looks");
  }
  if (max_memory_bytes <= 0) throw ConfigError("memory limit must be positive", "--max-memory");
  std::vector<fs::path> outs = {fs::path(contributions)};
  for (const char* suffix : {".tif", ".png", "_quicklook.png", "_mask.tif", ".json"}) outs.push_back(out_prefix + suffix);
  if (coherent) outs.push_back(out_prefix + "_slc.tif");
  CheckOutputsAreNotInputs(outs, {dem, scene, product, orbit, radar_grid, materials, reflectors});
}

namespace {

// Memory estimates for --max-memory (measured, kept on the safe side; peak
// RSS of `simulate` on fractal DEMs, 2026-11-29, docs/robustness.md; the
// terrain's per DEM post and scene byte are in terrain.cc).
// Per image pixel: the total and 4 per-bounce float planes, the per-block
// accumulation bands, mask, quicklook and writing buffers (measured 18 B
// with one bounce, 26 B with three).
constexpr double kBytesPerImagePixel = 64.0;
// The same in coherent mode, which adds the complex total and the complex
// plane of every bounce count and writes the SLC (measured 98 B per pixel
// with three bounces: 4096^2 posts, 96 Mpx, 10.0 GB).
constexpr double kBytesPerCoherentImagePixel = 160.0;
// Seed offset between the sensor stages (thermal noise, speckle) of the
// channels of a polarimetric run: independent draws per channel.
constexpr uint64_t kChannelSeedStride = 0x9e3779b97f4a7c15ULL;

double BytesPerImagePixel(const SimulateRequest& options) {
  // Every channel keeps its own planes (a polarimetric run holds them all
  // until they are written).
  const double channels =
      double(material::ParsePolarizationList(options.polarization, "--polarization").size());
  return channels * (options.coherent ? kBytesPerCoherentImagePixel : kBytesPerImagePixel);
}

// geo::ReadDemInfo, remembered per process for a file (path, size,
// modification time, vertical units): a worker rendering many poses of one
// DEM streams its heights once.
geo::DemInfo CachedDemInfo(const geo::DemFile& file, const geo::DemReadOptions& read_options) {
  const fs::path path = file.path();
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  const bool on_disk = !ec;
  const auto mtime = on_disk ? fs::last_write_time(path, ec) : fs::file_time_type();
  if (!on_disk || ec) return file.Info(read_options);
  const std::string key = fs::absolute(path).string() + "|" + std::to_string(size) + "|" +
                          std::to_string(mtime.time_since_epoch().count()) + "|" + read_options.vertical_units;
  static std::mutex mutex;
  static std::map<std::string, geo::DemInfo> cache;
  {
    std::lock_guard<std::mutex> lock(mutex);
    const auto found = cache.find(key);
    if (found != cache.end()) return found->second;
  }
  geo::DemInfo info = file.Info(read_options);
  std::lock_guard<std::mutex> lock(mutex);
  if (cache.size() > 64) cache.clear();
  cache[key] = info;
  return info;
}

// The ground point (ENU) of image pixel (col, row) at ENU height z: in
// exact mode the point of the pixel's range circle (in its zero-Doppler
// plane) nearest the look direction. nullopt when the range circle does not
// reach that height.
std::optional<Eigen::Vector3d> PixelAtHeight(const sensor::SarGeometry& g, double col, double row, double z) {
  const Eigen::Vector3d& l = g.look_direction();
  const Eigen::Vector3d& n = g.range_plane_normal();
  const Eigen::Vector3d& h = g.flight_direction();
  const double a = (row - g.v0()) * g.azimuth_spacing_m();
  const double range = g.slant_range_m() + (col - g.u0()) * g.range_spacing_m();
  if (g.mode() == sensor::ProjectionMode::kAffine) {
    const double s = range - g.slant_range_m();
    const Eigen::Vector3d base = g.scene_centre() + s * l + a * h;
    if (std::abs(n.z()) < 1e-12) return std::nullopt;
    return Eigen::Vector3d(base + (z - base.z()) / n.z() * n);
  }
  if (!(range > 0.0)) return std::nullopt;
  const Eigen::Vector3d sensor = g.SensorPosition(a);
  const double A = range * l.z(), B = range * n.z(), C = z - sensor.z();
  const double m = std::hypot(A, B);
  if (!(m > 0.0) || std::abs(C) > m) return std::nullopt;
  const double phi = std::atan2(B, A), delta = std::acos(C / m);
  auto wrap = [](double t) { return std::remainder(t, 2.0 * M_PI); };
  const double t1 = wrap(phi + delta), t2 = wrap(phi - delta);
  const double theta = std::abs(t1) <= std::abs(t2) ? t1 : t2;
  return Eigen::Vector3d(sensor + range * (std::cos(theta) * l + std::sin(theta) * n));
}

// Where the line of sight from `p` towards the sensor reaches height z_top
// (the farthest terrain that can shadow p); p itself when it does not rise.
Eigen::Vector3d ShadowReach(const sensor::SarGeometry& g, const Eigen::Vector3d& p, double z_top) {
  const Eigen::Vector3d up_sight = -g.RayDirectionTo(p);
  if (!(up_sight.z() > 1e-9) || !(z_top > p.z())) return p;
  return p + (z_top - p.z()) / up_sight.z() * up_sight;
}

// Why a simulation reads the whole DEM without planning a window (nullopt:
// a window is planned).
std::optional<std::string> NoWindowPlanned(const SimulateRequest& options) {
  if (options.dem.empty() || !options.product.empty()) return "not a DEM";
  if (options.geometry.width <= 0 || options.geometry.height <= 0) {
    return "no --width/--height: the image covers the whole DEM";
  }
  if (options.engine != SimulateEngine::kTrace) return "the raster engine spaces its horizon lines from the whole grid";
  return std::nullopt;
}

// Height bounds of the window's halo: exact for the stored heights; cubic
// refinement may overshoot (by less than the height span: Keys' kernel and
// its boundary rule); a geoid adds its undulation (EGM96/EGM2008 lie within
// -107..+86 m). sea_low: the lowest height the sea rule may compare.
struct HaloHeights {
  double lo = 0.0, hi = 0.0, sea_low = 0.0;
};
HaloHeights HaloHeightsOf(const geo::DemInfo& info, const SimulateRequest& options, const std::string& datum) {
  double lo = info.min_height_m, hi = info.max_height_m;
  if (options.dem_oversample > 1) {
    const double span = hi - lo;
    lo -= span;
    hi += span;
  }
  const double sea_low = lo;
  if (datum != "ellipsoid") {
    lo -= 110.0;
    hi += 90.0;
  }
  lo -= 1.0;
  hi += 1.0;
  return {lo, hi, sea_low};
}

// The source raster's header only: map coordinates of its posts.
geo::Dem PostLattice(const geo::DemInfo& info) {
  geo::Dem lattice;
  lattice.geotransform = info.geotransform;
  lattice.source_geotransform = info.geotransform;
  lattice.lattice_factor = 1;
  lattice.width = lattice.source_width = info.width;
  lattice.height = lattice.source_height = info.height;
  return lattice;
}

// The scene centre (--center, --center-map or the DEM's centre) in source
// posts (column, row). Throws ConfigError for a centre that is not a
// longitude,latitude or lies outside the DEM.
Eigen::Vector2d SceneCentrePost(const SimulateRequest& options, const geo::DemInfo& info, const geo::Dem& lattice,
                                const geo::CrsTransform& crs) {
  Eigen::Vector2d centre_map;
  if (options.center_lonlat) {
    std::vector<double> x{options.center_lonlat->x()}, y{options.center_lonlat->y()};
    if (!std::isfinite(x[0]) || !std::isfinite(y[0]) || std::abs(y[0]) > 90.0) {
      throw ConfigError("scene centre is not a valid longitude,latitude", "--center");
    }
    crs.FromLonLat(x, y);
    centre_map = {x[0], y[0]};
  } else if (options.center_map) {
    centre_map = *options.center_map;
  } else {
    centre_map = lattice.MapFromPost((info.width - 1) / 2.0, (info.height - 1) / 2.0);
  }
  double centre_col = 0.0, centre_row = 0.0;
  lattice.PostFromMap(centre_map.x(), centre_map.y(), &centre_col, &centre_row);
  if (!(centre_col >= 0.0 && centre_row >= 0.0 && centre_col <= info.width - 1 && centre_row <= info.height - 1)) {
    throw ConfigError("scene centre lies outside the DEM", options.center_map ? "--center-map" : "--center");
  }
  return {centre_col, centre_row};
}

// The frame, scene centre (ENU), post spacing and image geometry exactly as
// the whole DEM gives them.
struct CentredGeometry {
  geo::LocalFrame frame;
  Eigen::Vector3d xc;
  double post_spacing_m;
  sensor::SarGeometry geometry;
};

// CentredGeometry from the posts around the scene centre; nullopt (and the
// reason) when voids next to it are filled from the whole DEM.
std::optional<CentredGeometry> GeometryAtCentre(const SimulateRequest& options, const geo::DemFile& file,
                                                const geo::DemReadOptions& read_options,
                                                const geo::DemInfo& info, const std::string& datum,
                                                const Eigen::Vector2d& centre_post, std::string* reason) {
  const int c = static_cast<int>(std::floor(centre_post.x())), r = static_cast<int>(std::floor(centre_post.y()));
  const int c0 = std::max(0, c - 3), r0 = std::max(0, r - 3);
  const int c1 = std::min(info.width - 1, c + 4), r1 = std::min(info.height - 1, r + 4);
  geo::DemReadOptions small_options = read_options;
  small_options.window = std::array<int, 4>{c0, r0, c1 - c0 + 1, r1 - r0 + 1};
  geo::Dem small = file.Read(small_options);
  if (small.filled_nodata_cells > 0) {
    *reason = "--fill-nodata with voids next to the scene centre (filled from the whole DEM)";
    return std::nullopt;
  }
  small = geo::RefineDem(small, options.dem_oversample, int64_t{1} << 40);
  geo::ToEllipsoidalHeights(small, datum);
  std::optional<Eigen::Vector2d> small_map = options.center_map;
  if (!options.center_lonlat && !small_map) {
    const Eigen::Vector2d post = small.SourceCentrePost();
    small_map = small.MapFromPost(post.x(), post.y());
  }
  const geo::GeoPoint centre = geo::ResolveSceneCentre(small, options.center_lonlat, small_map);
  const geo::LocalFrame frame(centre.lon_deg, centre.lat_deg, 0.0);
  const Eigen::Vector3d xc = frame.EnuFromGeodetic(centre.lon_deg, centre.lat_deg, centre.height_m);
  sensor::SarGeometryOptions g = options.geometry;
  const Eigen::Vector2d spacing = geo::DemPostSpacingMetres(small, frame, /*at_source_centre=*/true);
  const double post_spacing_m = 0.5 * (spacing.x() + spacing.y()) * options.dem_oversample;
  if (g.range_spacing_m == 0.0) g.range_spacing_m = post_spacing_m;
  if (g.azimuth_spacing_m == 0.0) g.azimuth_spacing_m = post_spacing_m;
  return CentredGeometry{frame, xc, post_spacing_m, sensor::SarGeometry::Covering(g, xc, {})};
}

// Points along the image's border (and the window's) per side.
constexpr int kWindowBorderSteps = 64;

// The ground the image can see (ENU): its border (plus the margin) at the
// lowest and highest ENU heights, and where its lines of sight reach the
// highest. ENU heights drop with distance d from the origin (about
// d^2 / 2R): the lowest bound (z_low) is lowered by the drop at the
// farthest point found.
struct ImageReach {
  std::vector<Eigen::Vector3d> points;
  double z_low = 0.0;
};
ImageReach ImageReachOf(const sensor::SarGeometry& geometry, const HaloHeights& heights) {
  const double lo = heights.lo, hi = heights.hi;
  const double m = kDemWindowMarginPx;
  const double c_lo = -m, c_hi = geometry.width() - 1 + m, r_lo = -m, r_hi = geometry.height() - 1 + m;
  std::vector<Eigen::Vector2d> border;
  const int steps = kWindowBorderSteps;
  for (int k = 0; k <= steps; ++k) {
    const double f = double(k) / steps;
    border.emplace_back(c_lo + f * (c_hi - c_lo), r_lo);
    border.emplace_back(c_lo + f * (c_hi - c_lo), r_hi);
    border.emplace_back(c_lo, r_lo + f * (r_hi - r_lo));
    border.emplace_back(c_hi, r_lo + f * (r_hi - r_lo));
  }
  ImageReach reach;
  std::vector<Eigen::Vector3d>& points = reach.points;
  double z_low = lo;
  for (int pass = 0; pass < 2; ++pass) {
    points.clear();
    double farthest = 0.0;
    for (const Eigen::Vector2d& px : border) {
      for (const double z : {z_low, hi}) {
        const auto p = PixelAtHeight(geometry, px.x(), px.y(), z);
        if (!p) continue;
        points.push_back(*p);
        points.push_back(ShadowReach(geometry, *p, hi));
        farthest = std::max({farthest, p->head<2>().norm(), points.back().head<2>().norm()});
      }
    }
    const double drop = 1.2 * farthest * farthest / (2.0 * 6.35e6) + 1.0;
    if (lo - drop >= z_low) break;
    z_low = lo - drop;
  }
  reach.z_low = z_low;
  return reach;
}

// The window of source posts (first column, first row, columns, rows)
// holding `points` plus kDemWindowMarginPosts; nullopt (and the reason)
// when the footprint leaves the CRS's domain or the DEM.
std::optional<std::array<int, 4>> WindowOfPoints(const std::vector<Eigen::Vector3d>& points,
                                                 const geo::LocalFrame& frame, const geo::CrsTransform& crs,
                                                 const geo::Dem& lattice, const geo::DemInfo& info,
                                                 std::string* reason) {
  // Source posts of those points.
  std::vector<double> x, y;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d geodetic = frame.GeodeticFromEnu(p);
    x.push_back(geodetic.x());
    y.push_back(geodetic.y());
  }
  try {
    crs.FromLonLat(x, y);
  } catch (const InputError&) {  // a footprint beyond the domain of the DEM's CRS: read the whole DEM
    *reason = "the image's footprint reaches outside the domain of the DEM's CRS";
    return std::nullopt;
  }
  double col_min = 1e300, col_max = -1e300, row_min = 1e300, row_max = -1e300;
  for (size_t i = 0; i < x.size(); ++i) {
    double c = 0.0, r = 0.0;
    lattice.PostFromMap(x[i], y[i], &c, &r);
    if (!std::isfinite(c) || !std::isfinite(r)) continue;
    col_min = std::min(col_min, c);
    col_max = std::max(col_max, c);
    row_min = std::min(row_min, r);
    row_max = std::max(row_max, r);
  }
  auto clamp_post = [](double v, int size) {
    return static_cast<int>(std::clamp(v, 0.0, double(size - 1)));
  };
  const int wc0 = clamp_post(std::floor(col_min) - kDemWindowMarginPosts, info.width);
  const int wc1 = clamp_post(std::ceil(col_max) + kDemWindowMarginPosts, info.width);
  const int wr0 = clamp_post(std::floor(row_min) - kDemWindowMarginPosts, info.height);
  const int wr1 = clamp_post(std::ceil(row_max) + kDemWindowMarginPosts, info.height);
  if (wc1 - wc0 < 1 || wr1 - wr0 < 1) {
    *reason = "the image's footprint lies outside the DEM";
    return std::nullopt;
  }
  return std::array<int, 4>{wc0, wr0, wc1 - wc0 + 1, wr1 - wr0 + 1};
}

// The ray box: the window's posts at both height bounds (its border,
// densely, and its centre; ENU heights are lowest at the border), the scene
// centre, a post of slack (the window's plan is curved in ENU) and the ENU
// drop below heights.lo.
Eigen::AlignedBox3d WindowRayBox(const std::array<int, 4>& window, const geo::Dem& lattice,
                                 const geo::CrsTransform& crs, const CentredGeometry& centred,
                                 const HaloHeights& heights, double z_low) {
  const double lo = heights.lo, hi = heights.hi;
  const int wc0 = window[0], wr0 = window[1], wc1 = window[0] + window[2] - 1, wr1 = window[1] + window[3] - 1;
  const int steps = kWindowBorderSteps;
  std::vector<double> bx, by;
  for (int k = 0; k <= steps; ++k) {
    const double f = double(k) / steps;
    const double cc = wc0 + f * (wc1 - wc0), rr = wr0 + f * (wr1 - wr0);
    for (const auto& [pc, pr] : {std::pair{cc, double(wr0)}, {cc, double(wr1)}, {double(wc0), rr}, {double(wc1), rr}}) {
      const Eigen::Vector2d mp = lattice.MapFromPost(pc, pr);
      bx.push_back(mp.x());
      by.push_back(mp.y());
    }
  }
  const Eigen::Vector2d mid = lattice.MapFromPost(0.5 * (wc0 + wc1), 0.5 * (wr0 + wr1));
  bx.push_back(mid.x());
  by.push_back(mid.y());
  crs.ToLonLat(bx, by);
  Eigen::AlignedBox3d box;
  for (size_t i = 0; i < bx.size(); ++i) {
    for (const double z : {lo, hi}) box.extend(centred.frame.EnuFromGeodetic(bx[i], by[i], z));
  }
  box.extend(centred.xc);
  const double slack = 2.0 * centred.post_spacing_m + 1.0;
  box.min() -= Eigen::Vector3d(slack, slack, slack + (z_low < lo ? lo - z_low : 0.0));
  box.max() += Eigen::Vector3d(slack, slack, slack);
  return box;
}

// Why the whole DEM is read anyway although a window was planned ("": the
// window is read).
std::string WhyWholeDem(const SimulateRequest& options, const std::array<int, 4>& window, const geo::DemInfo& info,
                        double sea_low) {
  material::MaterialTable materials;
  ApplyMaterialsFile(materials, TerrainRequestOf(options));
  const bool mirror_paths = options.bounces > 1 && materials.Get(scene::kClassDefault).mirror > 0.0;
  const double window_posts = double(window[2]) * window[3];
  if (options.dem_window == "off") return "--dem-window off";
  if (options.sea == "auto" && sea_low <= options.sea_level_m) {
    return "--sea auto on a DEM reaching the sea level (the sea is what connects to the whole DEM's border; "
           "--sea off reads a window)";
  }
  if (mirror_paths) return "mirror paths (--materials with a mirror share and --bounces > 1) may reach any terrain";
  if (!options.reflectors.empty()) return "--reflectors may lie anywhere on the DEM";
  if (!options.contributions.empty()) return "--contributions records returns from anywhere on the DEM";
  if (window_posts >= 0.8 * double(info.width) * double(info.height)) return "the window is most of the DEM";
  return "";
}

}  // namespace

DemWindowPlan PlanDemWindow(const SimulateRequest& options, Reporter& reporter) {
  DemWindowPlan plan;
  if (const std::optional<std::string> why = NoWindowPlanned(options)) {
    plan.reason = *why;
    return plan;
  }
  const geo::DemReadOptions read_options = DemReadOptionsOf(TerrainRequestOf(options), TerrainShapeOf(options));
  // Opened once: its header and bounds, the posts at the centre, then the
  // window or the whole DEM (LoadTerrain reads plan.dem_file).
  plan.dem_file.emplace(options.dem);
  const geo::DemInfo info = CachedDemInfo(*plan.dem_file, read_options);
  if (!info.any_valid) {
    plan.reason = "the DEM has no valid height";
    return plan;
  }
  plan.source_width = info.width;
  plan.source_height = info.height;
  const geo::VerticalDatumChoice datum =
      geo::ResolveVerticalDatum(geo::CanonicalVerticalDatum(options.vertical_datum), info.file_vertical_datum);
  const HaloHeights heights = HaloHeightsOf(info, options, datum.datum);

  // The scene centre, frame and geometry exactly as the whole DEM gives
  // them: the centre's height from the posts around it.
  const geo::Dem lattice = PostLattice(info);
  const geo::CrsTransform crs(info.crs_wkt);
  const Eigen::Vector2d centre_post = SceneCentrePost(options, info, lattice, crs);
  const std::optional<CentredGeometry> centred =
      GeometryAtCentre(options, *plan.dem_file, read_options, info, datum.datum, centre_post, &plan.reason);
  if (!centred) return plan;

  // The posts the image can see or be shadowed from, and the rays' box.
  const ImageReach reach = ImageReachOf(centred->geometry, heights);
  if (reach.points.empty()) {
    plan.reason = "the image's lines of sight do not reach the DEM's heights";
    return plan;
  }
  plan.z_low_m = reach.z_low;
  plan.z_high_m = heights.hi;
  const std::optional<std::array<int, 4>> window =
      WindowOfPoints(reach.points, centred->frame, crs, lattice, info, &plan.reason);
  if (!window) return plan;
  plan.window = *window;
  plan.ray_box = WindowRayBox(plan.window, lattice, crs, *centred, heights, reach.z_low);
  plan.applies = true;

  // When the whole DEM is read anyway.
  plan.reason = WhyWholeDem(options, plan.window, info, heights.sea_low);
  plan.read_window = plan.reason.empty();
  (void)reporter;
  return plan;
}

TerrainRequest TerrainRequestOf(const SimulateRequest& options) {
  TerrainRequest r;
  r.dem = options.dem;
  r.scene = options.scene;
  r.fill_nodata = options.fill_nodata;
  r.dem_oversample = options.dem_oversample;
  r.vertical_units = options.vertical_units;
  r.vertical_datum = options.vertical_datum;
  r.sea = options.sea;
  r.sea_level_m = options.sea_level_m;
  r.materials = options.materials;
  r.max_memory_bytes = options.max_memory_bytes;
  return r;
}

TerrainShape TerrainShapeOf(const SimulateRequest& options) {
  TerrainShape s;
  s.posts_only = options.engine == SimulateEngine::kRaster;
  s.heightfield = options.heightfield;
  s.center_lonlat = options.center_lonlat;
  s.center_map = options.center_map;
  return s;
}

Terrain LoadTerrain(const SimulateRequest& options, Reporter& reporter) {
  TerrainShape shape = TerrainShapeOf(options);
  if (options.scene.empty()) shape.window = PlanDemWindow(options, reporter);
  return LoadTerrain(TerrainRequestOf(options), shape, reporter);
}

render::TerrainGrid TracedGrid(const Terrain& terrain, const SimulateRequest& options) {
  if (!options.heightfield) return {};
  // A scene's directly split terrain cells, the others holes.
  if (!terrain.scene_grid.cells.empty()) return terrain.scene_grid;
  // A DEM's posts and MeshFromGrid's triangles are the mesh (LoadTerrain).
  if (terrain.grid_width < 2 || terrain.grid_height < 2) return {};
  return render::TerrainGrid{terrain.grid_width, terrain.grid_height, {}};
}

void PlaceSceneCentre(Terrain& terrain, const render::EmbreeScene& embree, const SimulateRequest& options) {
  if (options.scene.empty() || !(options.center_lonlat || options.center_map)) return;
  if (options.center_map) throw ConfigError("a scene's centre is given as --center LON,LAT", "--center-map");
  const Eigen::Vector3d top = terrain.frame.EnuFromGeodetic(
      options.center_lonlat->x(), options.center_lonlat->y(), terrain.mesh.Bounds().max().z() + 100.0);
  const auto hit = embree.Intersect(top.cast<float>(), Eigen::Vector3f(0, 0, -1), 0.0f,
                                    std::numeric_limits<float>::infinity());
  if (!hit) throw ConfigError("scene centre lies outside the scene", "--center");
  terrain.centre_enu = top - Eigen::Vector3d(0, 0, hit->t);
  terrain.centre = {options.center_lonlat->x(), options.center_lonlat->y(),
                    terrain.frame.GeodeticFromEnu(terrain.centre_enu).z()};
}

sensor::SarGeometryOptions ResolvedGeometry(const SimulateRequest& options, const Terrain& terrain) {
  sensor::SarGeometryOptions g = options.geometry;
  if (g.range_spacing_m == 0.0) g.range_spacing_m = terrain.post_spacing_m;
  if (g.azimuth_spacing_m == 0.0) g.azimuth_spacing_m = terrain.post_spacing_m;
  return g;
}

std::vector<double> ColumnIncidenceDeg(const sensor::SarGeometry& geometry) {
  std::vector<double> incidence(geometry.width());
  for (int c = 0; c < geometry.width(); ++c) incidence[c] = geometry.IncidenceDeg(c);
  return incidence;
}

void CheckVerticalUnits(const std::string& units) {
  if (!units.empty() && units != "m" && units != "ft" && units != "us-ft") {
    throw ConfigError("vertical units must be m, ft or us-ft, got '" + units + "'", "--vertical-units");
  }
}

void CheckImpulseResponsePixels(double range_resolution_px, double azimuth_resolution_px) {
  auto check = [](double px, const char* axis, const char* flag) {
    if (px > kMaxImpulseResponsePx) {
      throw ConfigError(std::string(axis) + " resolution spans " + std::to_string(std::llround(std::min(px, 1e18))) +
                            " pixels of the " + axis + " spacing, over the limit of " +
                            std::to_string(int(kMaxImpulseResponsePx)) + "; give a finer resolution or a coarser spacing",
                        flag);
    }
  };
  check(range_resolution_px, "range", "--range-resolution");
  check(azimuth_resolution_px, "azimuth", "--azimuth-resolution");
}

namespace {
std::string FormatNumber(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.4g", v);
  return text;
}
}  // namespace

void CheckViewingGeometry(const sensor::SarGeometry& geometry, const scene::TriangleMesh& mesh, Reporter& reporter) {
  const double depression = geometry.options().depression_deg;
  if (depression < kGrazingDepressionDeg) {
    reporter.Warn("simulate: depression " + FormatNumber(depression) + " deg is grazing (below " +
                  FormatNumber(kGrazingDepressionDeg) + "): most terrain will be in shadow");
  } else if (depression > kSteepDepressionDeg) {
    reporter.Warn("simulate: depression " + FormatNumber(depression) + " deg is near nadir (above " +
                  FormatNumber(kSteepDepressionDeg) + "): slant range barely resolves the ground");
  }
  if (geometry.mode() != sensor::ProjectionMode::kExact || mesh.vertices.empty()) return;
  // Exact mode: a sensor at or below the highest terrain sees it from below
  // (lines of sight run through the relief).
  double top = -std::numeric_limits<double>::infinity();
  for (const auto& v : mesh.vertices) if (std::isfinite(v.z())) top = std::max(top, double(v.z()));
  const double sensor_z = geometry.SensorPosition(0.0).z();
  if (!(sensor_z > top)) {
    throw ConfigError("the sensor (" + FormatNumber(sensor_z) + " m) is not above the terrain's highest point (" +
                          FormatNumber(top) + " m): raise --slant-range or --depression",
                      "--slant-range/--depression");
  }
}

void ApplySensorEffects(render::SarImage& image, const SimulateRequest& options,
                        const sensor::SarGeometry& geometry) {
  image::SensorEffects effects;
  effects.range_resolution_px = options.RangeResolutionM() / geometry.range_spacing_m();
  effects.azimuth_resolution_px = options.AzimuthResolutionM() / geometry.azimuth_spacing_m();
  effects.window = image::ParseSpectralWindow(options.psf_window, "--psf-window");
  effects.speckle_looks = options.speckle_looks;
  effects.nesz_db = options.nesz_db;
  effects.seed = options.seed;
  effects.radiometry = image::ParseRadiometry(options.radiometry, "--radiometry");
  effects.db = options.db;
  effects.wavelength_m = options.wavelength_m;
  // The footprint: pixel centres a surface covers, and pixels a return
  // reached before the impulse response spreads it (a multi-bounce path may
  // land beyond the terrain's projection).
  std::vector<uint8_t> inside = image.footprint;
  if (inside.size() == image.intensity.size()) {
    for (size_t i = 0; i < inside.size(); ++i) {
      if (image.intensity[i] > 0.0f || (!image.real.empty() && (image.real[i] != 0.0f || image.imag[i] != 0.0f))) {
        inside[i] = 1;
      }
    }
  }
  image::ApplySensorEffects(image, effects, ColumnIncidenceDeg(geometry));
  if (inside.size() == image.intensity.size()) MarkOutsideFootprint(image, inside);
}

void MarkOutsideFootprint(render::SarImage& image, const std::vector<uint8_t>& inside) {
  GISSAR_CHECK(inside.size() == image.intensity.size());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  auto blank = [&](std::vector<float>& band) {
    if (band.size() != inside.size()) return;
    for (size_t i = 0; i < inside.size(); ++i) if (!inside[i]) band[i] = nan;
  };
  blank(image.intensity);
  blank(image.real);
  blank(image.imag);
  for (int layer = 0; layer < render::kBounceLayers; ++layer) {
    blank(image.bounce_layers[layer]);
    blank(image.bounce_real[layer]);
    blank(image.bounce_imag[layer]);
  }
  if (image.mask.size() == inside.size()) {
    for (size_t i = 0; i < inside.size(); ++i) if (!inside[i]) image.mask[i] = render::kMaskOutside;
  }
  image.footprint = inside;
}

render::RenderOptions RenderOptionsOf(const SimulateRequest& options, Reporter* reporter) {
  render::RenderOptions r;
  r.rays_per_cell = options.rays_per_cell;
  r.max_bounces = options.bounces;
  r.coherent = options.coherent;
  r.wavelength_m = options.wavelength_m;
  // The first channel; SimulateImage renders the others as further passes.
  r.polarization = material::ParsePolarizationList(options.polarization, "--polarization").front();
  r.seed = options.seed;
  r.record_contributions = !options.contributions.empty();
  r.adaptive_sampling = options.adaptive_sampling;
  r.reporter = reporter;
  return r;
}

SimulatedImage SimulateImage(const SimulateRequest& options, Reporter& reporter) {
  if (options.UsesProductGeometry()) {
    throw ConfigError("a radar grid is rendered by SimulateProduct (Python: gissar.simulate_product)",
                      options.product.empty() ? "--orbit" : "--product");
  }
  SimulatedImage out;
  Stopwatch step;
  // The terrain: a DEM (bare terrain, unit Lambertian class 0) or a GIS
  // scene (classes and their materials, frame and centre stored with it).
  out.terrain = LoadTerrain(options, reporter);
  out.timings_s["terrain"] = step.ElapsedSeconds();
  Terrain& terrain = out.terrain;
  const scene::TriangleMesh& mesh = terrain.mesh;
  out.geometry_options = ResolvedGeometry(options, terrain);
  step = Stopwatch();
  // The raster engine needs no BVH (and renders DEMs only: no scene centre
  // to place).
  const bool raster_engine = options.engine == SimulateEngine::kRaster;
  std::unique_ptr<render::EmbreeScene> embree;
  if (!raster_engine) {
    embree = std::make_unique<render::EmbreeScene>(mesh, TracedGrid(terrain, options));
    out.timings_s["bvh"] = step.ElapsedSeconds();
    PlaceSceneCentre(terrain, *embree, options);
  }
  out.geometry = sensor::SarGeometry::Covering(out.geometry_options, terrain.centre_enu, mesh.vertices);
  const sensor::SarGeometry& geometry = *out.geometry;
  CheckViewingGeometry(geometry, mesh, reporter);
  CheckImpulseResponsePixels(options.RangeResolutionM() / geometry.range_spacing_m(),
                             options.AzimuthResolutionM() / geometry.azimuth_spacing_m());
  const bool sized = options.geometry.width > 0 || options.geometry.height > 0;
  CheckImagePixels(geometry.width(), geometry.height(), options.max_memory_bytes,
                   "image of " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) +
                       " pixels",
                   sized ? "give a smaller --width/--height" : "use coarser --range-spacing/--azimuth-spacing",
                   sized ? (options.geometry.width > 0 ? "--width" : "--height") : "--range-spacing");
  const double image_bytes = BytesPerImagePixel(options) * geometry.width() * double(geometry.height()) +
                             double(mesh.MemoryBytes()) * 3.0;
  const std::string image_what =
      "image of " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) + " pixels";
  const std::string image_how = "use coarser --range-spacing/--azimuth-spacing, a smaller --width/--height";
  const auto waiting = [&reporter](const std::string& line) { reporter.Info("simulate: " + line); };
  if (options.contributions.empty()) {
    out.memory = ReserveMemory(image_bytes, options.max_memory_bytes, image_what, image_how,
                               kDefaultMemoryWaitSeconds, DefaultMemoryLedgerPath(), waiting);
  } else {
    // Every ray may return once per bounce, each return kept in memory.
    CheckMemoryBudget(image_bytes, options.max_memory_bytes, image_what, image_how);
    const double returns = geometry.width() * double(geometry.height()) * options.rays_per_cell * options.bounces;
    out.memory = ReserveMemory(returns * double(sizeof(render::Contribution)) + image_bytes, options.max_memory_bytes,
                               "recording up to " + std::to_string(int64_t(returns)) + " contributions (--contributions)",
                               "use fewer --rays-per-cell or --bounces, coarser spacings, or no --contributions",
                               kDefaultMemoryWaitSeconds, DefaultMemoryLedgerPath(), waiting);
  }
  if (out.memory.waited_s() > 0.05) out.timings_s["memory_wait"] = out.memory.waited_s();
  {
    reporter.Info("simulate: image " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) +
        " pixels, " +
        (raster_engine ? std::to_string(int64_t(terrain.grid_width - 1) * (terrain.grid_height - 1)) + " DEM cells"
                       : std::to_string(mesh.triangle_count()) + " triangles"));
  }
  // One pass per channel (VH copies the HV pass: monostatic reciprocity).
  // Several channels: polarimetric passes with one seed, so that the passes
  // are the channels of one scattering matrix per return.
  out.channels = material::ParsePolarizationList(options.polarization, "--polarization");
  const bool polarimetric = out.channels.size() > 1;
  std::vector<render::SceneReflector> reflectors = terrain.reflectors;
  std::optional<render::GridHeightfield> heightfield;
  if (raster_engine) {
    // Reflectors: the tracer's closed-form returns, hidden by the DEM grid's
    // triangles (a height field: no BVH).
    if (!options.reflectors.empty() || !terrain.reflectors.empty()) {
      heightfield.emplace(mesh.vertices, terrain.grid_width, terrain.grid_height);
      if (!options.reflectors.empty()) {
        const auto placed = PlaceReflectorRows(
            material::ReadReflectorsCsv(options.reflectors), options.reflectors, terrain.frame,
            [&](double x, double y) { return heightfield->SurfaceHeight(x, y); });
        reflectors.insert(reflectors.end(), placed.begin(), placed.end());
      }
    }
  } else {
    const auto placed = PlaceReflectors(options.reflectors, terrain, *embree);
    reflectors.insert(reflectors.end(), placed.begin(), placed.end());
  }
  auto render_channel = [&](material::Polarization channel) {
    if (raster_engine) {
      render::SarImage image = render::RenderSarRaster(mesh.vertices, terrain.grid_width, terrain.grid_height,
                                                       terrain.materials, geometry, terrain.grid_classes,
                                                       options.wavelength_m, channel);
      if (heightfield) {
        // A single channel keeps the scalar RCS (as the tracer does).
        image.points = render::ReflectorReturns(*heightfield, reflectors, geometry, options.wavelength_m,
                                                polarimetric ? std::optional(channel) : std::nullopt);
      }
      return image;
    }
    render::RenderOptions ro = RenderOptionsOf(options, &reporter);
    ro.polarization = channel;
    ro.polarimetric = polarimetric;
    ro.ray_box = terrain.ray_box;
    ro.reflectors = reflectors;
    return render::RenderSar(*embree, mesh, terrain.materials, geometry, ro);
  };
  for (size_t k = 0; k < out.channels.size(); ++k) {
    const material::Polarization channel = out.channels[k];
    if (polarimetric) reporter.Info("simulate: channel " + material::ToString(channel));
    render::SarImage rendered;
    const auto hv = std::find(out.channels.begin(), out.channels.begin() + k, material::Polarization::kHV);
    const auto vh = std::find(out.channels.begin(), out.channels.begin() + k, material::Polarization::kVH);
    if (channel == material::Polarization::kVH && hv != out.channels.begin() + k) {
      rendered = hv == out.channels.begin() ? out.image : out.other_channels[hv - out.channels.begin() - 1];
    } else if (channel == material::Polarization::kHV && vh != out.channels.begin() + k) {
      rendered = vh == out.channels.begin() ? out.image : out.other_channels[vh - out.channels.begin() - 1];
    } else {
      rendered = render_channel(channel);
    }
    if (k == 0) out.image = std::move(rendered);
    else out.other_channels.push_back(std::move(rendered));
  }
  // Sensor effects: impulse response, speckle, thermal noise (in this order).
  // Each further channel has its own noise and speckle draws (seeds offset
  // by kChannelSeedStride); the first keeps the request's seed.
  step = Stopwatch();
  ApplySensorEffects(out.image, options, geometry);
  for (size_t k = 0; k < out.other_channels.size(); ++k) {
    SimulateRequest channel_options = options;
    channel_options.seed = options.seed + kChannelSeedStride * (k + 1);
    ApplySensorEffects(out.other_channels[k], channel_options, geometry);
  }
  out.timings_s["sensor_effects"] = step.ElapsedSeconds();
  out.timings_s[ToString(options.engine)] = out.image.stats.trace_seconds;
  if (!raster_engine) out.timings_s["mask"] = out.image.stats.mask_seconds;
  return out;
}

}  // namespace gissar::pipeline
