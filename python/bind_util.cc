// Binds the util layer: version, set_threads (the process-wide thread cap, TBB) and _PrefixLock (the
// output-prefix lock of util/atomic_output.h, for the Python pipelines that write sets of files).
#include "bindings.h"

#include <optional>

#include <tbb/global_control.h>

#include "gissar/util/atomic_output.h"
#include "gissar/util/provenance.h"

namespace gissar::python {

namespace {

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

void BindUtil(py::module_& m) {
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
  py::class_<PrefixLock>(m, "_PrefixLock",
                         "An advisory lock on an output prefix (internal): IoError when another gissar run holds "
                         "it; released by release(), on leaving a with-block, or when the object is destroyed.")
      .def(py::init<const std::string&>(), py::arg("prefix"))
      .def("__enter__", [](PrefixLock& self) -> PrefixLock& { return self; }, py::return_value_policy::reference)
      .def("__exit__", [](PrefixLock& self, const py::args&) { self.Release(); })
      .def("release", &PrefixLock::Release, "Release the lock now (idempotent).");
}

}  // namespace gissar::python
