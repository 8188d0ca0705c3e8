// Python bindings: `import gissar` (pybind11, NumPy arrays in and out).
// Options are passed as keyword arguments named exactly like the fields of
// the C++ options structs (the single source of truth shared with the CLI);
// an unknown keyword is a gissar.ConfigError naming it. Library errors become
// gissar.InputError / ConfigError / IoError (subclasses of gissar.Error)
// with the same message. Heavy work runs without the GIL.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <nlohmann/json.hpp>

#include "gissar/cli/scene_build.h"
#include "gissar/cli/simulate.h"
#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/registration.h"
#include "gissar/mvg/resection.h"
#include "gissar/mvg/two_view.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

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

Eigen::Vector2d Pair(const py::handle& h, const std::string& key) {
  const auto v = h.cast<std::vector<double>>();
  if (v.size() != 2) throw ConfigError("expected two numbers", key);
  return {v[0], v[1]};
}

// Sets SimulateOptions fields from keyword arguments named like the fields.
cli::SimulateOptions SimulateOptionsFrom(const py::kwargs& kwargs) {
  cli::SimulateOptions o;
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = key_handle.cast<std::string>();
    if (key == "dem") o.dem = value.cast<std::string>();
    else if (key == "scene") o.scene = value.cast<std::string>();
    else if (key == "fill_nodata") o.fill_nodata = value.cast<bool>();
    else if (key == "center_lonlat") o.center_lonlat = Pair(value, key);
    else if (key == "center_map") o.center_map = Pair(value, key);
    else if (key == "heading_deg") o.geometry.heading_deg = value.cast<double>();
    else if (key == "depression_deg") o.geometry.depression_deg = value.cast<double>();
    else if (key == "look_side") o.geometry.look_side = sensor::ParseLookSide(value.cast<std::string>());
    else if (key == "slant_range_m") o.geometry.slant_range_m = value.cast<double>();
    else if (key == "range_spacing_m") o.geometry.range_spacing_m = value.cast<double>();
    else if (key == "azimuth_spacing_m") o.geometry.azimuth_spacing_m = value.cast<double>();
    else if (key == "mode") o.geometry.mode = sensor::ParseProjectionMode(value.cast<std::string>());
    else if (key == "width") o.geometry.width = value.cast<int>();
    else if (key == "height") o.geometry.height = value.cast<int>();
    else if (key == "rays_per_cell") o.rays_per_cell = value.cast<double>();
    else if (key == "bounces") o.bounces = value.cast<int>();
    else if (key == "coherent") o.coherent = value.cast<bool>();
    else if (key == "wavelength_m") o.wavelength_m = value.cast<double>();
    else if (key == "range_resolution_m") o.range_resolution_m = value.cast<double>();
    else if (key == "azimuth_resolution_m") o.azimuth_resolution_m = value.cast<double>();
    else if (key == "psf_window") o.psf_window = value.cast<std::string>();
    else if (key == "speckle_looks") o.speckle_looks = value.cast<double>();
    else if (key == "nesz_db") o.nesz_db = value.cast<double>();
    else if (key == "seed") o.seed = value.cast<uint64_t>();
    else throw ConfigError("unknown option '" + key + "'", "gissar.simulate");
  }
  o.out_prefix = "(python)";
  o.quiet = true;
  return o;
}

py::dict Simulate(const py::kwargs& kwargs) {
  const cli::SimulateOptions options = SimulateOptionsFrom(kwargs);
  render::SarImage image;
  std::map<std::string, std::string> metadata;
  {
    py::gil_scoped_release release;
    options.Check();
    cli::Terrain terrain = cli::LoadTerrain(options);
    const render::EmbreeScene embree(terrain.mesh);
    cli::PlaceSceneCentre(terrain, embree, options);
    const sensor::SarGeometry geometry = sensor::SarGeometry::Covering(
        cli::ResolvedGeometry(options, terrain), terrain.centre_enu, terrain.mesh.vertices);
    render::RenderOptions ro;
    ro.rays_per_cell = options.rays_per_cell;
    ro.max_bounces = options.bounces;
    ro.coherent = options.coherent;
    ro.wavelength_m = options.wavelength_m;
    ro.seed = options.seed;
    ro.show_progress = false;
    image = render::RenderSar(embree, terrain.mesh, terrain.materials, geometry, ro);
    cli::ApplySensorEffects(image, options, geometry);
    metadata = geometry.ToMetadata();
  }
  py::array_t<float> bands({render::kBounceLayers, image.height, image.width});
  for (int b = 0; b < render::kBounceLayers; ++b) {
    std::copy(image.bounce_layers[b].begin(), image.bounce_layers[b].end(),
              bands.mutable_data() + size_t(b) * image.width * image.height);
  }
  py::dict out;
  out["image"] = Image(image.intensity, image.height, image.width);
  out["bounces"] = bands;
  out["mask"] = Image(image.mask, image.height, image.width);
  out["geometry"] = metadata;
  out["options"] = JsonToPython(options.ToJson());
  return out;
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

}  // namespace

