#include "gissar/pipeline/simulation_output.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <optional>
#include <span>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include "gissar/geo/raster_io.h"
#include "gissar/image/annotated.h"
#include "gissar/image/polarimetry.h"
#include "gissar/image/quicklook.h"
#include "gissar/image/radiometry.h"
#include "gissar/pipeline/georeferencing.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/stac.h"
#include "gissar/render/terrain_layers.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;

namespace {

std::vector<std::string> ChannelNames(const std::vector<material::Polarization>& channels) {
  std::vector<std::string> names;
  for (const material::Polarization c : channels) names.push_back(material::ToString(c));
  return names;
}

// "four_or_more" as words (GISSAR_BANDS of one channel: "... 5 four or more
// bounces").
std::string SpelledBounceCounts(std::string text) {
  const std::string name = kBounceLayerNames[render::kBounceLayers - 1];
  if (const size_t at = text.find(name); at != std::string::npos) text.replace(at, name.size(), "four or more");
  return text;
}

// Per channel: the share of the total power (summed over the footprint,
// before the sensor stage's noise) in each bounce layer: the double-bounce
// share of HH is above VV's where walls and ground form dihedrals.
nlohmann::json BounceShares(const SimulatedImage& simulated) {
  nlohmann::json shares = nlohmann::json::object();
  for (size_t k = 0; k < simulated.channels.size(); ++k) {
    const render::SarImage& c = k == 0 ? simulated.image : simulated.other_channels[k - 1];
    double layer_sum[render::kBounceLayers] = {0, 0, 0, 0}, total = 0.0;
    for (int layer = 0; layer < render::kBounceLayers; ++layer) {
      for (const float v : c.bounce_layers[layer]) {
        if (std::isfinite(v)) layer_sum[layer] += v;
      }
      total += layer_sum[layer];
    }
    nlohmann::json row = nlohmann::json::object();
    for (int layer = 0; layer < render::kBounceLayers; ++layer) {
      row[kBounceLayerNames[layer]] = total > 0.0 ? layer_sum[layer] / total : 0.0;
    }
    shares[material::ToString(simulated.channels[k])] = row;
  }
  return shares;
}

void WriteContributions(const fs::path& path, const std::vector<render::Contribution>& contributions,
                        const sensor::SarGeometry& geometry) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) throw WriteError("cannot open contributions file", path, errno);
  std::fprintf(f, "azimuth_m,range_m,elevation_m,column,row,intensity,bounces,specular,x_enu_m,y_enu_m,z_enu_m,class\n");
  for (const render::Contribution& c : contributions) {
    std::fprintf(f, "%.4f,%.4f,%.4f,%.3f,%.3f,%.6g,%d,%d,%.3f,%.3f,%.3f,%d\n", c.azimuth_m, c.range_m, c.elevation_m,
                 geometry.ColumnOfRange(c.range_m), geometry.RowOfAlongTrack(c.azimuth_m), c.intensity, c.bounces,
                 c.specular ? 1 : 0, c.hit_enu.x(), c.hit_enu.y(), c.hit_enu.z(), c.class_id);
  }
  const int write_error = std::ferror(f) != 0 ? errno : 0;
  if (std::fclose(f) != 0 || write_error != 0) {
    throw WriteError("failed writing contributions file", path, write_error != 0 ? write_error : errno);
  }
}

// --- The phases of WriteSimulation ---

// Where the write phase's time goes (sidecar timings_s.write_detail): each
// Lap records the time since the previous one under its name.
class WriteLaps {
 public:
  void Lap(const char* name) {
    detail_[name] = part_.ElapsedSeconds();
    part_ = Stopwatch();
  }
  // Starts the next lap now (the time since the last is booked elsewhere).
  void Restart() { part_ = Stopwatch(); }
  void Record(const char* name, double seconds) { detail_[name] = seconds; }
  const nlohmann::json& detail() const { return detail_; }

 private:
  nlohmann::json detail_ = nlohmann::json::object();
  Stopwatch part_;
};

// The metadata every GeoTIFF of the simulation carries: the geometry, the
// frame, units, radiometry, terrain and version.
geo::Metadata ImageMetadata(const SimulateRequest& options, const SimulatedImage& simulated) {
  const geo::LocalFrame& frame = simulated.terrain.frame;
  geo::Metadata metadata;
  for (const auto& [k, v] : simulated.geometry->ToMetadata()) metadata[k] = v;
  metadata["GISSAR_FRAME"] = "local ENU tangent frame on WGS84, origin lon,lat,h=" +
                             std::to_string(frame.origin_lon_deg()) + "," +
                             std::to_string(frame.origin_lat_deg()) + ",0";
  metadata["GISSAR_UNITS"] = options.radiometry + (options.db ? " (dB)" : " (linear, m2/m2)");
  metadata["GISSAR_RADIOMETRY"] = options.radiometry;
  metadata["GISSAR_TERRAIN"] = fs::absolute(options.scene.empty() ? options.dem : options.scene).string();
  metadata["GISSAR_VERSION"] = VersionString();
  return metadata;
}

// The annotated quicklook's multilook factor: above kQuicklookMaxSidePx a
// side it shows the image multilooked by an integer factor.
int AnnotatedQuicklookLooks(const render::SarImage& image) {
  const int side = std::max(image.width, image.height);
  return (side + kQuicklookMaxSidePx - 1) / kQuicklookMaxSidePx;
}

