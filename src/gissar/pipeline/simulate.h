// `gissar simulate`: DEM in, SAR image out. SimulateRequest is the single
// source of truth for the command's flags, its JSON provenance and (later)
// config files and Python.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/util/reporter.h"
#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/material/material.h"
#include "gissar/material/reflector.h"
#include "gissar/pipeline/terrain.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/scene_io.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/memory_ledger.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/enum_table.h"
#include "gissar/util/progress.h"

namespace gissar::pipeline {

// Image formation of `simulate`: kTrace (ray tracing, any terrain,
// multi-bounce) or kRaster (DEM-raster: every DEM cell projected
// analytically, single bounce, DEMs only; docs/geometry.md). Read and
// written (options files, sidecars, Python) as "trace" / "raster".
enum class SimulateEngine { kTrace, kRaster };
inline constexpr auto kSimulateEngines =
    util::MakeEnumTable<SimulateEngine>("engine", {{SimulateEngine::kTrace, "trace"}, {SimulateEngine::kRaster, "raster"}});
std::string ToString(SimulateEngine engine);

// Accepted range of --nesz (dB in image units): beyond 60 dB the noise
// intensity 10^(NESZ/10) overflows a float pixel.
constexpr double kMinNeszDb = -100.0;
constexpr double kMaxNeszDb = 60.0;
// Widest impulse response, in pixels of the image spacing: the PSF kernel
// grows with it (a 1e9 m resolution would never finish).
constexpr double kMaxImpulseResponsePx = 1024.0;
// PREFIX_quicklook.png (the annotated picture) shows images larger than this
// on either side multilooked by the smallest integer factor that brings
// both sides to at most this many pixels; PREFIX.png keeps every pixel.
inline constexpr int kQuicklookMaxSidePx = 2048;

// Throws ConfigError naming --range-resolution / --azimuth-resolution when
// the impulse response is wider than kMaxImpulseResponsePx pixels.
void CheckImpulseResponsePixels(double range_resolution_px, double azimuth_resolution_px);

// Throws ConfigError naming --vertical-units unless `units` is "" (from the
// DEM file), "m", "ft" or "us-ft".
void CheckVerticalUnits(const std::string& units);

struct SimulateRequest {
  std::string dem;                               // DEM raster (any GDAL format)
  std::string scene;                             // or a scene built by `gissar scene build`
  // A real product (NISAR RSLC HDF5): render on its radar grid with its
  // orbit instead of the idealised geometry (product_simulate.h).
  std::string product;
  // Or any sensor's track: state vectors (--orbit: CSV or JSON of UTC time,
  // ECEF position and velocity, or an ESA Earth Explorer .EOF such as
  // Sentinel-1's) and the radar grid to render on (--radar-grid JSON), read by
  // geo/orbit_file.h; both or neither, not with `product`. Renders exactly as
  // `product` does, on that grid.
  std::string orbit;
  std::string radar_grid;
  // Product selection (docs/conventions.md, "Products and sources"):
  // --frequency A|B of a NISAR product ("" = A); --swath (IW1, ..., S3; "" =
  // the product's only swath) and --burst N (1-based per swath; 0 = none) of
  // a Sentinel-1 SAFE (pipeline/sentinel1_simulate.h). With a SAFE, `orbit`
  // alone (no radar_grid) replaces the annotation's orbit.
  std::string frequency;
  std::string swath;
  int burst = 0;
  // A part of the product's grid to render (--product-window
  // LINE,PIXEL,LINES,PIXELS, in the product's own numbering: a burst's lines,
  // a GRD's lines and ground-range pixels): first line, first pixel, lines,
  // pixels; none = the whole grid.
  std::optional<std::array<int, 4>> product_window_px;
  // True when the image is rendered on a real radar grid (product or orbit).
  bool UsesProductGeometry() const { return !product.empty() || !orbit.empty() || !radar_grid.empty(); }
  // Vertical datum of the DEM heights (--vertical-datum): "" = from the
  // file's vertical CRS, else ellipsoid with a warning; "ellipsoid" (WGS84
  // ellipsoidal heights, used as given), "egm96" (orthometric, as SRTM),
  // "egm2008" or "EPSG:<n>" of a vertical CRS: the geoid undulation is added
  // at every post (geo/vertical_datum.h). A scene keeps the datum it was
  // built with: an explicit different one is a ConfigError.
  std::string vertical_datum;
  // Unit of the DEM's heights: "" = from the file (band unit, vertical CRS,
  // else metres), or m, ft, us-ft (geo::DemReadOptions::vertical_units).
  std::string vertical_units;
  bool fill_nodata = false;                      // fill DEM voids instead of failing
  // Refine the DEM by this factor before meshing (geo::RefineDem: cubic
  // convolution, original posts kept): 1 = posts as given. Use it when the
  // posts are coarser than the radar pixels, so that the mesh's planar
  // facets do not imprint streaks (docs/geometry.md).
  int dem_oversample = 1;
  // Sea of a DEM (--sea auto|off, --sea-level M; both engines): triangles
  // whose three posts are at or below the sea level and connected to the DEM
  // border get class `sea` (scene::SeaPostMask, the rule of `scene build`
  // without coastline).
  std::string sea = "auto";
  double sea_level_m = 0.0;
  // DEM window (--dem-window auto|off): with auto, a fixed-size image
  // (width and height set) of a DEM with the trace engine reads only the DEM
  // window its footprint needs (the image's ground footprint at the DEM's
  // lowest and highest heights, the terrain that can shadow it, and a
  // margin), and renders exactly the image the whole DEM gives
  // (PlanDemWindow, docs/performance.md); off reads the whole DEM.
  std::string dem_window = "auto";
  std::optional<Eigen::Vector2d> center_lonlat;  // scene centre, WGS84 degrees
  std::optional<Eigen::Vector2d> center_map;     // scene centre, DEM CRS units
  // Geometry; range/azimuth spacing 0 means "the DEM's post spacing".
  sensor::SarGeometryOptions geometry;
  // Image formation (kSimulateEngines; JSON key "engine").
  SimulateEngine engine = SimulateEngine::kTrace;
  double rays_per_cell = 4.0;
  int bounces = 3;                 // reflections followed per ray
  bool coherent = false;           // complex sum with phase 4 pi r / lambda
  double wavelength_m = 0.031;     // X band; selects the materials' sigma0 laws
  // Channels (docs/conventions.md, "Polarimetry"): one of
  // material::kPolarizations (the materials' laws of that channel), a comma
  // list ("HH,VV") or "quad". Several channels render one polarimetric pass each
  // (render::RenderOptions::polarimetric): bands per channel in PREFIX.tif
  // and PREFIX_slc.tif, a Pauli quicklook for coherent quad runs.
  std::string polarization = "VV";
  // Output radiometry (docs/radiometry.md): a name of image::kRadiometries,
  // linear (m2/m2) or, with `db`, decibels.
  std::string radiometry = "sigma0";
  bool db = false;
  // A materials file (JSON: class name -> law parameters) applied over the
  // defaults; with --dem it sets the single class `default`.
  std::string materials;
  // Canonical reflectors (CSV, docs/radiometry.md): trihedrals, dihedrals,
  // plates with their physical-optics RCS.
  std::string reflectors;
  std::string contributions;       // optional CSV of every return (RaySAR-style)
  // Also write PREFIX_layers.tif (slant-range geometry, same GCPs/RPCs):
  // band 1 local_incidence (deg), band 2 projected_area (m2 of terrain per
  // pixel), render::ComputeTerrainLayers; NaN outside the footprint.
  bool layers = false;
  // Append the local incidence angle (degrees, as band 1 of
  // PREFIX_layers.tif) as the last band of PREFIX.tif, named
  // "local_incidence" with unit deg, so that one file carries the image and
  // the angle a radiometric normalisation needs.
  bool incidence_band = false;
  // Rasters over geo::kCogMinSidePx a side are Cloud-Optimized GeoTIFFs
  // with internal overviews; false leaves the overviews out (the COG layout
  // stays).
  bool overviews = true;
  // GCPs for gdalwarp -tps: true refines the 12 x 12 lattice where the
  // thin-plate spline through it misses the terrain (SimulationGeoreference;
  // 0.1-0.4 s); false (the default) keeps the lattice alone. The RPCs, exact
  // with a DEM (gdalwarp -rpc -to RPC_DEM=), are the same either way.
  bool tps_gcps = false;
  // Trace engine: a DEM's terrain is traced as a height field (a quadtree of
  // bounds over its cells, render/heightfield.h: no BVH over its triangles,
  // a fraction of the memory); false builds Embree's BVH over the triangles
  // (the same hits to rounding; GIS scenes always use it).
  bool heightfield = true;
  // Adaptive sampling: a near-grazing first hit whose footprint is wider
  // than a pixel is split into sub-rays across its interval (the default);
  // false (--fixed-sampling) traces exactly the primary rays of the ray grid,
  // as benchmarks count them.
  bool adaptive_sampling = true;
  // Sensor impulse response: 3 dB resolutions in metres (0 = none) and the
  // spectral window (a name of image::kSpectralWindows). NaN (the default; null in
  // JSON): not set: none, except on a product that states its processed
  // bandwidths, whose resolutions then follow them (ProductResolutions,
  // pipeline/product_simulate.h). RangeResolutionM() / AzimuthResolutionM():
  // the value with NaN read as none (0).
  double range_resolution_m = std::numeric_limits<double>::quiet_NaN();
  double azimuth_resolution_m = std::numeric_limits<double>::quiet_NaN();
  double RangeResolutionM() const { return std::isnan(range_resolution_m) ? 0.0 : range_resolution_m; }
  double AzimuthResolutionM() const { return std::isnan(azimuth_resolution_m) ? 0.0 : azimuth_resolution_m; }
  std::string psf_window = "none";
  // Multiplicative L-look gamma speckle (0 = off) and thermal noise floor
  // (NESZ, dB sigma0; NaN = off), both seeded.
  double speckle_looks = 0.0;
  double nesz_db = std::numeric_limits<double>::quiet_NaN();  // NaN = none; else in [kMinNeszDb, kMaxNeszDb]
  uint64_t seed = 1;
  // writes PREFIX.tif, PREFIX.png, PREFIX_quicklook.png, PREFIX_mask.tif,
  // PREFIX.json and, in coherent mode, PREFIX_slc.tif (CFloat32)
  std::string out_prefix;
  // Memory budget (--max-memory), bytes: the DEM (or scene) and the image
  // are checked against it before they are allocated, and a job over it
  // fails with a ConfigError saying how to reduce it.
  int64_t max_memory_bytes = DefaultMemoryLimitBytes();

