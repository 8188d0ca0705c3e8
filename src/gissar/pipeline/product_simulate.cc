#include "gissar/pipeline/product_simulate.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <complex>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/orbit_file.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/reference_geolocation.h"
#include "gissar/geo/sentinel1_measurement.h"
#include "gissar/image/impulse_response.h"
#include "gissar/image/radiometry.h"
#include "gissar/image/quicklook.h"
#include "gissar/image/side_by_side.h"
#include "gissar/material/scattering.h"
#include "gissar/pipeline/sentinel1_simulate.h"
#include "gissar/pipeline/simulation_output.h"
#include "gissar/render/embree_scene.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;

namespace {

// Incidence on the ellipsoid of every pixel's ground point: the angle between
// the geodetic normal there and the line of sight to the sensor at the pixel's
// zero-Doppler time (degrees; NaN without a ground point).
std::vector<float> EllipsoidIncidenceDeg(const render::ProductImage& image, const sensor::Orbit& orbit,
                                         const sensor::RadarGrid& grid) {
  std::vector<float> incidence(size_t(grid.rows) * grid.cols, std::numeric_limits<float>::quiet_NaN());
  for (int row = 0; row < grid.rows; ++row) {
    const Eigen::Vector3d sensor_ecef = orbit.Interpolate(grid.TimeOfRow(row)).position_m;
    for (int col = 0; col < grid.cols; ++col) {
      const size_t k = size_t(row) * grid.cols + col;
      if (!std::isfinite(image.height_m[k])) continue;
      const double lon = image.lon_deg_exact[k] * M_PI / 180.0, lat = image.lat_deg_exact[k] * M_PI / 180.0;
      const Eigen::Vector3d ground =
          geo::LocalFrame::EcefFromGeodetic(image.lon_deg_exact[k], image.lat_deg_exact[k], image.height_m[k]);
      const Eigen::Vector3d up(std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat));
      const double cos_incidence = std::clamp(up.dot((sensor_ecef - ground).normalized()), -1.0, 1.0);
      incidence[k] = static_cast<float>(std::acos(cos_incidence) * 180.0 / M_PI);
    }
  }
  return incidence;
}

}  // namespace

namespace {

// Several channels simulate a real product's channels: each must be a layer
// the product holds (ConfigError naming the product's channels otherwise).
void CheckProductHasChannels(const geo::RslcProduct& p, const std::vector<material::Polarization>& channels,
                             const std::string& product_path) {
  std::string held;
  for (const std::string& s : p.stored_polarizations) held += (held.empty() ? "" : ", ") + s;
  for (const material::Polarization c : channels) {
    const std::string name = material::ToString(c);
    if (std::find(p.stored_polarizations.begin(), p.stored_polarizations.end(), name) ==
        p.stored_polarizations.end()) {
      throw ConfigError("the product holds " + (held.empty() ? std::string("no channel") : held) + " (frequency " +
                            p.frequency + ", " + product_path + "), not " + name,
                        "--polarization");
    }
  }
}

}  // namespace

namespace {

// Keeps the part `window` (first line, first pixel, lines, pixels) of a
// product's grid and of its image layers. ConfigError naming
// --product-window when it does not lie inside the grid.
void CropProductGrid(geo::RslcProduct& p, const std::array<int, 4>& window, const std::string& where) {
  const int rows = p.rows(), cols = p.cols();
  if (int64_t(window[0]) + window[2] > rows || int64_t(window[1]) + window[3] > cols) {
    throw ConfigError("window of lines " + std::to_string(window[0]) + "+" + std::to_string(window[2]) +
                          ", pixels " + std::to_string(window[1]) + "+" + std::to_string(window[3]) +
                          " outside the grid of " + std::to_string(rows) + " lines x " + std::to_string(cols) +
                          " pixels (" + where + ")",
                      "--product-window");
  }
  auto crop = [&](auto& layer) {
    if (layer.size() != size_t(rows) * cols) return;
    std::remove_reference_t<decltype(layer)> out(size_t(window[2]) * window[3]);
    for (int i = 0; i < window[2]; ++i) {
      std::copy_n(layer.begin() + (size_t(window[0] + i) * cols + window[1]), window[3],
                  out.begin() + size_t(i) * window[3]);
    }
    layer = std::move(out);
  };
  crop(p.amplitude);
  crop(p.slc);
  p.zero_doppler_time_s = std::vector<double>(p.zero_doppler_time_s.begin() + window[0],
                                              p.zero_doppler_time_s.begin() + window[0] + window[2]);
  p.slant_range_m = std::vector<double>(p.slant_range_m.begin() + window[1],
                                        p.slant_range_m.begin() + window[1] + window[3]);
}

// A NISAR RSLC's selection: no orbit or radar grid beside it (the product
// has both), no Sentinel-1 swath or burst, band A or B. Throws ConfigError
// naming the option.
void CheckNisarSelection(const SimulateRequest& o) {
  if (!o.orbit.empty() || !o.radar_grid.empty()) {
    throw ConfigError("give a product or an orbit with a radar grid, not both", "--product/--orbit");
  }
  if (!o.swath.empty()) throw ConfigError("only for a Sentinel-1 product (--product S1.SAFE)", "--swath");
  if (o.burst != 0) throw ConfigError("only for a Sentinel-1 product (--product S1.SAFE)", "--burst");
  if (!o.frequency.empty() && o.frequency != "A" && o.frequency != "B") {
    throw ConfigError("expected A or B, got '" + o.frequency + "'", "--frequency");
  }
}

}  // namespace

geo::RslcProduct ReadProductGeometry(const SimulateRequest& options, bool read_amplitude, Reporter& reporter) {
  if (IsSentinel1Request(options)) return ReadSentinel1Source(options, reporter).grid;
  if (!options.product.empty()) CheckNisarSelection(options);
  geo::RslcProduct product;
  geo::RslcReadOptions read;
  read.frequency = options.frequency.empty() ? "A" : options.frequency;
  read.read_amplitude = read_amplitude;
  read.max_bytes = options.max_memory_bytes;  // checked from the shapes, before reading
  // A window renders (and SimulateProduct checks) only its part of the grid.
  read.bytes_per_pixel = options.product_window_px && !read_amplitude ? 0.0 : 400.0;
  if (!options.product.empty()) {
    product = geo::ReadRslcProduct(options.product, read);
  } else {
    const geo::StateVectors vectors = geo::ReadStateVectors(options.orbit);
    product = geo::ProductFromOrbit(vectors, options.orbit, geo::ReadRadarGrid(options.radar_grid), options.radar_grid);
    product.polarization = options.polarization;
    reporter.Info("simulate: orbit: " + std::to_string(vectors.utc_s.size()) + " state vectors (" + vectors.format +
                  ")");
  }
  if (options.product_window_px) {
    CropProductGrid(product, *options.product_window_px,
                    options.product.empty() ? options.radar_grid : options.product);
  }
  return product;
}

sensor::RadarGrid RadarGridOf(const geo::RslcProduct& p) {
  sensor::RadarGrid grid;
  grid.t0_s = p.zero_doppler_time_s.front();
  grid.dt_s = p.azimuth_spacing_s();
  grid.rows = p.rows();
  grid.r0_m = p.slant_range_m.front();
  grid.dr_m = p.range_spacing_m();
  grid.cols = p.cols();
  grid.look_side = p.look_left ? sensor::LookSide::kLeft : sensor::LookSide::kRight;
  grid.wavelength_m = p.wavelength_m;
  return grid;
}