// PREFIX_quicklook.png: annotated (title, axes in metres, dB colour bar);
// multilooked above kQuicklookMaxSidePx a side (a NaN pixel: no return, 0).
// Unmultilooked, it shows `levels` stretched as `stretch` (PREFIX.png's
// levels of `linear`: given, not computed again).
void DrawAnnotatedQuicklook(const SimulationOutputs& reserved, const SimulatedImage& simulated,
                            std::span<const float> linear, const std::vector<uint8_t>& levels,
                            const image::DbStretch& stretch) {
  const render::SarImage& image = simulated.image;
  const sensor::SarGeometryOptions& geometry_options = simulated.geometry_options;
  const sensor::SarGeometry& geometry = *simulated.geometry;
  char title[160];
  std::snprintf(title, sizeof(title), "heading %.1f deg, depression %.1f deg, %.3g x %.3g m pixels",
                geometry_options.heading_deg, geometry_options.depression_deg, geometry.range_spacing_m(),
                geometry.azimuth_spacing_m());
  // The annotated quicklook is a picture for people: above
  // kQuicklookMaxSidePx a side, it shows the image multilooked by an
  // integer factor (linear power averaged, its own stretch), its axes at the
  // block centres.
  const int looks = AnnotatedQuicklookLooks(image);
  const int width = image.width / looks, height = image.height / looks;
  image::DbStretch multilooked_stretch;
  const std::vector<uint8_t> multilooked_levels =
      looks > 1 ? image::DbQuicklook(image::Multilook(linear, image.height, image.width, looks, looks,
                                                      image::NanPixels::kAsZero),
                                     2.0, 98.0, &multilooked_stretch)
                : std::vector<uint8_t>();
  const double dr = geometry.range_spacing_m(), da = geometry.azimuth_spacing_m();
  const double half_block = 0.5 * (looks - 1);
  // Affine geometry has parallel rays and no sensor: its range axis is
  // relative to the scene centre (a nominal slant range added to it would
  // read ranges shorter than the sensor's height).
  const bool affine = geometry_options.mode == sensor::ProjectionMode::kAffine;
  const image::GreyImage annotated = image::AnnotatedGreyQuicklook(
      looks > 1 ? multilooked_levels : levels, looks > 1 ? multilooked_stretch : stretch, width, height,
      {(affine ? 0.0 : geometry.slant_range_m()) + (half_block - geometry.u0()) * dr, dr * looks,
       (half_block - geometry.v0()) * da, da * looks, affine},
      title);
  geo::WritePng(reserved.annotated_png, annotated.grey, annotated.width, annotated.height, 1);
}

// The two quicklooks, from the linear values, drawn by tasks (PNG encoding
// is single-threaded) while the georeferencing and the GeoTIFFs are
// computed and written; on an exception the task group's destructor waits.
// PREFIX.png's grey levels (the dB stretch of every pixel; NaN black) are
// computed once: the unmultilooked annotated quicklook shows the same
// levels. Linear values are read where they are (no copy): the image's
// intensity buffer must outlive the tasks and stay unchanged until Wait(),
// wherever it moves meanwhile (the writer moves it into its raster and
// back).
class QuicklookPictures {
 public:
  void Start(const SimulateRequest& options, const SimulatedImage& simulated, const SimulationOutputs& reserved) {
    const std::vector<float>& intensity = simulated.image.intensity;
    if (options.db) {
      linear_.resize(intensity.size());
      for (size_t i = 0; i < intensity.size(); ++i) {
        const float v = intensity[i];
        linear_[i] = std::isnan(v) ? 0.0f : static_cast<float>(std::pow(10.0, v / 10.0));
      }
      shown_ = linear_;
    } else {
      shown_ = intensity;
    }
    const bool multilooked = AnnotatedQuicklookLooks(simulated.image) > 1;
    if (multilooked) group_.run([this, &simulated, &reserved] { DrawAnnotated(simulated, reserved); });
    group_.run([this, &simulated, &reserved, multilooked] {
      const Stopwatch watch;
      levels_ = image::DbQuicklook(shown_, 2.0, 98.0, &stretch_);
      if (!multilooked) group_.run([this, &simulated, &reserved] { DrawAnnotated(simulated, reserved); });
      geo::WritePng(reserved.png, levels_, simulated.image.width, simulated.image.height, 1);
      seconds_[0] = watch.ElapsedSeconds();
    });
  }
  // Waits for the pictures; the seconds they took (both tasks, added).
  double Wait() {
    group_.wait();
    return seconds_[0] + seconds_[1];
  }
  const image::DbStretch& stretch() const { return stretch_; }

 private:
  void DrawAnnotated(const SimulatedImage& simulated, const SimulationOutputs& reserved) {
    const Stopwatch watch;
    DrawAnnotatedQuicklook(reserved, simulated, shown_, levels_, stretch_);
    seconds_[1] = watch.ElapsedSeconds();
  }

  std::vector<float> linear_;     // dB images: the linear values (NaN: 0)
  std::span<const float> shown_;  // the linear values drawn
  std::vector<uint8_t> levels_;   // PREFIX.png's grey levels
  image::DbStretch stretch_;
  double seconds_[2] = {0.0, 0.0};
  tbb::task_group group_;  // last: destroyed (waiting) before what its task reads
};

