// Binds the scene layer: the Scene class (a .gscene held in memory: arrays, pickling by path and hash,
// class map, 3-D view, OBJ export, simulate), load_scene and build_scene (`gissar scene build`).
#include "bindings.h"

#include <array>
#include <cstring>
#include <filesystem>

#include "gissar/image/class_map.h"
#include "gissar/image/mesh_view.h"
#include "gissar/pipeline/field_names.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/atomic_output.h"

namespace gissar::python {

namespace {

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

void BindSceneClass(py::module_& m) {
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
}

}  // namespace

void BindScene(py::module_& m) {
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

  BindSceneClass(m);
}

}  // namespace gissar::python
