// Python bindings: `import gissar` (pybind11, NumPy arrays in and out).
// Options are passed as keyword arguments named exactly like the fields of
// the C++ options structs (the single source of truth shared with the CLI);
// an unknown keyword is a gissar.ConfigError naming it. Library errors become
// gissar.InputError / ConfigError / IoError (subclasses of gissar.Error)
// with the same message. Heavy work runs without the GIL.
#include <atomic>
#include <cctype>
#include <map>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>

#include <pybind11/eval.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "gissar/pipeline/evaluate_fields.h"
#include "gissar/pipeline/geocode.h"
#include "gissar/pipeline/geocode_fields.h"
#include "gissar/util/check.h"
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_fields.h"
#include "gissar/pipeline/polsar.h"
#include "gissar/pipeline/pta.h"
#include "gissar/pipeline/pta_fields.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/scene_build_fields.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/pipeline/simulate_fields.h"
#include "gissar/pipeline/views.h"
#include "gissar/geo/memory_raster.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/geo/raster_io.h"
#include "gissar/geo/rslc_product.h"
#include "gissar/geo/sentinel1_measurement.h"
#include "gissar/image/annotated.h"
#include "gissar/image/class_map.h"
#include "gissar/pipeline/product_simulate.h"
#include "gissar/image/composite.h"
#include "gissar/image/contact_sheet.h"
#include "gissar/image/epipolar_plot.h"
#include "gissar/image/gif_writer.h"
#include "gissar/image/mesh_view.h"
#include "gissar/image/quicklook.h"
#include "gissar/mvg/affine_fundamental.h"
#include "gissar/mvg/kvd.h"
#include "gissar/nav/locate.h"
#include "gissar/nav/matching.h"
#include "gissar/render/raster_renderer.h"
#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/registration.h"
#include "gissar/mvg/resection.h"
#include "gissar/mvg/two_view.h"
#include "gissar/render/embree_scene.h"
#include "gissar/material/material.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/util/atomic_output.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/reporter.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"
#include "gissar/util/utc_time.h"
#include "gissar/util/progress.h"
#include "gissar/util/provenance.h"

#include <opencv2/imgproc.hpp>

namespace py = pybind11;
using namespace gissar;