// The simulated image of every channel, in output order.
std::vector<render::SarImage*> ChannelImages(SimulatedImage& simulated) {
  std::vector<render::SarImage*> channel_images = {&simulated.image};
  for (render::SarImage& other : simulated.other_channels) channel_images.push_back(&other);
  return channel_images;
}

// The raster of PREFIX.tif, its bands moved in from the channel images (no
// copies of full-size planes; GiveBackBands returns them). One channel:
// total, then one band per bounce count the run holds (HeldBounceLayers).
// Several: each channel's total (named by its channel), then each channel's
// bounce bands.
geo::FloatRaster ImageRaster(const SimulateRequest& options, const SimulatedImage& simulated,
                             const std::vector<render::SarImage*>& channel_images, int held,
                             const geo::Metadata& metadata) {
  const render::SarImage& image = simulated.image;
  geo::FloatRaster raster{image.width, image.height, {}, {}, metadata};
  raster.band_unit = image::RadiometryUnit(options.db);
  raster.band_names = ImageBandNames(simulated.channels, channel_images.size(), held);
  for (size_t k = 0; k < channel_images.size(); ++k) raster.bands.push_back(std::move(channel_images[k]->intensity));
  for (size_t k = 0; k < channel_images.size(); ++k) {
    for (int layer = 0; layer < held; ++layer) {
      raster.bands.push_back(std::move(channel_images[k]->bounce_layers[layer]));
      // A layer with no return below the highest held (a reflector's bounce
      // count beyond those traced) shares one plane.
      if (raster.bands.back().empty() && raster.empty_band_pixels.empty()) {
        raster.empty_band_pixels = NoReturnPlane(image, options.db);
      }
    }
  }
  return raster;
}

// The image bands moved back from `raster` (as ImageRaster laid them out,
// `held` bounce layers per channel) into the channel images (the caller may
// still read the image); the raster is left without bands.
void GiveBackBands(geo::FloatRaster& raster, const std::vector<render::SarImage*>& channel_images, int held) {
  if (raster.bands.empty()) return;
  const size_t n = channel_images.size();
  for (size_t k = 0; k < n; ++k) {
    channel_images[k]->intensity = std::move(raster.bands[k]);
    for (int layer = 0; layer < held; ++layer) {
      channel_images[k]->bounce_layers[layer] = std::move(raster.bands[n + k * held + layer]);
    }
  }
  raster.bands.clear();
}

// The terrain layers (--layers, --incidence-band), computed on first use:
// NaN outside the imaged footprint.
class TerrainLayersOnce {
 public:
  explicit TerrainLayersOnce(const SimulatedImage& simulated) : simulated_(simulated) {}
  const render::TerrainLayers& Get() {
    if (!layers_) {
      const Terrain& terrain = simulated_.terrain;
      const scene::TriangleMesh& mesh = terrain.mesh;
      const render::SarImage& image = simulated_.image;
      // The raster engine keeps the DEM as posts only: triangulate them as it does.
      const bool posts_only = mesh.triangle_count() == 0 && terrain.grid_width > 1 && terrain.grid_height > 1;
      layers_ = render::ComputeTerrainLayers(
          posts_only ? scene::MeshFromGrid(mesh.vertices, terrain.grid_width, terrain.grid_height) : mesh,
          *simulated_.geometry);
      for (size_t i = 0; i < image.footprint.size() && i < layers_->local_incidence_deg.size(); ++i) {
        if (!image.footprint[i]) {
          layers_->local_incidence_deg[i] = layers_->projected_area_m2[i] = std::numeric_limits<float>::quiet_NaN();
        }
      }
    }
    return *layers_;
  }

 private:
  const SimulatedImage& simulated_;
  std::optional<render::TerrainLayers> layers_;
};

// GISSAR_BANDS (and GISSAR_POLARIZATIONS), band units, no-data and
// overviews of PREFIX.tif.
void DescribeImageBands(geo::FloatRaster& raster, const SimulateRequest& options, const SimulatedImage& simulated) {
  const std::string bands_text = NumberedBands(raster.band_names);
  if (!simulated.other_channels.empty()) {  // several channels
    raster.metadata["GISSAR_BANDS"] = bands_text + " (channel totals, then each channel's bounce counts)";
    raster.metadata["GISSAR_POLARIZATIONS"] = material::ToString(simulated.channels);
  } else {
    raster.metadata["GISSAR_BANDS"] = SpelledBounceCounts(bands_text) + " bounces";
  }
  if (options.incidence_band) raster.metadata["GISSAR_BANDS"] += "; last: local incidence (deg)";
  raster.band_units.assign(raster.bands.size(), raster.band_unit);
  if (options.incidence_band) raster.band_units.back() = "deg";
  // NaN outside the imaged footprint (ApplySensorEffects), declared.
  raster.nodata_nan = true;
  raster.overviews = options.overviews;
}

