// Binds gissar's exception family (gissar.Error and its subclasses, GissarWarning) and the translation of
// the library's errors into them, with messages in Python names (bindings.h: PythonMessage), and
// _name_path, which names an in-memory raster's virtual path in those messages.
#include "bindings.h"

#include <exception>

#include <pybind11/eval.h>

namespace gissar::python {

void BindErrors(py::module_& m) {
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

  m.def("_name_path", &NamePath, py::arg("path"), py::arg("description"),
        "Internal (gissar._adapt): messages and warnings say `description` (e.g. \"the `dem` array\") instead of "
        "the virtual path `path` of an in-memory raster; an empty description forgets it.");
}

}  // namespace gissar::python
