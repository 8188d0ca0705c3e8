// Binds the pipeline's simulations: simulate (a DEM, given as a path or an array, or a scene), simulate_product
// (a real product's radar grid) and sequence (`gissar sequence`: frames at evenly spaced headings).
#include "bindings.h"

#include <array>
#include <cmath>
#include <memory>
#include <optional>

#include "gissar/geo/memory_raster.h"
#include "gissar/material/material.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/simulation_output.h"
#include "gissar/pipeline/views.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/check.h"
#include "gissar/util/progress.h"

namespace gissar::python {

namespace {

// The first `held` bounce layers (pipeline::HeldBounceLayers) as a (layer,
// row, column) array; a layer the render left empty (no return of that
// order) as the writers give it.
py::array_t<float> BounceBands(const render::SarImage& image, bool db, int held) {
  const size_t n = size_t(image.width) * image.height;
  py::array_t<float> bands({held, image.height, image.width});
  std::vector<float> no_return;
  for (int b = 0; b < held; ++b) {
    const std::vector<float>* layer = &image.bounce_layers[b];
    if (layer->empty()) {
      if (no_return.empty()) no_return = pipeline::NoReturnPlane(image, db);
      layer = &no_return;
    }
    GISSAR_CHECK(layer->size() == n);
    std::copy(layer->begin(), layer->end(), bands.mutable_data() + size_t(b) * n);
  }
  return bands;
}

// A SimulateRequest from keyword arguments named like its fields (the keys
// of SimulateRequest::ToJson; docs/conventions.md).
pipeline::SimulateRequest SimulateOptionsFrom(const py::kwargs& kwargs) {
  const nlohmann::json values = JsonOfFields(kwargs);
  pipeline::SimulateRequest o;
  o.ApplyJson(values, "gissar.simulate keyword");
  if (o.out_prefix.empty()) o.out_prefix = "(python)";
  return o;
}

// A DEM given as an array: dem=(H, W) array with transform= (GDAL's six
// coefficients, or an affine.Affine) and crs= (EPSG code, "EPSG:n", WKT or
// an object with to_wkt()), optional nodata=. Returns the in-memory raster
// the request reads (nullptr when dem is a path); the transform/crs/nodata
// keywords are removed from kwargs either way.
std::unique_ptr<geo::MemoryRaster> TakeArrayDem(py::kwargs& kwargs) {
  const py::object transform = TakeKeyword(kwargs, "transform");
  const py::object crs = TakeKeyword(kwargs, "crs");
  const py::object nodata = TakeKeyword(kwargs, "nodata");
  if (!kwargs.contains("dem") || !py::isinstance<py::array>(kwargs["dem"])) {
    if (!transform.is_none() || !crs.is_none()) {
      throw ConfigError("transform and crs go with a DEM given as an array", "gissar keyword 'dem'");
    }
    return nullptr;
  }
  if (transform.is_none() || crs.is_none()) {
    throw ConfigError("a DEM given as an array needs transform= and crs=", "gissar keyword 'dem'");
  }
  // Only real numbers are heights: a bool, complex, text or object array is
  // refused here too (the package's converters refuse it first, naming the
  // parameter; this is the core's own guard for direct callers).
  const char kind = py::array(kwargs["dem"]).dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw InputError("must be an array of real heights, got dtype " +
                         py::str(py::array(kwargs["dem"]).dtype()).cast<std::string>(),
                     "gissar keyword 'dem'");
  }
  const auto heights = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(kwargs["dem"]);
  if (!heights || heights.ndim() != 2) throw ConfigError("must be a 2-D array of heights", "gissar keyword 'dem'");
  std::vector<double> gt;
  if (py::hasattr(transform, "to_gdal")) gt = transform.attr("to_gdal")().cast<std::vector<double>>();
  else gt = transform.cast<std::vector<double>>();
  if (gt.size() != 6) throw ConfigError("needs GDAL's six coefficients", "gissar keyword 'transform'");
  std::string crs_text;
  if (py::hasattr(crs, "to_wkt")) crs_text = crs.attr("to_wkt")().cast<std::string>();
  else crs_text = py::str(crs).cast<std::string>();
  const double nodata_value = nodata.is_none() ? std::nan("") : nodata.cast<double>();
  const int height = static_cast<int>(heights.shape(0)), width = static_cast<int>(heights.shape(1));
  std::vector<float> values(heights.data(), heights.data() + heights.size());
  auto raster = std::make_unique<geo::MemoryRaster>(values, width, height,
                                                    std::array<double, 6>{gt[0], gt[1], gt[2], gt[3], gt[4], gt[5]},
                                                    crs_text, nodata_value, "gissar keyword 'dem'");
  kwargs["dem"] = raster->path();
  return raster;
}

// `gissar simulate` requires --heading and --depression unless --product or
// --orbit fixes the geometry (cli/simulate_command.cc); the keywords alike:
// ConfigError "is required (heading_deg)". None counts as not given.
void RequireKeywords(const py::kwargs& kwargs, const pipeline::SimulateRequest& request,
                     std::initializer_list<const char*> keys) {
  if (request.UsesProductGeometry()) return;
  for (const char* key : keys) {
    if (!kwargs.contains(key) || kwargs[key].is_none()) throw ConfigError("is required", key);
  }
}

// Simulate once the progress keyword and a DEM array are taken off: the request from the keywords, the
// image (and, with out_prefix, the command line's files), the result dict.
py::dict SimulateWith(const py::kwargs& kwargs, PyReporter& reporter) {
  const pipeline::SimulateRequest options = SimulateOptionsFrom(kwargs);
  RequireKeywords(kwargs, options, {"heading_deg", "depression_deg"});
  render::SarImage image;
  // Several channels (polarization="HH,VV" or "quad"): the other channels'
  // images, in the GeoTIFF's band order.
  std::vector<material::Polarization> channels;
  std::vector<render::SarImage> other_channels;
  std::optional<sensor::SarGeometry> geometry;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  // With out_prefix: also the command line's files (GeoTIFF, mask, quicklooks,
  // sidecar, STAC Item), reserved first and written from the same image.
  const bool write_files = options.out_prefix != "(python)";
  std::vector<std::string> written;
  {
    py::gil_scoped_release release;
    options.Check();
    const Stopwatch total;
    std::unique_ptr<pipeline::SimulationOutputs> outputs;
    if (write_files) {
      outputs = std::make_unique<pipeline::SimulationOutputs>();
      pipeline::ReserveSimulationOutputs(options, *outputs);
    }
    pipeline::SimulatedImage simulated = pipeline::SimulateImage(options, reporter);
    geometry = simulated.geometry;
    centre = simulated.terrain.centre_enu;
    channels = simulated.channels;
    if (write_files) {
      image = simulated.image;
      other_channels = simulated.other_channels;
      const pipeline::SimulateResult r =
          pipeline::WriteSimulation(options, simulated, "python: gissar.simulate", *outputs, total);
      for (const auto& p : r.outputs) written.push_back(p.string());
    } else {
      image = std::move(simulated.image);
      other_channels = std::move(simulated.other_channels);
    }
  }
  std::vector<const render::SarImage*> images = {&image};
  for (const render::SarImage& c : other_channels) images.push_back(&c);
  const int held = pipeline::HeldBounceLayers(images);  // as PREFIX.tif holds them
  py::array_t<float> bands = BounceBands(image, options.db, held);
  py::array_t<bool> layover({image.height, image.width}), shadow({image.height, image.width});
  for (size_t i = 0; i < image.mask.size(); ++i) {
    const bool inside = image.mask[i] != render::kMaskOutside;
    layover.mutable_data()[i] = inside && (image.mask[i] & 1) != 0;
    shadow.mutable_data()[i] = inside && (image.mask[i] & 2) != 0;
  }
  py::dict out;
  out["image"] = Image(image.intensity, image.height, image.width);
  out["bounces"] = bands;
  out["mask"] = Image(image.mask, image.height, image.width);
  out["layover"] = layover;
  out["shadow"] = shadow;
  out["geometry"] = py::cast(*geometry);
  out["metadata"] = geometry->ToMetadata();
  out["centre_enu_m"] = std::array<double, 3>{centre.x(), centre.y(), centre.z()};
  out["options"] = JsonToPython(options.ToJson());
  if (write_files) out["outputs"] = written;
  if (!other_channels.empty()) {
    // The GeoTIFF's bands: each channel's total, then each channel's bounce
    // counts, with their names.
    const size_t n = size_t(image.width) * image.height;
    const size_t count = channels.size() * (1 + size_t(held));
    py::array_t<float> all({py::ssize_t(count), py::ssize_t(image.height), py::ssize_t(image.width)});
    size_t band = 0;
    for (size_t k = 0; k < images.size(); ++k, ++band) {
      GISSAR_CHECK(images[k]->intensity.size() == n);
      std::copy(images[k]->intensity.begin(), images[k]->intensity.end(), all.mutable_data() + band * n);
    }
    for (size_t k = 0; k < images.size(); ++k) {
      const py::array_t<float> layers = BounceBands(*images[k], options.db, held);
      std::copy(layers.data(), layers.data() + size_t(held) * n, all.mutable_data() + band * n);
      band += size_t(held);
    }
    out["channel_bands"] = all;
    out["band_names"] = pipeline::ImageBandNames(channels, images.size(), held);
  }
  return out;
}

py::dict SimulateProduct(const std::string& product, py::kwargs kwargs) {
  PyReporter reporter(TakeProgress(kwargs));
  pipeline::SimulateRequest options = SimulateOptionsFrom(kwargs);
  options.product = product;
  pipeline::ProductSimulation sim;
  {
    py::gil_scoped_release release;
    options.Check();
    sim = pipeline::SimulateProduct(options, /*read_amplitude=*/true, reporter);
  }
  // As the CLI writes it: NaN (mask 255) where a pixel has no ground point.
  render::SarImage image = sim.image.image;
  if (image.footprint.size() == image.intensity.size()) pipeline::MarkOutsideFootprint(image, sim.image.image.footprint);
  const int h = image.height, w = image.width;
  py::array_t<float> bands = BounceBands(image, options.db, pipeline::HeldBounceLayers(image, sim.other_channels));
  py::dict out;
  out["image"] = Image(image.intensity, h, w);
  out["bounces"] = bands;
  out["mask"] = Image(image.mask, h, w);
  out["lon_deg"] = Image(sim.image.lon_deg, h, w);
  out["lat_deg"] = Image(sim.image.lat_deg, h, w);
  out["height_m"] = Image(sim.image.height_m, h, w);
  if (static_cast<int64_t>(sim.product.amplitude.size()) == int64_t(h) * w) {
    out["real_amplitude"] = Image(sim.product.amplitude, h, w);
  }
  out["zero_doppler_time_s"] = sim.product.zero_doppler_time_s;
  out["slant_range_m"] = sim.product.slant_range_m;
  out["wavelength_m"] = sim.product.wavelength_m;
  out["look_side"] = sensor::ToString(sensor::LookSideOf(sim.product.look_left));
  out["options"] = JsonToPython(options.ToJson());
  return out;
}

}  // namespace