namespace {

// Adds each point return as a phasor sqrt(beta0_sum) exp(j phase_offset_rad)
// exp(-j 4 pi range_m / lambda) with the amplitude response of `effects` centred on it, to the
// complex total and its bounce layer (coherent product grids).
void AddPointPhasors(render::SarImage& image, const std::vector<render::PointReturn>& points,
                     const image::SensorEffects& effects) {
  const int w = image.width, h = image.height;
  const size_t n = size_t(w) * h;
  for (const render::PointReturn& p : points) {
    const bool layered = p.layer >= 0 && p.layer < render::kBounceLayers;
    if (layered && image.bounce_real[p.layer].size() != n) {
      image.bounce_real[p.layer].assign(n, 0.0f);
      image.bounce_imag[p.layer].assign(n, 0.0f);
    }
    int c0 = 0, r0 = 0;
    const std::vector<double> hx =
        image::ShiftedAmplitudeResponse(p.col, effects.range_resolution_px, effects.window, &c0);
    const std::vector<double> hy =
        image::ShiftedAmplitudeResponse(p.row, effects.azimuth_resolution_px, effects.window, &r0);
    // phase_offset_rad: arg S_c of a polarimetric pass's reflector matrix.
    const std::complex<double> a = std::sqrt(p.beta0_sum) * std::polar(1.0, p.phase_offset_rad) *
                                   material::PathPhase(2.0 * p.range_m, effects.wavelength_m);
    for (size_t j = 0; j < hy.size(); ++j) {
      const int r = r0 + int(j);
      if (r < 0 || r >= h) continue;
      for (size_t i = 0; i < hx.size(); ++i) {
        const int c = c0 + int(i);
        if (c < 0 || c >= w) continue;
        const size_t k = size_t(r) * w + c;
        const std::complex<double> z = a * (hx[i] * hy[j]);
        image.real[k] += static_cast<float>(z.real());
        image.imag[k] += static_cast<float>(z.imag());
        if (layered) {
          image.bounce_real[p.layer][k] += static_cast<float>(z.real());
          image.bounce_imag[p.layer][k] += static_cast<float>(z.imag());
        }
      }
    }
  }
}

// The coherent end of the chain on a real radar grid (the complex
// counterpart of image::ConvertPixelRadiometry): beta0 -> sigma0 with
// pixel k's own incidence (complex planes by sqrt(sin theta_i)), complex
// thermal noise of mean power nesz_db on the total, conversion to
// `radiometry`, detection of the total and of each bounce layer, dB.
// Pixels whose incidence is NaN (no ground point) keep their values.
void ConvertPixelRadiometryCoherent(render::SarImage& image, const std::vector<float>& incidence_deg,
                                    image::Radiometry radiometry, double nesz_db, uint64_t seed, bool db) {
  const size_t n = image.real.size();
  std::vector<std::vector<float>*> planes = {&image.real, &image.imag};
  for (int b = 0; b < render::kBounceLayers; ++b) {
    if (image.bounce_real[b].size() != n) continue;
    planes.push_back(&image.bounce_real[b]);
    planes.push_back(&image.bounce_imag[b]);
  }
  auto scale = [&](auto factor_of) {
    for (size_t k = 0; k < n; ++k) {
      if (std::isnan(incidence_deg[k])) continue;
      const float factor = static_cast<float>(std::sqrt(factor_of(double(incidence_deg[k]))));
      for (auto* plane : planes) (*plane)[k] *= factor;
    }
  };
  scale([](double incidence) { return image::FactorFromBeta0(image::Radiometry::kSigma0, incidence); });
  if (!std::isnan(nesz_db)) image::AddComplexThermalNoise(image.real, image.imag, nesz_db, seed);
  if (radiometry != image::Radiometry::kSigma0) {
    scale([&](double incidence) {
      const double to_sigma0 = image::FactorFromBeta0(image::Radiometry::kSigma0, incidence);
      return to_sigma0 > 0.0 ? image::FactorFromBeta0(radiometry, incidence) / to_sigma0 : 0.0;
    });
  }
  auto detect = [](const std::vector<float>& re, const std::vector<float>& im, std::vector<float>& power) {
    power.resize(re.size());
    for (size_t k = 0; k < re.size(); ++k) power[k] = re[k] * re[k] + im[k] * im[k];
  };
  detect(image.real, image.imag, image.intensity);
  for (int b = 0; b < render::kBounceLayers; ++b) {
    if (image.bounce_real[b].size() == n) detect(image.bounce_real[b], image.bounce_imag[b], image.bounce_layers[b]);
  }
  if (db) {
    image::ToDecibels(image.intensity);
    for (auto& layer : image.bounce_layers) {
      if (layer.size() == n) image::ToDecibels(layer);
    }
  }
}

}  // namespace

ProductResolutions ResolveProductResolutions(const SimulateRequest& options, const geo::RslcProduct& product,
                                             double ground_speed_mps) {
  ProductResolutions r;
  const double unit = image::UnitHalfPowerWidth(image::ParseSpectralWindow(options.psf_window, "--psf-window"));
  if (!std::isnan(options.range_resolution_m)) {
    r.range_m = options.range_resolution_m;
    r.range_source = "--range-resolution";
  } else if (product.processed_range_bandwidth_hz > 0.0) {
    r.range_bandwidth_hz = product.processed_range_bandwidth_hz;
    r.range_m = unit * geo::kSpeedOfLightMps / (2.0 * r.range_bandwidth_hz);
    r.range_source = "processedRangeBandwidth";
  }
  if (!std::isnan(options.azimuth_resolution_m)) {
    r.azimuth_m = options.azimuth_resolution_m;
    r.azimuth_source = "--azimuth-resolution";
  } else if (product.processed_azimuth_bandwidth_hz > 0.0 && ground_speed_mps > 0.0) {
    r.azimuth_bandwidth_hz = product.processed_azimuth_bandwidth_hz;
    r.azimuth_m = unit * ground_speed_mps / r.azimuth_bandwidth_hz;
    r.azimuth_source = "processedAzimuthBandwidth";
  }
  return r;
}

void ResampleToGroundRange(const Sentinel1Source& source, ProductSimulation& sim) {
  const geo::Sentinel1Annotation& a = source.annotation;
  GISSAR_CHECK(source.ground_range && !a.range_conversion.empty());
  const sensor::RadarGrid slant = sim.grid;
  const int rows = source.window[2], cols = source.window[3], slant_cols = slant.cols;
  GISSAR_CHECK(slant.rows == rows);
  const size_t n_slant = size_t(rows) * slant_cols, n = size_t(rows) * cols;
  const float nan = std::numeric_limits<float>::quiet_NaN();

  // The bands to carry over: float (linear), double (linear), byte (nearest).
  std::vector<render::SarImage*> images = {&sim.image.image};
  for (render::SarImage& c : sim.other_channels) images.push_back(&c);
  std::vector<std::vector<float>*> floats = {&sim.image.lon_deg, &sim.image.lat_deg, &sim.image.height_m};
  std::vector<std::vector<uint8_t>*> bytes;
  std::vector<uint8_t> byte_fill;  // outside the slant grid: mask "outside", footprint 0
  for (render::SarImage* image : images) {
    GISSAR_CHECK(image->real.empty());  // a GRD is simulated incoherently
    floats.push_back(&image->intensity);
    for (auto& layer : image->bounce_layers) {
      if (layer.size() == n_slant) floats.push_back(&layer);
    }
    if (image->mask.size() == n_slant) {
      bytes.push_back(&image->mask);
      byte_fill.push_back(render::kMaskOutside);
    }
    if (image->footprint.size() == n_slant) {
      bytes.push_back(&image->footprint);
      byte_fill.push_back(0);
    }
  }
  std::vector<std::vector<double>*> doubles = {&sim.image.lon_deg_exact, &sim.image.lat_deg_exact};
  std::vector<std::vector<float>> float_out(floats.size(), std::vector<float>(n, nan));
  std::vector<std::vector<double>> double_out(doubles.size(),
                                              std::vector<double>(n, std::numeric_limits<double>::quiet_NaN()));
  std::vector<std::vector<uint8_t>> byte_out;
  for (const uint8_t fill : byte_fill) byte_out.emplace_back(n, fill);
  for (auto* f : floats) GISSAR_CHECK(f->size() == n_slant);
  for (auto* d : doubles) GISSAR_CHECK(d->size() == n_slant);

  tbb::parallel_for(tbb::blocked_range<int>(0, rows, 8), [&](const tbb::blocked_range<int>& range) {
    for (int i = range.begin(); i != range.end(); ++i) {
      for (int j = 0; j < cols; ++j) {
        const double ground = double(source.window[1] + j) * source.ground_spacing_m;
        const double c = slant.ColOfRange(a.SlantRangeOfGroundRange(ground, slant.TimeOfRow(i)));
        if (!(c >= 0.0 && c <= double(slant_cols - 1))) continue;
        const int c0 = std::min(static_cast<int>(std::floor(c)), slant_cols - 2);
        const double f = c - c0;
        const size_t k0 = size_t(i) * slant_cols + c0, out = size_t(i) * cols + j;
        for (size_t b = 0; b < floats.size(); ++b) {
          const float v0 = (*floats[b])[k0], v1 = (*floats[b])[k0 + 1];
          float_out[b][out] = (std::isnan(v0) || std::isnan(v1)) ? nan : static_cast<float>((1.0 - f) * v0 + f * v1);
        }
        for (size_t b = 0; b < doubles.size(); ++b) {
          const double v0 = (*doubles[b])[k0], v1 = (*doubles[b])[k0 + 1];
          double_out[b][out] = (1.0 - f) * v0 + f * v1;  // NaN when either is
        }
        for (size_t b = 0; b < bytes.size(); ++b) byte_out[b][out] = (*bytes[b])[f < 0.5 ? k0 : k0 + 1];
      }
    }
  });
  for (size_t b = 0; b < floats.size(); ++b) *floats[b] = std::move(float_out[b]);
  for (size_t b = 0; b < doubles.size(); ++b) *doubles[b] = std::move(double_out[b]);
  for (size_t b = 0; b < bytes.size(); ++b) *bytes[b] = std::move(byte_out[b]);
  // A ground point needs both neighbours (the float bands are NaN otherwise).
  for (size_t k = 0; k < n; ++k) {
    if (std::isnan(sim.image.height_m[k]) || std::isnan(sim.image.lon_deg[k])) {
      sim.image.lon_deg[k] = sim.image.lat_deg[k] = sim.image.height_m[k] = nan;
      sim.image.lon_deg_exact[k] = sim.image.lat_deg_exact[k] = std::numeric_limits<double>::quiet_NaN();
    }
  }
  sim.image.geolocated = 0;
  for (size_t k = 0; k < n; ++k) sim.image.geolocated += std::isfinite(sim.image.height_m[k]) ? 1 : 0;
  for (render::SarImage* image : images) {
    image->width = cols;
    image->height = rows;
    // Reflector returns: their ground-range pixel (rows are unchanged).
    for (render::PointReturn& p : image->points) {
      p.col = a.GroundRangeOfSlantRange(p.range_m, slant.TimeOfRow(p.row)) / source.ground_spacing_m -
              double(source.window[1]);
    }
  }
}