PYBIND11_MODULE(gissar, m) {
  m.doc() = "gissar: SAR simulation of real terrain from GIS data, and affine SAR pose estimation.";
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<InputError> input_error(m, "InputError", error.ptr());
  static py::exception<ConfigError> config_error(m, "ConfigError", error.ptr());
  static py::exception<IoError> io_error(m, "IoError", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      input_error(e.what());
    } catch (const ConfigError& e) {
      config_error(e.what());
    } catch (const IoError& e) {
      io_error(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });

  m.def("version", &VersionString, "Version string of the library.");

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
      .def("metadata", &sensor::SarGeometry::ToMetadata);

  m.def("simulate", &Simulate,
        "Simulate a SAR image. Keywords = SimulateOptions fields: dem or scene, heading_deg, depression_deg, "
        "slant_range_m, range_spacing_m, azimuth_spacing_m (m), mode, look_side, width, height, rays_per_cell, "
        "bounces, coherent, wavelength_m, range_resolution_m, azimuth_resolution_m, psf_window, speckle_looks, "
        "nesz_db, seed, fill_nodata, center_lonlat, center_map. Returns {'image': (H, W) float32 linear "
        "intensity, 'bounces': (4, H, W) single/double/triple/>=4, 'mask': (H, W) uint8 (1 layover, 2 shadow), "
        "'geometry': metadata, 'options': the options}. Identical to `gissar simulate`'s GeoTIFF.");

  m.def("load_scene", [](const std::string& path) {
        const scene::SceneFile s = scene::ReadScene(path);
        py::array_t<float> v({py::ssize_t(s.mesh.vertices.size()), py::ssize_t(3)});
        std::memcpy(v.mutable_data(), s.mesh.vertices.data(), s.mesh.vertices.size() * 12);
        py::array_t<int32_t> t({py::ssize_t(s.mesh.triangles.size()), py::ssize_t(3)});
        std::memcpy(t.mutable_data(), s.mesh.triangles.data(), s.mesh.triangles.size() * 12);
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
                          const std::string& osm, const std::string& config, bool fill_nodata) {
        cli::SceneBuildOptions o;
        o.dem = dem;
        o.out_prefix = out_prefix;
        o.vectors = vectors;
        o.osm = osm;
        o.config = config;
        o.fill_nodata = fill_nodata;
        o.quiet = true;
        cli::SceneBuildResult r;
        {
          py::gil_scoped_release release;
          r = cli::RunSceneBuild(o, "python");
        }
        return JsonToPython(r.summary);
      }, py::arg("dem"), py::arg("out_prefix"), py::arg("vectors") = std::vector<std::string>{},
      py::arg("osm") = "", py::arg("config") = "", py::arg("fill_nodata") = false,
      "`gissar scene build`: writes PREFIX.gscene/.ply/_classes.png/.json, returns the summary.");

  m.def("fmatrix", [](const py::array_t<double, py::array::c_style>& x1, const py::array_t<double, py::array::c_style>& x2,
                      std::optional<std::array<double, 2>> res1, std::optional<std::array<double, 2>> res2,
                      std::optional<std::array<double, 2>> depressions_deg, double threshold_px, uint64_t seed) {
        const auto matches = Matches(x1, x2);
        mvg::TwoViewOptions o;
        o.ransac.threshold_px = threshold_px;
        o.ransac.seed = seed;
        if (res1) o.k1 = mvg::SarIntrinsics((*res1)[0], (*res1)[1]);
        if (res2) o.k2 = mvg::SarIntrinsics((*res2)[0], (*res2)[1]);
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
      py::arg("depressions_deg") = py::none(), py::arg("threshold_px") = 1.5, py::arg("seed") = 1,
      "Affine fundamental matrix of (N, 2) pixel matches x1 <-> x2 (RANSAC + Gold Standard), KvD, heading change.");

  m.def("resect", [](const py::array_t<double, py::array::c_style>& world, const py::array_t<double, py::array::c_style>& pixels,
                     std::array<double, 3> scene_centre_enu_m) {
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
        o.scene_centre = {scene_centre_enu_m[0], scene_centre_enu_m[1], scene_centre_enu_m[2]};
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
      }, py::arg("world_enu_m"), py::arg("pixels"), py::arg("scene_centre_enu_m") = std::array<double, 3>{0, 0, 0},
      "Affine SAR resection from (N, 3) ENU points (m) and their (N, 2) pixels.");

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
}
