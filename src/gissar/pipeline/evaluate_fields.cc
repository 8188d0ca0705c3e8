#include "gissar/pipeline/evaluate_fields.h"

#include "gissar/material/material.h"
#include "gissar/nav/matching.h"
#include "gissar/nav/product_locate.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulate_fields.h"

namespace gissar::pipeline {
namespace {

using F = Fields<EvaluateRequest>;
using R = EvaluateRequest;

}  // namespace

// Fields in the order of `gissar evaluate --help` (locate.h states what each means).
const FieldTable<EvaluateRequest>& EvaluateFields() {
  static const FieldTable<EvaluateRequest> kTable(
      {
          F::Plain("scene", F::At(&R::scene), "Scene built by `gissar scene build`", false),
          F::Plain("dem", F::At(&R::dem), "Or a DEM (bare terrain)", false),
          F::Plain("vertical_datum", F::At(&R::vertical_datum), SimulateHelp("vertical_datum"), false),
          F::Plain("product", F::At(&R::product),
                   "A real product (NISAR RSLC HDF5, Sentinel-1 SLC SAFE): trials displace its annotated track "
                   "(docs/navigation.md)", false),
          F::Plain("frequency", F::At(&R::frequency), "Product band, A or B"),
          F::Plain("polarization", F::At(&R::polarization),
                   "Product layer (" + material::kPolarizations.List() + ")"),
          F::Plain("swath", F::At(&R::swath),
                   "Sentinel-1 --product: swath, e.g. IW2 (default: the product's only one)", false),
          F::Plain("burst", F::At(&R::burst), "Sentinel-1 IW/EW SLC --product: burst, 1-based per swath", false),
          F::OptionalWindow("product_window_px", F::At(&R::product_window_px),
                            "Sentinel-1 --product: the part of the burst or swath fixed, LINE,PIXEL,LINES,PIXELS in "
                            "its own numbering (default: all of it)",
                            ProductWindowJson),
          F::Plain("looks_range", F::At(&R::looks_range), "With --product: range looks of the multilook"),
          F::Plain("looks_azimuth", F::At(&R::looks_azimuth), "With --product: azimuth looks of the multilook"),
          F::Plain("dem_oversample", F::At(&R::dem_oversample), "Refine the DEM N x by cubic interpolation"),
          F::Plain("reflectors", F::At(&R::reflectors),
                   "With --product: point landmarks, a reflectors CSV (type,lon,lat,apex_height_m,size_m,"
                   "boresight_azimuth_deg,boresight_elevation_deg): rendered in the references; one in the image "
                   "fixes along and cross track where the terrain is flat (up and heading from the prior)",
                   false),
          F::Plain("terrain_horizontal_sigma_m", F::At(&R::terrain_horizontal_sigma_m),
                   "With --product: the DEM's/scene's absolute horizontal error, one sigma per axis, m; added to a "
                   "relief fix's along/cross variance (default: SRTM-class 1\" DEMs)"),
          F::Plain("sea", F::At(&R::sea),
                   "auto or off: the terrain's sea (auto: DEM cells at or below sea level connected to its border)"),
          F::Plain("trials", F::At(&R::trials), "Trials"),
          F::Plain("seed", F::At(&R::seed), "Seed"),
          F::Plain("trial_first", F::At(&R::trial_first),
                   "Run trials from this index (trial k depends only on the seed and k)"),
          F::Plain("trial_count", F::At(&R::trial_count), "Run this many trials (-1: the rest)"),
          F::Plain("out_prefix", F::At(&R::out_prefix),
                   "Output prefix: PREFIX.json, PREFIX_trials.csv, PREFIX_hist.png", false),
          F::Plain("spacing_m", F::At(&R::spacing_m), "Pixel spacing (range = azimuth), m: the resolution cell"),
          F::Plain("size_px", F::At(&R::size_px), "Image side, pixels"),
          F::Plain("slant_range_m", F::At(&R::slant_range_m), "Slant range to the image centre, m"),
          F::Plain("depression_min_deg", F::At(&R::depression_min_deg), "Smallest true depression, deg"),
          F::Plain("depression_max_deg", F::At(&R::depression_max_deg), "Largest true depression, deg"),
          F::Plain("speckle_looks", F::At(&R::speckle_looks), "Speckle looks of the observed image (0 = none)")
              .WithFlag("--looks"),
          F::NullableNumber("nesz_db", F::At(&R::nesz_db), "Thermal noise of the observed image, dB", true),
          F::Plain("material_db", F::At(&R::material_db), "Material mismatch, +- dB per class")
              .WithFlag("--material-db"),
          F::Plain("dem_smoothing", F::At(&R::dem_smoothing), "Laplacian weight of the observed terrain heights"),
          F::Plain("prior_error_horizontal_m", F::At(&R::prior_error_horizontal_m),
                   "INS drift, +- m per horizontal axis (negative: 200, or the product footprint / 8)"),
          F::Plain("prior_error_vertical_m", F::At(&R::prior_error_vertical_m),
                   "INS drift, +- m vertical (negative: 50, or the horizontal / 8)"),
          F::Plain("prior_error_heading_deg", F::At(&R::prior_error_heading_deg),
                   "INS heading drift, +- deg (negative: 3, or 0.05 on a product)"),
          F::Plain("success_cells", F::At(&R::success_cells), "Success: position error at most this many cells"),
          F::Plain("success_heading_deg", F::At(&R::success_heading_deg),
                   "Success: and heading error at most this, deg")
              .WithFlag("--success-heading-deg"),
          F::Plain("matcher", F::At(&R::matcher),
                   nav::kMatchers.Alternatives() + " (--product: " + nav::kShiftMatchers.Alternatives() + ")"),
          F::Plain("compare_matchers", F::At(&R::compare_matchers),
                   "Per-trial matcher comparison (--no-compare: skip it)")
              .WithFlag("--compare"),
          F::Plain("search_px", F::At(&R::search_px), "First-iteration search radius, px (0 = from the prior errors)"),
          F::Plain("step_px", F::At(&R::step_px), "Grid step of the matched patches, px"),
          F::Plain("dense_renders", F::At(&R::dense_renders),
                   "Renders of the dense stage (all-pixel fit with one gain per class; 0 = off)"),
          F::Plain("polish_evaluations", F::At(&R::polish_evaluations),
                   "Nelder-Mead renders after convergence (0 = off)")
              .WithFlag("--polish"),
          F::Plain("bounces", F::At(&R::bounces), "Reflections per ray"),
          F::Plain("rays_per_cell", F::At(&R::rays_per_cell), "Rays per cell"),
          F::Plain("database", F::At(&R::database),
                   "Reference database PREFIX_catalog.json: trials around its stored poses, its image size and "
                   "spacing; fixes from the stored references (docs/navigation.md)",
                   false),
          F::Plain("database_fixes", F::At(&R::database_fixes),
                   "With --database: stored (match the stored references) or render (on the fly, same images)"),
          F::Plain("database_fallback", F::At(&R::database_fallback),
                   "No stored reference covers the prior: none (no fix) or render (on the fly)"),
          F::Plain("database_heading_tolerance_deg", F::At(&R::database_heading_tolerance_deg),
                   "Largest heading difference between the prior and a stored reference, deg"),
          F::Plain("reference_floor", F::At(&R::reference_floor),
                   "References with the observed noise floor (--nesz), or (--no-reference-floor) dark areas at "
                   "-40 dB"),
          F::Plain("max_memory_bytes", F::At(&R::max_memory_bytes), "", false),
      },
      /*null_keeps_default=*/true);
  return kTable;
}

// The request's JSON form is its table's (locate.h states the promises).
nlohmann::json EvaluateRequest::ToJson() const { return EvaluateFields().ToJson(*this); }

void EvaluateRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  EvaluateFields().ApplyJson(*this, values, source);
}

}  // namespace gissar::pipeline