ProductSimulation SimulateProduct(const SimulateRequest& options, bool read_amplitude, Reporter& reporter) {
  RealImageOptions real;
  real.read = read_amplitude;
  return SimulateProduct(options, real, reporter);
}

ProductSimulation SimulateProduct(const SimulateRequest& options, const RealImageOptions& real, Reporter& reporter) {
  auto say = [&](const std::string& line) { reporter.Info("simulate: " + line); };
  ProductSimulation sim;
  if (IsSentinel1Request(options)) {
    auto source = std::make_shared<Sentinel1Source>(ReadSentinel1Source(options, reporter));
    sim.product = source->grid;
    if (real.read) {
      // The real image on the output grid (a GRD's: its ground-range pixels).
      sim.product.amplitude = AmplitudeOfPower(ReadSentinel1Calibrated(
          *source, options.product, geo::ParseSentinel1Radiometry(real.radiometry, "--radiometry"), real.remove_noise));
    }
    sim.sentinel1 = std::move(source);
  } else {
    sim.product = ReadProductGeometry(options, real.read, reporter);
  }
  const geo::RslcProduct& p = sim.product;
  const sensor::Orbit orbit(p.orbit.time_s, p.orbit.position_m, p.orbit.velocity_mps);
  sim.grid = RadarGridOf(p);
  CheckMemoryBudget(400.0 * double(p.rows()) * p.cols(), options.max_memory_bytes,
                    "product grid of " + std::to_string(p.rows()) + " x " + std::to_string(p.cols()) + " pixels",
                    "simulate a part of it (--product-window LINE,PIXEL,LINES,PIXELS)");
  say("product " + std::to_string(p.rows()) + " lines x " + std::to_string(p.cols()) + " range bins, " +
      sensor::ToString(sensor::LookSideOf(p.look_left)) + "-looking, wavelength " + std::to_string(p.wavelength_m) + " m");

  sim.channels = material::ParsePolarizationList(options.polarization, "--polarization");
  const bool polarimetric = sim.channels.size() > 1;
  if (polarimetric && !options.product.empty()) CheckProductHasChannels(p, sim.channels, options.product);

  Terrain terrain = LoadTerrain(options, reporter);
  const render::EmbreeScene embree(terrain.mesh, TracedGrid(terrain, options));
  render::RenderOptions ro = RenderOptionsOf(options, sim.channels.front(), &reporter);
  ro.wavelength_m = p.wavelength_m;  // the product's band selects the materials' laws
  ro.reflectors = terrain.reflectors;  // a scene's own
  const auto placed = PlaceReflectors(options.reflectors, terrain, embree);
  ro.reflectors.insert(ro.reflectors.end(), placed.begin(), placed.end());
  // One pass per channel (polarimetric passes with one seed; VH = HV).
  ro.polarimetric = polarimetric;
  sim.image = render::RenderProduct(embree, terrain.mesh, terrain.materials, terrain.frame, orbit, sim.grid, ro);
  for (size_t k = 1; k < sim.channels.size(); ++k) {
    const material::Polarization c = sim.channels[k];
    const auto twin = std::find(sim.channels.begin(), sim.channels.begin() + k,
                                c == material::Polarization::kVH ? material::Polarization::kHV
                                : c == material::Polarization::kHV ? material::Polarization::kVH
                                                                   : c);
    if ((c == material::Polarization::kHV || c == material::Polarization::kVH) && twin != sim.channels.begin() + k) {
      const size_t t = size_t(twin - sim.channels.begin());
      sim.other_channels.push_back(t == 0 ? sim.image.image : sim.other_channels[t - 1]);
      continue;
    }
    say("channel " + material::ToString(c));
    ro.polarization = c;
    sim.other_channels.push_back(
        render::RenderProduct(embree, terrain.mesh, terrain.materials, terrain.frame, orbit, sim.grid, ro).image);
  }
  sim.ground_speed_mps = sim.image.tracing_geometry.azimuth_spacing_m / sim.grid.dt_s;
  say(std::to_string(sim.image.geolocated) + " pixels geolocated, " + std::to_string(sim.image.contributions) +
      " returns re-projected");

  // The impulse response on the product's pixel spacings: the request's
  // resolutions, or the product's processed bandwidths.
  sim.resolutions = ResolveProductResolutions(options, p, sim.ground_speed_mps);
  image::SensorEffects response;
  response.range_resolution_px = sim.resolutions.range_m / sim.grid.dr_m;
  response.azimuth_resolution_px = sim.resolutions.azimuth_m / sim.image.tracing_geometry.azimuth_spacing_m;
  char line[200];
  std::snprintf(line, sizeof line, "impulse response %.3f m (%s) x %.3f m (%s), window %s", sim.resolutions.range_m,
                sim.resolutions.range_source.c_str(), sim.resolutions.azimuth_m, sim.resolutions.azimuth_source.c_str(),
                options.psf_window.c_str());
  say(line);
  response.window = image::ParseSpectralWindow(options.psf_window, "--psf-window");
  response.wavelength_m = p.wavelength_m;
  CheckImpulseResponsePixels(response.range_resolution_px, response.azimuth_resolution_px);
  const std::vector<float> incidence = EllipsoidIncidenceDeg(sim.image, orbit, sim.grid);
  // Each further channel draws its own noise and speckle (seed offset).
  auto sensor_stage = [&](render::SarImage& image, uint64_t seed) {
    if (options.coherent) {
      // The complex image (speckle from the phasors), the reflectors' phasors
      // added with the same response, then the per-pixel radiometry.
      if (response.range_resolution_px > 0.0 || response.azimuth_resolution_px > 0.0) {
        image::ApplyComplexImpulseResponse(image.real, image.imag, image.width, image.height,
                                           response.range_resolution_px, response.azimuth_resolution_px,
                                           response.window);
        for (int b = 0; b < render::kBounceLayers; ++b) {
          if (image.bounce_real[b].size() != image.real.size()) continue;
          image::ApplyComplexImpulseResponse(image.bounce_real[b], image.bounce_imag[b], image.width, image.height,
                                             response.range_resolution_px, response.azimuth_resolution_px,
                                             response.window);
        }
      }
      AddPointPhasors(image, image.points, response);
      ConvertPixelRadiometryCoherent(image, incidence, image::ParseRadiometry(options.radiometry, "--radiometry"),
                                     options.nesz_db, seed, options.db);
    } else {
      image::ApplyImpulseResponse(image.intensity, image.width, image.height, response.range_resolution_px,
                                  response.azimuth_resolution_px, response.window);
      if (options.speckle_looks >= 1.0) image::ApplyMultiplicativeSpeckle(image.intensity, options.speckle_looks, seed);
      image::AddPointIntensities(image, response);  // reflectors: the same impulse response, added after the speckle
      // beta0 so far: sigma0 / gamma0 need each pixel's own ellipsoid incidence.
      image::ConvertPixelRadiometry(image, incidence, image::ParseRadiometry(options.radiometry, "--radiometry"),
                                    options.nesz_db, seed, options.db);
    }
  };
  sensor_stage(sim.image.image, options.seed);
  for (size_t k = 0; k < sim.other_channels.size(); ++k) {
    sensor_stage(sim.other_channels[k], options.seed + 0x9e3779b97f4a7c15ULL * (k + 1));
  }
  sim.terrain = terrain.description;
  sim.frame = {{"origin_lon_deg", terrain.frame.origin_lon_deg()},
               {"origin_lat_deg", terrain.frame.origin_lat_deg()},
               {"vertical_datum", terrain.vertical_datum},
               {"vertical_datum_source", terrain.vertical_datum_source}};
  return sim;
}

