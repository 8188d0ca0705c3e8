#include "gissar/pipeline/mvg_commands.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "gissar/geo/raster_io.h"
#include "gissar/image/annotated.h"
#include "gissar/image/composite.h"
#include "gissar/image/epipolar_plot.h"
#include "gissar/image/quicklook.h"
#include "gissar/mvg/affine_camera.h"
#include "gissar/mvg/affine_fundamental.h"
#include "gissar/mvg/consensus.h"
#include "gissar/mvg/match_io.h"
#include "gissar/mvg/registration.h"
#include "gissar/mvg/resection.h"
#include "gissar/mvg/two_view.h"
#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json Matrix(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (int r = 0; r < m.rows(); ++r) {
    json row = json::array();
    for (int c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(row);
  }
  return rows;
}

void RequireOutput(const std::string& path, const std::string& option) {
  if (path.empty()) throw ConfigError("an output file is required", option);
}

void WriteJsonAtomically(const json& value, const std::string& path) {
  AtomicOutputs outputs;
  WriteJsonFile(value, outputs.Add(path));
  outputs.Commit();
}

void CheckSpacing(const std::optional<Eigen::Vector2d>& r, const std::string& option) {
  if (r && !(r->x() > 0 && r->y() > 0)) throw ConfigError("pixel spacings must be positive", option);
}

// Grey quicklook of any raster's first band (dB stretch).
std::vector<uint8_t> LoadGrey(const std::string& path, int* width, int* height, std::vector<float>* values) {
  geo::FloatRaster raster = geo::ReadFloatRaster(path);
  if (raster.bands.empty()) throw InputError("raster has no band", path);
  *width = raster.width;
  *height = raster.height;
  std::vector<float> band = raster.bands[0];
  for (float& v : band) v = std::max(v, 0.0f) + 1e-12f;  // byte images: 0 stays displayable
  std::vector<uint8_t> grey = image::DbQuicklook(band, 1.0, 99.0);
  if (values != nullptr) *values = std::move(raster.bands[0]);
  return grey;
}

// Grey quicklooks of an image pair, as EpipolarPlotInput holds them.
image::EpipolarPlotInput LoadGreyPair(const std::string& image1, const std::string& image2) {
  image::EpipolarPlotInput in;
  in.image1 = LoadGrey(image1, &in.width1, &in.height1, nullptr);
  in.image2 = LoadGrey(image2, &in.width2, &in.height2, nullptr);
  return in;
}

// The image pair (LoadGreyPair) with the matches and their epipolar lines under `f`.
image::RgbImage EpipolarPicture(const std::vector<mvg::PointMatch>& matches, const Eigen::Matrix3d& f,
                                const std::vector<int>& inliers, image::EpipolarPlotInput in) {
  std::vector<bool> inlier(matches.size(), false);
  for (int i : inliers) inlier[i] = true;
  in.inlier = inlier;
  for (const mvg::PointMatch& m : matches) {
    in.matches.push_back({m.p1, m.p2});
    in.lines_in_2.push_back(mvg::EpipolarLineInImage2(f, m.p1));
    in.lines_in_1.push_back(mvg::EpipolarLineInImage1(f, m.p2));
  }
  return image::DrawEpipolarPair(in);
}

}  // namespace

void FmatrixRequest::Check() const {
  if (matches.empty()) throw ConfigError("a matches CSV is required", "--matches");
  RequireOutput(json_out, "--out");
  CheckSpacing(range_spacing_m, "--range-spacing");
  CheckSpacing(azimuth_spacing_m, "--azimuth-spacing");
  if (range_spacing_m.has_value() != azimuth_spacing_m.has_value()) {
    throw ConfigError("give both --range-spacing R1,R2 and --azimuth-spacing A1,A2", "--range-spacing/--azimuth-spacing");
  }
  if (depressions && !(depressions->x() > 0 && depressions->x() < 90 && depressions->y() > 0 &&
                       depressions->y() < 90)) {
    throw ConfigError("depressions must be in (0, 90) degrees", "--depressions");
  }
  if (!(threshold_px > 0) || !std::isfinite(threshold_px)) throw ConfigError("threshold must be positive", "--threshold");
  if (image1.empty() != image2.empty()) throw ConfigError("give both images or none", "--image1/--image2");
  if (!image1.empty() && plot_prefix.empty()) throw ConfigError("images are drawn only with --plot", "--image1/--image2");
}

