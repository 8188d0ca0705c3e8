#include "gissar/pipeline/views.h"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>

#include "gissar/geo/orthophoto.h"
#include "gissar/geo/raster_io.h"
#include "gissar/image/class_map.h"
#include "gissar/image/contact_sheet.h"
#include "gissar/image/gif_writer.h"
#include "gissar/image/quicklook.h"
#include "gissar/render/ortho_renderer.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string FrameSuffix(int i) {
  std::ostringstream s;
  s << "_f" << std::setw(2) << std::setfill('0') << i;
  return s.str();
}

}  // namespace

void SequenceRequest::Check() const {
  base.Check();
  if (!(std::abs(heading_from_deg) <= sensor::kMaxAbsHeadingDeg)) {
    throw ConfigError("heading must be within +-10000 degrees", "--heading-from");
  }
  if (!(std::abs(heading_to_deg) <= sensor::kMaxAbsHeadingDeg)) {
    throw ConfigError("heading must be within +-10000 degrees", "--heading-to");
  }
  if (frames < 2 || frames > 360) throw ConfigError("frames must be in [2, 360]", "--frames");
  if (frame_delay_cs < 1 || frame_delay_cs > 6000) throw ConfigError("frame delay must be in [1, 6000] cs", "--frame-delay");
}

json SequenceRequest::ToJson() const {
  json j = base.ToJson();
  j.erase("heading_deg");
  j["heading_from_deg"] = heading_from_deg;
  j["heading_to_deg"] = heading_to_deg;
  j["frames"] = frames;
  j["frame_delay_cs"] = frame_delay_cs;
  return j;
}

