// The shared helpers of the binding files (bindings.h): JSON and array
// conversions, the Python names in error messages, the Python door's Reporter.
#include "bindings.h"

#include <cctype>
#include <cmath>
#include <map>
#include <mutex>

#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/simulate.h"

namespace gissar::python {

// ---------------------------------------------------------------- conversions

py::object JsonToPython(const nlohmann::json& j) {
  return py::module_::import("json").attr("loads")(j.dump());
}

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

nlohmann::json JsonOfFields(const py::dict& fields) {
  nlohmann::json values = nlohmann::json::object();
  for (const auto& [key_handle, value] : fields) {
    const std::string key = key_handle.cast<std::string>();
    values[key] = JsonOf(value, key);
  }
  return values;
}

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

// ---------------------------------------------------------------- names in messages

namespace {

// The descriptions NamePath registers, by virtual path.
std::mutex path_names_mutex;
std::map<std::string, std::string>& PathNames() {
  static std::map<std::string, std::string> names;
  return names;
}

}  // namespace

void NamePath(const std::string& path, const std::string& description) {
  if (path.empty()) return;
  const std::lock_guard<std::mutex> lock(path_names_mutex);
  if (description.empty()) PathNames().erase(path);
  else PathNames()[path] = description;
}

std::string UserPaths(std::string text) {
  const std::lock_guard<std::mutex> lock(path_names_mutex);
  for (const auto& [path, description] : PathNames()) {
    for (size_t at = text.find(path); at != std::string::npos; at = text.find(path, at + description.size())) {
      text.replace(at, path.size(), description);
    }
  }
  return text;
}

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

std::string PythonMessage(const Error& e) {
  const std::string where = e.where();
  const std::string message = PythonNames(e.message());
  return where.empty() ? message : message + " (" + PythonNames(where) + ")";
}

// ---------------------------------------------------------------- reporting

void PyReporter::StageProgress(const std::string& stage, int64_t done, int64_t total) {
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

void PyReporter::Info(const std::string& line) {
  py::gil_scoped_acquire gil;
  py::module_::import("logging").attr("getLogger")("gissar").attr("info")(UserPaths(line));
}

void PyReporter::Warn(const std::string& line) {
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

PyObject*& PyReporter::WarningType() {
  static PyObject* type = PyExc_UserWarning;
  return type;
}

py::object TakeProgress(py::kwargs& kwargs) {
  if (!kwargs.contains("progress")) return py::none();
  py::object progress = kwargs["progress"];
  PyDict_DelItemString(kwargs.ptr(), "progress");
  if (!progress.is_none() && !PyCallable_Check(progress.ptr())) {
    throw ConfigError("progress must be a callable(stage, done, total) or None", "gissar keyword 'progress'");
  }
  return progress;
}

py::object TakeKeyword(py::kwargs& kwargs, const char* key) {
  if (!kwargs.contains(key)) return py::none();
  py::object value = kwargs[key];
  PyDict_DelItemString(kwargs.ptr(), key);
  return value;
}

}  // namespace gissar::python