// WGS84 GCPs on the terrain and RPCs fitted to the geometry
// (docs/georeferencing.md) into raster.georeference; the sidecar's record of
// them (or why there are none).
nlohmann::json GeoreferenceImage(const SimulatedImage& simulated, bool refine_for_tps, geo::FloatRaster& raster) {
  try {
    sensor::GeoreferenceReport georeference_report;
    TpsRefinement tps;
    raster.georeference = SimulationGeoreference(simulated.terrain, *simulated.geometry, refine_for_tps,
                                                 &georeference_report, &simulated.image.mask, &tps);
    return {{"gcps", georeference_report.gcp_count},
            {"rpc_max_error_px", georeference_report.rpc_max_error_px},
            {"rpc_rms_error_px", georeference_report.rpc_rms_error_px},
            {"tps_refinement",
             {{"enabled", tps.enabled},
              {"candidates", tps.candidates},
              {"added_gcps", tps.added_gcps},
              {"rounds", tps.rounds},
              {"tolerance_m", tps.tolerance_m},
              {"max_error_m", tps.max_error_m},
              {"p95_error_m", tps.p95_error_m}}}};
  } catch (const ConfigError& e) {
    return {{"gcps", 0}, {"reason", e.what()}};
  }
}

// PREFIX.tif; the bands go back to the channel images whether or not the
// write succeeds.
void WriteImageGeoTiff(const fs::path& tif, geo::FloatRaster& raster,
                       const std::vector<render::SarImage*>& channel_images, int held) {
  try {
    geo::WriteFloatGeoTiff(tif, raster);
  } catch (...) {
    GiveBackBands(raster, channel_images, held);
    throw;
  }
  GiveBackBands(raster, channel_images, held);
}

// Coherent mode: PREFIX_slc.tif and, with a Pauli vector, PREFIX_pauli.png;
// the Pauli quicklook's looks and stretch (null without one).
nlohmann::json WriteComplexOutputs(const SimulateRequest& options, const SimulatedImage& simulated,
                                   const std::vector<render::SarImage*>& channel_images, const geo::Metadata& metadata,
                                   const geo::Georeference& georeference, const SimulationOutputs& reserved,
                                   WriteLaps& laps) {
  const render::SarImage& image = simulated.image;
  nlohmann::json pauli_record;
  geo::Metadata slc_metadata = metadata;
  slc_metadata["GISSAR_UNITS"] = "complex amplitude, |z|^2 = " + options.radiometry + " (linear)";
  // The complex total, then the complex image of each bounce count: they
  // add up to the total (before thermal noise). Several channels: each
  // channel's complex total, then each channel's bounce counts.
  std::vector<float> no_return;  // the real and imaginary parts of a layer with no return
  const std::vector<geo::ComplexBand> slc_bands = SlcBands(channel_images, simulated.channels, no_return, slc_metadata);
  geo::WriteComplexGeoTiff(reserved.slc_tif, slc_bands, image.width, image.height, slc_metadata, "sqrt(m2/m2)",
                           georeference, /*nodata_nan=*/true, options.overviews);
  laps.Lap("slc");
  if (!reserved.pauli_png.empty()) {
    const std::vector<const render::SarImage*> images(channel_images.begin(), channel_images.end());
    WritePauliQuicklook(reserved.pauli_png, simulated.channels, images, &pauli_record);
    laps.Lap("pauli");
  }
  return pauli_record;
}

// PREFIX_layers.tif: local incidence and projected area.
void WriteLayersGeoTiff(const fs::path& path, const render::TerrainLayers& layers, const render::SarImage& image,
                        const geo::Metadata& metadata, const geo::Georeference& georeference, bool overviews) {
  geo::FloatRaster out{image.width, image.height, {layers.local_incidence_deg, layers.projected_area_m2},
                       {"local_incidence", "projected_area"}, metadata};
  out.band_units = {"deg", "m2"};
  out.nodata_nan = true;
  out.overviews = overviews;
  out.georeference = georeference;
  out.metadata["GISSAR_BANDS"] =
      "1 local incidence (deg, area-weighted over the surfaces facing the radar), 2 projected area (m2 of "
      "terrain facing the radar in the pixel, occlusion ignored)";
  geo::WriteFloatGeoTiff(path, out);
}

// PREFIX_mask.tif: the layover/shadow codes.
void WriteMaskGeoTiff(const fs::path& path, const render::SarImage& image, const geo::Metadata& metadata,
                      const geo::Georeference& georeference, bool overviews) {
  geo::Metadata mask_metadata = metadata;
  mask_metadata["GISSAR_MASK_CODES"] = kMaskCodesText;
  geo::WriteByteGeoTiff(path, image.mask, image.width, image.height, mask_metadata, georeference, MaskCategories(),
                        overviews);
}

// The sidecar's record of the ENU frame and the scene centre.
void RecordFrame(const Terrain& terrain, nlohmann::json& provenance) {
  const geo::LocalFrame& frame = terrain.frame;
  const Eigen::Vector3d xc = terrain.centre_enu;
  const geo::GeoPoint centre = terrain.centre;
  provenance["frame"] = {{"type", terrain.vertical_datum != "ellipsoid"
                                      ? "ENU tangent frame, WGS84; DEM heights " + terrain.vertical_datum +
                                            " + undulation = ellipsoidal"
                                      : "ENU tangent frame, WGS84; DEM heights used as ellipsoidal"},
                         {"origin_lon_deg", frame.origin_lon_deg()},
                         {"origin_lat_deg", frame.origin_lat_deg()},
                         {"origin_height_m", frame.origin_height_m()}};
  provenance["scene_centre"] = {{"lon_deg", centre.lon_deg},
                                {"lat_deg", centre.lat_deg},
                                {"height_m", centre.height_m},
                                {"enu_m", {xc.x(), xc.y(), xc.z()}}};
}