namespace {

nlohmann::json ProductJson(const ProductSimulation& sim) {
  const geo::RslcProduct& p = sim.product;
  const sensor::SarGeometryOptions& g = sim.image.tracing_geometry;
  return {{"file", p.path},
          {"product_version", p.product_version},
          {"epoch_utc", p.epoch_utc},
          {"frequency", p.frequency},
          {"polarization", p.polarization},
          {"rows", p.rows()},
          {"cols", p.cols()},
          {"first_zero_doppler_time_s", sim.grid.t0_s},
          {"zero_doppler_time_spacing_s", sim.grid.dt_s},
          {"first_slant_range_m", sim.grid.r0_m},
          {"slant_range_spacing_m", sim.grid.dr_m},
          {"look_side", sensor::ToString(sensor::LookSideOf(p.look_left))},
          {"wavelength_m", p.wavelength_m},
          {"orbit_state_vectors", p.orbit.time_s.size()},
          {"orbit_type", p.orbit.type},
          {"orbit_interpolation", "cubic Hermite (positions and velocities)"},
          {"sentinel1", sim.sentinel1 ? sim.sentinel1->ToJson() : nlohmann::json(nullptr)},
          {"tracing_geometry",
           {{"heading_deg", g.heading_deg},
            {"depression_deg", g.depression_deg},
            {"slant_range_m", g.slant_range_m},
            {"azimuth_spacing_m", g.azimuth_spacing_m},
            {"width", g.width},
            {"height", g.height}}}};
}

// The impulse response applied and where each resolution came from.
nlohmann::json ImpulseResponseJson(const ProductSimulation& sim, const SimulateRequest& options) {
  const ProductResolutions& r = sim.resolutions;
  auto bandwidth = [](double hz) { return hz > 0.0 ? nlohmann::json(hz) : nlohmann::json(nullptr); };
  auto stated = [](double hz) { return std::isnan(hz) ? nlohmann::json(nullptr) : nlohmann::json(hz); };
  return {{"range_resolution_m", r.range_m},
          {"azimuth_resolution_m", r.azimuth_m},
          {"range_resolution_px", r.range_m / sim.grid.dr_m},
          {"azimuth_resolution_px", r.azimuth_m / sim.image.tracing_geometry.azimuth_spacing_m},
          {"window", options.psf_window},
          {"range_resolution_source", r.range_source},
          {"azimuth_resolution_source", r.azimuth_source},
          {"range_bandwidth_hz", bandwidth(r.range_bandwidth_hz)},
          {"azimuth_bandwidth_hz", bandwidth(r.azimuth_bandwidth_hz)},
          {"product_processed_range_bandwidth_hz", stated(sim.product.processed_range_bandwidth_hz)},
          {"product_processed_azimuth_bandwidth_hz", stated(sim.product.processed_azimuth_bandwidth_hz)},
          {"ground_speed_mps", sim.ground_speed_mps},
          {"rule", "3 dB widths: --range-resolution / --azimuth-resolution when given, else the product's processed "
                   "bandwidth: UnitHalfPowerWidth(window) c / (2 B_r) and UnitHalfPowerWidth(window) v_ground / "
                   "B_az (0.886 with no window), else none"}};
}

geo::Metadata ProductMetadata(const ProductSimulation& sim, const SimulateRequest& options) {
  geo::Metadata m;
  m["GISSAR_GEOMETRY"] = "product radar grid: row = zero-Doppler azimuth line, column = slant-range bin";
  if (!options.product.empty()) {
    m["GISSAR_PRODUCT"] = fs::absolute(options.product).string();
  } else {
    m["GISSAR_ORBIT"] = fs::absolute(options.orbit).string();
    m["GISSAR_RADAR_GRID"] = fs::absolute(options.radar_grid).string();
  }
  m["GISSAR_EPOCH_UTC"] = sim.product.epoch_utc;
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, "%.9f", sim.grid.t0_s);
  m["GISSAR_FIRST_TIME_S"] = buffer;
  std::snprintf(buffer, sizeof buffer, "%.12g", sim.grid.dt_s);
  m["GISSAR_TIME_SPACING_S"] = buffer;
  std::snprintf(buffer, sizeof buffer, "%.6f", sim.grid.r0_m);
  m["GISSAR_FIRST_RANGE_M"] = buffer;
  std::snprintf(buffer, sizeof buffer, "%.9g", sim.grid.dr_m);
  m["GISSAR_RANGE_SPACING_M"] = buffer;
  m["GISSAR_LOOK_SIDE"] = sensor::ToString(sensor::LookSideOf(sim.product.look_left));
  const std::string datum = sim.frame.value("vertical_datum", std::string("ellipsoid"));
  m["GISSAR_VERTICAL_DATUM"] = datum != "ellipsoid" ? "DEM " + datum + " heights + geoid undulation"
                                                    : "DEM heights used as WGS84 ellipsoidal";
  m["GISSAR_UNITS"] = options.radiometry + (options.db ? " (dB)" : " (linear, m2/m2)");
  m["GISSAR_RADIOMETRY"] = options.radiometry;
  m["GISSAR_VERSION"] = VersionString();
  if (options.product_window_px) {
    const auto& w = *options.product_window_px;
    m["GISSAR_PRODUCT_WINDOW"] = std::to_string(w[0]) + "," + std::to_string(w[1]) + "," + std::to_string(w[2]) +
                                 "," + std::to_string(w[3]) +
                                 " (first line, first pixel, lines, pixels of the product's grid)";
  }
  if (sim.sentinel1) AddSentinel1Metadata(*sim.sentinel1, m);
  return m;
}

// The files a product simulation writes: PREFIX.tif, .png, _mask.tif, .json
// and, coherent, _slc.tif (and _pauli.png with the Pauli channels).
struct ProductSimulationFiles {
  fs::path tif, png, mask_tif, json, slc_tif, pauli_png;
};

ProductSimulationFiles AddProductSimulationFiles(AtomicOutputs& outputs, const SimulateRequest& options) {
  ProductSimulationFiles files;
  files.tif = outputs.Add(options.out_prefix + ".tif");
  files.png = outputs.Add(options.out_prefix + ".png");
  files.mask_tif = outputs.Add(options.out_prefix + "_mask.tif");
  files.json = outputs.Add(options.out_prefix + ".json");
  files.slc_tif = options.coherent ? outputs.Add(options.out_prefix + "_slc.tif") : fs::path();
  files.pauli_png =
      options.coherent && HasPauliChannels(options) ? outputs.Add(options.out_prefix + "_pauli.png") : fs::path();
  return files;
}

// The simulation in the units it is written in. Sentinel-1: a GRD is
// rendered in slant range and resampled to its ground range pixels, in
// linear units (dB after the resampling).
ProductSimulation SimulateForWriting(const SimulateRequest& options, Reporter& reporter) {
  SimulateRequest run = options;
  if (IsSentinel1Request(options)) run.db = false;
  ProductSimulation sim = SimulateProduct(run, false, reporter);
  if (sim.sentinel1) {
    if (sim.sentinel1->ground_range) ResampleToGroundRange(*sim.sentinel1, sim);
    if (options.db) {
      std::vector<render::SarImage*> images = {&sim.image.image};
      for (render::SarImage& c : sim.other_channels) images.push_back(&c);
      for (render::SarImage* im : images) {
        image::ToDecibels(im->intensity);
        for (auto& layer : im->bounce_layers) {
          if (layer.size() == im->intensity.size()) image::ToDecibels(layer);
        }
      }
    }
  }
  return sim;
}

// The bands of PREFIX.tif: one channel: the total and its bounce layers;
// several (as `simulate` writes them): each channel's total, then each
// channel's bounce layers (`channel_images`: the channels, NaN where the
// pixel has no ground point, as the first); then longitude, latitude and
// height of each pixel's ground point, located by GDAL geolocation arrays.
geo::FloatRaster ProductRaster(const ProductSimulation& sim, const render::SarImage& image,
                               const geo::Metadata& metadata, const SimulateRequest& options,
                               std::vector<render::SarImage>& channel_images) {
  geo::FloatRaster raster{image.width, image.height, {}, {}, metadata};
  const std::string unit = image::RadiometryUnit(options.db);
  // Channel 0 is `image`; the others follow (several channels).
  const int held = HeldBounceLayers(image, sim.other_channels);
  raster.band_names = ImageBandNames(sim.channels, 1 + sim.other_channels.size(), held);
  if (sim.other_channels.empty()) {
    raster.bands.push_back(image.intensity);
    for (int layer = 0; layer < held; ++layer) raster.bands.push_back(image.bounce_layers[layer]);
  } else {
    channel_images.push_back(image);
    for (render::SarImage c : sim.other_channels) {
      if (c.footprint.size() == c.intensity.size()) MarkOutsideFootprint(c, sim.image.image.footprint);
      channel_images.push_back(std::move(c));
    }
    for (const render::SarImage& c : channel_images) raster.bands.push_back(c.intensity);
    for (const render::SarImage& c : channel_images) {
      for (int layer = 0; layer < held; ++layer) raster.bands.push_back(c.bounce_layers[layer]);
    }
    raster.metadata["GISSAR_POLARIZATIONS"] = material::ToString(sim.channels);
  }
  const int image_bands = static_cast<int>(raster.bands.size());
  raster.band_units.assign(raster.bands.size(), unit);
  raster.nodata_nan = true;
  raster.bands.push_back(sim.image.lon_deg);
  raster.band_names.push_back("lon_deg");
  raster.bands.push_back(sim.image.lat_deg);
  raster.band_names.push_back("lat_deg");
  raster.bands.push_back(sim.image.height_m);
  raster.band_names.push_back("height_m");
  raster.band_units.insert(raster.band_units.end(), {"deg", "deg", "m"});
  const std::string bands_text =
      NumberedBands(std::vector<std::string>(raster.band_names.begin(), raster.band_names.begin() + image_bands));
  const int lon_band = image_bands + 1, lat_band = image_bands + 2;
  raster.metadata["GISSAR_BANDS"] =
      bands_text + " (" + options.radiometry + (options.db ? ", dB" : ", linear") + "); " + std::to_string(lon_band) +
      " longitude, " + std::to_string(lat_band) + " latitude (WGS84 degrees, float32: ~1 m), " +
      std::to_string(image_bands + 3) + " ellipsoidal height (m) of each pixel's ground point (NaN: none)";
  // GDAL geolocation arrays: gdalwarp -geoloc places the image from the longitude and latitude bands.
  raster.georeference.geolocation = geo::LonLatGeolocation(lon_band, lat_band);
  return raster;
}

