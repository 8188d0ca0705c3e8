#include "gissar/pipeline/simulate_help.h"

#include "gissar/image/impulse_response.h"
#include "gissar/image/radiometry.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::pipeline {

const std::map<std::string, std::string>& SimulateFieldHelp() {
  static const std::map<std::string, std::string> kHelp = {
      {"dem", "DEM raster, any GDAL format and CRS"},
      {"scene", "Scene file from `gissar scene build` (instead of --dem)"},
      {"product",
       "Real product: NISAR RSLC HDF5 (--frequency) or Sentinel-1 SAFE directory/.zip (--swath, --burst; a GRD is "
       "resampled to its ground range; no real image is written): render on its radar grid with its orbit (no "
       "--heading/--depression)"},
      {"orbit",
       "Any sensor's track: state vectors (CSV or JSON of UTC time, ECEF position and velocity, or an ESA .EOF orbit "
       "file); with --radar-grid, instead of --heading/--depression; with a Sentinel-1 --product, replaces its "
       "annotation's orbit"},
      {"radar_grid",
       "Radar grid JSON (starting_range_m, range_spacing_m, sensing_start_utc, azimuth_time_interval_s, width, "
       "length, look_side, wavelength_m) to render on with --orbit"},
      {"dem_oversample",
       "Refine the DEM this many times (cubic convolution) before meshing; for posts coarser than the pixels"},
      {"vertical_units", "Unit of the DEM heights: m, ft or us-ft (default: the file's band unit or vertical CRS, else m)"},
      {"vertical_datum",
       "Datum of the DEM heights: ellipsoid, egm96, egm2008 or EPSG:n of a vertical CRS (default: the file's "
       "vertical CRS, else ellipsoid with a warning)"},
      {"sea", "DEM sea: auto (heights <= --sea-level connected to the border are class sea) or off"},
      {"dem_window",
       "auto: with --width/--height read only the DEM window the image needs (same image); off: read the whole DEM"},
      {"sea_level_m", "Sea level for --sea auto, metres in the DEM's heights"},
      {"fill_nodata", "Fill DEM no-data cells (GDAL FillNodata) instead of failing"},
      {"heading_deg", "Flight heading, degrees clockwise from north (required without --product/--orbit)"},
      {"depression_deg", "Depression angle at the scene centre, degrees in (0, 90) (required without --product/--orbit)"},
      {"look_side", "Look side: " + sensor::kLookSides.Alternatives()},
      {"center_lonlat", "Scene centre LON,LAT in degrees (default: DEM centre)"},
      {"center_map", "Scene centre X,Y in the DEM's CRS"},
      {"slant_range_m", "Slant range from the sensor to the scene centre, metres"},
      {"range_spacing_m", "Slant-range pixel spacing, metres (default: DEM post spacing)"},
      {"azimuth_spacing_m", "Azimuth pixel spacing, metres (default: DEM post spacing)"},
      {"mode", "Projection: " + sensor::ToString(sensor::ProjectionMode::kAffine) + " (parallel rays) or " +
                   sensor::ToString(sensor::ProjectionMode::kExact) + " (flight line)"},
      {"width", "Image columns (range); default: cover the scene"},
      {"height", "Image rows (azimuth); default: cover the scene"},
      {"engine",
       "Image formation: " + ToString(SimulateEngine::kTrace) + " (ray tracing) or " +
           ToString(SimulateEngine::kRaster) + " (DEM-raster, single bounce and reflectors, DEMs only)"},
      {"rays_per_cell", "Rays per resolution cell on flat ground"},
      {"bounces", "Reflections followed per ray (1 = single bounce)"},
      {"coherent",
       "Coherent mode: complex sum per pixel (path phase 4 pi r / lambda, random micro-phase of rough surfaces), "
       "complex PSF; writes PREFIX_slc.tif"},
      {"wavelength_m", "Radar wavelength, metres (materials' sigma0 laws, coherent phase)"},
      {"polarization", "Channels: " + material::kPolarizations.Alternatives() + " (the materials' sigma0 laws), a comma list (HH,VV) or quad; several channels give bands per channel and, with --coherent and quad, PREFIX_pauli.png"},
      {"radiometry", "Output quantity: " + image::kRadiometries.Alternatives() + " (ellipsoid incidence; docs/radiometry.md)"},
      {"db", "Write decibels (10 log10) instead of linear m2/m2 (no return: NaN)"},
      {"layers", "Also write PREFIX_layers.tif: local incidence (deg) and projected terrain area (m2) per pixel"},
      {"overviews",
       "Rasters over 1024 px a side: COGs with internal overviews, or (--no-overviews) without them (faster, a "
       "third smaller)"},
      {"heightfield",
       "Trace a DEM's terrain as a height field (a quadtree over its cells, no BVH), or (--no-heightfield) through "
       "Embree's BVH over its triangles"},
      {"adaptive_sampling",
       "Split near-grazing first hits wider than a pixel into sub-rays, or (--no-adaptive-sampling, also "
       "--fixed-sampling) trace exactly the ray grid's primary rays (benchmarks)"},
      {"materials", "Materials file (JSON, class -> sigma0 law); with --dem it sets the class 'default'"},
      {"reflectors",
       "Canonical reflectors CSV: type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg"},
      {"contributions",
       "CSV with one row per return: azimuth, range, elevation, intensity, bounces, specular, hit, class"},
      {"range_resolution_m", "Impulse response: 3 dB slant-range resolution, metres (0 = none; not given: none, "
                             "or with --product the product's processed range bandwidth when it states it)"},
      {"azimuth_resolution_m", "Impulse response: 3 dB azimuth resolution, metres (0 = none; not given: none, "
                               "or with --product the product's processed azimuth bandwidth when it states it)"},
      {"psf_window", "Spectral window: " + image::kSpectralWindows.Alternatives()},
      {"speckle_looks", "Multiplicative L-look gamma speckle (0 = off)"},
      {"nesz_db", "Thermal noise floor (NESZ), dB sigma0"},
      {"seed", "Seed of speckle and noise"},
      {"out_prefix",
       "Output prefix: PREFIX.tif, PREFIX.png, PREFIX_quicklook.png (dB colour bar, axes in m), PREFIX_mask.tif, "
       "PREFIX.json, PREFIX_stac.json (STAC Item)"},
  };
  return kHelp;
}

const std::string& SimulateHelp(const std::string& field) { return SimulateFieldHelp().at(field); }

}  // namespace gissar::pipeline