namespace {

// The final paths of fmatrix's outputs, each with the flag that names it:
// two naming the same file (also through links or different spellings) are
// a ConfigError naming both flags, before anything is read or written.
void CheckFmatrixOutputsDiffer(const std::vector<std::pair<std::string, std::string>>& outputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      const auto& [a, a_flag] = outputs[j];
      const auto& [b, b_flag] = outputs[i];
      if (a.empty() || b.empty()) continue;
      try {
        CheckOutputsAreNotInputs({a, b}, {});
      } catch (const ConfigError&) {
        const std::string flags = a_flag == b_flag ? a_flag : a_flag + " and " + b_flag;
        throw ConfigError(flags + " name the same file " + a + (a == b ? "" : " (also as " + b + ")"),
                          a_flag == b_flag ? a_flag : a_flag + "/" + b_flag);
      }
    }
  }
}

json ConsensusJson(const mvg::ConsensusTest& t) {
  return {{"inliers", t.inliers},
          {"matches", t.matches},
          {"chance_inlier_probability", t.chance_probability},
          {"expected_by_chance", t.expected_by_chance},
          {"p_value", t.p_value},
          {"required", t.required >= 0 ? json(t.required) : json(nullptr)},
          {"hypotheses", t.hypotheses},
          {"alpha", t.alpha},
          {"significant", t.significant}};
}

std::string Figure(double value, int digits) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*g", digits, value);
  return text;
}

// Why a consensus no better than chance is no result.
std::string NoConsensusReason(const mvg::ConsensusTest& t) {
  std::string reason = "no consensus better than chance: the best F has " + std::to_string(t.inliers) +
                       " inliers of " + std::to_string(t.matches) + " matches, " +
                       Figure(t.expected_by_chance, 3) + " expected from unrelated matches (p-value " +
                       Figure(t.p_value, 2) + "); ";
  if (t.required >= 0) {
    reason += std::to_string(t.required) + " are needed";
  } else {
    reason += "even all " + std::to_string(t.matches) + " would not be enough at this spread of the points";
  }
  return reason + " for a false-alarm rate of " + Figure(t.alpha, 2) + " over " + std::to_string(t.hypotheses) +
         " RANSAC samples";
}

}  // namespace