// The coherent outputs: the complex total and the complex image of each
// bounce count in PREFIX_slc.tif, as `gissar simulate --coherent` writes
// them, and PREFIX_pauli.png with the Pauli channels; returns the Pauli
// quicklook's looks and stretch (null without it).
// `detected_geolocation`: PREFIX.tif's geolocation arrays (ProductRaster).
nlohmann::json WriteProductSlc(const ProductSimulationFiles& files, const ProductSimulation& sim,
                               render::SarImage& image, std::vector<render::SarImage>& channel_images,
                               const geo::Metadata& metadata, const SimulateRequest& options,
                               const geo::Metadata& detected_geolocation) {
  nlohmann::json pauli_record;
  // Located by the geolocation arrays of PREFIX.tif beside it.
  geo::Metadata slc_metadata = metadata;
  slc_metadata["GISSAR_UNITS"] = "complex amplitude, |z|^2 = " + options.radiometry + " (linear)";
  slc_metadata["GISSAR_PHASE"] = "exp(-j 4 pi R / lambda), R = true slant range (geo2rdr on the product orbit)";
  // As `gissar simulate --coherent` writes them: one channel: the total
  // and its bounce bands; several: each channel's total, then each
  // channel's bounce bands.
  std::vector<render::SarImage*> slc_images = {&image};
  for (size_t k = 1; k < channel_images.size(); ++k) slc_images.push_back(&channel_images[k]);
  std::vector<float> no_return;  // a layer with no return
  const std::vector<geo::ComplexBand> slc_bands = SlcBands(slc_images, sim.channels, no_return, slc_metadata);
  // Georeference: GDAL geolocation arrays = the longitude and latitude bands
  // of PREFIX.tif (after its image bands; by its absolute path: GDAL 3.6
  // opens X_DATASET as given), and, for when the files are moved apart, a
  // lattice of up to 8 x 8 GCPs at pixel centres with a ground point (lon,
  // lat, ellipsoidal height).
  geo::Georeference slc_georeference;
  slc_georeference.geolocation = detected_geolocation;
  const std::string detected_path = fs::absolute(options.out_prefix + ".tif").lexically_normal().string();
  slc_georeference.geolocation["X_DATASET"] = detected_path;
  slc_georeference.geolocation["Y_DATASET"] = detected_path;
  constexpr int kGcpLattice = 8;
  for (int i = 0; i < kGcpLattice; ++i) {
    const int row = int(std::lround(double(i) * (image.height - 1) / (kGcpLattice - 1)));
    for (int j = 0; j < kGcpLattice; ++j) {
      const int col = int(std::lround(double(j) * (image.width - 1) / (kGcpLattice - 1)));
      const size_t k = size_t(row) * image.width + col;
      if (!std::isfinite(sim.image.height_m[k])) continue;
      slc_georeference.gcps.push_back({col + 0.5, row + 0.5, sim.image.lon_deg_exact[k], sim.image.lat_deg_exact[k],
                                       double(sim.image.height_m[k])});
    }
  }
  geo::WriteComplexGeoTiff(files.slc_tif, slc_bands, image.width, image.height, slc_metadata, "sqrt(m2/m2)",
                           slc_georeference, /*nodata_nan=*/true, options.overviews);
  if (!files.pauli_png.empty()) {
    const std::vector<const render::SarImage*> images(slc_images.begin(), slc_images.end());
    WritePauliQuicklook(files.pauli_png, sim.channels, images, &pauli_record);
  }
  return pauli_record;
}

// The input files of a product simulation, in the provenance's order.
nlohmann::json ProductSimulationInputs(const ProductSimulation& sim, const SimulateRequest& options) {
  nlohmann::json inputs = nlohmann::json::array();
  if (sim.sentinel1) {
    // The product, the terrain (where `pta` finds them), then the orbit file.
    inputs.push_back(Sentinel1InputRecord(*sim.sentinel1));
    inputs.push_back(InputFileRecord(options.scene.empty() ? options.dem : options.scene));
    if (!options.orbit.empty()) inputs.push_back(InputFileRecord(options.orbit));
  } else {
    for (const std::string& input : {options.product, options.orbit, options.radar_grid}) {
      if (!input.empty()) inputs.push_back(InputFileRecord(input));
    }
    inputs.push_back(InputFileRecord(options.scene.empty() ? options.dem : options.scene));
  }
  return inputs;
}

// How a coherent product simulation makes its phases.
nlohmann::json CoherentRecord(const ProductSimulation& sim, const SimulateRequest& options) {
  return {
      {"phase", "exp(-j 4 pi R / lambda): R = true slant range of each return (geo2rdr on the product orbit; "
                "multi-bounce: plus the path excess) and of each reflector's phase centre"},
      {"rough_surface", sim.other_channels.empty()
                            ? "seeded random micro-phase per return and pixel (expected intensity = incoherent image)"
                            : "per return and pixel, three seeded phases shared by the channels: HH exp(j phi1), "
                              "VV conj(rho) exp(j phi1) + sqrt(1 - |rho|^2) exp(j phi2), HV = VH exp(j phi3) "
                              "(rho: the class's HH-VV correlation)"},
      {"mirror_paths", sim.other_channels.empty()
                           ? "path phase, twice the amplitude of one path (the path and its reverse)"
                           : "sqrt(P) (S_c + S^T_c) with the path phase (Fresnel chain of the path and its reverse)"},
      {"impulse_response", ImpulseResponseJson(sim, options)},
      {"wavelength_m", sim.product.wavelength_m},
      {"seed", options.seed}};
}

// PREFIX.json of a product simulation (but its timings).
nlohmann::json ProductSimulationProvenance(ProductSimulation& sim, const render::SarImage& image,
                                           const SimulateRequest& options, const std::string& command_line,
                                           const nlohmann::json& pauli_record, const image::DbStretch& stretch) {
  const std::vector<uint8_t>& mask = image.mask;
  nlohmann::json provenance = ProvenanceHeader("simulate", command_line, options.ToJson());
  provenance["inputs"] = ProductSimulationInputs(sim, options);
  provenance["product"] = ProductJson(sim);
  provenance["terrain"] = sim.terrain;
  provenance["frame"] = sim.frame;
  provenance["vertical_datum"] = {{"datum", sim.frame["vertical_datum"]}, {"source", sim.frame["vertical_datum_source"]}};
  if (options.coherent) provenance["coherent"] = CoherentRecord(sim, options);
  if (!sim.other_channels.empty()) {
    provenance["polarimetry"] = {
        {"channels", material::ToString(sim.channels)},
        {"model", "one polarimetric pass per channel (VH = HV by reciprocity), one seed: scattering matrices per "
                  "return (docs/radiometry.md, Polarimetry in the renderer)"}};
    if (!pauli_record.is_null()) provenance["polarimetry"]["pauli_quicklook"] = pauli_record;
  }
  provenance["impulse_response"] = ImpulseResponseJson(sim, options);
  provenance["radiometry"] = {
      {"quantity", options.radiometry},
      {"scale", options.db ? "dB" : "linear"},
      {"unit", image::RadiometryUnit(options.db)},
      {"polarization", options.polarization},
      {"channels", material::ToString(sim.channels)},
      {"wavelength_m", sim.product.wavelength_m},
      {"nesz_db", std::isnan(options.nesz_db) ? nlohmann::json(nullptr) : nlohmann::json(options.nesz_db)},
      {"incidence_reference", "per pixel: WGS84 ellipsoid normal at the pixel's ground point vs the line of sight "
                              "at its zero-Doppler time"}};
  provenance["stats"] = {{"rays", image.stats.rays},
                         {"hits", image.stats.hits},
                         {"returns_reprojected", sim.image.contributions},
                         {"pixels_geolocated", sim.image.geolocated},
                         {"reflector_returns", image.points.size()},
                         {"mask_pixels", MaskPixelCounts(mask)}};
  provenance["quicklook"] = {{"db_low", stretch.low_db}, {"db_high", stretch.high_db}, {"percentiles", {2, 98}}};
  return provenance;
}

}  // namespace

