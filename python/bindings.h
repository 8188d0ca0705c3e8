// What the binding files of gissar._core share (python/bind_*.cc, one per
// layer, each with its Bind<Layer>(module); python/gissar_module.cc calls
// them in order): conversions between Python values and JSON, arrays and
// images; the Python names in error messages (virtual paths, flags →
// parameters); the Python door's Reporter; the Scene held in memory.
// Options are passed as keyword arguments named exactly like the fields of
// the C++ request structs (the single source of truth shared with the CLI);
// library errors become gissar.InputError / ConfigError / IoError (subclasses
// of gissar.Error) with the same message. Heavy work runs without the GIL.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/image/class_map.h"
#include "gissar/mvg/point_match.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/error.h"
#include "gissar/util/reporter.h"

namespace gissar::python {

namespace py = pybind11;

// The bindings, one function per layer (python/bind_<layer>.cc), in the
// order PYBIND11_MODULE calls them: the exception classes first, the Scene
// class before the functions that take one (locate).
void BindErrors(py::module_& m);            // bind_errors.cc
void BindUtil(py::module_& m);              // bind_util.cc
void BindGeo(py::module_& m);               // bind_geo.cc
void BindScene(py::module_& m);             // bind_scene.cc
void BindSensor(py::module_& m);            // bind_sensor.cc
void BindImage(py::module_& m);             // bind_image.cc
void BindMvg(py::module_& m);               // bind_mvg.cc
void BindNav(py::module_& m);               // bind_nav.cc
void BindPipelineFields(py::module_& m);    // bind_pipeline_fields.cc
void BindPipelineSimulate(py::module_& m);  // bind_pipeline_simulate.cc
void BindPipelineCommands(py::module_& m);  // bind_pipeline_commands.cc

// ---------------------------------------------------------------- conversions

py::object JsonToPython(const nlohmann::json& j);

template <typename T>
py::array_t<T> Image(const std::vector<T>& values, int height, int width) {
  py::array_t<T> out({height, width});
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

// Keyword arguments as JSON values (str, bool, int, float, None, and
// sequences of those), for the pipeline's ApplyJson.
nlohmann::json JsonOf(const py::handle& value, const std::string& key);

// {key: value} of a dict of request fields (or keyword arguments).
nlohmann::json JsonOfFields(const py::dict& fields);

// A float image (H, W) from a NumPy array (any real dtype, C order after
// conversion); `what` names the argument in errors. No-data (NaN, e.g.
// outside a simulation's footprint) counts as no return: 0, as the file
// readers of locate and matchpair do.
struct FloatImage {
  std::vector<float> values;
  int width = 0, height = 0;
};
FloatImage ToFloatImage(const py::array_t<float, py::array::c_style | py::array::forcecast>& a,
                        const std::string& what);

py::array_t<uint8_t> RgbArray(const image::RgbImage& img);

// Pixel matches from two (N, 2) arrays of the same N.
std::vector<mvg::PointMatch> Matches(const py::array_t<double, py::array::c_style>& x1,
                                     const py::array_t<double, py::array::c_style>& x2);

py::array_t<double> Mat(const Eigen::MatrixXd& m);

// ---------------------------------------------------------------- names in messages

// What the user gave for each in-memory raster a call reads through a GDAL
// virtual path (/vsimem/gissar_*.tif, a DEM given as an array, DataArray or
// dataset): "the `dem` array". Named by gissar._adapt (and TakeArrayDem) for
// the duration of the call; messages and warnings say it instead of the path.
// Registers (description non-empty) or forgets the description of `path`.
void NamePath(const std::string& path, const std::string& description);

// `text` with every registered virtual path replaced by its description.
std::string UserPaths(std::string text);

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
[[noreturn]] void RethrowWithUserPaths();

// `text` with every command-line flag of a request field ("--heading",
// "--range-spacing/--azimuth-spacing", "give --vertical-datum ...") replaced
// by the Python parameter of the same field ("heading_deg"), and every
// in-memory raster's virtual path by what the user gave (UserPaths).
std::string PythonNames(const std::string& raw_text);

// An error's text for Python: "<what> (<where>)" with Python parameter names.
std::string PythonMessage(const Error& e);

// ---------------------------------------------------------------- reporting

// The Python door's Reporter (util/reporter.h): warnings become Python
// warnings of category gissar.GissarWarning, information lines go to the
// "gissar" logger, stage progress to the optional `progress(stage, done,
// total)` callable; a callback returning False stops the run, which then
// raises gissar.Cancelled. Built and destroyed with the GIL held; its
// methods take the GIL themselves (StageProgress runs on worker threads).
class PyReporter : public Reporter {
 public:
  explicit PyReporter(py::object progress) : progress_(std::move(progress)) {}
  void StageProgress(const std::string& stage, int64_t done, int64_t total) override;
  void Info(const std::string& line) override;
  void Warn(const std::string& line) override;
  bool CancelRequested() const override { return cancelled_.load(); }

  // gissar.GissarWarning once BindErrors has made it (UserWarning before).
  static PyObject*& WarningType();

 private:
  py::object progress_;
  std::atomic<bool> cancelled_{false};
};

// Removes the `progress` keyword (not a request field) from `kwargs`.
py::object TakeProgress(py::kwargs& kwargs);

// Pops keyword `key` from `kwargs` (None when absent).
py::object TakeKeyword(py::kwargs& kwargs, const char* key);

// ---------------------------------------------------------------- shared between layers

// A scene built by `gissar scene build` (a .gscene file) held in memory
// (bind_scene.cc; gissar.locate takes one, bind_nav.cc).
struct PyScene {
  std::string path;
  scene::SceneFile file;
  py::object summary = py::none();  // the build summary when built here
  std::string sha256;               // of the file, computed when first pickled
};

// gissar._core.simulate (bind_pipeline_simulate.cc; Scene.simulate calls it
// with scene= its path).
py::dict Simulate(py::kwargs kwargs);

}  // namespace gissar::python