// gissar._core.simulate; a DEM array (TakeArrayDem) is "the `dem` array" in
// its warnings and errors.
py::dict Simulate(py::kwargs kwargs) {
  PyReporter reporter(TakeProgress(kwargs));
  const std::unique_ptr<geo::MemoryRaster> array_dem = TakeArrayDem(kwargs);
  const NamedPath array_dem_name(array_dem ? array_dem->path() : "", "the `dem` array");
  try {
    return SimulateWith(kwargs, reporter);
  } catch (const Error&) {
    RethrowWithUserPaths();
  }
}

void BindPipelineSimulate(py::module_& m) {
  m.def("simulate", &Simulate,
        "Simulate a SAR image. Keywords = SimulateRequest fields: dem or scene, heading_deg, depression_deg, "
        "slant_range_m, range_spacing_m, azimuth_spacing_m (m), mode, look_side, width, height, rays_per_cell, "
        "bounces, coherent, wavelength_m, range_resolution_m, azimuth_resolution_m, psf_window, speckle_looks, "
        "nesz_db, seed, fill_nodata, center_lonlat, center_map (the keys of the sidecar's options; "
        "docs/conventions.md); dem may be a (H, W) NumPy array of heights with transform= (GDAL's six "
        "coefficients or affine.Affine) and crs= (EPSG code, WKT or pyproj CRS); progress=callable(stage, done, total) gets the tracing progress (return False "
        "to stop: gissar.Cancelled); information lines go to the 'gissar' logger. Returns {'image': (H, W) float32 linear "
        "intensity, 'bounces': (4, H, W) single/double/triple/>=4, 'mask': (H, W) uint8 (1 layover, 2 shadow, 3 both, 255 outside the imaged footprint where the images are NaN), "
        "'geometry': metadata, 'options': the options}. Identical to `gissar simulate`'s GeoTIFF.");

  m.def("simulate_product", &SimulateProduct, py::arg("product"),
        "Simulate a real product's radar grid (NISAR RSLC HDF5, e.g. the UAVSAR chips): keywords as for "
        "simulate (dem or scene, fill_nodata, dem_oversample, vertical_datum ''|'ellipsoid'|'egm96'|'egm2008'|'EPSG:n', rays_per_cell, "
        "bounces, seed, ...; no heading/depression/spacings: the product fixes them). Returns {'image': (rows, "
        "cols) float32 linear intensity on the product grid (rows = zero-Doppler lines, cols = slant-range bins), "
        "'bounces': (4, rows, cols), 'mask': uint8, 'lon_deg'/'lat_deg'/'height_m': per-pixel ground point "
        "(WGS84 degrees, ellipsoidal m; NaN where none), 'real_amplitude': |SLC|, 'zero_doppler_time_s', "
        "'slant_range_m', 'wavelength_m', 'look_side', 'options'}. Same as `gissar simulate --product`.");

  m.def("sequence", [](const std::string& out_prefix, double heading_from_deg, double heading_to_deg, int frames,
                       int frame_delay_cs, py::kwargs kwargs) {
        PyReporter reporter(TakeProgress(kwargs));
        pipeline::SequenceRequest o;
        o.base = SimulateOptionsFrom(kwargs);
        RequireKeywords(kwargs, o.base, {"depression_deg"});  // as `gissar sequence --depression`
        o.base.out_prefix = out_prefix;
        o.heading_from_deg = heading_from_deg;
        o.heading_to_deg = heading_to_deg;
        o.frames = frames;
        o.frame_delay_cs = frame_delay_cs;
        pipeline::SequenceResult r;
        {
          py::gil_scoped_release release;
          o.Check();
          r = pipeline::RunSequence(o, "python: gissar.sequence", reporter);
        }
        std::vector<std::string> paths;
        for (const auto& p : r.outputs) paths.push_back(p.string());
        return paths;
      }, py::arg("out_prefix"), py::arg("heading_from_deg"), py::arg("heading_to_deg"), py::arg("frames") = 7,
      py::arg("frame_delay_cs") = 50,
      "`gissar sequence`: frames at evenly spaced headings (degrees) around the scene centre, one dB stretch: "
      "PREFIX_fNN.tif/.png, PREFIX_contact.png, PREFIX.gif (animated), PREFIX.json. Other keywords as "
      "gissar.simulate. Returns the written paths.");
}

}  // namespace gissar::python