namespace {

py::object JsonToPython(const nlohmann::json& j) {
  return py::module_::import("json").attr("loads")(j.dump());
}

template <typename T>
py::array_t<T> Image(const std::vector<T>& values, int height, int width) {
  py::array_t<T> out({height, width});
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

// The bounce layers as a (layer, row, column) array; a layer the render left
// empty (no return of that order) as the writers give it.
py::array_t<float> BounceBands(const render::SarImage& image, bool db) {
  const size_t n = size_t(image.width) * image.height;
  py::array_t<float> bands({render::kBounceLayers, image.height, image.width});
  std::vector<float> no_return;
  for (int b = 0; b < render::kBounceLayers; ++b) {
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

// The (M, 3) vertex indices of every triangle of `mesh` (an implicit grid's
// included).
py::array_t<int32_t> TriangleIndices(const scene::TriangleMesh& mesh) {
  py::array_t<int32_t> t({py::ssize_t(mesh.triangle_count()), py::ssize_t(3)});
  int32_t* out = t.mutable_data();
  for (size_t k = 0; k < mesh.triangle_count(); ++k) {
    const Eigen::Vector3i tri = mesh.Triangle(k);
    std::copy(tri.data(), tri.data() + 3, out + 3 * k);
  }
  return t;
}

// Keyword arguments as JSON values (str, bool, int, float, None, and
// sequences of those), for the pipeline's ApplyJson.
nlohmann::json JsonOf(const py::handle& value, const std::string& key) {
  if (value.is_none()) return nullptr;
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
  if (py::isinstance<py::int_>(value)) return value.cast<int64_t>();
  if (py::isinstance<py::float_>(value)) return value.cast<double>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::hasattr(value, "__fspath__")) return py::str(value.attr("__fspath__")()).cast<std::string>();
  if (py::isinstance<py::sequence>(value)) {
    nlohmann::json list = nlohmann::json::array();
    for (const py::handle item : value.cast<py::sequence>()) list.push_back(JsonOf(item, key));
    return list;
  }
  if (py::hasattr(value, "item")) return JsonOf(value.attr("item")(), key);  // NumPy scalars
  throw ConfigError("keyword '" + key + "' has an unsupported type", "gissar");
}

// {key: value} of a dict of request fields (or keyword arguments).
nlohmann::json JsonOfFields(const py::dict& fields) {
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [key_handle, value] : fields) {
    const std::string key = key_handle.cast<std::string>();
    values[key] = JsonOf(value, key);
  }
  return values;
}

// The rows of a request's field table (pipeline/request_fields.h), in its
// order: {name, flag, help, default, show_default} per field, the default
// that of a request R().
template <class R>
py::list FieldRows(const pipeline::FieldTable<R>& table) {
  py::list fields;
  const R defaults;
  for (const auto& field : table.fields()) {
    py::dict d;
    d["name"] = field.name;
    d["flag"] = field.Flag();
    d["help"] = field.help;
    d["default"] = JsonToPython(field.get(defaults));
    d["show_default"] = field.show_default;
    fields.append(d);
  }
  return fields;
}

// The field table of `command` as FieldRows: "simulate", "evaluate",
// "locate", "geocode" or "scene_build"; ConfigError naming the argument for
// another name.
py::list RequestFieldRows(const std::string& command) {
  if (command == "simulate") return FieldRows(pipeline::SimulateFields());
  if (command == "evaluate") return FieldRows(pipeline::EvaluateFields());
  if (command == "locate") return FieldRows(pipeline::LocateFields());
  if (command == "geocode") return FieldRows(pipeline::GeocodeFields());
  if (command == "scene_build") return FieldRows(pipeline::SceneBuildFields());
  if (command == "pta") return FieldRows(pipeline::PtaFields());
  throw ConfigError("unknown request '" + command + "': must be simulate, evaluate, locate, geocode, scene_build or pta",
                    "gissar.request_fields: command");
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

// An EvaluateRequest from a dict of its fields (EvaluateRequest::ToJson keys).
pipeline::EvaluateRequest EvaluateOptionsFrom(const py::dict& values, const std::string& where) {
  pipeline::EvaluateRequest o;
  o.ApplyJson(JsonOfFields(values), where);
  if (o.out_prefix.empty() && o.product.empty()) o.out_prefix = "(python)";
  return o;
}

// Trial records from Python (dicts, as evaluate_trials returns them).
std::vector<nlohmann::json> RecordsFrom(const py::iterable& records) {
  std::vector<nlohmann::json> out;
  const py::object dumps = py::module_::import("json").attr("dumps");
  for (const py::handle r : records) out.push_back(nlohmann::json::parse(dumps(r).cast<std::string>()));
  return out;
}

// A float image (H, W) from a NumPy array (any real dtype, C order after
// conversion); `what` names the argument in errors. No-data (NaN, e.g.
// outside a simulation's footprint) counts as no return: 0, as the file
// readers of locate and matchpair do.
struct FloatImage {
  std::vector<float> values;
  int width = 0, height = 0;
};
FloatImage ToFloatImage(const py::array_t<float, py::array::c_style | py::array::forcecast>& a,
                        const std::string& what) {
  if (a.ndim() != 2 || a.shape(0) < 1 || a.shape(1) < 1) {
    throw InputError("must be a non-empty 2-D array (rows = azimuth, columns = range)", what);
  }
  FloatImage out;
  out.height = static_cast<int>(a.shape(0));
  out.width = static_cast<int>(a.shape(1));
  out.values.assign(a.data(), a.data() + a.size());
  for (float& v : out.values) if (std::isnan(v)) v = 0.0f;
  return out;
}

py::array_t<uint8_t> RgbArray(const image::RgbImage& img) {
  py::array_t<uint8_t> out({img.height, img.width, 3});
  std::copy(img.rgb.begin(), img.rgb.end(), out.mutable_data());
  return out;
}

// What the user gave for each in-memory raster a call reads through a GDAL
// virtual path (/vsimem/gissar_*.tif, a DEM given as an array, DataArray or
// dataset): "the `dem` array". Named by gissar._adapt (and TakeArrayDem) for
// the duration of the call; messages and warnings say it instead of the path.
std::mutex path_names_mutex;
std::map<std::string, std::string>& PathNames() {
  static std::map<std::string, std::string> names;
  return names;
}

// Registers (description non-empty) or forgets the description of `path`.
void NamePath(const std::string& path, const std::string& description) {
  if (path.empty()) return;
  const std::lock_guard<std::mutex> lock(path_names_mutex);
  if (description.empty()) PathNames().erase(path);
  else PathNames()[path] = description;
}

// `text` with every registered virtual path replaced by its description.
std::string UserPaths(std::string text) {
  const std::lock_guard<std::mutex> lock(path_names_mutex);
  for (const auto& [path, description] : PathNames()) {
    for (size_t at = text.find(path); at != std::string::npos; at = text.find(path, at + description.size())) {
      text.replace(at, path.size(), description);
    }
  }
  return text;
}

// A path named for the lifetime of this object.
class NamedPath {
 public:
  NamedPath(std::string path, const std::string& description) : path_(std::move(path)) {
    NamePath(path_, description);
  }
  ~NamedPath() { NamePath(path_, ""); }
  NamedPath(const NamedPath&) = delete;
  NamedPath& operator=(const NamedPath&) = delete;

 private:
  std::string path_;
};

// Rethrows the Error being handled with UserPaths applied to its message and
// context (same class), while its virtual paths are still named; call in a
// catch block.
[[noreturn]] void RethrowWithUserPaths() {
  try {
    throw;
  } catch (const CancelledError&) {
    throw;
  } catch (const InputError& e) {
    throw InputError(UserPaths(e.message()), UserPaths(e.where()));
  } catch (const ConfigError& e) {
    throw ConfigError(UserPaths(e.message()), UserPaths(e.where()));
  } catch (const IoError& e) {
    throw IoError(UserPaths(e.message()), UserPaths(e.where()));
  } catch (const Error& e) {
    throw Error(UserPaths(e.message()), UserPaths(e.where()));
  }
}

// `text` with every command-line flag of a request field ("--heading",
// "--range-spacing/--azimuth-spacing", "give --vertical-datum ...") replaced
// by the Python parameter of the same field ("heading_deg"), and every
// in-memory raster's virtual path by what the user gave (UserPaths).
std::string PythonNames(const std::string& raw_text) {
  const std::string text = UserPaths(raw_text);
  static const std::map<std::string, std::string> parameter_of_flag = [] {
    std::map<std::string, std::string> m;
    const nlohmann::json fields = pipeline::SimulateRequest().ToJson();
    for (const auto& [key, value] : fields.items()) {
      m[pipeline::FlagOfField(key)] = key;
    }
    return m;
  }();
  std::string out;
  size_t i = 0;
  while (i < text.size()) {
    const size_t start = text.find("--", i);
    if (start == std::string::npos) {
      out += text.substr(i);
      break;
    }
    size_t end = start + 2;
    while (end < text.size() && (std::isalnum(static_cast<unsigned char>(text[end])) || text[end] == '-')) ++end;
    out += text.substr(i, start - i);
    const std::string flag = text.substr(start, end - start);
    const auto it = parameter_of_flag.find(flag);
    out += it != parameter_of_flag.end() ? it->second : flag;
    i = end;
  }
  return out;
}

// An error's text for Python: "<what> (<where>)" with Python parameter names.
std::string PythonMessage(const Error& e) {
  const std::string where = e.where();
  const std::string message = PythonNames(e.message());
  return where.empty() ? message : message + " (" + PythonNames(where) + ")";
}

// The Python door's Reporter (util/reporter.h): warnings become Python
// warnings of category gissar.GissarWarning, information lines go to the
// "gissar" logger, stage progress to the optional `progress(stage, done,
// total)` callable; a callback returning False stops the run, which then
// raises gissar.Cancelled. Built and destroyed with the GIL held; its
// methods take the GIL themselves (StageProgress runs on worker threads).
class PyReporter : public Reporter {
 public:
  explicit PyReporter(py::object progress) : progress_(std::move(progress)) {}
  void StageProgress(const std::string& stage, int64_t done, int64_t total) override {
    if (progress_.is_none() || cancelled_.load()) return;
    py::gil_scoped_acquire gil;
    try {
      const py::object answer = progress_(stage, done, total);
      if (!answer.is_none() && !answer.cast<bool>()) cancelled_ = true;
    } catch (py::error_already_set& e) {
      cancelled_ = true;  // the callback failed: stop, and say why
      e.discard_as_unraisable("gissar progress callback");
    }
  }
  void Info(const std::string& line) override {
    py::gil_scoped_acquire gil;
    py::module_::import("logging").attr("getLogger")("gissar").attr("info")(UserPaths(line));
  }
  void Warn(const std::string& line) override {
    py::gil_scoped_acquire gil;
    // gissar._adapt.run calls the core on a worker thread and gives its progress hook a list,
    // `_gissar_warnings`: the texts go there and the calling thread issues them as warnings (the warnings
    // module's state is process-wide, so capturing it per thread would break concurrent calls).
    if (!progress_.is_none() && py::hasattr(progress_, "_gissar_warnings")) {
      progress_.attr("_gissar_warnings").attr("append")(PythonNames(line));
      return;
    }
    if (PyErr_WarnEx(WarningType(), PythonNames(line).c_str(), 1) != 0) {
      // Warnings turned into errors (-W error): stop the run with it.
      cancelled_ = true;
      PyErr_Clear();
    }
  }
  bool CancelRequested() const override { return cancelled_.load(); }

  static PyObject*& WarningType() {
    static PyObject* type = PyExc_UserWarning;
    return type;
  }

 private:
  py::object progress_;
  std::atomic<bool> cancelled_{false};
};

// Removes the `progress` keyword (not a request field) from `kwargs`.
py::object TakeProgress(py::kwargs& kwargs) {
  if (!kwargs.contains("progress")) return py::none();
  py::object progress = kwargs["progress"];
  PyDict_DelItemString(kwargs.ptr(), "progress");
  if (!progress.is_none() && !PyCallable_Check(progress.ptr())) {
    throw ConfigError("progress must be a callable(stage, done, total) or None", "gissar keyword 'progress'");
  }
  return progress;
}

// Pops keyword `key` from `kwargs` (None when absent).
py::object TakeKeyword(py::kwargs& kwargs, const char* key) {
  if (!kwargs.contains(key)) return py::none();
  py::object value = kwargs[key];
  PyDict_DelItemString(kwargs.ptr(), key);
  return value;
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

py::dict SimulateWith(const py::kwargs& kwargs, PyReporter& reporter);

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
  py::array_t<float> bands = BounceBands(image, options.db);
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
    const size_t count = channels.size() * (1 + render::kBounceLayers);
    py::array_t<float> all({py::ssize_t(count), py::ssize_t(image.height), py::ssize_t(image.width)});
    std::vector<std::string> names;
    const char* layer_names[render::kBounceLayers] = {"single", "double", "triple", "four_or_more"};
    std::vector<const render::SarImage*> images = {&image};
    for (const render::SarImage& c : other_channels) images.push_back(&c);
    size_t band = 0;
    for (size_t k = 0; k < images.size(); ++k, ++band) {
      GISSAR_CHECK(images[k]->intensity.size() == n);
      std::copy(images[k]->intensity.begin(), images[k]->intensity.end(), all.mutable_data() + band * n);
      names.push_back(material::ToString(channels[k]));
    }
    for (size_t k = 0; k < images.size(); ++k) {
      const py::array_t<float> layers = BounceBands(*images[k], options.db);
      std::copy(layers.data(), layers.data() + render::kBounceLayers * n, all.mutable_data() + band * n);
      band += render::kBounceLayers;
      for (const char* layer : layer_names) names.push_back(material::ToString(channels[k]) + "_" + layer);
    }
    out["channel_bands"] = all;
    out["band_names"] = names;
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
  py::array_t<float> bands = BounceBands(image, options.db);
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

// A renamed keyword: DeprecationWarning naming the new one (docs/conventions.md:
// old spellings keep working for one release). Raises when warnings are errors.
void WarnDeprecatedKeyword(const std::string& old_keyword, const std::string& replacement) {
  const std::string message = old_keyword + " is deprecated and will be removed; use " + replacement;
  if (PyErr_WarnEx(PyExc_DeprecationWarning, message.c_str(), 1) != 0) throw py::error_already_set();
}

py::array_t<double> Project(const sensor::SarGeometry& g, const py::array_t<double, py::array::c_style>& points) {
  if (points.ndim() != 2 || points.shape(1) != 3) throw InputError("points must be an (N, 3) array", "project");
  py::array_t<double> out({points.shape(0), py::ssize_t(2)});
  for (py::ssize_t i = 0; i < points.shape(0); ++i) {
    const Eigen::Vector2d p = g.Project({points.at(i, 0), points.at(i, 1), points.at(i, 2)});
    out.mutable_at(i, 0) = p.x();
    out.mutable_at(i, 1) = p.y();
  }
  return out;
}

std::vector<mvg::PointMatch> Matches(const py::array_t<double, py::array::c_style>& x1,
                                     const py::array_t<double, py::array::c_style>& x2) {
  if (x1.ndim() != 2 || x1.shape(1) != 2 || x2.ndim() != 2 || x2.shape(1) != 2 || x1.shape(0) != x2.shape(0)) {
    throw InputError("x1 and x2 must be (N, 2) arrays of the same N", "matches");
  }
  std::vector<mvg::PointMatch> m(x1.shape(0));
  for (py::ssize_t i = 0; i < x1.shape(0); ++i) {
    m[i].p1 = {x1.at(i, 0), x1.at(i, 1)};
    m[i].p2 = {x2.at(i, 0), x2.at(i, 1)};
  }
  return m;
}

py::array_t<double> Mat(const Eigen::MatrixXd& m) {
  py::array_t<double> out({m.rows(), m.cols()});
  for (int r = 0; r < m.rows(); ++r)
    for (int c = 0; c < m.cols(); ++c) out.mutable_at(r, c) = m(r, c);
  return out;
}

// ---------------------------------------------------------------- scenes

// A scene built by `gissar scene build` (a .gscene file) held in memory.
struct PyScene {
  std::string path;
  scene::SceneFile file;
  py::object summary = py::none();  // the build summary when built here
  std::string sha256;               // of the file, computed when first pickled
};

// SHA-256 (hex) of a file's contents (Python's hashlib).
std::string FileSha256(const std::string& path) {
  py::object h = py::module_::import("hashlib").attr("sha256")();
  py::object f = py::module_::import("builtins").attr("open")(path, "rb");
  while (true) {
    py::bytes chunk = f.attr("read")(1 << 22);
    if (PyBytes_Size(chunk.ptr()) == 0) break;
    h.attr("update")(chunk);
  }
  f.attr("close")();
  return h.attr("hexdigest")().cast<std::string>();
}

PyScene LoadPyScene(const std::string& path) {
  PyScene s;
  s.path = path;
  {
    py::gil_scoped_release release;
    s.file = scene::ReadScene(path);
  }
  return s;
}

// `gissar scene build` of the request's fields `options` (SceneBuildRequest
// ToJson keys, read by its table: an unknown key names itself and `source`).
PyScene BuildPyScene(const py::dict& options, py::object progress, const std::string& source) {
  pipeline::SceneBuildRequest o;
  o.ApplyJson(JsonOfFields(options), source);
  pipeline::SceneBuildResult r;
  if (!progress.is_none() && !PyCallable_Check(progress.ptr())) {
    throw ConfigError("progress must be a callable(stage, done, total) or None", "gissar keyword 'progress'");
  }
  PyReporter reporter{progress};
  {
    py::gil_scoped_release release;
    r = pipeline::RunSceneBuild(o, "python: gissar.Scene.build", reporter);
  }
  PyScene s = LoadPyScene(o.out_prefix + ".gscene");
  s.summary = JsonToPython(r.summary);
  return s;
}

image::MeshViewOptions MeshViewOptionsFrom(const py::kwargs& kwargs) {
  image::MeshViewOptions o;
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = key_handle.cast<std::string>();
    if (key == "view_azimuth_deg") o.view_azimuth_deg = value.cast<double>();
    else if (key == "view_elevation_deg") o.view_elevation_deg = value.cast<double>();
    else if (key == "vertical_exaggeration") o.vertical_exaggeration = value.cast<double>();
    else if (key == "field_of_view_deg") o.field_of_view_deg = value.cast<double>();
    else if (key == "sun_azimuth_deg") o.sun_azimuth_deg = value.cast<double>();
    else if (key == "sun_elevation_deg") o.sun_elevation_deg = value.cast<double>();
    else if (key == "width") o.width = value.cast<int>();
    else if (key == "height") o.height = value.cast<int>();
    else {
      const std::string closest = pipeline::ClosestKey(
          key, {"view_azimuth_deg", "view_elevation_deg", "vertical_exaggeration", "field_of_view_deg",
                "sun_azimuth_deg", "sun_elevation_deg", "width", "height"});
      throw ConfigError("unknown option '" + key + "'" + (closest.empty() ? "" : "; did you mean " + closest + "?"),
                        "gissar.Scene.view_3d");
    }
  }
  return o;
}

// ---------------------------------------------------------------- pictures

void WritePngArray(const std::string& path, const py::array_t<uint8_t, py::array::c_style | py::array::forcecast>& a) {
  int channels = 1;
  if (a.ndim() == 3 && (a.shape(2) == 3 || a.shape(2) == 4)) channels = static_cast<int>(a.shape(2));
  else if (a.ndim() != 2) throw InputError("expected (H, W) grey or (H, W, 3|4) RGB(A) uint8", path);
  if (a.shape(0) < 1 || a.shape(1) < 1) throw InputError("empty image", path);
  const std::vector<uint8_t> data(a.data(), a.data() + a.size());
  const int width = static_cast<int>(a.shape(1)), height = static_cast<int>(a.shape(0));
  py::gil_scoped_release release;
  AtomicOutputs outputs;
  geo::WritePng(outputs.Add(path), data, width, height, channels);
  outputs.Commit();
}

void WriteGifFrames(const std::string& path, const std::vector<py::array_t<uint8_t, py::array::c_style | py::array::forcecast>>& frames,
                    int delay_cs) {
  if (frames.empty()) throw InputError("no frames", path);
  if (delay_cs < 1) throw ConfigError("must be >= 1", "delay_cs");
  const py::ssize_t h = frames[0].ndim() == 2 ? frames[0].shape(0) : 0, w = frames[0].ndim() == 2 ? frames[0].shape(1) : 0;
  std::vector<std::vector<uint8_t>> grey;
  for (const auto& f : frames) {
    if (f.ndim() != 2 || f.shape(0) != h || f.shape(1) != w || h < 1 || w < 1) {
      throw InputError("frames must be 2-D uint8 arrays of one size", path);
    }
    grey.emplace_back(f.data(), f.data() + f.size());
  }
  py::gil_scoped_release release;
  AtomicOutputs outputs;
  image::WriteAnimatedGif(outputs.Add(path), grey, static_cast<int>(w), static_cast<int>(h), delay_cs);
  outputs.Commit();
}

// ---------------------------------------------------------------- navigation

py::dict PoseDict(const nav::NavPose& pose, sensor::LookSide side) {
  const Eigen::Vector3d s = pose.SensorPosition(side);
  return py::dict(py::arg("heading_deg") = pose.heading_deg, py::arg("depression_deg") = pose.depression_deg,
                  py::arg("slant_range_m") = pose.slant_range_m,
                  py::arg("centre_enu_m") = std::array<double, 3>{pose.centre_enu.x(), pose.centre_enu.y(), pose.centre_enu.z()},
                  py::arg("sensor_enu_m") = std::array<double, 3>{s.x(), s.y(), s.z()});
}

py::dict Locate(const PyScene& scene, const py::array_t<float, py::array::c_style | py::array::forcecast>& observed_image,
                const py::dict& prior_dict, double range_spacing_m, double azimuth_spacing_m,
                const std::string& look_side, const std::string& matcher, int search_px, int step_px,
                int dense_renders, int polish_evaluations, int bounces, double rays_per_cell, bool references) {
  const FloatImage observed = ToFloatImage(observed_image, "gissar.locate: image");
  const nlohmann::json prior_json = nlohmann::json::parse(py::module_::import("json").attr("dumps")(prior_dict).cast<std::string>());
  const pipeline::PriorPose prior = pipeline::ParsePriorJson(prior_json, "gissar.locate: prior");
  nav::SensorModel model;
  model.width = observed.width;
  model.height = observed.height;
  model.range_spacing_m = range_spacing_m;
  model.azimuth_spacing_m = azimuth_spacing_m;
  model.look_side = sensor::ParseLookSide(look_side);
  model.Check();
  nav::LocateOptions lo;
  lo.matcher = nav::ParseMatcher(matcher, "matcher");
  lo.initial_search_px = search_px;
  lo.step_px = step_px;
  lo.dense_renders = dense_renders;
  lo.polish_evaluations = polish_evaluations;
  lo.Check();
  if (bounces < 1 || bounces > 16) throw ConfigError("must be in [1, 16]", "bounces");
  if (!(rays_per_cell > 0)) throw ConfigError("must be > 0", "rays_per_cell");
  std::vector<float> values = observed.values;
  for (float& v : values) if (!std::isfinite(v)) v = 0.0f;
  nav::LocateResult r;
  nav::NavPose start;
  std::vector<float> at_prior, at_fix;
  {
    py::gil_scoped_release release;
    const render::EmbreeScene embree(scene.file.mesh);
    const material::MaterialTable materials = material::SceneMaterials(scene.file.materials, scene.path);
    nav::NavScene ns{&scene.file.mesh, &embree, &materials, rays_per_cell, bounces};
    std::optional<nav::NavPose> s;
    if (prior.sensor_enu) {
      s = nav::PoseFromSensor(ns, *prior.sensor_enu, prior.heading_deg, prior.slant_range_m,
                              prior.depression_deg.value_or(40.0), model.look_side);
    } else {
      Eigen::Vector3d c = prior.centre_enu.value_or(Eigen::Vector3d::Zero());
      if (prior.centre_lonlat) {
        const geo::LocalFrame frame(scene.file.origin_lon_deg, scene.file.origin_lat_deg, 0.0);
        c = frame.EnuFromGeodetic(prior.centre_lonlat->x(), prior.centre_lonlat->y(), 0.0);
      }
      const auto ground = nav::SurfaceBelow(embree, scene.file.mesh, c.x(), c.y());
      if (ground) s = nav::NavPose{prior.heading_deg, *prior.depression_deg, prior.slant_range_m, *ground};
    }
    if (!s) throw InputError("the prior's line of sight does not reach the scene", "gissar.locate: prior");
    start = *s;
    r = nav::Locate(ns, model, values, start, lo);
    if (references) {
      at_prior = nav::RenderReference(ns, start, model).intensity;
      at_fix = nav::RenderReference(ns, r.pose, model).intensity;
    }
  }
  py::dict out;
  out["pose"] = PoseDict(r.pose, model.look_side);
  out["prior"] = PoseDict(start, model.look_side);
  out["converged"] = r.converged;
  out["iterations"] = r.iterations;
  out["renders"] = r.renders;
  out["matches"] = r.matches;
  out["inliers"] = r.inliers;
  out["rms_px"] = r.rms_px;
  out["dense_renders"] = r.dense_renders;
  out["dense_rms_db"] = r.dense_rms_db;
  out["similarity_ncc"] = r.similarity;
  out["prior_similarity_ncc"] = r.prior_similarity;
  out["heading_sigma_deg"] = r.heading_sigma_deg;
  out["depression_sigma_deg"] = r.depression_sigma_deg;
  out["position_sigma_lhn_m"] = std::array<double, 3>{r.position_sigma_lhn_m.x(), r.position_sigma_lhn_m.y(),
                                                      r.position_sigma_lhn_m.z()};
  out["seconds"] = r.seconds;
  if (references) {
    out["reference_at_prior"] = Image(at_prior, model.height, model.width);
    out["reference_at_fix"] = Image(at_fix, model.height, model.width);
  }
  return out;
}

py::dict MatchImages(const py::array_t<float, py::array::c_style | py::array::forcecast>& reference_image,
                     const py::array_t<float, py::array::c_style | py::array::forcecast>& observed_image,
                     const std::string& matcher, int patch_px, int step_px, int search_px, int filter_px,
                     double min_score, std::optional<py::array_t<double, py::array::c_style | py::array::forcecast>> warp) {
  const FloatImage ref = ToFloatImage(reference_image, "gissar.match_images: reference");
  const FloatImage obs = ToFloatImage(observed_image, "gissar.match_images: observed");
  nav::MatchOptions mo;
  mo.patch_px = patch_px;
  mo.step_px = step_px;
  mo.search_px = search_px;
  mo.min_score = min_score;
  mo.Check();
  if (filter_px < 1) throw ConfigError("must be >= 1", "filter_px");
  const nav::Matcher which = nav::ParseMatcher(matcher, "matcher");
  cv::Mat a = cv::Mat::eye(2, 3, CV_64F);  // reference pixel -> observed pixel
  if (warp) {
    if (warp->ndim() != 2 || warp->shape(0) != 2 || warp->shape(1) != 3) {
      throw InputError("warp must be a (2, 3) affine map: reference pixel -> observed pixel", "gissar.match_images");
    }
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 3; ++c) a.at<double>(r, c) = warp->at(r, c);
    if (!cv::checkRange(a) || std::abs(cv::determinant(a(cv::Rect(0, 0, 2, 2)))) < 1e-9) {
      throw InputError("warp is not an invertible finite affine map", "gissar.match_images");
    }
  } else if (ref.width != obs.width || ref.height != obs.height) {
    throw InputError("images differ in size: give the warp that maps the reference onto the observed image",
                     "gissar.match_images");
  }
  std::vector<nav::Correspondence> found;
  {
    py::gil_scoped_release release;
    const cv::Mat obs_mat(obs.height, obs.width, CV_32F, const_cast<float*>(obs.values.data()));
    cv::Mat resampled;  // the observed image on the reference grid
    cv::warpAffine(obs_mat, resampled, a, cv::Size(ref.width, ref.height), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                   cv::BORDER_CONSTANT, cv::Scalar(0));
    const std::vector<float> resampled_values(resampled.begin<float>(), resampled.end<float>());
    const cv::Mat ref_log = nav::LogIntensity(ref.values, ref.width, ref.height, filter_px);
    const cv::Mat obs_log = nav::LogIntensity(resampled_values, ref.width, ref.height, filter_px);
    // Only patches whose warped observed neighbourhood lies inside the observed image.
    cv::Mat inside(ref.height, ref.width, CV_8U);
    const cv::Mat ones(obs.height, obs.width, CV_8U, cv::Scalar(255));
    cv::warpAffine(ones, inside, a, cv::Size(ref.width, ref.height), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                   cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::erode(inside, inside, cv::Mat(), cv::Point(-1, -1), (patch_px + 1) / 2 + search_px);
    found = nav::Match(which, ref_log, obs_log, mo, inside);
  }
  py::array_t<double> x_ref({py::ssize_t(found.size()), py::ssize_t(2)}), x_obs({py::ssize_t(found.size()), py::ssize_t(2)});
  py::array_t<double> score(py::ssize_t(found.size()));
  for (size_t i = 0; i < found.size(); ++i) {
    const Eigen::Vector2d& p = found[i].observed;
    x_ref.mutable_at(i, 0) = found[i].reference.x();
    x_ref.mutable_at(i, 1) = found[i].reference.y();
    x_obs.mutable_at(i, 0) = a.at<double>(0, 0) * p.x() + a.at<double>(0, 1) * p.y() + a.at<double>(0, 2);
    x_obs.mutable_at(i, 1) = a.at<double>(1, 0) * p.x() + a.at<double>(1, 1) * p.y() + a.at<double>(1, 2);
    score.mutable_at(i) = found[i].score;
  }
  return py::dict(py::arg("x_reference") = x_ref, py::arg("x_observed") = x_obs, py::arg("score") = score);
}

// ---------------------------------------------------------------- open_product

// gissar.open_product: one swath/polarisation (optionally one burst) of a
// Sentinel-1 SAFE, or one layer of a NISAR RSLC, opened for reading windows
// (gissar._adapt.ProductArray turns it into a lazy xarray variable). Rows and
// columns are relative to the opened window (a burst's first line is row 0).
class OpenedProduct {
 public:
  OpenedProduct(const std::string& path, const std::optional<std::string>& swath, const std::optional<int>& burst,
                const std::optional<std::string>& polarization, const std::optional<std::string>& radiometry,
                bool noise_removal, const std::optional<std::string>& frequency) {
    try {
      radiometry_ = geo::ParseSentinel1Radiometry(radiometry.value_or(""), "--radiometry");
      if (geo::IsSentinel1Path(path)) {
        if (frequency) throw ConfigError("a Sentinel-1 product has no frequency bands (NISAR only)", "--frequency");
        geo::Sentinel1ImageOptions o;
        o.swath = swath.value_or("");
        o.polarization = polarization.value_or("");
        o.burst = burst.value_or(0);
        if (burst && *burst < 1) throw ConfigError("must be 1 or more (bursts are numbered from 1)", "--burst");
        o.radiometry = radiometry_;
        o.remove_noise = noise_removal;
        s1_ = std::make_shared<const geo::Sentinel1Image>(geo::Sentinel1Image::Open(path, o));
      } else {
        OpenNisar(path, swath, burst, polarization, noise_removal, frequency);
      }
    } catch (const Error& e) {
      RethrowWithParameterNames(e);
    }
  }

  int rows() const { return s1_ ? s1_->window().lines : nisar_->rows(); }
  int cols() const { return s1_ ? s1_->window().samples : nisar_->cols(); }
  bool is_complex() const {
    return radiometry_ == geo::Sentinel1Radiometry::kNone && (!s1_ || s1_->measurement().is_complex());
  }

  py::dict Info() const {
    py::dict info;
    info["rows"] = rows();
    info["cols"] = cols();
    info["dtype"] = is_complex() ? "complex64" : "float32";
    const std::string radiometry = geo::ToString(radiometry_);
    py::dict attrs;
    attrs["look_side"] = sensor::ToString(sensor::LookSideOf(s1_ ? s1_->annotation().look_left : nisar_->look_left));
    attrs["radiometry"] = radiometry;
    std::vector<int64_t> time_ns(static_cast<size_t>(rows()));
    if (s1_) {
      const geo::Sentinel1Image& s = *s1_;
      const geo::Sentinel1Annotation& a = s.annotation();
      const geo::Sentinel1Window& w = s.window();
      const bool grd = a.is_grd();
      const bool swath_of_bursts = !a.bursts.empty() && s.options().burst == 0;
      info["kind"] = "sentinel1";
      info["dims"] = swath_of_bursts ? py::make_tuple("line", "pixel")
                                     : py::make_tuple("azimuth_time", grd ? "ground_range" : "slant_range");
      std::vector<int> lines(size_t(w.lines)), pixels(size_t(w.samples));
      for (int r = 0; r < w.lines; ++r) {
        lines[size_t(r)] = w.first_line + r;
        time_ns[size_t(r)] = NanosecondsOf(s.product().epoch_unix_s, geo::Sentinel1LineTime(a, w.first_line + r));
      }
      std::vector<double> range(size_t(w.samples));
      for (int c = 0; c < w.samples; ++c) {
        pixels[size_t(c)] = w.first_sample + c;
        const double j = double(w.first_sample + c);
        range[size_t(c)] = grd ? j * a.range_pixel_spacing_m
                               : a.SlantRangeOfTime(a.slant_range_time_s) + j * a.slant_range_spacing_m();
      }
      info["line"] = py::array_t<int32_t>(py::ssize_t(lines.size()), lines.data());
      info["pixel"] = py::array_t<int32_t>(py::ssize_t(pixels.size()), pixels.data());
      info[grd ? "ground_range_m" : "slant_range_m"] = py::array_t<double>(py::ssize_t(range.size()), range.data());
      const std::string mission = a.mission.empty() ? s.product().mission : a.mission;
      attrs["sensor"] = "Sentinel-1" + (mission.size() == 3 ? mission.substr(2) : std::string());
      attrs["mission"] = mission;
      attrs["product"] = s.product().name;
      attrs["product_type"] = a.product_type;
      attrs["mode"] = s.product().mode;
      attrs["swath"] = a.swath;
      if (s.options().burst != 0) attrs["burst"] = s.options().burst;
      attrs["polarization"] = a.polarization;
      attrs["orbit_pass"] = a.pass;
      attrs["wavelength_m"] = a.wavelength_m;
      attrs["azimuth_time_interval_s"] = a.azimuth_time_interval_s;
      attrs["azimuth_spacing_m"] = a.azimuth_pixel_spacing_m;
      if (grd) {
        attrs["ground_range_spacing_m"] = a.range_pixel_spacing_m;
      } else {
        attrs["range_spacing_m"] = a.slant_range_spacing_m();
      }
      attrs["noise_removal"] = int(s.options().remove_noise);
      py::list sources;
      sources.append(s.product().name + "/" + s.entry().annotation_file);
      sources.append(s.measurement().file());
      if (s.calibration()) sources.append(s.calibration()->file);
      if (s.noise()) sources.append(s.noise()->file);
      attrs["source_files"] = sources;
      std::string nodata = "NaN: DN = 0 (ESA's fill value)";
      if (!a.bursts.empty()) nodata += "; samples outside the burst's valid window (firstValidSample..lastValidSample)";
      if (radiometry_ != geo::Sentinel1Radiometry::kNone) {
        const char* lut = radiometry_ == geo::Sentinel1Radiometry::kSigma0  ? "sigmaNought"
                          : radiometry_ == geo::Sentinel1Radiometry::kBeta0 ? "betaNought"
                                                                             : "gamma";
        std::string text = radiometry + " = ";
        text += s.noise() ? "(|DN|^2 - N) / A^2" : "|DN|^2 / A^2";
        text += ", A = " + std::string(lut) + " of " + s.calibration()->file +
                ", bilinear in line and pixel (ESA)";
        if (s.noise()) {
          text += "; N = noiseRangeLut x noiseAzimuthLut of " + s.noise()->file;
          nodata += "; |DN|^2 - N < 0";
        }
        attrs["calibration"] = text;
      }
      attrs["nodata"] = nodata;
    } else {
      const geo::RslcProduct& p = *nisar_;
      info["kind"] = "nisar";
      info["dims"] = py::make_tuple("azimuth_time", "slant_range");
      const double epoch = ParseUtcSeconds(p.epoch_utc, p.path);
      for (int r = 0; r < p.rows(); ++r) time_ns[size_t(r)] = NanosecondsOf(epoch, p.zero_doppler_time_s[size_t(r)]);
      info["slant_range_m"] = py::array_t<double>(py::ssize_t(p.cols()), p.slant_range_m.data());
      attrs["sensor"] = p.mission.empty() ? "NISAR-format RSLC" : p.mission;
      attrs["mission"] = p.mission;
      attrs["product"] = std::filesystem::path(p.path).filename().string();
      attrs["product_type"] = "RSLC";
      attrs["frequency"] = p.frequency;
      attrs["polarization"] = p.polarization;
      attrs["wavelength_m"] = p.wavelength_m;
      attrs["azimuth_time_interval_s"] = p.azimuth_spacing_s();
      attrs["range_spacing_m"] = p.range_spacing_m();
      attrs["noise_removal"] = 0;
      py::list sources;
      sources.append(p.path);
      attrs["source_files"] = sources;
      if (radiometry_ == geo::Sentinel1Radiometry::kBeta0) {
        attrs["calibration"] = "beta0 = LUT x |DN|^2, LUT " + p.beta0_lut->dataset +
                               " (bilinear in zero-Doppler time and slant range)";
      }
      attrs["nodata"] = "NaN: non-finite samples as stored";
    }
    info["azimuth_time_ns"] = py::array_t<int64_t>(py::ssize_t(time_ns.size()), time_ns.data());
    info["name"] = radiometry_ != geo::Sentinel1Radiometry::kNone ? radiometry
                   : is_complex()                                 ? "slc"
                                                                  : "amplitude";
    info["long_name"] = radiometry_ != geo::Sentinel1Radiometry::kNone
                            ? radiometry + " (linear power)"
                            : (is_complex() ? "complex digital number (uncalibrated SLC)"
                                            : "amplitude digital number (uncalibrated)");
    info["attrs"] = attrs;
    return info;
  }

  // Rows [row, row + rows) x columns [col, col + cols) of the opened window.
  py::array Read(int row, int nrows, int col, int ncols) const {
    if (row < 0 || col < 0 || nrows < 0 || ncols < 0 || int64_t(row) + nrows > rows() ||
        int64_t(col) + ncols > cols()) {
      throw InputError("window outside the " + std::to_string(rows()) + " x " + std::to_string(cols()) + " image",
                       "gissar.open_product");
    }
    const double pixels = double(nrows) * double(ncols);
    const double bytes = pixels * (is_complex() ? 16.0 : 12.0);  // the DN read and the result
    const int64_t limit = DefaultMemoryLimitBytes();
    if (bytes > double(limit)) {
      throw ConfigError("reading " + std::to_string(nrows) + " x " + std::to_string(ncols) + " pixels needs about " +
                            FormatBytes(bytes) + ", over the memory limit of " + FormatBytes(double(limit)) +
                            "; select a smaller window first (isel/sel or [...] on the variable)",
                        "gissar.open_product");
    }
    if (is_complex()) {
      std::vector<std::complex<float>> v;
      {
        py::gil_scoped_release release;
        v = ReadComplex(row, nrows, col, ncols);
      }
      return Owning(std::move(v), nrows, ncols);
    }
    std::vector<float> v;
    {
      py::gil_scoped_release release;
      v = ReadFloat(row, nrows, col, ncols);
    }
    return Owning(std::move(v), nrows, ncols);
  }

 private:
  // A NumPy array that owns `v` (no copy of a large read).
  template <typename T>
  static py::array_t<T> Owning(std::vector<T>&& v, int nrows, int ncols) {
    auto* heap = new std::vector<T>(std::move(v));
    py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>({nrows, ncols}, heap->data(), owner);
  }

  static int64_t NanosecondsOf(double epoch_unix_s, double t_s) {
    const double whole = std::floor(epoch_unix_s);
    return int64_t(whole) * 1000000000LL + std::llround((epoch_unix_s - whole + t_s) * 1e9);
  }

  // The readers name CLI flags; open_product's parameters have Python names,
  // and an error about one of them is a bad argument (ConfigError).
  [[noreturn]] static void RethrowWithParameterNames(const Error& e) {
    static const std::pair<const char*, const char*> kNames[] = {
        {"--swath/--polarization", "swath/polarization"}, {"--swath", "swath"}, {"--burst", "burst"},
        {"--polarization", "polarization"}, {"--radiometry", "radiometry"}, {"--noise-removal", "noise_removal"},
        {"--frequency", "frequency"}};
    std::string message = e.message(), where = e.where();
    bool argument = false;
    for (const auto& [flag, name] : kNames) {
      if (where.rfind(flag, 0) == 0) argument = true;
      for (std::string* s : {&message, &where}) {
        for (size_t at = s->find(flag); at != std::string::npos; at = s->find(flag, at + std::strlen(name))) {
          s->replace(at, std::strlen(flag), name);
        }
      }
    }
    if (argument || dynamic_cast<const ConfigError*>(&e) != nullptr) throw ConfigError(message, where);
    if (dynamic_cast<const IoError*>(&e) != nullptr) throw IoError(message, where);
    if (dynamic_cast<const InputError*>(&e) != nullptr) throw InputError(message, where);
    throw Error(message, where);
  }

  void OpenNisar(const std::string& path, const std::optional<std::string>& swath, const std::optional<int>& burst,
                 const std::optional<std::string>& polarization, bool noise_removal,
                 const std::optional<std::string>& frequency) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw InputError("product does not exist", path);
    if (swath) throw ConfigError("a NISAR product has no swaths (Sentinel-1 only)", "--swath");
    if (burst) throw ConfigError("a NISAR product has no bursts (Sentinel-1 IW/EW only)", "--burst");
    if (noise_removal) throw ConfigError("no thermal noise LUT is read from NISAR products", "--noise-removal");
    if (radiometry_ == geo::Sentinel1Radiometry::kSigma0 || radiometry_ == geo::Sentinel1Radiometry::kGamma0) {
      throw ConfigError(std::string("a NISAR RSLC is calibrated to beta0 only (its beta0 LUT); ") +
                            geo::ToString(radiometry_) + " needs the incidence angle of every pixel",
                        "--radiometry");
    }
    geo::RslcReadOptions o;
    o.frequency = frequency.value_or("A");
    for (char& c : o.frequency) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    o.read_amplitude = false;
    o.read_complex = false;
    std::string pol = polarization.value_or("");
    for (char& c : pol) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const auto no_layer = [](const InputError& e) {
      return e.message().rfind("product has no dataset", 0) == 0 &&
             e.message().find("polarisations stored") != std::string::npos;
    };
    const auto read = [&](const geo::RslcReadOptions& options) {
      try {
        return geo::ReadRslcProduct(path, options);
      } catch (const InputError& e) {
        if (e.message().rfind("product has no frequency band", 0) == 0) throw ConfigError(e.message(), "--frequency");
        throw;
      }
    };
    if (pol.empty()) {  // the first layer stored, in the order HH, VV, HV, VH
      std::string stored;
      for (const char* candidate : {"HH", "VV", "HV", "VH"}) {
        o.polarization = candidate;
        try {
          read(o);
          pol = candidate;
          break;
        } catch (const InputError& e) {
          if (!no_layer(e)) throw;
          stored = e.message();
        }
      }
      if (pol.empty()) throw InputError(stored, path);
    }
    o.polarization = pol;
    o.read_complex = true;
    o.read_calibration = radiometry_ == geo::Sentinel1Radiometry::kBeta0;
    o.max_bytes = DefaultMemoryLimitBytes();
    o.bytes_per_pixel = 8.0;
    try {
      nisar_ = std::make_shared<const geo::RslcProduct>(read(o));
    } catch (const InputError& e) {
      if (no_layer(e)) {
        const std::string m = e.message();
        throw ConfigError("polarization " + pol + " is not stored in " + path + m.substr(m.find(" (polarisations")),
                          "--polarization");
      }
      if (e.message().rfind("product has no frequency band", 0) == 0) throw ConfigError(e.message(), "--frequency");
      throw;
    }
    if (o.read_calibration && !nisar_->beta0_lut) {
      throw ConfigError("the product states no beta0 calibration (no metadata/calibrationInformation/geometry/beta0); "
                        "open it with radiometry=None for the uncalibrated SLC",
                        "--radiometry");
    }
  }

  std::vector<std::complex<float>> ReadComplex(int row, int nrows, int col, int ncols) const {
    if (s1_) {
      const geo::Sentinel1Window& w = s1_->window();
      return s1_->ReadDn({w.first_line + row, w.first_sample + col, nrows, ncols});
    }
    std::vector<std::complex<float>> out(size_t(nrows) * size_t(ncols));
    for (int r = 0; r < nrows; ++r) {
      const auto* src = nisar_->slc.data() + size_t(row + r) * size_t(nisar_->cols()) + size_t(col);
      std::copy(src, src + ncols, out.data() + size_t(r) * size_t(ncols));
    }
    return out;
  }

  std::vector<float> ReadFloat(int row, int nrows, int col, int ncols) const {
    if (s1_) {
      const geo::Sentinel1Window& w = s1_->window();
      return s1_->ReadFloat({w.first_line + row, w.first_sample + col, nrows, ncols});
    }
    const std::vector<std::complex<float>> dn = ReadComplex(row, nrows, col, ncols);
    std::vector<float> out(dn.size());
    const geo::RslcProduct& p = *nisar_;
    for (int r = 0; r < nrows; ++r) {
      for (int c = 0; c < ncols; ++c) {
        const size_t k = size_t(r) * size_t(ncols) + size_t(c);
        const double power = double(dn[k].real()) * dn[k].real() + double(dn[k].imag()) * dn[k].imag();
        out[k] = static_cast<float>(
            power * p.beta0_lut->At(p.zero_doppler_time_s[size_t(row + r)], p.slant_range_m[size_t(col + c)]));
      }
    }
    return out;
  }

  geo::Sentinel1Radiometry radiometry_ = geo::Sentinel1Radiometry::kNone;
  std::shared_ptr<const geo::Sentinel1Image> s1_;
  std::shared_ptr<const geo::RslcProduct> nisar_;
};

// The output-prefix lock of every gissar command (util/atomic_output.h), for the Python pipelines that
// write sets of files under one prefix (the corridor): a second run on the prefix is refused at once.
class PrefixLock {
 public:
  explicit PrefixLock(const std::string& prefix) { outputs_.emplace().LockPrefix(prefix); }
  void Release() { outputs_.reset(); }

 private:
  std::optional<AtomicOutputs> outputs_;
};

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "gissar: SAR simulation of real terrain from GIS data, and affine SAR pose estimation.";
  // The exception family, as Python classes with the Python bases users
  // catch: bad arguments are ValueError, files OSError (a missing file
  // FileNotFoundError), numerical failures RuntimeError.
  py::dict classes;
  py::exec(R"(
class Error(Exception):
    """Base class of gissar's errors."""
class InputError(Error, ValueError):
    """Bad input data: unreadable or invalid contents."""
class MissingFileError(InputError, FileNotFoundError):
    """An input file that does not exist."""
class ConfigError(Error, ValueError):
    """A bad argument: out of range, unknown or inconsistent."""
class IoError(Error, OSError):
    """A read or write that failed at the operating-system or driver level."""
class Cancelled(Error, RuntimeError):
    """The run was stopped by its progress callback."""
class GissarWarning(UserWarning):
    """Something the user should know although the run went on."""
for _c in (Error, InputError, MissingFileError, ConfigError, IoError, Cancelled, GissarWarning):
    _c.__module__ = "gissar"
)", py::globals(), classes);
  static py::object error_type, input_type, missing_type, config_type, io_type, cancelled_type;
  error_type = classes["Error"];
  input_type = classes["InputError"];
  missing_type = classes["MissingFileError"];
  config_type = classes["ConfigError"];
  io_type = classes["IoError"];
  cancelled_type = classes["Cancelled"];
  for (const char* name : {"Error", "InputError", "MissingFileError", "ConfigError", "IoError", "Cancelled",
                           "GissarWarning"}) {
    m.attr(name) = classes[name];
  }
  PyReporter::WarningType() = classes["GissarWarning"].ptr();
  Py_INCREF(PyReporter::WarningType());
  py::register_exception_translator([](std::exception_ptr p) {
    auto raise = [](const py::object& type, const Error& e) {
      PyErr_SetString(type.ptr(), PythonMessage(e).c_str());
    };
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      raise(e.message().find("does not exist") != std::string::npos ? missing_type : input_type, e);
    } catch (const ConfigError& e) {
      raise(config_type, e);
    } catch (const IoError& e) {
      raise(io_type, e);
    } catch (const CancelledError& e) {
      raise(cancelled_type, e);
    } catch (const Error& e) {
      raise(error_type, e);
    }
  });

