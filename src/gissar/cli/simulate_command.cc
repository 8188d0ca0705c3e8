// `gissar simulate` flags, bound to SimulateRequest.
#include <memory>

#include "gissar/cli/command.h"
#include "gissar/pipeline/simulate.h"

namespace gissar::cli {
using namespace gissar::pipeline;  // the requests and Run functions this command binds

void AddSimulateCommand(CLI::App& root, CommandRegistry& registry) {
  auto options = std::make_shared<SimulateRequest>();
  auto center = std::make_shared<std::string>();
  auto center_map = std::make_shared<std::string>();
  auto mode = std::make_shared<std::string>("affine");
  auto look = std::make_shared<std::string>("right");
  CLI::App* cmd = root.add_subcommand(
      "simulate", "Simulate a SAR image (azimuth x slant range) of a DEM by ray tracing.");
  cmd->add_option("--dem", options->dem, "DEM raster, any GDAL format and CRS");
  cmd->add_option("--scene", options->scene, "Scene file from `gissar scene build` (instead of --dem)");
  cmd->add_option("--product", options->product,
                  "Real product (NISAR RSLC HDF5): render on its radar grid with its orbit (no --heading/--depression)");
  cmd->add_option("--orbit", options->orbit,
                  "Any sensor's track: state vectors (CSV or JSON of UTC time, ECEF position and velocity, or an ESA "
                  ".EOF orbit file); with --radar-grid, instead of --heading/--depression");
  cmd->add_option("--radar-grid", options->radar_grid,
                  "Radar grid JSON (starting_range_m, range_spacing_m, sensing_start_utc, azimuth_time_interval_s, "
                  "width, length, look_side, wavelength_m) to render on with --orbit");
  cmd->add_option("--dem-oversample", options->dem_oversample,
                  "Refine the DEM this many times (cubic convolution) before meshing; for posts coarser than the pixels")
      ->capture_default_str();
  cmd->add_option("--vertical-units", options->vertical_units,
                  "Unit of the DEM heights: m, ft or us-ft (default: the file's band unit or vertical CRS, else m)");
  cmd->add_option("--vertical-datum", options->vertical_datum, kVerticalDatumHelp);
  cmd->add_option("--sea", options->sea, "DEM sea: auto (heights <= --sea-level connected to the border are class sea) or off")->capture_default_str();
  cmd->add_option("--dem-window", options->dem_window,
                  "auto: with --width/--height read only the DEM window the image needs (same image); off: read the whole DEM")
      ->capture_default_str();
  cmd->add_option("--sea-level", options->sea_level_m, "Sea level for --sea auto, metres in the DEM's heights")->capture_default_str();
  cmd->add_flag("--fill-nodata", options->fill_nodata,
                "Fill DEM no-data cells (GDAL FillNodata) instead of failing");
  cmd->add_option("--heading", options->geometry.heading_deg,
                  "Flight heading, degrees clockwise from north (required without --product/--orbit)");
  cmd->add_option("--depression", options->geometry.depression_deg,
                  "Depression angle at the scene centre, degrees in (0, 90) (required without --product/--orbit)");
  cmd->add_option("--look", *look, "Look side: right or left")->capture_default_str();
  cmd->add_option("--center", *center, "Scene centre LON,LAT in degrees (default: DEM centre)");
  cmd->add_option("--center-map", *center_map, "Scene centre X,Y in the DEM's CRS");
  cmd->add_option("--slant-range", options->geometry.slant_range_m,
                  "Slant range from the sensor to the scene centre, metres")
      ->capture_default_str();
  cmd->add_option("--range-spacing", options->geometry.range_spacing_m,
                  "Slant-range pixel spacing, metres (default: DEM post spacing)");
  cmd->add_option("--azimuth-spacing", options->geometry.azimuth_spacing_m,
                  "Azimuth pixel spacing, metres (default: DEM post spacing)");
  cmd->add_option("--mode", *mode, "Projection: affine (parallel rays) or exact (flight line)")
      ->capture_default_str();
  cmd->add_option("--width", options->geometry.width,
                  "Image columns (range); default: cover the scene");
  cmd->add_option("--height", options->geometry.height,
                  "Image rows (azimuth); default: cover the scene");
  cmd->add_option("--engine", options->engine,
                  "Image formation: trace (ray tracing) or raster (DEM-raster, single bounce and reflectors, DEMs only)")
      ->capture_default_str();
  cmd->add_option("--rays-per-cell", options->rays_per_cell,
                  "Rays per resolution cell on flat ground")
      ->capture_default_str();
  cmd->add_option("--bounces", options->bounces, "Reflections followed per ray (1 = single bounce)")
      ->capture_default_str();
  cmd->add_flag("--coherent", options->coherent,
                "Coherent mode: complex sum per pixel (path phase 4 pi r / lambda, random micro-phase of rough surfaces), complex PSF; writes PREFIX_slc.tif");
  cmd->add_option("--wavelength", options->wavelength_m, "Radar wavelength, metres (materials' sigma0 laws, coherent phase)")
      ->capture_default_str();
  cmd->add_option("--polarization", options->polarization,
                  "Polarisation of the materials' sigma0 laws: HH, HV, VH or VV")
      ->capture_default_str();
  cmd->add_option("--radiometry", options->radiometry,
                  "Output quantity: sigma0, beta0 or gamma0 (ellipsoid incidence; docs/radiometry.md)")
      ->capture_default_str();
  cmd->add_flag("--db", options->db, "Write decibels (10 log10) instead of linear m2/m2 (no return: NaN)");
  cmd->add_flag("--layers", options->layers,
                "Also write PREFIX_layers.tif: local incidence (deg) and projected terrain area (m2) per pixel");
  cmd->add_flag("--overviews,!--no-overviews", options->overviews,
                "Rasters over 1024 px a side: COGs with internal overviews (default), or without them "
                "(--no-overviews: faster, a third smaller)");
  cmd->add_flag("--heightfield,!--no-heightfield", options->heightfield,
                "Trace a DEM's terrain as a height field (default: a quadtree over its cells, no BVH), or "
                "(--no-heightfield) through Embree's BVH over its triangles");
  cmd->add_flag("--adaptive-sampling,!--fixed-sampling", options->adaptive_sampling,
                "Split near-grazing first hits wider than a pixel into sub-rays (default), or (--fixed-sampling) "
                "trace exactly the ray grid's primary rays (benchmarks)");
  cmd->add_option("--materials", options->materials,
                  "Materials file (JSON, class -> sigma0 law); with --dem it sets the class 'default'");
  cmd->add_option("--reflectors", options->reflectors,
                  "Canonical reflectors CSV: type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg");
  cmd->add_option("--contributions", options->contributions,
                  "CSV with one row per return: azimuth, range, elevation, intensity, bounces, specular, hit, class");
  cmd->add_option("--range-resolution", options->range_resolution_m,
                  "Impulse response: 3 dB slant-range resolution, metres (0 = none)");
  cmd->add_option("--azimuth-resolution", options->azimuth_resolution_m,
                  "Impulse response: 3 dB azimuth resolution, metres (0 = none)");
  cmd->add_option("--psf-window", options->psf_window, "Spectral window: none, hamming or taylor")
      ->capture_default_str();
  cmd->add_option("--speckle-looks", options->speckle_looks,
                  "Multiplicative L-look gamma speckle (0 = off)")
      ->capture_default_str();
  cmd->add_option("--nesz", options->nesz_db, "Thermal noise floor (NESZ), dB sigma0");
  cmd->add_option("--seed", options->seed, "Seed of speckle and noise")->capture_default_str();
  cmd->add_option("--out", options->out_prefix,
                  "Output prefix: PREFIX.tif, PREFIX.png, PREFIX_quicklook.png (dB colour bar, axes in m), PREFIX_mask.tif, PREFIX.json, PREFIX_stac.json (STAC Item)")
      ->required();
  auto max_memory = std::make_shared<std::string>();
  cmd->add_option("--max-memory", *max_memory,
                  "Memory budget, e.g. 4G (default: 3/4 of physical memory); larger jobs fail early");

  registry.Add(cmd, [=](const CommandContext& context) {
    SimulateRequest resolved = *options;
    for (const char* flag : {"--heading", "--depression"}) {
      if (!resolved.UsesProductGeometry() && cmd->count(flag) == 0) throw ConfigError("is required", flag);
      if (resolved.UsesProductGeometry() && cmd->count(flag) > 0) {
        const std::string by = resolved.product.empty() ? "the orbit" : "the product";
        throw ConfigError(by + " fixes the geometry", std::string(resolved.product.empty() ? "--orbit/" : "--product/") + flag);
      }
    }
    RequirePositiveIfGiven(*cmd, "--range-spacing", resolved.geometry.range_spacing_m);
    RequirePositiveIfGiven(*cmd, "--azimuth-spacing", resolved.geometry.azimuth_spacing_m);
    resolved.max_memory_bytes = MemoryBudgetBytes(*max_memory, context.force, resolved.max_memory_bytes);
    resolved.geometry.mode = sensor::ParseProjectionMode(*mode);
    resolved.geometry.look_side = sensor::ParseLookSide(*look);
    if (!center->empty()) resolved.center_lonlat = ParseNumberPair(*center, "--center");
    if (!center_map->empty()) resolved.center_map = ParseNumberPair(*center_map, "--center-map");
    const SimulateResult result = RunSimulate(resolved, context.command_line, context.reporter);
    for (const auto& path : result.outputs) context.out << path.string() << "\n";
  });
}

}  // namespace gissar::cli