SequenceResult RunSequence(const SequenceRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  Stopwatch total;
  const std::string& prefix = options.base.out_prefix;
  AtomicOutputs outputs;
  outputs.LockPrefix(prefix);  // one lock for every frame
  std::vector<fs::path> tifs, pngs;
  for (int i = 0; i < options.frames; ++i) {
    tifs.push_back(outputs.Add(prefix + FrameSuffix(i) + ".tif"));
    pngs.push_back(outputs.Add(prefix + FrameSuffix(i) + ".png"));
  }
  const fs::path contact = outputs.Add(prefix + "_contact.png");
  const fs::path gif = outputs.Add(prefix + ".gif");
  const fs::path json_path = outputs.Add(prefix + ".json");

  Terrain terrain = LoadTerrain(options.base, reporter);
  Stopwatch bvh_watch;
  const render::EmbreeScene embree(terrain.mesh);
  SequenceResult result;
  result.bvh_seconds = bvh_watch.ElapsedSeconds();
  PlaceSceneCentre(terrain, embree, options.base);

  // Headings and a common image size (the largest covering frame).
  std::vector<sensor::SarGeometryOptions> frame_options;
  int width = 0, height = 0;
  for (int i = 0; i < options.frames; ++i) {
    sensor::SarGeometryOptions g = ResolvedGeometry(options.base, terrain);
    g.heading_deg = options.heading_from_deg +
                    (options.heading_to_deg - options.heading_from_deg) * i / (options.frames - 1);
    const sensor::SarGeometry covering = sensor::SarGeometry::Covering(g, terrain.centre_enu, terrain.mesh.vertices);
    width = std::max(width, covering.width());
    height = std::max(height, covering.height());
    frame_options.push_back(g);
  }
  // One frame traced at a time (64 B per pixel, as simulate), plus every
  // frame's 8-bit quicklook and the RGB contact sheet kept for the end.
  const double pixels = double(width) * double(height);
  CheckImagePixels(width, height, options.base.max_memory_bytes,
                   "a frame of " + std::to_string(width) + " x " + std::to_string(height) + " pixels",
                   "use coarser --range-spacing/--azimuth-spacing", "--range-spacing");
  CheckMemoryBudget(64.0 * pixels + 4.0 * pixels * options.frames + 3.0 * double(terrain.mesh.MemoryBytes()),
                    options.base.max_memory_bytes,
                    "sequence of " + std::to_string(options.frames) + " frames of " + std::to_string(width) + " x " +
                        std::to_string(height) + " pixels",
                    "use fewer --frames, coarser --range-spacing/--azimuth-spacing");
  render::RenderOptions render_options = RenderOptionsOf(options.base, FirstChannel(options.base), &reporter);
  // A scene's stored reflectors and any --reflectors rows, as simulate renders them.
  render_options.reflectors = terrain.reflectors;
  for (const render::SceneReflector& r : PlaceReflectors(options.base.reflectors, terrain, embree)) {
    render_options.reflectors.push_back(r);
  }
  std::vector<std::vector<uint8_t>> grey_frames;
  std::vector<std::string> captions;
  image::DbStretch stretch;
  json frames_json = json::array();
  for (int i = 0; i < options.frames; ++i) {
    sensor::SarGeometryOptions g = frame_options[i];
    g.width = width;
    g.height = height;
    const sensor::SarGeometry geometry(g, terrain.centre_enu, (width - 1) / 2.0, (height - 1) / 2.0, width, height);
    Stopwatch frame_watch;
    render::SarImage image = render::RenderSar(embree, terrain.mesh, terrain.materials, geometry, render_options);
    ApplySensorEffects(image, options.base, geometry);
    result.frame_seconds.push_back(frame_watch.ElapsedSeconds());
    {
      char line[128];
      std::snprintf(line, sizeof(line), "sequence: frame %d/%d heading %.2f deg in %.2f s", i + 1, options.frames,
                    g.heading_deg, result.frame_seconds.back());
      reporter.Info(line);
      ThrowIfCancelled(reporter, "sequence");
    }
    geo::Metadata metadata;
    for (const auto& [k, v] : geometry.ToMetadata()) metadata[k] = v;
    metadata["GISSAR_VERSION"] = VersionString();
    geo::FloatRaster frame_raster{width, height, {image.intensity}, {"total"}, metadata};
    frame_raster.nodata_nan = true;  // outside the imaged footprint (ApplySensorEffects)
    geo::WriteFloatGeoTiff(tifs[i], frame_raster);
    std::vector<uint8_t> grey = i == 0 ? image::DbQuicklook(image.intensity, 2.0, 98.0, &stretch)
                                       : image::DbQuicklookWithStretch(image.intensity, stretch);
    geo::WritePng(pngs[i], grey, width, height, 1);
    grey_frames.push_back(std::move(grey));
    std::ostringstream caption;
    caption << "heading " << std::fixed << std::setprecision(1) << g.heading_deg << " deg";
    captions.push_back(caption.str());
    frames_json.push_back({{"heading_deg", g.heading_deg}, {"seconds", result.frame_seconds.back()},
                           {"rays", image.stats.rays}});
  }
  const image::RgbImage sheet = image::ContactSheet(grey_frames, width, height, captions);
  geo::WritePng(contact, sheet.rgb, sheet.width, sheet.height, 3);
  image::WriteAnimatedGif(gif, grey_frames, width, height, options.frame_delay_cs);

  const Eigen::Vector3d sensor0 = terrain.centre_enu - options.base.geometry.slant_range_m *
                                                           sensor::SarGeometry(frame_options[0], terrain.centre_enu, 0, 0, 1, 1).look_direction();
  json provenance = {{"command", "sequence"},
                     {"command_line", command_line},
                     {"version", VersionString()},
                     {"created_utc", UtcTimestamp()},
                     {"options", options.ToJson()},
                     {"inputs", json::array({InputFileRecord(options.base.scene.empty() ? options.base.dem : options.base.scene)})},
                     {"terrain", terrain.description},
                     {"vertical_datum", VerticalDatumRecord(terrain)},
                     {"materials", terrain.materials.ToJson()},
                     {"image", {{"width", width}, {"height", height}}},
                     {"sensor_altitude_enu_m", sensor0.z()},
                     {"frames", frames_json},
                     {"stretch_db", {stretch.low_db, stretch.high_db}},
                     {"bvh_seconds", result.bvh_seconds},
                     {"total_seconds", total.ElapsedSeconds()}};
  WriteJsonFile(provenance, json_path);
  outputs.Commit();
  result.outputs = outputs.final_paths();
  return result;
}

void OrthoRequest::Check() const {
  base.Check();
  if (base.geometry.mode != sensor::ProjectionMode::kAffine) {
    throw ConfigError("ortho views use the affine model: --mode affine", "--mode");
  }
}