  m.def("simulate_request_defaults", [] { return JsonToPython(pipeline::SimulateRequest().ToJson()); },
        "The keywords of simulate with their defaults (the request fields, docs/conventions.md).");
  m.def("simulate_request_help", [] { return pipeline::SimulateFieldHelp(); },
        "{field: one-line help} of the simulate request fields the doors offer as flags or keywords (the text "
        "of `gissar simulate --help`, without defaults; simulate_request_defaults() gives those).");
  m.def("simulate_request_fields", [] { return RequestFieldRows("simulate"); },
        "The simulate request's field table (pipeline/simulate_fields.cc), in its order: one dict per field with "
        "name (the keyword and options-file key), flag (the CLI's), help (one line; empty: no flag), default and "
        "show_default. The corridor's flags and docs/options.md are made from it. Same as "
        "request_fields('simulate').");
  m.def("request_fields", &RequestFieldRows, py::arg("command"),
        "The field table of a command's request, in its order, as simulate_request_fields() gives simulate's: "
        "command 'simulate', 'evaluate', 'locate', 'geocode', 'scene_build' or 'pta' (pipeline/<command>_fields.cc). "
        "docs/options.md is made from them.");
  m.def("flag_of_field", &pipeline::FlagOfField, py::arg("field"),
        "The CLI flag of a request field: kebab case without the unit suffix (heading_deg -> --heading; "
        "out_prefix -> --out, center_lonlat -> --center, look_side -> --look).");
  m.def("unknown_key_message", &pipeline::UnknownKeyMessage, py::arg("key"), py::arg("known"),
        "\"unknown key 'KEY'\" with \"; did you mean K?\" when a key of `known` is close (the same case, '-' for "
        "'_', the flag name without its unit suffix, or at most 2 edits): the message of every request's "
        "unknown keyword.");
  m.def("_name_path", &NamePath, py::arg("path"), py::arg("description"),
        "Internal (gissar._adapt): messages and warnings say `description` (e.g. \"the `dem` array\") instead of "
        "the virtual path `path` of an in-memory raster; an empty description forgets it.");