nlohmann::json GeometryRecord(const sensor::SarGeometry& geometry) {
  const Eigen::Vector3d sensor_position = geometry.SensorPosition(0.0);
  return {{"width", geometry.width()},
          {"height", geometry.height()},
          {"u0", geometry.u0()},
          {"v0", geometry.v0()},
          {"range_spacing_m", geometry.range_spacing_m()},
          {"azimuth_spacing_m", geometry.azimuth_spacing_m()},
          {"sensor_enu_m_at_centre", {sensor_position.x(), sensor_position.y(), sensor_position.z()}},
          {"flight_direction_enu",
           {geometry.flight_direction().x(), geometry.flight_direction().y(), geometry.flight_direction().z()}},
          {"look_direction_enu",
           {geometry.look_direction().x(), geometry.look_direction().y(), geometry.look_direction().z()}}};
}

nlohmann::json StatsRecord(const scene::TriangleMesh& mesh, const render::SarImage& image) {
  return {{"triangles", mesh.triangle_count()},
          {"rays", image.stats.rays},
          {"hits", image.stats.hits},
          {"sub_rays", image.stats.sub_rays},
          {"shadow_rays", image.stats.shadow_rays},
          {"dem_cells", image.stats.cells},
          {"heightfield_cells", image.stats.heightfield_cells},
          {"profile_swept_lines", image.stats.profile_swept_lines},
          {"profile_swept_mask_rows", image.stats.profile_swept_mask_rows},
          {"traced_mask_rows", image.stats.traced_mask_rows},
          {"mask_pixels", MaskPixelCounts(image.mask)}};
}

nlohmann::json RadiometryRecord(const SimulateRequest& options, const SimulatedImage& simulated) {
  const sensor::SarGeometry& geometry = *simulated.geometry;
  return {{"quantity", options.radiometry},
          {"scale", options.db ? "dB" : "linear"},
          {"unit", image::RadiometryUnit(options.db)},
          {"polarization", options.polarization},
          {"channels", ChannelNames(simulated.channels)},
          {"wavelength_m", options.wavelength_m},
          {"nesz_db", std::isnan(options.nesz_db) ? nlohmann::json(nullptr) : nlohmann::json(options.nesz_db)},
          {"incidence_reference",
           geometry.mode() == sensor::ProjectionMode::kAffine
               ? "ellipsoid incidence = 90 deg - depression (affine)"
               : "ellipsoid incidence on the tangent plane through the scene centre, per range column"},
          {"incidence_deg_first_last_column", {geometry.IncidenceDeg(0), geometry.IncidenceDeg(geometry.width() - 1)}},
          {"range_spacing_m", geometry.range_spacing_m()},
          {"azimuth_spacing_m", geometry.azimuth_spacing_m()},
          {"reflector_returns", simulated.image.points.size()}};
}

// Polarimetric passes: the bounce shares per channel, the Pauli
// quicklook's stretch.
nlohmann::json PolarimetryRecord(const SimulatedImage& simulated, const nlohmann::json& pauli_record) {
  nlohmann::json polarimetry = {
      {"channels", ChannelNames(simulated.channels)},
      {"model", "one polarimetric pass per channel (VH = HV by reciprocity), one seed: scattering matrices per "
                "return (docs/radiometry.md, Polarimetry in the renderer)"},
      {"bounce_shares", BounceShares(simulated)}};
  if (!pauli_record.is_null()) polarimetry["pauli_quicklook"] = pauli_record;
  return polarimetry;
}

nlohmann::json SamplingRecord(const render::SarImage& image) {
  return {{"footprint_pixels", image.stats.footprint_pixels},
          {"empty_footprint_pixels", image.stats.empty_footprint_pixels},
          {"empty_footprint_fraction",
           image.stats.footprint_pixels > 0
               ? double(image.stats.empty_footprint_pixels) / double(image.stats.footprint_pixels)
               : 0.0}};
}

// The provenance sidecar, short of its timings, memory and outputs.
nlohmann::json SimulationProvenance(const SimulateRequest& options, const SimulatedImage& simulated,
                                    const PendingInputRecord& terrain_input,
                                    const std::string& command_line, const nlohmann::json& georeference_record,
                                    const nlohmann::json& pauli_record, const image::DbStretch& stretch) {
  const Terrain& terrain = simulated.terrain;
  nlohmann::json provenance = ProvenanceHeader("simulate", command_line, options.ToJson());
  provenance["inputs"] = nlohmann::json::array({terrain_input.Get()});
  provenance["georeference"] = georeference_record;
  provenance["terrain"] = terrain.description;
  provenance["materials"] = terrain.materials.ToJson();
  provenance["vertical_datum"] = VerticalDatumRecord(terrain);
  if (!terrain.dem_window.is_null()) provenance["dem_window"] = terrain.dem_window;
  RecordFrame(terrain, provenance);
  provenance["geometry"] = GeometryRecord(*simulated.geometry);
  provenance["stats"] = StatsRecord(terrain.mesh, simulated.image);
  provenance["radiometry"] = RadiometryRecord(options, simulated);
  if (!simulated.other_channels.empty()) provenance["polarimetry"] = PolarimetryRecord(simulated, pauli_record);
  provenance["sampling"] = SamplingRecord(simulated.image);
  provenance["quicklook"] = {{"db_low", stretch.low_db}, {"db_high", stretch.high_db},
                             {"percentiles", {2, 98}}};
  return provenance;
}

