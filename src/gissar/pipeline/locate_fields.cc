#include "gissar/pipeline/locate_fields.h"

#include "gissar/geo/look_side.h"
#include "gissar/pipeline/evaluate_fields.h"
#include "gissar/pipeline/sentinel1_simulate.h"

namespace gissar::pipeline {
namespace {

using F = Fields<LocateRequest>;
using R = LocateRequest;

// The help of a field locate shares with evaluate.
const std::string& Shared(const std::string& name) { return EvaluateFields().at(name).help; }

}  // namespace

// Fields in the order of `gissar locate --help` (locate.h states what each means).
const FieldTable<LocateRequest>& LocateFields() {
  static const FieldTable<LocateRequest> kTable(
      {
          F::Plain("image", F::At(&R::image), "Observed image (GeoTIFF, band 1 linear intensity, GISSAR_* metadata)",
                   false),
          F::Plain("product", F::At(&R::product),
                   "Or a real product (NISAR RSLC HDF5, Sentinel-1 SLC SAFE): fix its own track from a displaced prior "
                   "(docs/navigation.md)",
                   false),
          F::Plain("orbit", F::At(&R::orbit),
                   "Or any sensor's state vectors (CSV, JSON, ESA .EOF) of the --image, fixed like a product", false),
          F::Plain("radar_grid", F::At(&R::radar_grid), "Radar grid JSON of the --image (with --orbit)", false),
          F::Plain("frequency", F::At(&R::frequency), Shared("frequency")),
          F::Plain("polarization", F::At(&R::polarization), Shared("polarization")),
          F::Plain("swath", F::At(&R::swath), Shared("swath"), false),
          F::Plain("burst", F::At(&R::burst), Shared("burst"), false),
          F::OptionalWindow("product_window_px", F::At(&R::product_window_px), Shared("product_window_px"),
                            ProductWindowJson),
          F::Numbers("prior_offset_track", F::At(&R::prior_offset_track), 3,
                     "With --product: prior = annotated track moved ALONG,CROSS,UP metres (mid-scene velocity "
                     "frame)"),
          F::Plain("prior_heading_offset_deg", F::At(&R::prior_heading_offset_deg),
                   "With --product: and turned by this many degrees (clockwise)"),
          F::Plain("prior_sigma_horizontal_m", F::At(&R::prior_sigma_horizontal_m),
                   "With --product: INS one-sigma horizontal error, m"),
          F::Plain("prior_sigma_vertical_m", F::At(&R::prior_sigma_vertical_m),
                   "With --product: INS one-sigma vertical error, m"),
          F::Plain("prior_sigma_heading_deg", F::At(&R::prior_sigma_heading_deg),
                   "With --product: INS one-sigma track-angle error, deg"),
          F::Plain("looks_range", F::At(&R::looks_range), Shared("looks_range")),
          F::Plain("looks_azimuth", F::At(&R::looks_azimuth), Shared("looks_azimuth")),
          F::Plain("dem_oversample", F::At(&R::dem_oversample), Shared("dem_oversample")),
          F::Plain("reflectors", F::At(&R::reflectors), Shared("reflectors"), false),
          F::Plain("terrain_horizontal_sigma_m", F::At(&R::terrain_horizontal_sigma_m),
                   Shared("terrain_horizontal_sigma_m")),
          F::Plain("sea", F::At(&R::sea), Shared("sea")),
          F::Plain("scene", F::At(&R::scene), Shared("scene"), false),
          F::Plain("dem", F::At(&R::dem), Shared("dem"), false),
          F::Plain("vertical_datum", F::At(&R::vertical_datum), Shared("vertical_datum"), false),
          F::Plain("prior", F::At(&R::prior), "Prior pose JSON (docs/navigation.md; with --image)", false),
          F::Plain("out", F::At(&R::out), "Output prefix: PREFIX.json (the fix)", false),
          F::Plain("composite_png", F::At(&R::composite_png),
                   "PNG: observed (green) over simulated (magenta) at the prior and at the fix", false)
              .WithFlag("--composite"),
          F::Plain("range_spacing_m", F::At(&R::range_spacing_m),
                   "Slant-range pixel spacing, m (default: image metadata)", false),
          F::Plain("azimuth_spacing_m", F::At(&R::azimuth_spacing_m),
                   "Azimuth pixel spacing, m (default: image metadata)", false),
          F::Plain("look", F::At(&R::look),
                   geo::kLookSides.Alternatives() + " (default: image metadata, else " +
                       std::string(geo::kLookSides.Name(geo::LookSide::kRight)) + ")",
                   false),
          F::Plain("matcher", F::At(&R::matcher), Shared("matcher")),
          F::Plain("search_px", F::At(&R::search_px), "First-iteration search radius, px (prior uncertainty)"),
          F::Plain("step_px", F::At(&R::step_px), Shared("step_px")),
          F::Plain("dense_renders", F::At(&R::dense_renders), Shared("dense_renders")),
          F::Plain("polish_evaluations", F::At(&R::polish_evaluations), Shared("polish_evaluations"))
              .WithFlag("--polish"),
          F::Plain("bounces", F::At(&R::bounces), "Reflections per ray in the reference renders"),
          F::Plain("rays_per_cell", F::At(&R::rays_per_cell), "Rays per cell in the reference renders"),
          F::Plain("database", F::At(&R::database),
                   "Reference database PREFIX_catalog.json (gissar corridor, same --dem/--scene): match the stored "
                   "reference covering the prior, no rendering (docs/navigation.md)",
                   false),
          F::Plain("database_fallback", F::At(&R::database_fallback),
                   "No stored reference covers the prior: none (no fix, exit 3) or render (on the fly)"),
          F::Plain("database_heading_tolerance_deg", F::At(&R::database_heading_tolerance_deg),
                   Shared("database_heading_tolerance_deg")),
          F::Plain("max_memory_bytes", F::At(&R::max_memory_bytes), "", false),
      },
      /*null_keeps_default=*/true);
  return kTable;
}

// The request's JSON form is its table's (locate.h states the promises).
nlohmann::json LocateRequest::ToJson() const { return LocateFields().ToJson(*this); }

void LocateRequest::ApplyJson(const nlohmann::json& values, const std::string& source) {
  LocateFields().ApplyJson(*this, values, source);
}

// In the order of `gissar matchpair --help`.
const FieldTable<MatchPairRequest>& MatchPairFields() {
  using M = MatchPairRequest;
  using G = Fields<M>;
  static const FieldTable<MatchPairRequest> kTable({
      G::Plain("fixed", G::At(&M::fixed), "Fixed image", false),
      G::Plain("moving", G::At(&M::moving), "Moving image (same grid, another date)", false),
      G::Numbers("warp", G::At(&M::warp), 4, "Known warp ROT_DEG,SCALE,TX,TY applied to the moving image"),
      G::Plain("patch_px", G::At(&M::patch_px), "Patch side, px (odd)"),
      G::Plain("step_px", G::At(&M::step_px), "Grid step, px"),
      G::Plain("search_px", G::At(&M::search_px), "Search radius, px"),
      G::Plain("filter_px", G::At(&M::filter_px), "Speckle box filter, px"),
      G::Plain("out", G::At(&M::out), "Output prefix: PREFIX.json (errors per matcher)", false),
  });
  return kTable;
}

}  // namespace gissar::pipeline