  m.def("locate_request_defaults", [] { return JsonToPython(pipeline::LocateRequest().ToJson()); },
        "The locate request's fields and their defaults (the keywords of gissar.locate_product; "
        "pipeline/locate_fields.cc).");
  m.def("evaluate_request_defaults", [] { return JsonToPython(pipeline::EvaluateRequest().ToJson()); },
        "The evaluate request's fields and their defaults (the keywords of gissar.evaluate).");
  m.def("evaluate_trials", [](const py::dict& options) {
          const pipeline::EvaluateRequest o = EvaluateOptionsFrom(options, "gissar.evaluate_trials");
          std::vector<nlohmann::json> records;
          {
            py::gil_scoped_release release;
            records = pipeline::EvaluateTrials(o);
          }
          py::list out;
          for (const nlohmann::json& r : records) out.append(JsonToPython(r));
          return out;
        }, py::arg("options"),
        "Run trials trial_first .. trial_first + trial_count - 1 (trial_count -1: the rest) of an evaluate request "
        "(a dict of its fields) and return their records (list of dicts); trial k depends only on (seed, k).");
  m.def("locate_product", [](const py::dict& options) {
          pipeline::LocateRequest o;
          o.ApplyJson(JsonOfFields(options), "gissar.locate_product keyword");
          if (!o.UsesTrack()) throw ConfigError("give product, or orbit with radar_grid and image", "gissar.locate_product");
          nlohmann::json report;
          {
            py::gil_scoped_release release;
            report = pipeline::RunLocate(o, "gissar.locate_product (python)");
          }
          return JsonToPython(report);
        }, py::arg("options"),
        "Pose fix of a real product (or an orbit, radar grid and image) from a displaced prior: the locate "
        "request's fields as a dict (docs/navigation.md, 'Real images'). Returns the fix dict; no fix is "
        "converged=False with a reason.");
  m.def("pta", [](const py::dict& options) {
          pipeline::PtaRequest o;
          o.ApplyJson(JsonOfFields(options), "gissar.pta keyword");
          pipeline::PtaResult result;
          {
            py::gil_scoped_release release;
            o.Check();
            result = pipeline::RunPta(o, "gissar.pta (python)");
          }
          nlohmann::json out = result.report;
          out["outputs"] = nlohmann::json::array();
          for (const auto& p : result.outputs) out["outputs"].push_back(p.string());
          return JsonToPython(out);
        }, py::arg("options"),
        "`gissar pta` (docs/radiometry.md, point targets): the pta request's fields as a dict (product or image, "
        "reflectors, out_prefix, ...). Writes PREFIX.json and PREFIX_irf.png and returns PREFIX.json's dict "
        "(plus 'outputs'); no reflector found is converged=False with a reason.");
  m.def("pta_request_defaults", [] { return JsonToPython(pipeline::PtaRequest().ToJson()); },
        "The pta request's fields and their defaults (the keywords of gissar.pta).");
  m.def("polsar", [](const py::dict& options) {
          pipeline::PolsarRequest o;
          o.ApplyJson(JsonOfFields(options), "gissar.polsar keyword");
          pipeline::PolsarResult result;
          {
            py::gil_scoped_release release;
            o.Check();
            result = pipeline::RunPolsar(o, "gissar.polsar (python)");
          }
          nlohmann::json out = result.report;
          out["outputs"] = nlohmann::json::array();
          for (const auto& p : result.outputs) out["outputs"].push_back(p.string());
          return JsonToPython(out);
        }, py::arg("options"),
        "`gissar polsar` (docs/radiometry.md, polarimetric decomposition): the polsar request's fields as a dict "
        "(image or product, looks, matrix, out_prefix). Writes the C3/T3 and H/A/alpha rasters and the Pauli "
        "quicklook and returns PREFIX.json's dict (plus 'outputs').");
  m.def("polsar_request_defaults", [] { return JsonToPython(pipeline::PolsarRequest().ToJson()); },
        "The polsar request's fields and their defaults (the keywords of gissar.polsar).");
  m.def("summarise_trials", [](const py::dict& options, const py::iterable& records) {
          const pipeline::EvaluateRequest o = EvaluateOptionsFrom(options, "gissar.summarise_trials");
          return JsonToPython(pipeline::SummariseTrials(o, RecordsFrom(records)));
        }, py::arg("options"), py::arg("records"),
        "Summary statistics (success_rate, position_error_m median/p95, ...) of trial records in any order: "
        "the serial evaluate's table.");
  m.def("write_evaluation", [](const py::dict& options, const py::iterable& records, double seconds) {
          const pipeline::EvaluateRequest o = EvaluateOptionsFrom(options, "gissar.write_evaluation");
          return JsonToPython(pipeline::WriteEvaluation(o, RecordsFrom(records), "gissar (python)", seconds));
        }, py::arg("options"), py::arg("records"), py::arg("seconds") = 0.0,
        "Write PREFIX.json, PREFIX_trials.csv and PREFIX_hist.png of trial records (options['out_prefix']).");
  m.def("version", &VersionString, "Version string of the library.");
  m.def(
      "set_threads",
      [](int threads) {
        // One process-wide cap, as the command line's --threads: replaced by
        // each call; 0 removes it.
        static std::optional<tbb::global_control> limit;
        if (threads < 0) throw ConfigError("must be 0 (all cores) or a positive count", "gissar keyword 'threads'");
        limit.reset();
        if (threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
        return static_cast<int>(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
      },
      py::arg("threads"),
      "Caps the threads every later gissar call of this process uses (TBB max_allowed_parallelism, as the "
      "command line's --threads); 0 removes the cap. Returns the active limit.");

  py::class_<sensor::SarGeometry>(m, "SarGeometry", "SAR acquisition geometry (docs/geometry.md).")
      .def(py::init([](double heading_deg, double depression_deg, double range_spacing_m, double azimuth_spacing_m,
                       const std::string& look_side, const std::string& mode, double slant_range_m,
                       std::array<double, 3> scene_centre_enu_m, double u0, double v0, int width, int height) {
             sensor::SarGeometryOptions o;
             o.heading_deg = heading_deg;
             o.depression_deg = depression_deg;
             o.range_spacing_m = range_spacing_m;
             o.azimuth_spacing_m = azimuth_spacing_m;
             o.look_side = sensor::ParseLookSide(look_side);
             o.mode = sensor::ParseProjectionMode(mode);
             o.slant_range_m = slant_range_m;
             return sensor::SarGeometry(o, Eigen::Vector3d(scene_centre_enu_m[0], scene_centre_enu_m[1], scene_centre_enu_m[2]),
                                        u0, v0, width, height);
           }),
           py::arg("heading_deg"), py::arg("depression_deg"), py::arg("range_spacing_m") = 1.0,
           py::arg("azimuth_spacing_m") = 1.0, py::arg("look_side") = "right", py::arg("mode") = "affine",
           py::arg("slant_range_m") = 10000.0, py::arg("scene_centre_enu_m") = std::array<double, 3>{0, 0, 0},
           py::arg("u0") = 512.0, py::arg("v0") = 512.0, py::arg("width") = 1024, py::arg("height") = 1024,
           "Heading (deg clockwise from north), depression (deg), pixel spacings (m), look side, "
           "'affine' or 'exact', slant range (m), scene centre (ENU m), its pixel (u0, v0), image size.")
      .def("project", &Project, py::arg("points_enu_m"),
           "(N, 3) ENU points (m) -> (N, 2) pixels (column = slant range, row = azimuth).")
      .def_property_readonly("look_direction", [](const sensor::SarGeometry& g) {
        return std::array<double, 3>{g.look_direction().x(), g.look_direction().y(), g.look_direction().z()};
      })
      .def_property_readonly("flight_direction", [](const sensor::SarGeometry& g) {
        return std::array<double, 3>{g.flight_direction().x(), g.flight_direction().y(), g.flight_direction().z()};
      })
      .def_property_readonly("heading_deg", [](const sensor::SarGeometry& g) { return g.options().heading_deg; },
                             "Flight heading, degrees clockwise from north.")
      .def_property_readonly("depression_deg", [](const sensor::SarGeometry& g) { return g.options().depression_deg; },
                             "Depression of the line of sight below the horizontal, degrees.")
      .def_property_readonly("range_spacing_m", &sensor::SarGeometry::range_spacing_m, "Slant-range pixel spacing, m.")
      .def_property_readonly("azimuth_spacing_m", &sensor::SarGeometry::azimuth_spacing_m, "Azimuth pixel spacing, m.")
      .def_property_readonly("slant_range_m", &sensor::SarGeometry::slant_range_m, "Slant range to the scene centre, m.")
      .def_property_readonly("look_side", [](const sensor::SarGeometry& g) { return sensor::ToString(g.options().look_side); })
      .def_property_readonly("mode", [](const sensor::SarGeometry& g) {
        return sensor::ToString(g.mode());
      })
      .def_property_readonly("scene_centre_enu_m", [](const sensor::SarGeometry& g) {
        return std::array<double, 3>{g.scene_centre().x(), g.scene_centre().y(), g.scene_centre().z()};
      }, "Scene centre Xc (ENU m), imaged at pixel (u0, v0).")
      .def_property_readonly("u0", &sensor::SarGeometry::u0, "Column of the scene centre (pixels).")
      .def_property_readonly("v0", &sensor::SarGeometry::v0, "Row of the scene centre (pixels).")
      .def_property_readonly("width", &sensor::SarGeometry::width, "Image width (columns = slant range), pixels.")
      .def_property_readonly("height", &sensor::SarGeometry::height, "Image height (rows = azimuth), pixels.")
      .def("sensor_position", [](const sensor::SarGeometry& g, double along_track_m) {
        const Eigen::Vector3d p = g.SensorPosition(along_track_m);
        return std::array<double, 3>{p.x(), p.y(), p.z()};
      }, py::arg("along_track_m") = 0.0, "Sensor position (ENU m) at an along-track distance (m) from the centre.")
      .def("metadata", &sensor::SarGeometry::ToMetadata, "The GISSAR_* metadata of the GeoTIFFs.")
      // By value: the constructor's arguments, doubles exact.
      .def(py::pickle(
          [](const sensor::SarGeometry& g) {
            const sensor::SarGeometryOptions& o = g.options();
            return py::make_tuple(o.heading_deg, o.depression_deg, o.range_spacing_m, o.azimuth_spacing_m,
                                  sensor::ToString(o.look_side),
                                  sensor::ToString(g.mode()), o.slant_range_m,
                                  std::array<double, 3>{g.scene_centre().x(), g.scene_centre().y(), g.scene_centre().z()},
                                  g.u0(), g.v0(), g.width(), g.height());
          },
          [](const py::tuple& t) {
            if (t.size() != 12) throw InputError("not a pickled SarGeometry", "gissar.SarGeometry");
            sensor::SarGeometryOptions o;
            o.heading_deg = t[0].cast<double>();
            o.depression_deg = t[1].cast<double>();
            o.range_spacing_m = t[2].cast<double>();
            o.azimuth_spacing_m = t[3].cast<double>();
            o.look_side = sensor::ParseLookSide(t[4].cast<std::string>());
            o.mode = sensor::ParseProjectionMode(t[5].cast<std::string>());
            o.slant_range_m = t[6].cast<double>();
            const auto c = t[7].cast<std::array<double, 3>>();
            return sensor::SarGeometry(o, Eigen::Vector3d(c[0], c[1], c[2]), t[8].cast<double>(), t[9].cast<double>(),
                                       t[10].cast<int>(), t[11].cast<int>());
          }))
      .def("__repr__", [](const sensor::SarGeometry& g) {
        return "<gissar.SarGeometry heading " + std::to_string(g.options().heading_deg) + " deg, depression " +
               std::to_string(g.options().depression_deg) + " deg, " + std::to_string(g.width()) + " x " +
               std::to_string(g.height()) + " px>";
      });

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

  m.def("geocode", [](const py::dict& options) {
        pipeline::GeocodeRequest o;
        o.ApplyJson(JsonOfFields(options), "gissar.geocode keyword");
        pipeline::GeocodeResult r;
        PyReporter reporter{py::none()};
        {
          py::gil_scoped_release release;
          o.Check();
          r = pipeline::RunGeocode(o, "python: gissar.geocode", reporter);
        }
        std::vector<std::string> paths;
        for (const auto& p : r.outputs) paths.push_back(p.string());
        return py::dict(py::arg("outputs") = paths, py::arg("width") = r.width, py::arg("height") = r.height,
                        py::arg("geotransform") = r.geotransform, py::arg("crs") = r.crs,
                        py::arg("valid_pixels") = r.valid_pixels);
      }, py::arg("options"),
      "`gissar geocode` (docs/georeferencing.md): a simulation's PREFIX.tif (with its sidecar and mask beside "
      "it) to map geometry: out_prefix.tif (the image's bands, local_incidence, layover_shadow), .json, "
      "_stac.json. options: the geocode request's fields as a dict (image, out_prefix, dem, vertical_datum, crs, "
      "pixel_size_m, resampling; pipeline/geocode_fields.cc; None keeps a default). Returns {'outputs', 'width', "
      "'height', 'geotransform', 'crs', 'valid_pixels'}.");

  m.def("load_scene", [](const std::string& path) {
        const scene::SceneFile s = scene::ReadScene(path);
        py::array_t<float> v({py::ssize_t(s.mesh.vertices.size()), py::ssize_t(3)});
        std::memcpy(v.mutable_data(), s.mesh.vertices.data(), s.mesh.vertices.size() * 12);
        py::array_t<int32_t> t = TriangleIndices(s.mesh);
        py::array_t<uint8_t> c(py::ssize_t(s.mesh.classes.size()));
        std::memcpy(c.mutable_data(), s.mesh.classes.data(), s.mesh.classes.size());
        py::dict out;
        out["vertices_enu_m"] = v;
        out["triangles"] = t;
        out["classes"] = c;
        out["class_names"] = s.class_names;
        out["origin_lonlat_deg"] = std::array<double, 2>{s.origin_lon_deg, s.origin_lat_deg};
        return out;
      }, py::arg("path"), "A .gscene file as arrays: vertices (N, 3) ENU m, triangles (M, 3), classes (M,).");

  m.def("build_scene", [](const std::string& dem, const std::string& out_prefix, const std::vector<std::string>& vectors,
                          const std::string& osm, const std::string& config, bool fill_nodata,
                          const std::string& vertical_datum) {
        py::dict options(py::arg("dem") = dem, py::arg("out_prefix") = out_prefix, py::arg("vectors") = vectors,
                         py::arg("osm") = osm, py::arg("config") = config, py::arg("fill_nodata") = fill_nodata,
                         py::arg("vertical_datum") = vertical_datum);
        return BuildPyScene(options, py::none(), "gissar.build_scene keyword").summary;
      }, py::arg("dem"), py::arg("out_prefix"), py::arg("vectors") = std::vector<std::string>{},
      py::arg("osm") = "", py::arg("config") = "", py::arg("fill_nodata") = false, py::arg("vertical_datum") = "",
      "`gissar scene build`: writes PREFIX.gscene/.ply/_classes.png/.json, returns the summary.");

  m.def("fmatrix", [](const py::array_t<double, py::array::c_style>& x1, const py::array_t<double, py::array::c_style>& x2,
                      std::optional<std::array<double, 2>> res1, std::optional<std::array<double, 2>> res2,
                      std::optional<std::array<double, 2>> depressions_deg, double threshold_px, uint64_t seed,
                      std::optional<std::array<double, 2>> range_spacing_m,
                      std::optional<std::array<double, 2>> azimuth_spacing_m) {
        const auto matches = Matches(x1, x2);
        mvg::TwoViewOptions o;
        o.ransac.threshold_px = threshold_px;
        o.ransac.seed = seed;
        // res1=(R1, A1), res2=(R2, A2): deprecated spelling of
        // range_spacing_m=(R1, R2), azimuth_spacing_m=(A1, A2).
        if (res1 || res2) {
          const char* replacement = "range_spacing_m=(R1, R2), azimuth_spacing_m=(A1, A2)";
          if (res1) WarnDeprecatedKeyword("res1", replacement);
          if (res2) WarnDeprecatedKeyword("res2", replacement);
          if (!res1 || !res2) throw ConfigError("give both res1 and res2", "gissar.fmatrix");
          if (range_spacing_m || azimuth_spacing_m) {
            throw ConfigError("give the spacings once, as range_spacing_m/azimuth_spacing_m", "gissar.fmatrix");
          }
          range_spacing_m = std::array<double, 2>{(*res1)[0], (*res2)[0]};
          azimuth_spacing_m = std::array<double, 2>{(*res1)[1], (*res2)[1]};
        }
        if (range_spacing_m.has_value() != azimuth_spacing_m.has_value()) {
          throw ConfigError("give both range_spacing_m and azimuth_spacing_m", "gissar.fmatrix");
        }
        if (range_spacing_m) {
          for (int i = 0; i < 2; ++i) {
            if (!((*range_spacing_m)[i] > 0 && (*azimuth_spacing_m)[i] > 0)) {
              throw ConfigError("pixel spacings must be positive", "range_spacing_m/azimuth_spacing_m");
            }
          }
          o.k1 = mvg::SarIntrinsics((*range_spacing_m)[0], (*azimuth_spacing_m)[0]);
          o.k2 = mvg::SarIntrinsics((*range_spacing_m)[1], (*azimuth_spacing_m)[1]);
        }
        if (depressions_deg) {
          o.depression1_deg = (*depressions_deg)[0];
          o.depression2_deg = (*depressions_deg)[1];
        }
        std::optional<mvg::TwoViewAnalysis> a;
        {
          py::gil_scoped_release release;
          a = mvg::AnalyseTwoViews(matches, o);
        }
        if (!a) throw InputError("F is undetermined: the matches are degenerate", "gissar.fmatrix");
        py::dict out;
        out["F"] = Mat(a->f);
        out["F_calibrated"] = Mat(a->f_calibrated);
        out["inliers"] = a->inliers;
        out["rms_gs_px"] = a->rms_gs_px;
        out["kvd"] = py::dict(py::arg("s") = a->kvd.s, py::arg("theta_deg") = a->kvd.theta_deg,
                              py::arg("phi_deg") = a->kvd.phi_deg, py::arg("rho_recoverable") = false);
        if (a->sar) out["heading_change_deg"] = a->sar->heading_change_deg;
        return out;
      }, py::arg("x1"), py::arg("x2"), py::arg("res1") = py::none(), py::arg("res2") = py::none(),
      py::arg("depressions_deg") = py::none(), py::arg("threshold_px") = 1.5, py::arg("seed") = 1, py::kw_only(),
      py::arg("range_spacing_m") = py::none(), py::arg("azimuth_spacing_m") = py::none(),
      "Affine fundamental matrix of (N, 2) pixel matches x1 <-> x2 (RANSAC + Gold Standard), KvD, heading change. "
      "Calibrated with range_spacing_m=(R1, R2) and azimuth_spacing_m=(A1, A2), metres per pixel of images 1 and 2 "
      "(res1=(R1, A1), res2=(R2, A2): deprecated, DeprecationWarning).");

  m.def("resect", [](const py::array_t<double, py::array::c_style>& world, const py::array_t<double, py::array::c_style>& pixels,
                     std::optional<std::array<double, 3>> center_enu_m,
                     std::optional<std::array<double, 3>> scene_centre_enu_m) {
        if (scene_centre_enu_m) {
          WarnDeprecatedKeyword("scene_centre_enu_m", "center_enu_m");
          if (center_enu_m) throw ConfigError("give the scene centre once, as center_enu_m", "gissar.resect");
          center_enu_m = scene_centre_enu_m;
        }
        const std::array<double, 3> centre = center_enu_m.value_or(std::array<double, 3>{0, 0, 0});
        if (world.ndim() != 2 || world.shape(1) != 3 || pixels.ndim() != 2 || pixels.shape(1) != 2 ||
            world.shape(0) != pixels.shape(0)) {
          throw InputError("world must be (N, 3) and pixels (N, 2)", "gissar.resect");
        }
        std::vector<mvg::ControlPoint> points(world.shape(0));
        for (py::ssize_t i = 0; i < world.shape(0); ++i) {
          points[i].world = {world.at(i, 0), world.at(i, 1), world.at(i, 2)};
          points[i].pixel = {pixels.at(i, 0), pixels.at(i, 1)};
        }
        mvg::ResectionOptions o;
        o.scene_centre = {centre[0], centre[1], centre[2]};
        std::optional<mvg::ResectionResult> r;
        {
          py::gil_scoped_release release;
          r = mvg::ResectSarCamera(points, o);
        }
        if (!r) throw InputError("the camera is undetermined: control points are degenerate", "gissar.resect");
        return py::dict(py::arg("heading_deg") = r->pose.heading_deg, py::arg("depression_deg") = r->pose.depression_deg,
                        py::arg("range_spacing_m") = r->pose.range_spacing_m,
                        py::arg("azimuth_spacing_m") = r->pose.azimuth_spacing_m, py::arg("u0") = r->pose.u0,
                        py::arg("v0") = r->pose.v0, py::arg("rms_px") = r->rms_px, py::arg("camera") = Mat(r->camera));
      }, py::arg("world_enu_m"), py::arg("pixels"), py::arg("center_enu_m") = py::none(), py::kw_only(),
      py::arg("scene_centre_enu_m") = py::none(),
      "Affine SAR resection from (N, 3) ENU points (m) and their (N, 2) pixels; center_enu_m: the scene centre Xc "
      "(ENU m, default 0,0,0; scene_centre_enu_m: deprecated, DeprecationWarning).");

  m.def("register_points", [](const py::array_t<double, py::array::c_style>& fixed_px,
                              const py::array_t<double, py::array::c_style>& moving_px, const std::string& transform,
                              double threshold_px) {
        mvg::RegistrationOptions o;
        o.type = mvg::ParseTransformType(transform);
        o.threshold_px = threshold_px;
        const auto pairs = Matches(fixed_px, moving_px);
        std::optional<mvg::Registration> r;
        {
          py::gil_scoped_release release;
          r = mvg::RegisterControlPoints(pairs, o);
        }
        if (!r) throw InputError("the transform is undetermined: control points are degenerate", "gissar.register_points");
        return py::dict(py::arg("inliers") = r->inliers, py::arg("rms_px") = r->rms_px,
                        py::arg("residuals_px") = r->residuals_px);
      }, py::arg("fixed_px"), py::arg("moving_px"), py::arg("transform") = "affine", py::arg("threshold_px") = 2.0,
      "Fit a similarity/affine/projective/poly2/poly3 transform moving -> fixed to (N, 2) point pairs.");

  // ------------------------------------------------------------ Scene
  py::class_<PyScene>(m, "Scene",
                      "A GIS scene: classified triangle mesh in a local ENU frame (metres), as built by "
                      "`gissar scene build` (docs/scene.md).")
      .def(py::init(&LoadPyScene), py::arg("path"), "Load a .gscene file.")
      .def_static("build", [](const py::dict& options, py::object progress) {
                    return BuildPyScene(options, std::move(progress), "gissar.Scene.build keyword");
                  }, py::arg("options"), py::arg("progress") = py::none(),
                  "`gissar scene build`: DEM (+ vector layers / OSM / config) -> PREFIX.gscene, .ply, "
                  "_classes.png (class map), _3d.png (3-D view), .json (and .obj/.mtl with export_obj). "
                  "window = (col, row, cols, rows) of the DEM; vertical_datum as --vertical-datum (\"\" = from the file). Returns the loaded Scene (its .summary holds "
                  "the build summary).")
      .def_readonly("path", &PyScene::path)
      .def_readonly("summary", &PyScene::summary)
      .def_property_readonly("vertices_enu_m", [](const PyScene& s) {
        py::array_t<float> v({py::ssize_t(s.file.mesh.vertices.size()), py::ssize_t(3)});
        std::memcpy(v.mutable_data(), s.file.mesh.vertices.data(), s.file.mesh.vertices.size() * 12);
        return v;
      }, "(N, 3) float32 vertices, ENU metres.")
      .def_property_readonly("triangles", [](const PyScene& s) {
        return TriangleIndices(s.file.mesh);
      }, "(M, 3) int32 vertex indices.")
      .def_property_readonly("classes", [](const PyScene& s) {
        py::array_t<uint8_t> c(py::ssize_t(s.file.mesh.classes.size()));
        std::memcpy(c.mutable_data(), s.file.mesh.classes.data(), s.file.mesh.classes.size());
        return c;
      }, "(M,) uint8 class id per triangle (index into class_names).")
      .def_property_readonly("class_names", [](const PyScene& s) { return s.file.class_names; })
      .def_property_readonly("origin_lonlat_deg", [](const PyScene& s) {
        return std::array<double, 2>{s.file.origin_lon_deg, s.file.origin_lat_deg};
      }, "ENU frame origin (WGS84 lon, lat, degrees; height 0).")
      .def_property_readonly("centre_enu_m", [](const PyScene& s) {
        return std::array<double, 3>{s.file.centre_enu.x(), s.file.centre_enu.y(), s.file.centre_enu.z()};
      }, "Default scene centre (ENU m).")
      .def("simulate", [](const PyScene& s, const py::kwargs& kwargs) {
        py::kwargs all;
        for (const auto& item : kwargs) all[item.first] = item.second;
        if (all.contains("scene") || all.contains("dem")) throw ConfigError("the scene is given", "Scene.simulate");
        all["scene"] = s.path;
        return Simulate(all);
      }, "gissar.simulate(scene=self.path, ...): same keywords and result.")
      .def("class_map", [](const PyScene& s, int max_side_px) {
        if (max_side_px < 16) throw ConfigError("must be >= 16", "max_side_px");
        image::RgbImage img;
        {
          py::gil_scoped_release release;
          img = image::RenderClassMap(s.file.mesh, s.file.class_names, max_side_px);
        }
        return RgbArray(img);
      }, py::arg("max_side_px") = 1200,
      "Top view (east right, north up) in class colours, hill-shaded, with a legend: (H, W, 3) uint8.")
      .def("view_3d", [](const PyScene& s, const py::kwargs& kwargs) {
        const image::MeshViewOptions o = MeshViewOptionsFrom(kwargs);
        image::RgbImage img;
        {
          py::gil_scoped_release release;
          img = image::RenderMeshView(s.file.mesh, image::ClassColourList(), o);
        }
        return RgbArray(img);
      }, "Perspective 3-D view of the mesh in class colours (z-buffer, Lambertian sun): (H, W, 3) uint8. "
         "Keywords: view_azimuth_deg (camera direction from the centre, compass, default 200), "
         "view_elevation_deg (35), vertical_exaggeration (1.5), field_of_view_deg (30), sun_azimuth_deg (315), "
         "sun_elevation_deg (45), width (960), height (640).")
      .def("export_obj", [](const PyScene& s, const std::string& path) {
        py::gil_scoped_release release;
        if (std::filesystem::path(path).extension() != ".obj") throw ConfigError("must end in .obj", path);
        const std::filesystem::path mtl = std::filesystem::path(path).replace_extension(".mtl");
        AtomicOutputs outputs;
        const auto obj_tmp = outputs.Add(path);
        const auto mtl_tmp = outputs.Add(mtl);
        scene::WriteObj(obj_tmp, mtl_tmp, mtl.filename().string(), s.file.mesh, s.file.class_names,
                        image::ClassColourList());
        outputs.Commit();
      }, py::arg("path"), "Wavefront OBJ + MTL beside it (class colours), ENU metres, for any 3-D viewer.")
      // By path + content hash (a scene can be gigabytes): the unpickling
      // process reads the same file and refuses a missing or changed one.
      .def(py::pickle(
          [](PyScene& s) {
            if (s.sha256.empty()) s.sha256 = FileSha256(s.path);
            return py::make_tuple(std::filesystem::absolute(s.path).string(), s.sha256, s.summary);
          },
          [](const py::tuple& t) {
            if (t.size() != 3) throw InputError("not a pickled Scene", "gissar.Scene");
            const std::string path = t[0].cast<std::string>();
            const std::string sha256 = t[1].cast<std::string>();
            std::error_code ec;
            if (!std::filesystem::exists(path, ec)) {
              throw InputError("scene file does not exist here (a pickled Scene refers to its file: make it "
                               "visible to this process at the same path)", path);
            }
            if (FileSha256(path) != sha256) {
              throw InputError("scene file changed since the Scene was pickled (content hash differs)", path);
            }
            PyScene s = LoadPyScene(path);
            s.sha256 = sha256;
            s.summary = t[2];
            return s;
          }))
      .def_property_readonly("sha256", [](PyScene& s) {
        if (s.sha256.empty()) s.sha256 = FileSha256(s.path);
        return s.sha256;
      }, "SHA-256 of the .gscene file (what a pickled Scene checks on loading).")
      .def("__repr__", [](const PyScene& s) {
        return "<gissar.Scene '" + s.path + "', " + std::to_string(s.file.mesh.triangle_count()) + " triangles>";
      });

  // ------------------------------------------------------------ mvg
  m.def("kvd", [](const py::array_t<double, py::array::c_style | py::array::forcecast>& f) {
        if (f.ndim() != 2 || f.shape(0) != 3 || f.shape(1) != 3) throw InputError("F must be 3 x 3", "gissar.kvd");
        Eigen::Matrix3d m3;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) m3(r, c) = f.at(r, c);
        const mvg::KvdParameters k = mvg::KvdFromFundamental(m3);
        return py::dict(py::arg("s") = k.s, py::arg("theta_deg") = k.theta_deg, py::arg("phi_deg") = k.phi_deg,
                        py::arg("rho_recoverable") = k.rho_recoverable);
      }, py::arg("F"),
      "Koenderink-van Doorn decomposition of an affine F = [0 0 a; 0 0 b; c d e] (pass the calibrated F for "
      "metric values): scale s, cyclorotation theta_deg (-180, 180], rho-axis direction phi_deg (-90, 90]; "
      "rho is not recoverable from two views.");

  m.def("register_images", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& fixed,
                              const py::array_t<float, py::array::c_style | py::array::forcecast>& moving,
                              const py::array_t<double, py::array::c_style>& fixed_px,
                              const py::array_t<double, py::array::c_style>& moving_px, const std::string& transform,
                              double threshold_px) {
        const FloatImage f = ToFloatImage(fixed, "gissar.register_images: fixed");
        FloatImage mv = ToFloatImage(moving, "gissar.register_images: moving");
        mvg::RegistrationOptions o;
        o.type = mvg::ParseTransformType(transform);
        o.threshold_px = threshold_px;
        const auto pairs = Matches(fixed_px, moving_px);
        std::optional<mvg::Registration> r;
        std::vector<float> warped;
        {
          py::gil_scoped_release release;
          r = mvg::RegisterControlPoints(pairs, o);
          if (r) {
            const cv::Mat mm(mv.height, mv.width, CV_32F, mv.values.data());
            const cv::Mat w = mvg::WarpToFixed(mm, *r, cv::Size(f.width, f.height));
            warped.assign(w.begin<float>(), w.end<float>());
          }
        }
        if (!r) throw InputError("the transform is undetermined: control points are degenerate", "gissar.register_images");
        return py::dict(py::arg("warped") = Image(warped, f.height, f.width), py::arg("inliers") = r->inliers,
                        py::arg("rms_px") = r->rms_px, py::arg("residuals_px") = r->residuals_px);
      }, py::arg("fixed"), py::arg("moving"), py::arg("fixed_px"), py::arg("moving_px"),
      py::arg("transform") = "affine", py::arg("threshold_px") = 2.0,
      "Fit moving -> fixed (similarity/affine/projective/poly2/poly3) to (N, 2) pixel pairs (robust, threshold "
      "in pixels) and resample the moving image onto the fixed grid: {'warped': (H, W) float32, 'inliers', "
      "'rms_px', 'residuals_px'}.");

