// Binds the mvg layer (multiple-view geometry of affine SAR cameras): fmatrix (affine fundamental matrix,
// KvD, heading change), kvd, resect, register_points and register_images.
#include "bindings.h"

#include <array>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/affine_fundamental.h"
#include "gissar/mvg/kvd.h"
#include "gissar/mvg/registration.h"
#include "gissar/mvg/resection.h"
#include "gissar/mvg/two_view.h"

namespace gissar::python {

namespace {

// A renamed keyword: DeprecationWarning naming the new one (docs/conventions.md:
// old spellings keep working for one release). Raises when warnings are errors.
void WarnDeprecatedKeyword(const std::string& old_keyword, const std::string& replacement) {
  const std::string message = old_keyword + " is deprecated and will be removed; use " + replacement;
  if (PyErr_WarnEx(PyExc_DeprecationWarning, message.c_str(), 1) != 0) throw py::error_already_set();
}

// fmatrix and kvd: the two-view relation and its reading.
void BindTwoViews(py::module_& m) {
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
}

// resect, register_points, register_images: a camera or a transform from control points.
void BindResectionAndRegistration(py::module_& m) {
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
}

}  // namespace

void BindMvg(py::module_& m) {
  BindTwoViews(m);
  BindResectionAndRegistration(m);
}

}  // namespace gissar::python