// PREFIX_stac.json, the STAC Item (stac.h): footprint from the GCPs on the
// imaged terrain, dated as the provenance sidecar.
void WriteStacItem(const SimulateRequest& options, const SimulatedImage& simulated,
                   const SimulationOutputs& reserved, const geo::Georeference& georeference,
                   const std::string& created_utc) {
  const sensor::SarGeometryOptions& geometry_options = simulated.geometry_options;
  const sensor::SarGeometry& geometry = *simulated.geometry;
  const geo::GeoPoint centre = simulated.terrain.centre;
  StacProduct p;
  p.id = fs::path(options.out_prefix).filename().string();
  p.datetime_utc = created_utc;
  for (const auto& g : georeference.gcps) p.footprint_lonlat.emplace_back(g.lon_deg, g.lat_deg);
  if (p.footprint_lonlat.empty()) p.footprint_lonlat.emplace_back(centre.lon_deg, centre.lat_deg);
  p.wavelength_m = options.wavelength_m;
  p.polarization = options.polarization;
  p.product_type = "DETECTED_SLANT_RANGE";
  p.observation_direction = sensor::ToString(geometry_options.look_side);
  p.range_spacing_m = geometry.range_spacing_m();
  p.azimuth_spacing_m = geometry.azimuth_spacing_m();
  p.range_resolution_m = options.RangeResolutionM();
  p.azimuth_resolution_m = options.AzimuthResolutionM();
  p.looks_equivalent_number = options.speckle_looks;
  p.incidence_deg = geometry.IncidenceDeg(geometry.u0());
  p.off_nadir_deg = 90.0 - geometry_options.depression_deg;
  p.look_azimuth_deg = geometry_options.heading_deg + (geometry_options.look_side == sensor::LookSide::kRight ? 90.0 : -90.0);
  p.width = simulated.image.width;
  p.height = simulated.image.height;
  p.lineage = "simulated by gissar simulate (" + ToString(options.engine) + ", " + sensor::ToString(geometry.mode()) +
              " projection) from " + fs::path(options.scene.empty() ? options.dem : options.scene).filename().string();
  const std::string tiff = "image/tiff; application=geotiff";
  auto final_of = [&](const fs::path& suffix) { return fs::path(options.out_prefix + suffix.string()); };
  p.assets = {{"image", final_of(".tif"), tiff, "Slant-range " + options.radiometry + " (total and per-bounce bands)", {"data"}},
              {"layover_shadow_mask", final_of("_mask.tif"), tiff, "Layover/shadow mask", {"data", "layover-shadow"}},
              {"thumbnail", final_of(".png"), "image/png", "Quicklook (dB stretch)", {"thumbnail"}},
              {"quicklook", final_of("_quicklook.png"), "image/png", "Annotated quicklook", {"overview"}},
              {"provenance", final_of(".json"), "application/json", "gissar provenance sidecar", {"metadata"}}};
  if (options.coherent) p.assets.push_back({"slc", final_of("_slc.tif"), tiff, "Single-look complex image", {"data"}});
  if (!reserved.pauli_png.empty()) {
    p.assets.push_back({"pauli", final_of("_pauli.png"), "image/png", "Pauli RGB quicklook (multilooked)", {"overview"}});
  }
  if (options.layers) {
    p.assets.push_back({"layers", final_of("_layers.tif"), tiff, "Local incidence angle and projected terrain area",
                        {"data", "local-incidence-angle"}});
  }
  WriteJsonFile(StacItem(p, fs::path(options.out_prefix).parent_path()), reserved.stac_json);
}

}  // namespace

int HeldBounceLayers(const render::SarImage& image, const std::vector<render::SarImage>& others, bool complex) {
  std::vector<const render::SarImage*> images = {&image};
  for (const render::SarImage& other : others) images.push_back(&other);
  return HeldBounceLayers(images, complex);
}

std::vector<std::string> ImageBandNames(const std::vector<material::Polarization>& channels, size_t images,
                                        int held) {
  if (images <= 1) {
    std::vector<std::string> names = {"total"};
    names.insert(names.end(), kBounceLayerNames, kBounceLayerNames + held);
    return names;
  }
  auto channel = [&](size_t k) { return k < channels.size() ? material::ToString(channels[k]) : std::string("VV"); };
  std::vector<std::string> names;
  for (size_t k = 0; k < images; ++k) names.push_back(channel(k));
  for (size_t k = 0; k < images; ++k) {
    for (int layer = 0; layer < held; ++layer) names.push_back(channel(k) + "_" + kBounceLayerNames[layer]);
  }
  return names;
}

int HeldBounceLayers(std::span<const render::SarImage* const> images, bool complex) {
  int held = 1;
  for (const render::SarImage* image : images) {
    for (int layer = held; layer < render::kBounceLayers; ++layer) {
      const bool filled = complex ? image->bounce_real[layer].size() == image->real.size() && !image->real.empty()
                                  : image->bounce_layers[layer].size() == image->intensity.size() &&
                                        !image->intensity.empty();
      if (filled) held = layer + 1;
    }
  }
  return held;
}

std::string NumberedBands(const std::vector<std::string>& names) {
  std::string text;
  for (size_t k = 0; k < names.size(); ++k) {
    text += (k ? ", " : "") + std::to_string(k + 1) + " " + names[k];
  }
  return text;
}

