#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/field_names.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <cstdio>
#include <sstream>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "gissar/geo/dem.h"
#include "gissar/geo/geoid.h"
#include "gissar/geo/vertical_datum.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
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
// --range-spacing, --azimuth-spacing) and no --contributions; an orbit
// comes with a radar grid and takes no product selection (--swath, --burst,
// --frequency). Throws ConfigError naming the option. Coherent mode is
// allowed (render::RenderProduct forms the phasors on the product grid).
// The rules of each kind of product (a Sentinel-1 SAFE's, a NISAR RSLC's)
// are checked where the product is opened (ReadSentinel1Source,
// ReadProductGeometry): generic code does not tell products apart.
void CheckProductOptions(const SimulateRequest& o) {
  if (o.product.empty()) {
    if (o.orbit.empty() || o.radar_grid.empty()) {
      throw ConfigError("an orbit needs a radar grid and a radar grid an orbit", "--orbit/--radar-grid");
    }
    if (!o.swath.empty()) throw ConfigError("only for a Sentinel-1 product (--product S1.SAFE)", "--swath");
    if (o.burst != 0) throw ConfigError("only for a Sentinel-1 product (--product S1.SAFE)", "--burst");
    if (!o.frequency.empty()) throw ConfigError("only for a NISAR product (--product FILE.h5)", "--frequency");
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
  // The channel list first (its errors came first before), then the
  // tracer's options with the first channel.
  const std::vector<material::Polarization> channels = material::ParsePolarizationList(polarization, "--polarization");
  RenderOptionsOf(*this, channels.front()).Check();
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

double BytesPerImagePixel(bool coherent, size_t channels) {
  // Every channel keeps its own planes (a polarimetric run holds them all
  // until they are written).
  return double(channels) * (coherent ? kBytesPerCoherentImagePixel : kBytesPerImagePixel);
}

}  // namespace

DemWindowNeeds DemWindowNeedsOf(const SimulateRequest& options) {
  DemWindowNeeds n;
  n.product_grid = options.UsesProductGeometry();
  n.raster_engine = options.engine == SimulateEngine::kRaster;
  n.geometry = options.geometry;
  n.window_off = options.dem_window == "off";
  n.bounces = options.bounces;
  n.reflectors = !options.reflectors.empty();
  n.contributions = !options.contributions.empty();
  return n;
}

DemWindowPlan PlanDemWindow(const SimulateRequest& options) {
  return PlanDemWindow(TerrainRequestOf(options), TerrainShapeOf(options), DemWindowNeedsOf(options));
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
  const TerrainRequest request = TerrainRequestOf(options);
  TerrainShape shape = TerrainShapeOf(options);
  if (options.scene.empty()) shape.window = PlanDemWindow(request, shape, DemWindowNeedsOf(options));
  return LoadTerrain(request, shape, reporter);
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
  // (In parallel: tens of millions of posts; the maximum does not depend
  // on the order.)
  const double top = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, mesh.vertices.size(), size_t(1) << 16), -std::numeric_limits<double>::infinity(),
      [&](const tbb::blocked_range<size_t>& range, double m) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
          const float z = mesh.vertices[i].z();
          if (std::isfinite(z)) m = std::max(m, double(z));
        }
        return m;
      },
      [](double a, double b) { return std::max(a, b); });
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
  // (Computed in place: the sensor effects below neither read nor change
  // the footprint.)
  std::vector<uint8_t>& inside = image.footprint;
  const bool has_footprint = inside.size() == image.intensity.size();
  if (has_footprint) {
    const bool coherent = !image.real.empty();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, inside.size(), size_t(1) << 16),
                      [&](const tbb::blocked_range<size_t>& range) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          if (image.intensity[i] > 0.0f ||
                              (coherent && (image.real[i] != 0.0f || image.imag[i] != 0.0f))) {
                            inside[i] = 1;
                          }
                        }
                      });
  }
  image::ApplySensorEffects(image, effects, ColumnIncidenceDeg(geometry));
  if (has_footprint) MarkOutsideFootprint(image, inside);
}

void MarkOutsideFootprint(render::SarImage& image, const std::vector<uint8_t>& inside) {
  GISSAR_CHECK(inside.size() == image.intensity.size());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::vector<float>*> bands = {&image.intensity, &image.real, &image.imag};
  for (int layer = 0; layer < render::kBounceLayers; ++layer) {
    for (std::vector<float>* band : {&image.bounce_layers[layer], &image.bounce_real[layer], &image.bounce_imag[layer]}) {
      bands.push_back(band);
    }
  }
  std::erase_if(bands, [&](const std::vector<float>* band) { return band->size() != inside.size(); });
  const bool mask = image.mask.size() == inside.size();
  // Pixels in parallel, every band of a pixel range in turn.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, inside.size(), size_t(1) << 16),
                    [&](const tbb::blocked_range<size_t>& range) {
                      for (std::vector<float>* band : bands) {
                        float* values = band->data();
                        for (size_t i = range.begin(); i != range.end(); ++i) if (!inside[i]) values[i] = nan;
                      }
                      if (mask) {
                        for (size_t i = range.begin(); i != range.end(); ++i) {
                          if (!inside[i]) image.mask[i] = render::kMaskOutside;
                        }
                      }
                    });
  if (&inside != &image.footprint) image.footprint = inside;
}

