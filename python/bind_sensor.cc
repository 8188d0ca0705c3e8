// Binds the sensor layer: the SarGeometry class (the affine and exact SAR imaging geometry: projection of
// ENU points to pixels, its parameters, sensor position, GeoTIFF metadata, pickling).
#include "bindings.h"

#include <array>

#include "gissar/sensor/sar_geometry.h"

namespace gissar::python {

namespace {

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

}  // namespace

void BindSensor(py::module_& m) {
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
}

}  // namespace gissar::python