std::vector<fs::path> RunOrtho(const OrthoRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  const std::string& prefix = options.base.out_prefix;
  AtomicOutputs outputs;
  const fs::path los_path = outputs.Add(prefix + "_los.png");
  const fs::path sar_path = outputs.Add(prefix + "_sar.png");
  const fs::path gperp_path = outputs.Add(prefix + "_gperp.png");
  const fs::path trio_path = outputs.Add(prefix + "_trio.png");
  const fs::path json_path = outputs.Add(prefix + ".json");

  std::unique_ptr<geo::Orthophoto> photo;
  if (!options.orthophoto.empty()) {
    photo = std::make_unique<geo::Orthophoto>(options.orthophoto, options.base.max_memory_bytes);
  }
  Terrain terrain = LoadTerrain(options.base, reporter);
  const render::EmbreeScene embree(terrain.mesh);
  PlaceSceneCentre(terrain, embree, options.base);
  const sensor::SarGeometry geometry = sensor::SarGeometry::Covering(
      ResolvedGeometry(options.base, terrain), terrain.centre_enu, terrain.mesh.vertices);
  // The SAR image (64 B per pixel, as simulate), two RGB ortho views, the
  // SAR quicklook and the side-by-side trio (about 3 x 3 B): 112 B per pixel.
  CheckImagePixels(geometry.width(), geometry.height(), options.base.max_memory_bytes,
                   "ortho views of " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) +
                       " pixels",
                   "use coarser --range-spacing/--azimuth-spacing", "--range-spacing");
  CheckMemoryBudget(112.0 * double(geometry.width()) * double(geometry.height()) +
                        3.0 * double(terrain.mesh.MemoryBytes()),
                    options.base.max_memory_bytes,
                    "ortho views of " + std::to_string(geometry.width()) + " x " + std::to_string(geometry.height()) +
                        " pixels",
                    "use coarser --range-spacing/--azimuth-spacing");
  const geo::LocalFrame& frame = terrain.frame;
  const render::HitColour colour = [&](const Eigen::Vector3d& enu, int32_t triangle) {
    if (photo) {
      const Eigen::Vector3d geodetic = frame.GeodeticFromEnu(enu);
      if (auto rgb = photo->Sample(geodetic.x(), geodetic.y())) return *rgb;
    }
    const auto& c = image::ClassColours()[std::min<int>(terrain.mesh.classes[triangle], scene::kClassCount - 1)];
    return std::array<uint8_t, 3>{c[0], c[1], c[2]};
  };
  const render::OrthoImage los = render::RenderOrtho(embree, terrain.mesh, geometry, render::OrthoView::kLineOfSight, colour);
  const render::OrthoImage gperp =
      render::RenderOrtho(embree, terrain.mesh, geometry, render::OrthoView::kSlantRangeNormal, colour);
  render::RenderOptions render_options = RenderOptionsOf(options.base, FirstChannel(options.base), &reporter);
  render_options.reflectors = terrain.reflectors;
  for (const render::SceneReflector& r : PlaceReflectors(options.base.reflectors, terrain, embree)) {
    render_options.reflectors.push_back(r);
  }
  render::SarImage sar = render::RenderSar(embree, terrain.mesh, terrain.materials, geometry, render_options);
  ApplySensorEffects(sar, options.base, geometry);
  const image::RgbImage sar_rgb = image::GreyToRgb(image::DbQuicklook(sar.intensity, 2.0, 98.0), sar.width, sar.height);
  geo::WritePng(los_path, los.rgb, los.width, los.height, 3);
  geo::WritePng(sar_path, sar_rgb.rgb, sar_rgb.width, sar_rgb.height, 3);
  geo::WritePng(gperp_path, gperp.rgb, gperp.width, gperp.height, 3);
  const image::RgbImage trio = image::SideBySide(
      {image::RgbImage{los.width, los.height, los.rgb}, sar_rgb, image::RgbImage{gperp.width, gperp.height, gperp.rgb}},
      {"orthographic, along the line of sight", "SAR (affine model)", "virtual camera G_perp"});
  geo::WritePng(trio_path, trio.rgb, trio.width, trio.height, 3);
  json inputs = json::array({InputFileRecord(options.base.scene.empty() ? options.base.dem : options.base.scene)});
  if (photo) inputs.push_back(InputFileRecord(options.orthophoto));
  WriteJsonFile({{"command", "ortho"},
                 {"command_line", command_line},
                 {"version", VersionString()},
                 {"created_utc", UtcTimestamp()},
                 {"options", options.base.ToJson()},
                 {"orthophoto", options.orthophoto},
                 {"inputs", inputs},
                 {"vertical_datum", VerticalDatumRecord(terrain)},
                 {"geometry", geometry.ToMetadata()}},
                json_path);
  outputs.Commit();
  return outputs.final_paths();
}

}  // namespace gissar::pipeline