render::RenderOptions RenderOptionsOf(const SimulateRequest& options, material::Polarization channel,
                                      Reporter* reporter) {
  render::RenderOptions r;
  r.rays_per_cell = options.rays_per_cell;
  r.max_bounces = options.bounces;
  r.coherent = options.coherent;
  r.wavelength_m = options.wavelength_m;
  r.polarization = channel;
  r.seed = options.seed;
  r.record_contributions = !options.contributions.empty();
  // --contributions records returns from anywhere on the terrain.
  r.image_rays_only = !r.record_contributions;
  r.adaptive_sampling = options.adaptive_sampling;
  r.reporter = reporter;
  return r;
}

material::Polarization FirstChannel(const SimulateRequest& options) {
  return material::ParsePolarizationList(options.polarization, "--polarization").front();
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
  // The channels, each one pass (polarimetric when several), and the
  // tracer's options (RenderOptionsOf; each pass sets its channel).
  out.channels = material::ParsePolarizationList(options.polarization, "--polarization");
  const bool polarimetric = out.channels.size() > 1;
  render::RenderOptions trace_options = RenderOptionsOf(options, out.channels.front(), &reporter);
  trace_options.polarimetric = polarimetric;
  trace_options.ray_box = terrain.ray_box;
  const double image_bytes =
      BytesPerImagePixel(options.coherent, out.channels.size()) * geometry.width() * double(geometry.height()) +
      double(mesh.MemoryBytes()) * 3.0;
  CheckViewingGeometry(geometry, mesh, reporter);
  CheckImpulseResponsePixels(options.RangeResolutionM() / geometry.range_spacing_m(),
                             options.AzimuthResolutionM() / geometry.azimuth_spacing_m());
  const bool sized = options.geometry.width > 0 || options.geometry.height > 0;
  CheckImagePixels(geometry.width(), geometry.height(), options.max_memory_bytes,
                   "image of " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) +
                       " pixels",
                   sized ? "give a smaller --width/--height" : "use coarser --range-spacing/--azimuth-spacing",
                   sized ? (options.geometry.width > 0 ? "--width" : "--height") : "--range-spacing");
  const std::string image_what =
      "image of " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) + " pixels";
  const std::string image_how = "use coarser --range-spacing/--azimuth-spacing, a smaller --width/--height";
  const auto waiting = [&reporter](const std::string& line) { reporter.Info("simulate: " + line); };
  // With --contributions every ray may return once per bounce, each return
  // kept in memory: the image alone is checked first (its own message),
  // then the image and the returns are reserved.
  const bool recording = !options.contributions.empty();
  if (recording) CheckMemoryBudget(image_bytes, options.max_memory_bytes, image_what, image_how);
  const double returns = geometry.width() * double(geometry.height()) * options.rays_per_cell * options.bounces;
  out.memory = ReserveMemory(
      recording ? returns * double(sizeof(render::Contribution)) + image_bytes : image_bytes, options.max_memory_bytes,
      recording ? "recording up to " + std::to_string(int64_t(returns)) + " contributions (--contributions)"
                : image_what,
      recording ? "use fewer --rays-per-cell or --bounces, coarser spacings, or no --contributions" : image_how,
      kDefaultMemoryWaitSeconds, DefaultMemoryLedgerPath(), waiting);
  if (out.memory.waited_s() > 0.05) out.timings_s["memory_wait"] = out.memory.waited_s();
  {
    reporter.Info("simulate: image " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) +
        " pixels, " +
        (raster_engine ? std::to_string(int64_t(terrain.grid_width - 1) * (terrain.grid_height - 1)) + " DEM cells"
                       : std::to_string(mesh.triangle_count()) + " triangles"));
  }
  // Reflectors: the scene's stored ones and the --reflectors rows placed on
  // the surface the engine renders: the BVH, or for the raster engine the
  // DEM grid's triangles as a height field (no BVH), which also hides them.
  std::vector<render::SceneReflector> reflectors = terrain.reflectors;
  std::optional<render::GridHeightfield> heightfield;
  SurfaceHeightAt surface;
  if (!raster_engine) {
    surface = EmbreeSurface(*embree, terrain.mesh.Bounds().max().z() + 100.0);
  } else if (!options.reflectors.empty() || !terrain.reflectors.empty()) {
    heightfield.emplace(mesh.vertices, terrain.grid_width, terrain.grid_height);
    surface = [&](double x, double y) { return heightfield->SurfaceHeight(x, y); };
  }
  if (surface) {
    const auto placed = PlaceReflectors(options.reflectors, terrain.frame, surface);
    reflectors.insert(reflectors.end(), placed.begin(), placed.end());
  }
  trace_options.reflectors = reflectors;
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
    trace_options.polarization = channel;
    return render::RenderSar(*embree, mesh, terrain.materials, geometry, trace_options);
  };
  // One pass per channel (VH copies the HV pass: monostatic reciprocity).
  // Several channels: polarimetric passes with one seed, so that the passes
  // are the channels of one scattering matrix per return.
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