SimulateResult RunProductSimulate(const SimulateRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  Stopwatch total;
  AtomicOutputs outputs;
  const ProductSimulationFiles files = AddProductSimulationFiles(outputs, options);
  ProductSimulation sim = SimulateForWriting(options, reporter);
  // NaN where the pixel has no ground point on the terrain (declared no-data, mask 255).
  render::SarImage image = sim.image.image;
  if (image.footprint.size() == image.intensity.size()) MarkOutsideFootprint(image, sim.image.image.footprint);
  geo::Metadata metadata = ProductMetadata(sim, options);
  std::vector<render::SarImage> channel_images;  // several channels: channel 0 is `image`, the others follow
  geo::Metadata detected_geolocation;  // PREFIX.tif's longitude and latitude bands, for PREFIX_slc.tif
  {
    const geo::FloatRaster raster = ProductRaster(sim, image, metadata, options, channel_images);
    detected_geolocation = raster.georeference.geolocation;
    geo::WriteFloatGeoTiff(files.tif, raster);
  }
  nlohmann::json pauli_record;  // the Pauli quicklook's looks and stretch
  if (options.coherent) {
    pauli_record = WriteProductSlc(files, sim, image, channel_images, metadata, options, detected_geolocation);
  }
  image::DbStretch stretch;
  geo::WritePng(files.png, image::DbQuicklook(image.intensity, 2.0, 98.0, &stretch), image.width, image.height, 1);
  geo::Metadata mask_metadata = metadata;
  mask_metadata["GISSAR_MASK_CODES"] = kMaskCodesText;
  geo::WriteByteGeoTiff(files.mask_tif, image.mask, image.width, image.height, mask_metadata, {}, MaskCategories());

  nlohmann::json provenance = ProductSimulationProvenance(sim, image, options, command_line, pauli_record, stretch);
  provenance["timings_s"] = {{"total", total.ElapsedSeconds()}};
  return CommitSimulation(outputs, provenance, files.json, image, total.ElapsedSeconds());
}

void ValidateRequest::Check() const {
  if (simulate.product.empty()) throw ConfigError("a product is required", "--product");
  if (out_prefix.empty()) throw ConfigError("a report prefix is required", "--out");
  if (looks.empty()) throw ConfigError("give at least one multilook size", "--looks");
  for (int k : looks) {
    if (k < 1 || k > 64) throw ConfigError("multilook sizes must be in [1, 64], got " + std::to_string(k), "--looks");
  }
  SimulateRequest probe = simulate;
  probe.out_prefix = out_prefix;
  probe.Check();
  const image::Radiometry quantity = image::ParseRadiometry(radiometry, "--radiometry");
  if (!IsSentinel1Request(simulate)) {
    if (quantity != image::Radiometry::kBeta0) {
      throw ConfigError("only beta0 with a NISAR product: its |s|^2 is beta0 (NISAR's calibration); sigma0 and "
                        "gamma0 are calibrated with a Sentinel-1 product's LUTs",
                        "--radiometry");
    }
    if (noise_removal) {
      throw ConfigError("only for a Sentinel-1 product (gissar reads the thermal noise LUTs of a SAFE, not a NISAR "
                        "product's noise)",
                        "--noise-removal");
    }
  }
  if (!reference_geolocation.empty() && IsSentinel1Request(simulate)) {
    throw ConfigError("a peer's per-pixel geolocation (ISCE topo layers) goes with a NISAR product; a Sentinel-1 "
                      "product's geometry is checked against its geolocation grids (validate without terrain)",
                      "--reference-geolocation");
  }
  std::vector<fs::path> outs;
  for (const char* suffix : {".json", ".md", "_side_by_side.png", "_histogram.png"}) outs.push_back(out_prefix + suffix);
  std::vector<std::string> ins = {simulate.product, simulate.dem, simulate.scene};
  if (!reference_geolocation.empty()) {
    for (const char* f : {"x.rdr", "y.rdr", "z.rdr", "simamp.rdr"}) ins.push_back((fs::path(reference_geolocation) / f).string());
  }
  CheckOutputsAreNotInputs(outs, ins);
}

nlohmann::json ValidateRequest::ToJson() const {
  nlohmann::json j = simulate.ToJson();
  j.erase("out_prefix");
  j["radiometry"] = radiometry;  // the quantity compared, not simulate.radiometry
  j["noise_removal"] = noise_removal;
  j["reference_geolocation"] = reference_geolocation;
  j["looks"] = looks;
  j["out_prefix"] = out_prefix;
  return j;
}

double MultilookPearson(const std::vector<float>& a, const std::vector<float>& b, int width, int height, int k,
                        bool db_a, bool db_b, const std::vector<uint8_t>& valid, int64_t* blocks) {
  std::vector<double> x, y;
  for (int r0 = 0; r0 + k <= height; r0 += k) {
    for (int c0 = 0; c0 + k <= width; c0 += k) {
      double sa = 0, sb = 0;
      bool ok = true;
      for (int r = r0; r < r0 + k && ok; ++r) {
        for (int c = c0; c < c0 + k; ++c) {
          const size_t i = size_t(r) * width + c;
          if (!valid.empty() && !valid[i]) {
            ok = false;
            break;
          }
          sa += a[i];
          sb += b[i];
        }
      }
      if (!ok) continue;
      sa /= k * k;
      sb /= k * k;
      if (!std::isfinite(sa) || !std::isfinite(sb)) continue;
      if ((db_a && !(sa > 0.0)) || (db_b && !(sb > 0.0))) continue;
      if (db_a) sa = 10.0 * std::log10(sa);
      if (db_b) sb = 10.0 * std::log10(sb);
      x.push_back(sa);
      y.push_back(sb);
    }
  }
  if (blocks != nullptr) *blocks = int64_t(x.size());
  if (x.size() < 3) return std::nan("");
  const double n = double(x.size());
  double mx = 0, my = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= n;
  my /= n;
  double sxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  if (!(sxx > 0.0) || !(syy > 0.0)) return std::nan("");
  return sxy / std::sqrt(sxx * syy);
}