json RunFmatrix(const FmatrixRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  const std::string kvd_png = options.plot_prefix.empty() ? "" : options.plot_prefix + "_kvd.png";
  const std::string epipolar_png = options.image1.empty() ? "" : options.plot_prefix + "_epipolar.png";
  CheckFmatrixOutputsDiffer({{options.json_out, "--out"}, {kvd_png, "--plot"}, {epipolar_png, "--plot"}});
  CheckOutputsAreNotInputs({options.json_out, kvd_png, epipolar_png},
                           {options.matches, options.image1, options.image2});
  AtomicOutputs outputs;
  const fs::path json_path = outputs.Add(options.json_out);
  const std::vector<mvg::PointMatch> matches = mvg::ReadMatchesCsv(options.matches);
  if (matches.size() < 4) {
    throw InputError("at least 4 matches are needed, got " + std::to_string(matches.size()), options.matches);
  }
  // Every input is read before the outcome is decided: a bad image is an
  // error even when there is no result to draw.
  std::optional<image::EpipolarPlotInput> pair;
  if (!options.image1.empty()) pair = LoadGreyPair(options.image1, options.image2);
  mvg::TwoViewOptions two;
  two.robust = options.robust;
  two.ransac.threshold_px = options.threshold_px;
  two.ransac.seed = options.seed;
  if (options.range_spacing_m) {
    two.k1 = mvg::SarIntrinsics(options.range_spacing_m->x(), options.azimuth_spacing_m->x());
    two.k2 = mvg::SarIntrinsics(options.range_spacing_m->y(), options.azimuth_spacing_m->y());
  }
  if (options.depressions) {
    two.depression1_deg = options.depressions->x();
    two.depression2_deg = options.depressions->y();
  }
  std::optional<mvg::TwoViewAnalysis> analysis;
  try {
    analysis = mvg::AnalyseTwoViews(matches, two);
  } catch (const InputError& e) {
    throw InputError(e.message(), options.matches);
  }
  if (!analysis) {
    throw InputError("F is undetermined: the matches are degenerate (collinear or coplanar points, or no "
                     "consistent subset for RANSAC)",
                     options.matches);
  }
  const mvg::TwoViewAnalysis& a = *analysis;
  if (!std::isfinite(a.rms_gs_px) || !std::isfinite(a.rms_epi1_px) || !std::isfinite(a.rms_epi2_px)) {
    throw InputError("the fit of F is not finite (coordinates too large or degenerate)", options.matches);
  }
  json out = {{"command", "fmatrix"},
              {"command_line", command_line},
              {"version", VersionString()},
              {"options", options.ToJson()},
              {"inputs", json::array({InputFileRecord(options.matches)})},
              {"num_matches", a.num_matches}};
  if (pair) {
    out["inputs"].push_back(InputFileRecord(options.image1));
    out["inputs"].push_back(InputFileRecord(options.image2));
  }
  // RANSAC keeps the best of many hypotheses: its consensus must beat what
  // unrelated matches give by chance (mvg/consensus.h), else no result. One
  // fit to all matches (--no-ransac) tests no hypothesis.
  if (options.robust) {
    const int n = static_cast<int>(matches.size());
    const mvg::ConsensusTest consensus = mvg::TestConsensus(
        n, static_cast<int>(a.inliers.size()), mvg::ChanceInlierProbability(a.f, matches, options.threshold_px),
        std::max<int64_t>(1, std::min<int64_t>(a.ransac_iterations, mvg::DistinctSamples(n, 4))));
    out["consensus"] = ConsensusJson(consensus);
    if (!consensus.significant) {
      out["converged"] = false;
      out["reason"] = NoConsensusReason(consensus);
      out["ransac_iterations"] = a.ransac_iterations;
      out["pictures"] = json::array();  // nothing to draw
      WriteJsonFile(out, json_path);
      outputs.Commit();
      return out;
    }
  } else {
    out["consensus"] = nullptr;
  }
  out["converged"] = true;
  out["reason"] = nullptr;
  out.update({{"convention", "[x2 y2 1] F [x1 y1 1]' = 0, F = [0 0 a; 0 0 b; c d e], ||(a,b,c,d)|| = 1, c > 0"},
              {"F", Matrix(a.f)},
              {"F_calibrated", Matrix(a.f_calibrated)},
              {"calibrated", options.range_spacing_m.has_value()},
              {"inliers", a.inliers},
              {"rms_gs_px", a.rms_gs_px},
              {"rms_epi1_px", a.rms_epi1_px},
              {"rms_epi2_px", a.rms_epi2_px},
              {"ransac_iterations", a.ransac_iterations},
              {"kvd", {{"s", a.kvd.s}, {"theta_deg", a.kvd.theta_deg}, {"phi_deg", a.kvd.phi_deg},
                       {"rho", "not recoverable from two views (bas-relief ambiguity); needs a third view"}}}});
  if (a.sar) {
    out["heading_change_deg"] = a.sar->heading_change_deg;
    out["rho_abs_deg_from_model"] = a.sar->rho_abs_deg;
    out["phi_residual_deg"] = a.sar->phi_residual_deg;
    out["heading_change_candidates"] = a.sar->candidates;
  }
  if (!kvd_png.empty()) {
    const fs::path kvd_path = outputs.Add(kvd_png);
    const image::RgbImage kvd = image::KvdDiagram(a.kvd.s, a.kvd.theta_deg, a.kvd.phi_deg,
                                                  a.sar ? a.sar->heading_change_deg : 0.0, a.sar.has_value());
    geo::WritePng(kvd_path, kvd.rgb, kvd.width, kvd.height, 3);
    out["pictures"] = {kvd_png};
  }
  if (!epipolar_png.empty()) {
    const fs::path epipolar_path = outputs.Add(epipolar_png);
    const image::RgbImage picture = EpipolarPicture(matches, a.f, a.inliers, std::move(*pair));
    geo::WritePng(epipolar_path, picture.rgb, picture.width, picture.height, 3);
    out["pictures"].push_back(epipolar_png);
  }
  WriteJsonFile(out, json_path);
  outputs.Commit();
  return out;
}

void ResectRequest::Check() const {
  if (points.empty()) throw ConfigError("a points CSV is required", "--points");
  RequireOutput(json_out, "--out");
  if (!center_enu_m.allFinite() || center_enu_m.cwiseAbs().maxCoeff() > mvg::kMaxPointCoordinate) {
    throw ConfigError("scene centre must be finite and within [-1e9, 1e9] m", "--center-enu");
  }
  if (slant_range_m && !(*slant_range_m > 0)) throw ConfigError("slant range must be positive", "--slant-range");
}

