#include "gissar/pipeline/simulate_fields.h"

#include "gissar/image/impulse_response.h"
#include "gissar/image/radiometry.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/check.h"

namespace gissar::pipeline {
namespace {

using F = Fields<SimulateRequest>;

}  // namespace

// Fields in the order of `gissar simulate --help` (simulate.h states what each means).
const FieldTable<SimulateRequest>& SimulateFields() {
  static const FieldTable<SimulateRequest> kTable({
      F::Plain("dem", F::At(&SimulateRequest::dem),
          "DEM raster, any GDAL format and CRS", false),
      F::Plain("scene", F::At(&SimulateRequest::scene),
          "Scene file from `gissar scene build` (instead of --dem)", false),
      F::Plain("product", F::At(&SimulateRequest::product),
          "Real product: NISAR RSLC HDF5 (--frequency) or Sentinel-1 SAFE directory/.zip (--swath, --burst; a GRD "
          "is resampled to its ground range; no real image is written): render on its radar grid with its orbit "
          "(no --heading/--depression)", false),
      F::Plain("orbit", F::At(&SimulateRequest::orbit),
          "Any sensor's track: state vectors (CSV or JSON of UTC time, ECEF position and velocity, or an ESA .EOF "
          "orbit file); with --radar-grid, instead of --heading/--depression; with a Sentinel-1 --product, "
          "replaces its annotation's orbit", false),
      F::Plain("radar_grid", F::At(&SimulateRequest::radar_grid),
          "Radar grid JSON (starting_range_m, range_spacing_m, sensing_start_utc, azimuth_time_interval_s, width, "
          "length, look_side, wavelength_m) to render on with --orbit", false),
      F::Plain("frequency", F::At(&SimulateRequest::frequency),
          "NISAR product: frequency band A or B (default: A)", false),
      F::Plain("swath", F::At(&SimulateRequest::swath),
          "Sentinel-1 product: swath (IW1..IW3, EW1..EW5, S1..S6; default: the product's only swath)", false),
      F::Plain("burst", F::At(&SimulateRequest::burst),
          "Sentinel-1 IW/EW SLC: burst N (1-based, per swath), simulated in its own zero-Doppler grid (required "
          "for IW/EW SLC; a GRD or stripmap product has none)", false),
      F::OptionalWindow("product_window_px", F::At(&SimulateRequest::product_window_px),
          "Render a part of the product's grid: LINE,PIXEL,LINES,PIXELS in its own numbering (a burst's lines and "
          "samples, a GRD's lines and ground-range pixels)",
          ProductWindowJson),
      F::Plain("dem_oversample", F::At(&SimulateRequest::dem_oversample),
          "Refine the DEM this many times (cubic convolution) before meshing; for posts coarser than the pixels"),
      F::Plain("vertical_units", F::At(&SimulateRequest::vertical_units),
          "Unit of the DEM heights: m, ft or us-ft (default: the file's band unit or vertical CRS, else m)", false),
      F::Plain("vertical_datum", F::At(&SimulateRequest::vertical_datum),
          "Datum of the DEM heights: ellipsoid, egm96, egm2008 or EPSG:n of a vertical CRS (default: the file's "
          "vertical CRS, else ellipsoid with a warning)", false),
      F::Plain("sea", F::At(&SimulateRequest::sea),
          "DEM sea: auto (heights <= --sea-level connected to the border are class sea) or off"),
      F::Plain("dem_window", F::At(&SimulateRequest::dem_window),
          "auto: with --width/--height read only the DEM window the image needs (same image); off: read the whole "
          "DEM"),
      F::Plain("sea_level_m", F::At(&SimulateRequest::sea_level_m),
          "Sea level for --sea auto, metres in the DEM's heights"),
      F::Plain("fill_nodata", F::At(&SimulateRequest::fill_nodata),
          "Fill DEM no-data cells (GDAL FillNodata) instead of failing"),
      F::Plain("heading_deg", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::heading_deg),
          "Flight heading, degrees clockwise from north (required without --product/--orbit)", false),
      F::Plain("depression_deg", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::depression_deg),
          "Depression angle at the scene centre, degrees in (0, 90) (required without --product/--orbit)", false),
      F::Enum("look_side", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::look_side),
          sensor::kLookSides,
          "Look side: " + sensor::kLookSides.Alternatives()),
      F::OptionalPair("center_lonlat", F::At(&SimulateRequest::center_lonlat),
          "Scene centre LON,LAT in degrees (default: DEM centre)",
          NumberPairText),
      F::OptionalPair("center_map", F::At(&SimulateRequest::center_map),
          "Scene centre X,Y in the DEM's CRS",
          NumberPairText),
      F::Plain("slant_range_m", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::slant_range_m),
          "Slant range from the sensor to the scene centre, metres"),
      F::Plain("range_spacing_m", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::range_spacing_m),
          "Slant-range pixel spacing, metres (default: DEM post spacing)", false),
      F::Plain("azimuth_spacing_m", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::azimuth_spacing_m),
          "Azimuth pixel spacing, metres (default: DEM post spacing)", false),
      F::Enum("mode", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::mode), sensor::kProjectionModes,
          "Projection: " + sensor::ToString(sensor::ProjectionMode::kAffine) + " (parallel rays) or " +
              sensor::ToString(sensor::ProjectionMode::kExact) + " (flight line)"),
      F::Plain("width", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::width),
          "Image columns (range); default: cover the scene", false),
      F::Plain("height", F::At(&SimulateRequest::geometry, &sensor::SarGeometryOptions::height),
          "Image rows (azimuth); default: cover the scene", false),
      F::Enum("engine", F::At(&SimulateRequest::engine), kSimulateEngines,
          "Image formation: " + ToString(SimulateEngine::kTrace) + " (ray tracing) or " +
              ToString(SimulateEngine::kRaster) + " (DEM-raster, single bounce and reflectors, DEMs only)"),
      F::Plain("rays_per_cell", F::At(&SimulateRequest::rays_per_cell),
          "Rays per resolution cell on flat ground"),
      F::Plain("bounces", F::At(&SimulateRequest::bounces),
          "Reflections followed per ray (1 = single bounce)"),
      F::Plain("coherent", F::At(&SimulateRequest::coherent),
          "Coherent mode: complex sum per pixel (path phase 4 pi r / lambda, random micro-phase of rough "
          "surfaces), complex PSF; writes PREFIX_slc.tif"),
      F::Plain("wavelength_m", F::At(&SimulateRequest::wavelength_m),
          "Radar wavelength, metres (materials' sigma0 laws, coherent phase)"),
      F::Plain("polarization", F::At(&SimulateRequest::polarization),
          "Channels: " + material::kPolarizations.Alternatives() +
              " (the materials' sigma0 laws), a comma list (HH,VV) or quad; several channels give bands per channel "
              "and, with --coherent and quad, PREFIX_pauli.png"),
      F::Plain("radiometry", F::At(&SimulateRequest::radiometry),
          "Output quantity: " + image::kRadiometries.Alternatives() + " (ellipsoid incidence; docs/radiometry.md)"),
      F::Plain("db", F::At(&SimulateRequest::db),
          "Write decibels (10 log10) instead of linear m2/m2 (no return: NaN)"),
      F::Plain("layers", F::At(&SimulateRequest::layers),
          "Also write PREFIX_layers.tif: local incidence (deg) and projected terrain area (m2) per pixel"),
      F::Plain("incidence_band", F::At(&SimulateRequest::incidence_band),
          "Append the local incidence angle (deg, area-weighted over the surfaces facing the radar; NaN outside "
          "the footprint) to PREFIX.tif as its last band, local_incidence"),
      F::Plain("overviews", F::At(&SimulateRequest::overviews),
          "Rasters over 1024 px a side: COGs with internal overviews, or (--no-overviews) without them (faster, a "
          "third smaller)"),
      F::Plain("tps_gcps", F::At(&SimulateRequest::tps_gcps),
          "GCPs for gdalwarp -tps: the 12 x 12 lattice refined, up to 1024, where the thin-plate spline through "
          "them misses the terrain by more than 0.4 pixel spacings (0.1-0.4 s), or (--no-tps-gcps) the lattice "
          "alone; the RPCs (exact with a DEM: gdalwarp -rpc -to RPC_DEM=) are the same"),
      F::Plain("heightfield", F::At(&SimulateRequest::heightfield),
          "Trace a DEM's terrain as a height field (a quadtree over its cells, no BVH), or (--no-heightfield) "
          "through Embree's BVH over its triangles"),
      F::Plain("adaptive_sampling", F::At(&SimulateRequest::adaptive_sampling),
          "Split near-grazing first hits wider than a pixel into sub-rays, or (--no-adaptive-sampling, also "
          "--fixed-sampling) trace exactly the ray grid's primary rays (benchmarks)", true, "--fixed-sampling"),
      F::Plain("materials", F::At(&SimulateRequest::materials),
          "Materials file (JSON, class -> sigma0 law); with --dem it sets the class 'default'", false),
      F::Plain("reflectors", F::At(&SimulateRequest::reflectors),
          "Canonical reflectors CSV: "
          "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg", false),
      F::Plain("contributions", F::At(&SimulateRequest::contributions),
          "CSV with one row per return: azimuth, range, elevation, intensity, bounces, specular, hit, class", false),
      F::NullableNumber("range_resolution_m", F::At(&SimulateRequest::range_resolution_m),
          "Impulse response: 3 dB slant-range resolution, metres (0 = none; not given: none, or with --product "
          "the product's processed range bandwidth when it states it)"),
      F::NullableNumber("azimuth_resolution_m", F::At(&SimulateRequest::azimuth_resolution_m),
          "Impulse response: 3 dB azimuth resolution, metres (0 = none; not given: none, or with --product the "
          "product's processed azimuth bandwidth when it states it)"),
      F::Plain("psf_window", F::At(&SimulateRequest::psf_window),
          "Spectral window: " + image::kSpectralWindows.Alternatives()),
      F::Plain("speckle_looks", F::At(&SimulateRequest::speckle_looks),
          "Multiplicative L-look gamma speckle (0 = off)"),
      F::NullableNumber("nesz_db", F::At(&SimulateRequest::nesz_db),
          "Thermal noise floor (NESZ), dB sigma0"),
      F::Plain("seed", F::At(&SimulateRequest::seed),
          "Seed of speckle and noise"),
      F::Plain("out_prefix", F::At(&SimulateRequest::out_prefix),
          "Output prefix: PREFIX.tif, PREFIX.png, PREFIX_quicklook.png (dB colour bar, axes in m), "
          "PREFIX_mask.tif, PREFIX.json, PREFIX_stac.json (STAC Item)", false),
      F::Plain("max_memory_bytes", F::At(&SimulateRequest::max_memory_bytes),
          "", false),
  });
  return kTable;
}

const std::map<std::string, std::string>& SimulateFieldHelp() {
  static const std::map<std::string, std::string> kHelp = SimulateFields().Help();
  return kHelp;
}

const std::string& SimulateHelp(const std::string& field) {
  const auto it = SimulateFieldHelp().find(field);
  GISSAR_CHECK_MSG(it != SimulateFieldHelp().end(), "no help for simulate field " << field);
  return it->second;
}

// The request's JSON form is its table's (simulate.h states the promises).
nlohmann::json SimulateRequest::ToJson() const { return SimulateFields().ToJson(*this); }

void SimulateRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  SimulateFields().ApplyJson(*this, values, source);
}

}  // namespace gissar::pipeline