  // ------------------------------------------------------------ navigation
  m.def("match_images", &MatchImages, py::arg("reference"), py::arg("observed"), py::arg("matcher") = "ncc",
        py::arg("patch_px") = 31, py::arg("step_px") = 16, py::arg("search_px") = 16, py::arg("filter_px") = 3,
        py::arg("min_score") = 0.25, py::arg("warp") = py::none(),
        "Correspondences between two SAR images (linear intensities) with the nav matchers ('ncc', 'chamfer', "
        "'features') on log intensities after a filter_px box filter (speckle). `warp`: (2, 3) affine map "
        "predicting the observed pixel of a reference pixel (e.g. from the INS geometries); the observed image "
        "is resampled onto the reference grid with it, matched with a +-search_px search, and the matches are "
        "mapped back. Returns {'x_reference': (N, 2), 'x_observed': (N, 2) pixels (x = column = range, "
        "y = row = azimuth), 'score': (N,)}.");

  m.def("locate", &Locate, py::arg("scene"), py::arg("image"), py::arg("prior"), py::arg("range_spacing_m"),
        py::arg("azimuth_spacing_m"), py::arg("look_side") = "right", py::arg("matcher") = "ncc",
        py::arg("search_px") = 28, py::arg("step_px") = 12, py::arg("dense_renders") = 2,
        py::arg("polish_evaluations") = 0,
        py::arg("bounces") = 1, py::arg("rays_per_cell") = 4.0, py::arg("references") = true,
        "`gissar locate` (docs/navigation.md): pose fix of one observed SAR image (H, W) linear intensity with "
        "the given pixel spacings (m) against the Scene, from an INS prior dict {'heading_deg', "
        "'slant_range_m', and 'sensor_enu_m' [x, y, z] or 'depression_deg' + 'centre_enu_m'/'centre_lonlat'}. "
        "Returns {'pose': {heading_deg, depression_deg, slant_range_m, centre_enu_m, sensor_enu_m}, 'prior', "
        "'converged', 'iterations', 'matches', 'inliers', 'rms_px', 'dense_renders', 'dense_rms_db', 'similarity_ncc', 'prior_similarity_ncc', "
        "sigmas, 'seconds'} and with references=True the simulated images at the prior and at the fix.");

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