namespace {

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

std::string Fixed(double v, int digits) {
  if (!std::isfinite(v)) return "n/a";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// The files validate writes: PREFIX.json, .md, _side_by_side.png, _histogram.png.
struct ValidateFiles {
  fs::path json, md, side_by_side, histogram;
};

ValidateFiles AddValidateFiles(AtomicOutputs& outputs, const ValidateRequest& options) {
  ValidateFiles files;
  files.json = outputs.Add(options.out_prefix + ".json");
  files.md = outputs.Add(options.out_prefix + ".md");
  files.side_by_side = outputs.Add(options.out_prefix + "_side_by_side.png");
  files.histogram = outputs.Add(options.out_prefix + "_histogram.png");
  return files;
}

// A peer's per-pixel geolocation (ISCE topo layers), when given.
std::unique_ptr<geo::ReferenceGeolocation> ReadPeerGeolocation(const ValidateRequest& options) {
  std::unique_ptr<geo::ReferenceGeolocation> reference;
  if (!options.reference_geolocation.empty()) {
    reference = std::make_unique<geo::ReferenceGeolocation>(geo::ReadReferenceGeolocation(options.reference_geolocation));
  }
  return reference;
}

// Like with like: the simulation in the radiometry (`quantity`) the real
// image is calibrated to (an RSLC's |s|^2 is beta0, NISAR's calibration; a
// SAFE's with the LUT of options.radiometry), linear, with the real image
// read on the output grid. A GRD: the simulation onto the GRD's ground-range
// pixels, where its real image is.
ProductSimulation SimulateLikeTheRealImage(const ValidateRequest& options, const std::string& quantity,
                                           Reporter& reporter) {
  SimulateRequest compared = options.simulate;
  compared.radiometry = quantity;
  compared.db = false;
  // validate offers no resolutions: it compares the simulation without an
  // impulse response (not the product's processed bandwidths; with them the
  // San Andreas r dB falls from 0.139 to 0.132 at 3 x 3 looks).
  if (std::isnan(compared.range_resolution_m)) compared.range_resolution_m = 0.0;
  if (std::isnan(compared.azimuth_resolution_m)) compared.azimuth_resolution_m = 0.0;
  RealImageOptions real_options;
  real_options.read = true;
  real_options.radiometry = quantity;
  real_options.remove_noise = options.noise_removal;
  ProductSimulation sim = SimulateProduct(compared, real_options, reporter);
  if (sim.sentinel1 && sim.sentinel1->ground_range) ResampleToGroundRange(*sim.sentinel1, sim);
  return sim;
}

// The real image's intensity on the simulation's grid, and the pixels
// compared: those with a ground point and a positive real intensity.
struct RealWindow {
  int width = 0, height = 0;
  size_t n = 0;
  std::vector<float> real;
  std::vector<uint8_t> valid;
};

RealWindow ReadRealWindow(const ProductSimulation& sim) {
  RealWindow w;
  w.width = sim.image.image.width;
  w.height = sim.image.image.height;
  GISSAR_CHECK(sim.product.amplitude.size() == size_t(w.width) * w.height);
  const size_t n = w.n = size_t(w.width) * w.height;
  w.real.resize(n);
  for (size_t k = 0; k < n; ++k) w.real[k] = sim.product.amplitude[k] * sim.product.amplitude[k];
  w.valid.resize(n);
  for (size_t k = 0; k < n; ++k) w.valid[k] = std::isfinite(sim.image.height_m[k]) && w.real[k] > 0.0f ? 1 : 0;
  return w;
}

// Correlation with the real amplitude: per multilook size, r of the block
// means in dB, intensity and amplitude (and the peer's simamp, when given
// on the same grid).
nlohmann::json CorrelateAtLooks(const ProductSimulation& sim, const RealWindow& w,
                                const geo::ReferenceGeolocation* reference, const std::vector<int>& looks) {
  const render::SarImage& image = sim.image.image;
  const int width = w.width, height = w.height;
  const size_t n = w.n;
  const std::vector<float>& real = w.real;
  const std::vector<uint8_t>& valid = w.valid;
  nlohmann::json corr = nlohmann::json::array();
  for (int k : looks) {
    int64_t blocks = 0;
    const double r_db = MultilookPearson(image.intensity, real, width, height, k, true, true, valid, &blocks);
    std::vector<float> sim_amp(n), real_amp(n);
    for (size_t i = 0; i < n; ++i) {
      sim_amp[i] = std::sqrt(std::max(0.0f, image.intensity[i]));
      real_amp[i] = sim.product.amplitude[i];
    }
    const double r_amp = MultilookPearson(sim_amp, real_amp, width, height, k, false, false, valid);
    const double r_int = MultilookPearson(image.intensity, real, width, height, k, false, false, valid);
    nlohmann::json row = {{"looks", k},
                          {"blocks", blocks},
                          {"r_db", Number(r_db)},
                          {"r_intensity", Number(r_int)},
                          {"r_amplitude", Number(r_amp)}};
    if (reference && !reference->simamp.empty() && reference->width == width && reference->height == height) {
      // simamp is not a positive amplitude (ISCE writes it on its own
      // scale): its k x k mean is compared with the real multilooked
      // intensity (linear and dB) and mean amplitude.
      row["peer_simamp_r_db"] = Number(MultilookPearson(reference->simamp, real, width, height, k, false, true, valid));
      row["peer_simamp_r_intensity"] =
          Number(MultilookPearson(reference->simamp, real, width, height, k, false, false, valid));
      row["peer_simamp_r_amplitude"] = Number(MultilookPearson(reference->simamp, real_amp, width, height, k, false, false, valid));
    }
    corr.push_back(row);
  }
  return corr;
}

// Geolocation against the reference: ground distance, and the pixel the
// reference's point falls in by geo2rdr on the product orbit. Adds the
// reference's files to `inputs`.
nlohmann::json CompareGeolocation(const ProductSimulation& sim, const geo::ReferenceGeolocation& reference,
                                  const ValidateRequest& options, nlohmann::json& inputs) {
  const int width = sim.image.image.width, height = sim.image.image.height;
  if (reference.width != width || reference.height != height) {
    throw InputError("reference geolocation is " + std::to_string(reference.width) + " x " +
                         std::to_string(reference.height) + ", product grid " + std::to_string(width) + " x " +
                         std::to_string(height),
                     options.reference_geolocation);
  }
  inputs.push_back(InputFileRecord((fs::path(options.reference_geolocation) / "x.rdr").string()));
  inputs.push_back(InputFileRecord((fs::path(options.reference_geolocation) / "y.rdr").string()));
  inputs.push_back(InputFileRecord((fs::path(options.reference_geolocation) / "z.rdr").string()));
  const sensor::Orbit orbit(sim.product.orbit.time_s, sim.product.orbit.position_m, sim.product.orbit.velocity_mps);
  double s_col = 0, s_row = 0, s_col2 = 0, s_row2 = 0, s_ground2 = 0, s_h = 0, s_h2 = 0, max_ground = 0;
  int64_t count = 0;
  for (int i = 0; i < height; ++i) {
    for (int j = 0; j < width; ++j) {
      const size_t k = size_t(i) * width + j;
      if (!std::isfinite(sim.image.height_m[k])) continue;
      const Eigen::Vector3d ref = geo::LocalFrame::EcefFromGeodetic(reference.lon_deg[k], reference.lat_deg[k],
                                                                    reference.height_m[k]);
      const auto rc = sensor::Geo2Rdr(orbit, ref, sim.grid.TimeOfRow(i));
      if (!rc) continue;
      const double dcol = sim.grid.ColOfRange(rc->range_m) - j, drow = sim.grid.RowOfTime(rc->time_s) - i;
      const geo::LocalFrame local(reference.lon_deg[k], reference.lat_deg[k], reference.height_m[k]);
      const Eigen::Vector3d d = local.EnuFromGeodetic(sim.image.lon_deg_exact[k], sim.image.lat_deg_exact[k],
                                                      sim.image.height_m[k]);
      const double ground = std::hypot(d.x(), d.y());
      s_col += dcol;
      s_row += drow;
      s_col2 += dcol * dcol;
      s_row2 += drow * drow;
      s_ground2 += ground * ground;
      s_h += d.z();
      s_h2 += d.z() * d.z();
      max_ground = std::max(max_ground, ground);
      ++count;
    }
  }
  if (count == 0) throw InputError("no pixel geolocated by both gissar and the reference", options.reference_geolocation);
  const double c = double(count);
  return {{"pixels", count},
          {"range_px_rms", std::sqrt(s_col2 / c)},
          {"azimuth_px_rms", std::sqrt(s_row2 / c)},
          {"range_px_mean", s_col / c},
          {"azimuth_px_mean", s_row / c},
          {"range_m_rms", std::sqrt(s_col2 / c) * sim.grid.dr_m},
          {"azimuth_m_rms", std::sqrt(s_row2 / c) * sim.image.tracing_geometry.azimuth_spacing_m},
          {"ground_m_rms", std::sqrt(s_ground2 / c)},
          {"ground_m_max", max_ground},
          {"height_m_mean", s_h / c},
          {"height_m_rms", std::sqrt(s_h2 / c)},
          {"method",
           "range/azimuth: reference point -> geo2rdr on the product orbit -> pixel offset; ground: horizontal "
           "distance between gissar's and the reference's ground points of each pixel"}};
}

// Real | simulated (dB, each with its own 2-98 % stretch) | mask, side by side.
void WriteSideBySide(const fs::path& path, const render::SarImage& image, const RealWindow& w) {
  std::vector<uint8_t> real_grey = image::DbQuicklook(w.real, 2.0, 98.0);
  std::vector<uint8_t> sim_grey = image::DbQuicklook(image.intensity, 2.0, 98.0);
  std::vector<uint8_t> mask_grey(w.n);
  for (size_t k = 0; k < w.n; ++k) {
    const uint8_t m = image.mask[k] & 3;
    mask_grey[k] = m == 0 ? 255 : m == 1 ? 170 : m == 2 ? 0 : 85;
  }
  int strip_width = 0;
  const std::vector<uint8_t> strip = image::SideBySide({real_grey, sim_grey, mask_grey}, w.width, w.height, 6, &strip_width);
  geo::WritePng(path, strip, strip_width, w.height, 1);
}

// The radiometric level after k x k looks: real minus simulated, the medians
// of the block means in dB, and each block's dB difference (simulated -
// real, each image's median removed).
struct LevelComparison {
  double level_db = std::numeric_limits<double>::quiet_NaN();
  std::vector<float> differences;
};

LevelComparison CompareLevels(const render::SarImage& image, const RealWindow& w, int kmax) {
  const int width = w.width, height = w.height;
  LevelComparison out;
  std::vector<double> a, b;
  for (int r0 = 0; r0 + kmax <= height; r0 += kmax) {
    for (int c0 = 0; c0 + kmax <= width; c0 += kmax) {
      double sa = 0, sb = 0;
      bool ok = true;
      for (int r = r0; r < r0 + kmax; ++r) {
        for (int c2 = c0; c2 < c0 + kmax; ++c2) {
          const size_t i = size_t(r) * width + c2;
          ok = ok && w.valid[i];
          sa += image.intensity[i];
          sb += w.real[i];
        }
      }
      if (ok && sa > 0 && sb > 0) {
        a.push_back(10 * std::log10(sa));
        b.push_back(10 * std::log10(sb));
      }
    }
  }
  auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const double ma = median(a), mb = median(b);
  out.level_db = mb - ma;
  for (size_t i = 0; i < a.size(); ++i) out.differences.push_back(static_cast<float>((a[i] - ma) - (b[i] - mb)));
  return out;
}

// The real image's quantity: the formula (the LUT, the noise subtracted or not).
std::string RealFormula(const ProductSimulation& sim, const std::string& quantity, bool noise_removal) {
  std::string real_formula = "|s|^2 of the RSLC (beta0)";
  if (sim.sentinel1) {
    const std::string lut = quantity == "sigma0" ? "sigmaNought" : quantity == "gamma0" ? "gamma" : "betaNought";
    real_formula = quantity + (noise_removal ? " = (|DN|^2 - N) / " : " = |DN|^2 / ") + lut +
                   "^2 (the SAFE's calibration LUT, bilinear; " +
                   (noise_removal ? "N the thermal noise power of the noise annotation, noiseRangeLut x "
                                                    "noiseAzimuthLut where it has one, bilinear"
                                  : "no noise removal") +
                   ")";
  }
  return real_formula;
}

// PREFIX.md: the terrain, the quantity compared, the correlation table and
// the geolocation table of the report.
std::string ValidationMarkdown(const ValidateRequest& options, ProductSimulation& sim, const nlohmann::json& report,
                               const std::string& quantity) {
  const int width = sim.image.image.width, height = sim.image.image.height;
  const nlohmann::json& corr = report["correlation"];
  const nlohmann::json& geoloc = report["geolocation"];
  std::ostringstream md;
  md << "# Validation of " << fs::path(options.simulate.product).filename().string() << "\n\n";
  md << "Terrain: " << (options.simulate.scene.empty() ? options.simulate.dem : options.simulate.scene)
     << " (vertical datum: " << sim.frame["vertical_datum"].get<std::string>() << ", source: "
     << sim.frame["vertical_datum_source"].get<std::string>() << "); grid " << height << " lines x " << width
     << " range bins.\n\nCompared in " << quantity << ": real " << report["real_image"].get<std::string>()
     << "; simulated " << report["radiometry"]["simulated"].get<std::string>()
     << ".\n\n## Correlation with the real amplitude\n\n";
  md << "Multilook: k x k non-overlapping blocks; intensity (|SLC|^2, power) averaged for r (intensity) and "
        "r (dB) (10 log10 of the block mean), amplitude averaged for r (amplitude). Peer: simamp block means.\n\n";
  md << "| looks | blocks | r (dB) | r (intensity) | r (amplitude) | peer r (dB) | peer r (intensity) | peer r "
        "(amplitude) |\n|---|---|---|---|---|---|---|---|\n";
  auto cell = [](const nlohmann::json& row, const char* key) {
    return row.contains(key) && !row[key].is_null() ? Fixed(row[key].get<double>(), 3) : std::string("n/a");
  };
  for (const auto& row : corr) {
    md << "| " << row["looks"].get<int>() << "x" << row["looks"].get<int>() << " | " << row["blocks"].get<int64_t>()
       << " | " << cell(row, "r_db") << " | " << cell(row, "r_intensity") << " | " << cell(row, "r_amplitude") << " | "
       << cell(row, "peer_simamp_r_db") << " | " << cell(row, "peer_simamp_r_intensity") << " | "
       << cell(row, "peer_simamp_r_amplitude") << " |\n";
  }
  if (!geoloc.is_null()) {
    md << "\n## Geolocation against " << options.reference_geolocation << "\n\n";
    md << "| quantity | RMS | mean |\n|---|---|---|\n";
    md << "| range (px) | " << Fixed(geoloc["range_px_rms"], 4) << " | " << Fixed(geoloc["range_px_mean"], 4) << " |\n";
    md << "| azimuth (px) | " << Fixed(geoloc["azimuth_px_rms"], 4) << " | " << Fixed(geoloc["azimuth_px_mean"], 4)
       << " |\n";
    md << "| ground (m) | " << Fixed(geoloc["ground_m_rms"], 3) << " | max " << Fixed(geoloc["ground_m_max"], 3)
       << " |\n";
    md << "| height (m) | " << Fixed(geoloc["height_m_rms"], 3) << " | " << Fixed(geoloc["height_m_mean"], 3) << " |\n";
  }
  md << "\nMask pixels: " << report["mask_pixels"].dump() << "\n\nPictures: "
     << fs::path(options.out_prefix + "_side_by_side.png").filename().string() << " ("
     << report["side_by_side"].get<std::string>() << "), "
     << fs::path(options.out_prefix + "_histogram.png").filename().string() << ".\n";
  return md.str();
}

void WriteMarkdown(const fs::path& md_path, const std::string& text) {
  std::ofstream out(md_path);
  out << text;
  out.close();  // a full disk shows when the buffer is flushed
  if (!out) throw WriteError("cannot write report", md_path, errno);
}

}  // namespace

ValidateResult RunValidate(const ValidateRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  Stopwatch total;
  AtomicOutputs outputs;
  const ValidateFiles files = AddValidateFiles(outputs, options);
  const std::unique_ptr<geo::ReferenceGeolocation> reference = ReadPeerGeolocation(options);
  const std::string quantity = image::ToString(image::ParseRadiometry(options.radiometry, "--radiometry"));
  ProductSimulation sim = SimulateLikeTheRealImage(options, quantity, reporter);
  const RealWindow real = ReadRealWindow(sim);
  const render::SarImage& image = sim.image.image;

  nlohmann::json report = ProvenanceHeader("validate", command_line, options.ToJson());
  nlohmann::json inputs = nlohmann::json::array(
      {sim.sentinel1 ? Sentinel1InputRecord(*sim.sentinel1) : InputFileRecord(options.simulate.product),
       InputFileRecord(options.simulate.scene.empty() ? options.simulate.dem : options.simulate.scene)});
  report["product"] = ProductJson(sim);
  report["terrain"] = sim.terrain;
  report["frame"] = sim.frame;
  report["vertical_datum"] = {{"datum", sim.frame["vertical_datum"]}, {"source", sim.frame["vertical_datum_source"]}};
  report["mask_pixels"] = MaskPixelCounts(image.mask);
  report["pixels_geolocated"] = sim.image.geolocated;
  report["correlation"] = CorrelateAtLooks(sim, real, reference.get(), options.looks);
  report["geolocation"] = reference ? CompareGeolocation(sim, *reference, options, inputs) : nlohmann::json(nullptr);
  report["inputs"] = inputs;

  // Pictures: real | simulated, and the histogram of the dB difference after
  // the largest multilook.
  const int kmax = *std::max_element(options.looks.begin(), options.looks.end());
  WriteSideBySide(files.side_by_side, image, real);
  const LevelComparison levels = CompareLevels(image, real, kmax);
  std::vector<int64_t> counts;
  const std::vector<uint8_t> hist = image::HistogramPlot(levels.differences, -15.0, 15.0, 60, 480, 200, &counts);
  geo::WritePng(files.histogram, hist, 480, 200, 1);
  // The radiometric level: real minus simulated, the medians of the k x k
  // block means in dB (the calibration chains and the material model
  // together; 0 for a real image that is the simulation).
  report["level_difference_db"] = {{"looks", kmax},
                                   {"real_minus_simulated_median_db", Number(levels.level_db)},
                                   {"blocks", static_cast<int64_t>(levels.differences.size())}};
  report["difference_histogram"] = {{"looks", kmax},
                                    {"quantity", "simulated dB - real dB, each minus its median"},
                                    {"low_db", -15.0},
                                    {"high_db", 15.0},
                                    {"counts", counts}};
  std::vector<std::string> names;
  for (const fs::path& p : outputs.final_paths()) names.push_back(fs::absolute(p).string());
  report["outputs"] = names;
  // The quantity on both sides: the real image's formula and the
  // simulation's conversion from beta0.
  const std::string real_formula = RealFormula(sim, quantity, options.noise_removal);
  report["radiometry"] = {
      {"quantity", quantity},
      {"noise_removal", options.noise_removal},
      {"real", real_formula},
      {"simulated", quantity == "beta0" ? "beta0 as rendered"
                                        : quantity + " = beta0 x " + (quantity == "sigma0" ? "sin" : "tan") +
                                              "(ellipsoid incidence of each pixel)"}};
  report["real_image"] = real_formula + ", " + (sim.sentinel1 ? sim.sentinel1->annotation.polarization
                                                              : sim.product.polarization);
  report["side_by_side"] = std::string(sim.sentinel1 ? "left: real " + quantity + " dB" : "left: real |HH|^2 dB") + "; middle: simulated dB; right: mask (white none, light grey layover, black shadow, dark grey both)";
  report["timings_s"] = {{"total", total.ElapsedSeconds()}};

  WriteMarkdown(files.md, ValidationMarkdown(options, sim, report, quantity));
  WriteJsonFile(report, files.json);
  outputs.Commit();
  ValidateResult result;
  result.outputs = outputs.final_paths();
  result.report = report;
  return result;
}

}  // namespace gissar::pipeline
