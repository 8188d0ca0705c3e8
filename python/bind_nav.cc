// Binds the nav layer (positioning): match_images (the nav matchers between two SAR images, optionally
// through a predicted warp) and locate (`gissar locate`: the iterative pose fix against a Scene).
#include "bindings.h"

#include <array>
#include <cmath>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "gissar/geo/local_frame.h"
#include "gissar/material/material.h"
#include "gissar/nav/locate.h"
#include "gissar/nav/matching.h"
#include "gissar/pipeline/locate.h"
#include "gissar/render/embree_scene.h"

namespace gissar::python {

namespace {

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
      const auto ground = nav::SurfaceBelow(embree, c.x(), c.y());
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

}  // namespace

void BindNav(py::module_& m) {
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
}

}  // namespace gissar::python