  // ------------------------------------------------------------ pictures
  m.def("quicklook", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& intensity,
                        double low_percentile, double high_percentile) {
        const FloatImage im = ToFloatImage(intensity, "gissar.quicklook");
        if (!(low_percentile >= 0 && low_percentile < high_percentile && high_percentile <= 100)) {
          throw ConfigError("need 0 <= low < high <= 100", "low_percentile/high_percentile");
        }
        image::DbStretch stretch;
        std::vector<uint8_t> grey;
        {
          py::gil_scoped_release release;  // other Python threads run meanwhile (seconds for a large image)
          grey = image::DbQuicklook(im.values, low_percentile, high_percentile, &stretch);
        }
        return py::make_tuple(Image(grey, im.height, im.width), py::make_tuple(stretch.low_db, stretch.high_db));
      }, py::arg("intensity"), py::arg("low_percentile") = 2.0, py::arg("high_percentile") = 98.0,
      "dB quicklook of a linear intensity image: (grey (H, W) uint8, (low_db, high_db)); 10 log10 I mapped from "
      "its low to high percentile onto grey 1..255, no return (I <= 0) = 0.");
  m.def("annotated_quicklook", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& intensity,
                                  double range_spacing_m, double azimuth_spacing_m, const std::string& title,
                                  double near_range_m, double azimuth_origin_m) {
        const FloatImage im = ToFloatImage(intensity, "gissar.annotated_quicklook");
        if (!(range_spacing_m > 0 && azimuth_spacing_m > 0)) {
          throw ConfigError("pixel spacings must be positive", "range_spacing_m/azimuth_spacing_m");
        }
        if (!std::isfinite(near_range_m) || !std::isfinite(azimuth_origin_m)) {
          throw ConfigError("axis origins must be finite", "near_range_m/azimuth_origin_m");
        }
        image::RgbImage picture;
        {
          py::gil_scoped_release release;
          picture = image::AnnotatedQuicklook(
              im.values, im.width, im.height,
              image::QuicklookAxes{near_range_m, range_spacing_m, azimuth_origin_m, azimuth_spacing_m}, title);
        }
        return RgbArray(picture);
      }, py::arg("intensity"), py::arg("range_spacing_m"), py::arg("azimuth_spacing_m"), py::arg("title") = "",
      py::arg("near_range_m") = 0.0, py::arg("azimuth_origin_m") = 0.0,
      "dB quicklook with a slant-range axis (near_range_m = slant range of column 0) and an along-track axis "
      "(azimuth_origin_m = along-track coordinate of row 0, e.g. -v0 * azimuth_spacing_m for metres from the scene "
      "centre), km when values reach 1000 m, a dB colour bar and a title: (H', W', 3) uint8.");
  m.def("composite", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& green,
                        const py::array_t<float, py::array::c_style | py::array::forcecast>& magenta) {
        const FloatImage a = ToFloatImage(green, "gissar.composite: green");
        const FloatImage b = ToFloatImage(magenta, "gissar.composite: magenta");
        if (a.width != b.width || a.height != b.height) throw InputError("images differ in size", "gissar.composite");
        image::RgbImage picture;
        {
          py::gil_scoped_release release;
          picture = image::IntensityComposite(a.values, b.values, a.width, a.height);
        }
        return RgbArray(picture);
      }, py::arg("green"), py::arg("magenta"),
      "Green/magenta composite of two co-registered linear intensity images, each dB-stretched on its own: grey "
      "where they agree. (H, W, 3) uint8.");
  m.def("epipolar_plot", [](const py::array_t<float, py::array::c_style | py::array::forcecast>& image1,
                            const py::array_t<float, py::array::c_style | py::array::forcecast>& image2,
                            const py::array_t<double, py::array::c_style>& x1, const py::array_t<double, py::array::c_style>& x2,
                            const py::array_t<double, py::array::c_style | py::array::forcecast>& f,
                            std::optional<std::vector<int>> inliers) {
        const FloatImage a = ToFloatImage(image1, "gissar.epipolar_plot: image1");
        const FloatImage b = ToFloatImage(image2, "gissar.epipolar_plot: image2");
        const auto matches = Matches(x1, x2);
        if (f.ndim() != 2 || f.shape(0) != 3 || f.shape(1) != 3) throw InputError("F must be 3 x 3", "gissar.epipolar_plot");
        Eigen::Matrix3d m3;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) m3(r, c) = f.at(r, c);
        image::EpipolarPlotInput in;
        {
          py::gil_scoped_release release;
          in.image1 = image::DbQuicklook(a.values, 1.0, 99.0);
          in.image2 = image::DbQuicklook(b.values, 1.0, 99.0);
        }
        in.width1 = a.width;
        in.height1 = a.height;
        in.width2 = b.width;
        in.height2 = b.height;
        in.inlier.assign(matches.size(), !inliers.has_value());
        if (inliers) {
          for (int i : *inliers) {
            if (i < 0 || size_t(i) >= matches.size()) throw InputError("inlier index out of range", "gissar.epipolar_plot");
            in.inlier[i] = true;
          }
        }
        for (const mvg::PointMatch& mt : matches) {
          in.matches.push_back({mt.p1, mt.p2});
          in.lines_in_2.push_back(mvg::EpipolarLineInImage2(m3, mt.p1));
          in.lines_in_1.push_back(mvg::EpipolarLineInImage1(m3, mt.p2));
        }
        image::RgbImage picture;
        {
          py::gil_scoped_release release;
          picture = image::DrawEpipolarPair(in);
        }
        return RgbArray(picture);
      }, py::arg("image1"), py::arg("image2"), py::arg("x1"), py::arg("x2"), py::arg("F"), py::arg("inliers") = py::none(),
      "Image 1 | image 2 (dB quicklooks) with the matches x1 <-> x2 (N, 2 pixels): inliers green with their "
      "epipolar lines under F ([x2 y2 1] F [x1 y1 1]' = 0) in yellow, outliers red. (H, W, 3) uint8.");
  m.def("kvd_diagram", [](double s, double theta_deg, double phi_deg, std::optional<double> heading_change_deg) {
        return RgbArray(image::KvdDiagram(s, theta_deg, phi_deg, heading_change_deg.value_or(0.0),
                                          heading_change_deg.has_value()));
      }, py::arg("s"), py::arg("theta_deg"), py::arg("phi_deg"), py::arg("heading_change_deg") = py::none(),
      "The KvD reading of F: rho axis at phi, cyclorotation theta (degrees), scale s, heading change (degrees) "
      "when known. (H, W, 3) uint8.");
  m.def("side_by_side", [](const std::vector<py::array_t<uint8_t, py::array::c_style | py::array::forcecast>>& panels,
                           const std::vector<std::string>& titles) {
        if (panels.empty() || panels.size() != titles.size()) {
          throw InputError("give as many titles as panels (at least one)", "gissar.side_by_side");
        }
        std::vector<image::RgbImage> rgb;
        for (const auto& p : panels) {
          if (p.ndim() != 3 || p.shape(2) != 3 || p.shape(0) < 1 || p.shape(1) < 1) {
            throw InputError("panels must be (H, W, 3) uint8 arrays", "gissar.side_by_side");
          }
          rgb.push_back({static_cast<int>(p.shape(1)), static_cast<int>(p.shape(0)),
                         std::vector<uint8_t>(p.data(), p.data() + p.size())});
        }
        return RgbArray(image::SideBySide(rgb, titles));
      }, py::arg("panels"), py::arg("titles"),
      "RGB panels (H, W, 3) uint8 side by side, top-aligned on white, each under its title: (H', W', 3) uint8.");
  m.def("write_png", &WritePngArray, py::arg("path"), py::arg("image"),
        "Write an (H, W) grey or (H, W, 3|4) RGB(A) uint8 array as PNG (all-or-nothing: temporary name + rename).");
  m.def("write_gif", &WriteGifFrames, py::arg("path"), py::arg("frames"), py::arg("delay_cs") = 50,
        "Write grey uint8 frames (a list of (H, W) arrays of one size) as a looping animated GIF, delay_cs "
        "hundredths of a second per frame.");
  // The output-prefix lock of every gissar command (util/atomic_output.h), for the Python pipelines that
  // write sets of files under one prefix (the corridor): a second run on the prefix is refused at once.
  py::class_<PrefixLock>(m, "_PrefixLock",
                         "An advisory lock on an output prefix (internal): IoError when another gissar run holds "
                         "it; released by release(), on leaving a with-block, or when the object is destroyed.")
      .def(py::init<const std::string&>(), py::arg("prefix"))
      .def("__enter__", [](PrefixLock& self) -> PrefixLock& { return self; }, py::return_value_policy::reference)
      .def("__exit__", [](PrefixLock& self, const py::args&) { self.Release(); })
      .def("release", &PrefixLock::Release, "Release the lock now (idempotent).");
  py::class_<OpenedProduct, std::shared_ptr<OpenedProduct>>(m, "_OpenedProduct",
                                                             "A product opened by gissar.open_product (internal).")
      .def(py::init<const std::string&, const std::optional<std::string>&, const std::optional<int>&,
                    const std::optional<std::string>&, const std::optional<std::string>&, bool,
                    const std::optional<std::string>&>(),
           py::arg("path"), py::arg("swath") = py::none(), py::arg("burst") = py::none(),
           py::arg("polarization") = py::none(), py::arg("radiometry") = py::none(),
           py::arg("noise_removal") = false, py::arg("frequency") = py::none())
      .def("info", &OpenedProduct::Info,
           "Shape, dtype, variable name, dims, coordinates (azimuth_time_ns, line, pixel, slant_range_m or "
           "ground_range_m) and attributes.")
      .def("read", &OpenedProduct::Read, py::arg("row"), py::arg("rows"), py::arg("col"), py::arg("cols"),
           "Rows x cols of the image from (row, col): complex64 DN or float32 (amplitude DN or calibrated power), NaN "
           "no-data.");
}