json RunResect(const ResectRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  CheckOutputsAreNotInputs({options.json_out}, {options.points});
  const std::vector<mvg::ControlPoint> points = mvg::ReadControlPointsCsv(options.points);
  if (points.size() < 4) {
    throw InputError("at least 4 control points are needed, got " + std::to_string(points.size()), options.points);
  }
  mvg::ResectionOptions ro;
  ro.scene_centre = options.center_enu_m;
  ro.slant_range_m = options.slant_range_m;
  std::optional<mvg::ResectionResult> r;
  try {
    r = mvg::ResectSarCamera(points, ro);
  } catch (const InputError& e) {
    throw InputError(e.message(), options.points);
  }
  if (!r) {
    throw InputError("the camera is undetermined: control points are degenerate (coplanar or collinear)",
                     options.points);
  }
  // A fit that came out non-finite is never reported (let alone as converged).
  if (!std::isfinite(r->rms_px) || !std::isfinite(r->linear_rms_px) || !r->camera.allFinite() ||
      !std::isfinite(r->pose.heading_deg) || !std::isfinite(r->pose.depression_deg)) {
    throw InputError("the camera fit is not finite (coordinates too large or degenerate)", options.points);
  }
  json out = {{"command", "resect"},
              {"command_line", command_line},
              {"version", VersionString()},
              {"options", options.ToJson()},
              {"inputs", json::array({InputFileRecord(options.points)})},
              {"heading_deg", r->pose.heading_deg},
              {"depression_deg", r->pose.depression_deg},
              {"look_side", sensor::ToString(r->pose.look_side)},
              {"range_spacing_m", r->pose.range_spacing_m},
              {"azimuth_spacing_m", r->pose.azimuth_spacing_m},
              {"u0", r->pose.u0},
              {"v0", r->pose.v0},
              {"rms_px", r->rms_px},
              {"linear_rms_px", r->linear_rms_px},
              {"sigma", {{"heading_deg", r->heading_sigma_deg},
                         {"depression_deg", r->depression_sigma_deg},
                         {"range_spacing_m", r->range_spacing_sigma_m},
                         {"azimuth_spacing_m", r->azimuth_spacing_sigma_m}}},
              {"camera", Matrix(r->camera)},
              {"converged", r->converged}};
  if (r->sensor_position) {
    out["sensor_enu_m"] = {r->sensor_position->x(), r->sensor_position->y(), r->sensor_position->z()};
  }
  WriteJsonAtomically(out, options.json_out);
  return out;
}

void RegisterRequest::Check() const {
  if (fixed.empty()) throw ConfigError("a fixed image is required", "--fixed");
  if (moving.empty()) throw ConfigError("a moving image is required", "--moving");
  if (points.empty()) throw ConfigError("a control-point CSV is required", "--points");
  if (out_prefix.empty()) throw ConfigError("an output prefix is required", "--out");
  mvg::ParseTransformType(transform);
  if (!(threshold_px > 0)) throw ConfigError("threshold must be positive", "--threshold");
}