std::vector<float> NoReturnPlane(const render::SarImage& image, bool db) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const size_t n = size_t(image.width) * image.height;
  const bool everywhere = image.footprint.size() != n;
  std::vector<float> plane(n, db ? nan : 0.0f);
  if (db || everywhere) return plane;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, size_t(1) << 16), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) if (!image.footprint[i]) plane[i] = nan;
  });
  return plane;
}

bool HasPauliChannels(const SimulateRequest& options) {
  const auto channels = material::ParsePolarizationList(options.polarization, "--polarization");
  auto has = [&](material::Polarization p) { return std::find(channels.begin(), channels.end(), p) != channels.end(); };
  return has(material::Polarization::kHH) && has(material::Polarization::kVV) &&
         (has(material::Polarization::kHV) || has(material::Polarization::kVH));
}

std::vector<geo::ComplexBand> SlcBands(const std::vector<render::SarImage*>& images,
                                       const std::vector<material::Polarization>& channels,
                                       std::vector<float>& no_return, geo::Metadata& metadata) {
  GISSAR_CHECK(!images.empty());
  const bool several = images.size() > 1;
  const int held = HeldBounceLayers(images, /*complex=*/true);
  const std::vector<std::string> names = ImageBandNames(channels, images.size(), held);
  std::vector<geo::ComplexBand> slc_bands;
  for (size_t k = 0; k < images.size(); ++k) slc_bands.push_back({&images[k]->real, &images[k]->imag, names[k]});
  for (size_t k = 0; k < images.size(); ++k) {
    render::SarImage& c = *images[k];
    for (int layer = 0; layer < held; ++layer) {
      const std::string& name = names[slc_bands.size()];
      if (c.bounce_real[layer].size() != c.real.size()) {
        if (no_return.empty()) no_return = NoReturnPlane(*images[0], /*db=*/false);
        slc_bands.push_back({&no_return, &no_return, name});
      } else {
        slc_bands.push_back({&c.bounce_real[layer], &c.bounce_imag[layer], name});
      }
    }
  }
  if (several) {
    metadata["GISSAR_BANDS"] = NumberedBands(names) + " (complex; each channel's bounce bands add up to its total "
                                                      "before thermal noise)";
    metadata["GISSAR_POLARIZATIONS"] = material::ToString(channels);
  } else {
    metadata["GISSAR_BANDS"] = SpelledBounceCounts(NumberedBands(names)) + " bounces (complex; the bounce bands add up to band 1 "
                                                      "before thermal noise)";
  }
  return slc_bands;
}

void WritePauliQuicklook(const fs::path& path, const std::vector<material::Polarization>& channels,
                         const std::vector<const render::SarImage*>& images, nlohmann::json* record) {
  using material::Polarization;
  GISSAR_CHECK(channels.size() == images.size());
  auto channel_image = [&](Polarization pol) -> const render::SarImage* {
    for (size_t k = 0; k < channels.size(); ++k) {
      if (channels[k] == pol) return images[k];
    }
    return nullptr;
  };
  const render::SarImage* hh = channel_image(Polarization::kHH);
  const render::SarImage* vv = channel_image(Polarization::kVV);
  const render::SarImage* hv = channel_image(Polarization::kHV);
  const render::SarImage* vh = channel_image(Polarization::kVH);
  if (!hv) hv = vh;
  if (!vh) vh = hv;
  GISSAR_CHECK(hh && vv && hv && vh);
  image::QuadPolImage quad;
  quad.width = hh->width;
  quad.height = hh->height;
  auto complex_of = [](const render::SarImage& c) {
    std::vector<std::complex<float>> z(c.real.size());
    for (size_t i = 0; i < z.size(); ++i) z[i] = {c.real[i], c.imag[i]};
    return z;
  };
  quad.hh = complex_of(*hh);
  quad.hv = complex_of(*hv);
  quad.vh = complex_of(*vh);
  quad.vv = complex_of(*vv);
  const int side = std::max(quad.width, quad.height);
  const int looks = std::clamp((side + kQuicklookMaxSidePx - 1) / kQuicklookMaxSidePx, 2,
                               std::max(1, std::min(quad.width, quad.height)));
  const image::PolarimetricMatrixImage t3 = image::MultilookCoherency(quad, looks, looks);
  image::PauliStretch stretch;
  const image::RgbImage rgb = image::PauliRgb(t3, &stretch);
  geo::WritePng(path, rgb.rgb, rgb.width, rgb.height, 3);
  *record = {{"looks", {looks, looks}},
             {"db_low", stretch.low_db},
             {"db_high", stretch.high_db},
             {"percentiles", {2, 98}},
             {"channels", "R = |HH - VV| / sqrt 2, G = |HV + VH| / sqrt 2, B = |HH + VV| / sqrt 2 (multilooked "
                          "coherency T22, T33, T11; one dB stretch for the three)"}};
}

void ReserveSimulationOutputs(const SimulateRequest& options, SimulationOutputs& o) {
  o.tif = o.files.Add(options.out_prefix + ".tif");
  o.png = o.files.Add(options.out_prefix + ".png");
  o.annotated_png = o.files.Add(options.out_prefix + "_quicklook.png");
  o.mask_tif = o.files.Add(options.out_prefix + "_mask.tif");
  o.json = o.files.Add(options.out_prefix + ".json");
  o.stac_json = o.files.Add(options.out_prefix + "_stac.json");
  if (options.coherent) o.slc_tif = o.files.Add(options.out_prefix + "_slc.tif");
  if (options.coherent && HasPauliChannels(options)) o.pauli_png = o.files.Add(options.out_prefix + "_pauli.png");
  if (options.layers) o.layers_tif = o.files.Add(options.out_prefix + "_layers.tif");
  if (!options.contributions.empty()) o.contributions_csv = o.files.Add(options.contributions);
  o.terrain_input = PendingInputRecord(options.scene.empty() ? options.dem : options.scene);
}

