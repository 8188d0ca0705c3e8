// Python bindings: `import gissar` (pybind11, NumPy arrays in and out). The module gissar._core is made by
// one Bind<Layer> function per layer of the library (python/bind_<layer>.cc, declared in bindings.h with
// the helpers they share), called here in order: the exception classes first, so that every later binding
// raises them, and the Scene class before the functions that take a Scene.
#include "bindings.h"

PYBIND11_MODULE(_core, m) {
  namespace bindings = gissar::python;
  m.doc() = "gissar: SAR simulation of real terrain from GIS data, and affine SAR pose estimation.";
  bindings::BindErrors(m);
  bindings::BindUtil(m);
  bindings::BindGeo(m);
  bindings::BindScene(m);
  bindings::BindSensor(m);
  bindings::BindImage(m);
  bindings::BindMvg(m);
  bindings::BindNav(m);
  bindings::BindPipelineFields(m);
  bindings::BindPipelineSimulate(m);
  bindings::BindPipelineCommands(m);
}