json RunRegister(const RegisterRequest& options, const std::string& command_line, Reporter& reporter) {
  options.Check();
  CheckOutputsAreNotInputs({options.out_prefix + ".tif", options.out_prefix + "_composite.png",
                            options.out_prefix + ".json"},
                           {options.fixed, options.moving, options.points});
  AtomicOutputs outputs;
  const fs::path tif = outputs.Add(options.out_prefix + ".tif");
  const fs::path png = outputs.Add(options.out_prefix + "_composite.png");
  const fs::path json_path = outputs.Add(options.out_prefix + ".json");
  const std::vector<mvg::PointMatch> pairs = mvg::ReadMatchesCsv(options.points);
  mvg::RegistrationOptions ro;
  ro.type = mvg::ParseTransformType(options.transform);
  ro.robust = options.robust;
  ro.threshold_px = options.threshold_px;
  if (static_cast<int>(pairs.size()) < mvg::MinimumControlPoints(ro.type)) {
    throw InputError("a " + options.transform + " transform needs at least " +
                         std::to_string(mvg::MinimumControlPoints(ro.type)) + " point pairs, got " +
                         std::to_string(pairs.size()),
                     options.points);
  }
  std::optional<mvg::Registration> reg;
  try {
    reg = mvg::RegisterControlPoints(pairs, ro);
  } catch (const InputError& e) {
    throw InputError(e.message(), options.points);
  }
  if (!reg) throw InputError("the transform is undetermined: control points are degenerate", options.points);
  int fw = 0, fh = 0, mw = 0, mh = 0;
  std::vector<float> moving_values;
  const std::vector<uint8_t> fixed_grey = LoadGrey(options.fixed, &fw, &fh, nullptr);
  const std::vector<uint8_t> moving_grey = LoadGrey(options.moving, &mw, &mh, &moving_values);
  const cv::Mat moving_f(mh, mw, CV_32F, moving_values.data());
  const cv::Mat warped = mvg::WarpToFixed(moving_f, *reg, cv::Size(fw, fh));
  std::vector<float> warped_values(warped.begin<float>(), warped.end<float>());
  geo::WriteFloatGeoTiff(tif, geo::FloatRaster{fw, fh, {warped_values}, {"registered"},
                                               {{"GISSAR_TRANSFORM", options.transform},
                                                {"GISSAR_VERSION", VersionString()}}});
  const cv::Mat moving_g(mh, mw, CV_8U, const_cast<uint8_t*>(moving_grey.data()));
  const cv::Mat warped_grey = mvg::WarpToFixed(moving_g, *reg, cv::Size(fw, fh));
  const cv::Mat composite =
      mvg::GreenMagentaComposite(cv::Mat(fh, fw, CV_8U, const_cast<uint8_t*>(fixed_grey.data())), warped_grey);
  cv::Mat rgb;
  cv::cvtColor(composite, rgb, cv::COLOR_BGR2RGB);
  geo::WritePng(png, std::vector<uint8_t>(rgb.data, rgb.data + size_t(fw) * fh * 3), fw, fh, 3);
  json out = {{"command", "register"},
              {"command_line", command_line},
              {"version", VersionString()},
              {"options", options.ToJson()},
              {"inputs", json::array({InputFileRecord(options.fixed), InputFileRecord(options.moving),
                                      InputFileRecord(options.points)})},
              {"transform", options.transform},
              {"num_pairs", pairs.size()},
              {"inliers", reg->inliers},
              {"rms_px", reg->rms_px},
              {"inverse_rms_px", reg->inverse_rms_px},
              {"residuals_px", reg->residuals_px}};
  WriteJsonFile(out, json_path);
  outputs.Commit();
  return out;
}

void EpipolarRequest::Check() const {
  if (matches.empty()) throw ConfigError("a matches CSV is required", "--matches");
  if (image1.empty() || image2.empty()) throw ConfigError("both images are required", "--image1/--image2");
  RequireOutput(out_png, "--out");
}

void RunEpipolar(const EpipolarRequest& options) {
  options.Check();
  CheckOutputsAreNotInputs({options.out_png}, {options.matches, options.image1, options.image2});
  AtomicOutputs outputs;
  const fs::path png = outputs.Add(options.out_png);
  const std::vector<mvg::PointMatch> matches = mvg::ReadMatchesCsv(options.matches);
  mvg::TwoViewOptions two;
  two.ransac.threshold_px = options.threshold_px;
  two.ransac.seed = options.seed;
  std::optional<mvg::TwoViewAnalysis> a;
  try {
    a = mvg::AnalyseTwoViews(matches, two);
  } catch (const InputError& e) {
    throw InputError(e.message(), options.matches);
  }
  if (!a) throw InputError("F is undetermined: the matches are degenerate", options.matches);
  const image::RgbImage picture =
      EpipolarPicture(matches, a->f, a->inliers, LoadGreyPair(options.image1, options.image2));
  geo::WritePng(png, picture.rgb, picture.width, picture.height, 3);
  outputs.Commit();
}

void CompositeRequest::Check() const {
  if (green.empty()) throw ConfigError("a first (green) image is required", "--green");
  if (magenta.empty()) throw ConfigError("a second (magenta) image is required", "--magenta");
  RequireOutput(out_png, "--out");
}

void RunComposite(const CompositeRequest& options) {
  options.Check();
  CheckOutputsAreNotInputs({options.out_png}, {options.green, options.magenta});
  AtomicOutputs outputs;
  const fs::path png = outputs.Add(options.out_png);
  const geo::FloatRaster a = geo::ReadFloatRaster(options.green);
  const geo::FloatRaster b = geo::ReadFloatRaster(options.magenta);
  if (a.width != b.width || a.height != b.height) {
    throw InputError("images differ in size: " + std::to_string(a.width) + " x " + std::to_string(a.height) +
                         " and " + std::to_string(b.width) + " x " + std::to_string(b.height),
                     options.magenta);
  }
  const image::RgbImage c = image::IntensityComposite(a.bands.at(0), b.bands.at(0), a.width, a.height);
  geo::WritePng(png, c.rgb, c.width, c.height, 3);
  outputs.Commit();
}

}  // namespace gissar::pipeline