  // Throws ConfigError naming the option for every value that is out of
  // range before any file is read (spacings may still be 0 = automatic),
  // and when an output (PREFIX.* or --contributions) would overwrite an input.
  void Check() const;
  // The request as {snake_case name: value}: the provenance record, the
  // keys of --options files and the Python keywords (docs/conventions.md).
  nlohmann::json ToJson() const;
  // Sets the fields named by `values` (the keys ToJson writes; null keeps
  // the default). Throws ConfigError naming the key and `source` for an
  // unknown key or a value of the wrong type. ApplyJson(ToJson()) is the
  // identity.
  void ApplyJson(const nlohmann::json& values, const std::string& source);
};

struct SimulateResult {
  std::vector<std::filesystem::path> outputs;  // committed files
  render::RenderStats stats;
  int width = 0;
  int height = 0;
  double total_seconds = 0.0;
};

// What a simulation's image asks of its DEM window (terrain.h
// PlanDemWindow): the geometry and size, the engine, --dem-window, bounces,
// reflectors and contributions.
DemWindowNeeds DemWindowNeedsOf(const SimulateRequest& options);
// The DEM window of a simulation (options Check()ed): PlanDemWindow of its
// TerrainRequestOf, TerrainShapeOf and DemWindowNeedsOf.
DemWindowPlan PlanDemWindow(const SimulateRequest& options);

// The terrain grid the trace engine traces as a height field
// (render::EmbreeScene's TerrainGrid) when options.heightfield: a DEM's
// grid, or a scene's terrain grid with its holes (scenes built before it:
// none); none with --no-heightfield.
render::TerrainGrid TracedGrid(const Terrain& terrain, const SimulateRequest& options);
// The terrain fields of a simulation (terrain.h).
TerrainRequest TerrainRequestOf(const SimulateRequest& options);
// The mesh a simulation renders: the raster engine's posts or a triangle
// mesh, --heightfield, the centre of --center / --center-map (no window).
TerrainShape TerrainShapeOf(const SimulateRequest& options);
// Loads options.dem or options.scene (LoadTerrain of TerrainRequestOf and
// TerrainShapeOf), a DEM's window planned first (PlanDemWindow): the centre
// follows --center / --center-map for DEMs; with engine "raster" a DEM's mesh
// holds only its posts (no triangles). Throws the gissar::Error family.
Terrain LoadTerrain(const SimulateRequest& options, Reporter& reporter = NullReporter());
// For scenes: moves the centre to options.center_lonlat on the scene's
// surface (found by a vertical ray). Throws ConfigError when it is outside.
void PlaceSceneCentre(Terrain& terrain, const render::EmbreeScene& embree,
                      const SimulateRequest& options);

// The geometry options with automatic (0) pixel spacings resolved to the
// terrain's post spacing.
sensor::SarGeometryOptions ResolvedGeometry(const SimulateRequest& options, const Terrain& terrain);

// Ellipsoid incidence (degrees) of every image column (SarGeometry::IncidenceDeg).
std::vector<double> ColumnIncidenceDeg(const sensor::SarGeometry& geometry);

// Depressions outside [kGrazingDepressionDeg, kSteepDepressionDeg] are
// meaningful but unusual: a warning.
inline constexpr double kGrazingDepressionDeg = 5.0;
inline constexpr double kSteepDepressionDeg = 85.0;

// Sanity of a resolved viewing geometry: warns (through `reporter`) about a
// grazing or near-nadir depression; in exact mode throws ConfigError when the
// sensor is not above the terrain's highest vertex.
void CheckViewingGeometry(const sensor::SarGeometry& geometry, const scene::TriangleMesh& mesh, Reporter& reporter);

// Impulse response, speckle and thermal noise of the options, in that
// order, then the output radiometry (image::ApplySensorEffects). When the
// renderer gave a footprint, pixels outside it (no surface covers the centre
// and no return reached the pixel) become no-data: MarkOutsideFootprint.
void ApplySensorEffects(render::SarImage& image, const SimulateRequest& options,
                        const sensor::SarGeometry& geometry);

// Sets every float band of `image` (intensity, per-bounce, complex) to NaN
// and the mask to render::kMaskOutside where inside[i] == 0, and stores
// `inside` as image.footprint (`inside` may be image.footprint itself).
// CHECKs the size.
void MarkOutsideFootprint(render::SarImage& image, const std::vector<uint8_t>& inside);

// The tracer's options of a simulation rendering `channel` (one of
// options.polarization's list): rays per cell, bounces, coherence,
// wavelength, seed, contributions (when options.contributions is set) and
// progress (unless quiet). The one place SimulateRequest map to the tracer.
render::RenderOptions RenderOptionsOf(const SimulateRequest& options, material::Polarization channel,
                                      Reporter* reporter = nullptr);
// The first channel of options.polarization (a single-channel view renders
// it). Throws ConfigError naming --polarization for a bad list.
material::Polarization FirstChannel(const SimulateRequest& options);

// A simulated image before anything is written: the terrain it was rendered
// from, the geometry (automatic spacings resolved, covering the terrain),
// the image after sensor effects, and the stage timings in seconds.
struct SimulatedImage {
  Terrain terrain;
  sensor::SarGeometryOptions geometry_options;
  std::optional<sensor::SarGeometry> geometry;  // always set on return
  render::SarImage image;
  // The channels rendered (SimulateRequest::polarization) in output order:
  // `image` is channels[0], other_channels[i] is channels[i + 1]. One
  // channel: other_channels is empty and `image` is today's single-channel
  // render (RenderOptions::polarimetric false).
  std::vector<material::Polarization> channels;
  std::vector<render::SarImage> other_channels;
  nlohmann::json timings_s = nlohmann::json::object();
  // This run's share of the machine's memory budget (util/memory_ledger.h),
  // held while the image lives: concurrent gissar runs wait for it or are
  // refused instead of exhausting the machine together.
  MemoryReservation memory;
};

// Loads the terrain, places the scene centre, resolves and checks the
// geometry against the memory budget, renders with options.engine and
// applies the sensor effects: everything RunTerrainSimulate (simulate_door.h)
// does short of writing (the Python binding calls it too, so both give the
// same bits). Progress, information lines and cancellation go through
// `reporter`. Throws the gissar::Error family; options must have passed
// Check(). Not for a product's radar grid (product_simulate.h).
SimulatedImage SimulateImage(const SimulateRequest& options, Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
