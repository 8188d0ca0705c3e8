// raster_agreement: renders a DEM with the ray tracer (single bounce) and
// with the DEM-raster engine at the same pixel grid and prints how closely
// they agree (Pearson r of the dB images where both are non-zero, mask
// pixels that differ and those not within one pixel of an edge) and both
// times, as one JSON object. With --out PREFIX it also writes the two dB
// quicklooks and masks (PREFIX_trace.png, PREFIX_raster.png,
// PREFIX_trace_mask.png, PREFIX_raster_mask.png).
//
//   raster_agreement --dem DEM.tif --heading 30 --depression 40
//       [--fill-nodata] [--slant-range 20000] [--range-spacing M --azimuth-spacing M]
//       [--mode affine|exact] [--look right|left] [--rays-per-cell 16] [--out PREFIX]
#include <CLI/CLI.hpp>

#include <cstdio>
#include <nlohmann/json.hpp>

#include "gissar/pipeline/simulate.h"
#include "gissar/geo/raster_io.h"
#include "gissar/image/quicklook.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/image_agreement.h"
#include "gissar/render/raster_renderer.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"

int main(int argc, char** argv) {
  using namespace gissar;
  CLI::App app("Ray tracer vs DEM-raster engine agreement");
  pipeline::SimulateRequest options;
  std::string mode = "affine", look = "right", out;
  options.out_prefix = "unused";
  app.add_option("--dem", options.dem)->required();
  app.add_flag("--fill-nodata", options.fill_nodata);
  app.add_option("--heading", options.geometry.heading_deg)->required();
  app.add_option("--depression", options.geometry.depression_deg)->required();
  app.add_option("--slant-range", options.geometry.slant_range_m);
  app.add_option("--range-spacing", options.geometry.range_spacing_m);
  app.add_option("--azimuth-spacing", options.geometry.azimuth_spacing_m);
  app.add_option("--mode", mode);
  app.add_option("--look", look);
  app.add_option("--rays-per-cell", options.rays_per_cell);
  app.add_option("--out", out);
  CLI11_PARSE(app, argc, argv);
  try {
    options.geometry.mode = sensor::ParseProjectionMode(mode);
    options.geometry.look_side = sensor::ParseLookSide(look);
    pipeline::Terrain terrain = pipeline::LoadTerrain(options);
    const auto& grid = terrain.description;
    const int width = grid["width"].get<int>(), height = grid["height"].get<int>();
    const sensor::SarGeometry geometry = sensor::SarGeometry::Covering(
        pipeline::ResolvedGeometry(options, terrain), terrain.centre_enu, terrain.mesh.vertices);

    render::RenderOptions render_options;
    render_options.rays_per_cell = options.rays_per_cell;
    render_options.max_bounces = 1;
    Stopwatch trace_watch;
    const render::EmbreeScene embree(terrain.mesh);
    const render::SarImage traced =
        render::RenderSar(embree, terrain.mesh, terrain.materials, geometry, render_options);
    const double trace_seconds = trace_watch.ElapsedSeconds();
    // The raster engine's terrain: the same posts, those outside the scene
    // (a DEM's collar, border voids) non-finite.
    pipeline::SimulateRequest raster_options = options;
    raster_options.engine = pipeline::SimulateEngine::kRaster;
    const pipeline::Terrain raster_terrain = pipeline::LoadTerrain(raster_options);
    Stopwatch raster_watch;
    const render::SarImage raster =
        render::RenderSarRaster(raster_terrain.mesh.vertices, width, height, terrain.materials, geometry);
    const double raster_seconds = raster_watch.ElapsedSeconds();

    const render::IntensityAgreement intensity = render::CompareIntensities(raster.intensity, traced.intensity);
    const render::MaskAgreement mask =
        render::CompareMasks(raster.mask, traced.mask, geometry.width(), geometry.height());
    double sum_raster = 0, sum_trace = 0;
    for (size_t i = 0; i < raster.intensity.size(); ++i) {
      sum_raster += raster.intensity[i];
      sum_trace += traced.intensity[i];
    }
    nlohmann::json j = {{"dem", options.dem},
                        {"total_power_ratio", sum_raster / sum_trace},
                        {"heading_deg", options.geometry.heading_deg},
                        {"depression_deg", options.geometry.depression_deg},
                        {"mode", mode},
                        {"look", look},
                        {"image", {geometry.width(), geometry.height()}},
                        {"range_spacing_m", geometry.range_spacing_m()},
                        {"azimuth_spacing_m", geometry.azimuth_spacing_m()},
                        {"rays_per_cell", options.rays_per_cell},
                        {"db_pearson", intensity.db_pearson},
                        {"compared_pixels", intensity.compared_pixels},
                        {"one_sided_zero_pixels", intensity.one_sided_zero},
                        {"mask_flagged_pixels", mask.flagged},
                        {"mask_differing_pixels", mask.differing},
                        {"mask_differing_away_from_edges", mask.away_from_edges},
                        {"trace_seconds_with_bvh", trace_seconds},
                        {"raster_seconds", raster_seconds}};
    nlohmann::json unexplained = nlohmann::json::array();
    for (const auto& p : mask.unexplained) unexplained.push_back({p.col, p.row, p.a, p.b});
    j["mask_unexplained_col_row_raster_trace"] = unexplained;
    std::printf("%s\n", j.dump().c_str());
    if (!out.empty()) {
      image::DbStretch stretch;
      geo::WritePng(out + "_trace.png", image::DbQuicklook(traced.intensity, 2, 98, &stretch),
                    geometry.width(), geometry.height(), 1);
      geo::WritePng(out + "_raster.png", image::DbQuicklookWithStretch(raster.intensity, stretch),
                    geometry.width(), geometry.height(), 1);
      for (const auto& [name, m] : {std::pair{"_trace_mask.png", &traced.mask}, {"_raster_mask.png", &raster.mask}}) {
        std::vector<uint8_t> grey(m->size());
        for (size_t i = 0; i < grey.size(); ++i) grey[i] = static_cast<uint8_t>((*m)[i] * 80);
        geo::WritePng(out + name, grey, geometry.width(), geometry.height(), 1);
      }
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "raster_agreement: %s (%s)\n", e.message().c_str(), e.where().c_str());
    return 2;
  }
  return 0;
}