SimulateResult WriteSimulation(const SimulateRequest& options, SimulatedImage& simulated,
                               const std::string& command_line, SimulationOutputs& reserved,
                               const Stopwatch& total) {
  nlohmann::json timings = simulated.timings_s;
  const Stopwatch step;
  render::SarImage& image = simulated.image;
  const geo::Metadata metadata = ImageMetadata(options, simulated);
  // PREFIX.tif's raster holds the image bands between ImageRaster and
  // WriteImageGeoTiff: declared before the pictures, which read the total's
  // plane, so that on an exception they are waited for before it is freed.
  geo::FloatRaster raster;
  QuicklookPictures pictures;
  pictures.Start(options, simulated, reserved);

  // PREFIX.tif: the image bands (moved in and back), the incidence band.
  const std::vector<render::SarImage*> channel_images = ChannelImages(simulated);
  const int held_layers = HeldBounceLayers(channel_images);
  raster = ImageRaster(options, simulated, channel_images, held_layers, metadata);
  TerrainLayersOnce terrain_layers(simulated);
  if (options.incidence_band) {
    const Stopwatch layers_watch;
    raster.bands.push_back(terrain_layers.Get().local_incidence_deg);
    raster.band_names.push_back("local_incidence");
    timings["layers"] = layers_watch.ElapsedSeconds();
  }
  DescribeImageBands(raster, options, simulated);
  WriteLaps laps;
  const nlohmann::json georeference_record = GeoreferenceImage(simulated, options.tps_gcps, raster);
  laps.Lap("georeference");
  if (!reserved.contributions_csv.empty()) {
    WriteContributions(reserved.contributions_csv, image.contributions, *simulated.geometry);
  }
  WriteImageGeoTiff(reserved.tif, raster, channel_images, held_layers);
  laps.Lap("image");

  // The other rasters, on the same georeference.
  nlohmann::json pauli_record;  // the Pauli quicklook's looks and stretch
  if (options.coherent) {
    pauli_record = WriteComplexOutputs(options, simulated, channel_images, metadata, raster.georeference, reserved, laps);
  }
  if (!reserved.layers_tif.empty()) {
    const Stopwatch layers_watch;
    WriteLayersGeoTiff(reserved.layers_tif, terrain_layers.Get(), image, metadata, raster.georeference,
                       options.overviews);
    timings["layers"] = timings.value("layers", 0.0) + layers_watch.ElapsedSeconds();
    laps.Restart();
  }
  // The quicklooks were drawn meanwhile.
  laps.Record("quicklooks", pictures.Wait());
  laps.Lap("quicklooks_wait");
  WriteMaskGeoTiff(reserved.mask_tif, image, metadata, raster.georeference, options.overviews);
  laps.Lap("mask");

  // The sidecars.
  nlohmann::json provenance =
      SimulationProvenance(options, simulated, reserved.terrain_input, command_line, georeference_record, pauli_record,
                           pictures.stretch());
  WriteStacItem(options, simulated, reserved, raster.georeference, provenance["created_utc"].get<std::string>());
  laps.Lap("sidecars");
  timings["write"] = step.ElapsedSeconds();
  timings["write_detail"] = laps.detail();
  timings["total"] = total.ElapsedSeconds();
  provenance["timings_s"] = timings;
  // The run's share of the machine's memory budget (util/memory_ledger.h; 0 with --force).
  provenance["memory_reserved_bytes"] = static_cast<int64_t>(simulated.memory.bytes());
  return CommitSimulation(reserved.files, provenance, reserved.json, image, total.ElapsedSeconds());
}

geo::ByteCategories MaskCategories() {
  geo::ByteCategories c{{"none", "layover", "shadow", "layover and shadow"},
                        {{0, 0, 0, 0}, {255, 64, 0, 255}, {0, 64, 255, 255}, {255, 0, 255, 255}}};
  c.nodata = render::kMaskOutside;
  return c;
}

nlohmann::json MaskPixelCounts(const std::vector<uint8_t>& mask) {
  int64_t c[4] = {0, 0, 0, 0}, outside = 0;
  for (uint8_t v : mask) {
    if (v == render::kMaskOutside) ++outside;
    else ++c[v & 3];
  }
  return {{"none", c[0]}, {"layover", c[1]}, {"shadow", c[2]}, {"layover_and_shadow", c[3]}, {"outside", outside}};
}

SimulateResult CommitSimulation(AtomicOutputs& outputs, nlohmann::json& provenance, const fs::path& json,
                                const render::SarImage& image, double total_seconds) {
  std::vector<std::string> final_names;
  for (const fs::path& p : outputs.final_paths()) final_names.push_back(fs::absolute(p).string());
  provenance["outputs"] = final_names;
  WriteJsonFile(provenance, json);
  outputs.Commit();
  SimulateResult result;
  result.outputs = outputs.final_paths();
  result.stats = image.stats;
  result.width = image.width;
  result.height = image.height;
  result.total_seconds = total_seconds;
  return result;
}

}  // namespace gissar::pipeline
