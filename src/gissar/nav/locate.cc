#include "gissar/nav/locate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "gissar/mvg/registration.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"

namespace gissar::nav {
namespace {

constexpr double kDeg = M_PI / 180.0;
// A dense Gauss-Newton step that moves no pixel by more than this ends the
// iterations: 20 times below the dense stage's own settling (a pose update
// under 0.02 px), so further steps cannot change a fix that matters.
constexpr double kDenseSettledPx = 1e-3;
// A reference rendered at a pose that has since moved no pixel by more
// than this (the patch stage's own settling) serves the next step instead
// of a new render (a fifth of a fix each): the dense stage's first fit
// starts from its pose, and the result's whole-image NCC does not change
// at that scale.
constexpr double kReferenceReusePx = 0.1;

Eigen::Vector3d UpNormal(const sensor::SarGeometry& g) {
  Eigen::Vector3d n = g.range_plane_normal();
  return n.z() < 0 ? Eigen::Vector3d(-n) : n;
}

// Moves `pose` by (d_heading, d_depression) and the image-centre ground
// point by (a, b) metres along the new l and h; nullopt when the new
// centre misses the scene or the depression leaves (1, 89) degrees.
std::optional<NavPose> Moved(const NavScene& scene, const NavPose& pose, const SensorModel& model,
                             double d_heading, double d_depression, double a, double b) {
  NavPose p = pose;
  p.heading_deg += d_heading;
  p.depression_deg += d_depression;
  if (!(p.depression_deg > 1.0 && p.depression_deg < 89.0)) return std::nullopt;
  const sensor::SarGeometry g = GeometryOf(p, model);
  const Eigen::Vector3d base = pose.centre_enu + a * g.look_direction() + b * g.flight_direction();
  const auto centre = SurfaceAlongNormal(*scene.embree, base, UpNormal(g));
  if (!centre) return std::nullopt;
  p.centre_enu = *centre;
  return p;
}

double Similarity(const Reference& ref, const cv::Mat& observed_log, int filter_px, double floor) {
  const cv::Mat ref_log = LogIntensity(ref.intensity, ref.geometry.width(), ref.geometry.height(), filter_px, floor);
  return ImageNcc(ref_log, observed_log);
}

// Resection with the sensor's known pixel spacings: Gauss-Newton on
// (heading, depression, u0, v0) of x = u0 + (X - Xc).l / dr,
// y = v0 + (X - Xc).h / da (the scene centre Xc fixed). Unlike the general
// mvg::ResectSarCamera, which also fits both spacings, the known range
// spacing makes the range scale cos(depression) / dr pin the depression.
struct KnownSpacingResection {
  double heading_deg = 0, depression_deg = 0, u0 = 0, v0 = 0;
  Eigen::Vector4d sigma = Eigen::Vector4d::Zero();  // deg, deg, px, px
  double rms_px = 0;
};

std::optional<KnownSpacingResection> ResectKnownSpacing(const std::vector<Eigen::Vector3d>& world,
                                                         const std::vector<Eigen::Vector2d>& pixels,
                                                         const Eigen::Vector3d& xc, const SensorModel& model,
                                                         double heading_deg, double depression_deg) {
  const int n = static_cast<int>(world.size());
  if (n < 4) return std::nullopt;
  Eigen::Vector4d p(heading_deg, depression_deg, 0.0, 0.0);
  auto residuals = [&](const Eigen::Vector4d& q) {
    const Eigen::Vector3d l = sensor::LookDirection(q[0], q[1], model.look_side);
    const Eigen::Vector3d h = sensor::FlightDirection(q[0]);
    Eigen::VectorXd r(2 * n);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d d = world[i] - xc;
      r[2 * i] = q[2] + d.dot(l) / model.range_spacing_m - pixels[i].x();
      r[2 * i + 1] = q[3] + d.dot(h) / model.azimuth_spacing_m - pixels[i].y();
    }
    return r;
  };
  // Start u0, v0 from the mean residual.
  const Eigen::VectorXd r0 = residuals(p);
  double sx = 0, sy = 0;
  for (int i = 0; i < n; ++i) { sx += r0[2 * i]; sy += r0[2 * i + 1]; }
  p[2] = -sx / n;
  p[3] = -sy / n;
  Eigen::MatrixXd J(2 * n, 4);
  for (int it = 0; it < 20; ++it) {
    const Eigen::VectorXd r = residuals(p);
    const Eigen::Vector4d eps(1e-5, 1e-5, 1e-3, 1e-3);
    for (int k = 0; k < 4; ++k) {
      Eigen::Vector4d q = p;
      q[k] += eps[k];
      J.col(k) = (residuals(q) - r) / eps[k];
    }
    const Eigen::Vector4d step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    if (!step.allFinite()) return std::nullopt;
    p += step;
    if (std::abs(step[0]) < 1e-9 && std::abs(step[1]) < 1e-9 && step.tail<2>().norm() < 1e-7) break;
  }
  if (!(p[1] > 1.0 && p[1] < 89.0)) return std::nullopt;
  const Eigen::VectorXd r = residuals(p);
  KnownSpacingResection out;
  out.heading_deg = p[0];
  out.depression_deg = p[1];
  out.u0 = p[2];
  out.v0 = p[3];
  out.rms_px = std::sqrt(r.squaredNorm() / n);
  if (2 * n > 4) {
    const double s2 = r.squaredNorm() / (2 * n - 4);
    const Eigen::Matrix4d cov = s2 * (J.transpose() * J).inverse();
    out.sigma = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
  }
  return out;
}

// The pose a resection moves `pose` to, and the size of that move in pixels
// (the largest of the centre shift, the rotation at the image edge and the
// range rescaling of the depression change at the image edge); nullopt when
// the new line of sight leaves the scene.
struct PoseStep {
  NavPose pose;
  double update_px = 0.0;
};
std::optional<PoseStep> StepTo(const NavScene& scene, const NavPose& pose, const SensorModel& model,
                               const KnownSpacingResection& res) {
  const double a = ((model.width - 1) / 2.0 - res.u0) * model.range_spacing_m;
  const double b = ((model.height - 1) / 2.0 - res.v0) * model.azimuth_spacing_m;
  const double d_heading = std::remainder(res.heading_deg - pose.heading_deg, 360.0);
  const double d_depression = res.depression_deg - pose.depression_deg;
  const auto next = Moved(scene, pose, model, d_heading, d_depression, a, b);
  if (!next) return std::nullopt;
  const double rotation_px = std::abs(d_heading) * kDeg * 0.5 * std::max(model.width, model.height);
  // A depression change rescales the range axis by ~tan(delta) d_delta.
  const double tilt_px = std::abs(d_depression) * kDeg * std::tan(pose.depression_deg * kDeg) * 0.5 * model.width;
  return PoseStep{*next, std::max({std::abs(a) / model.range_spacing_m, std::abs(b) / model.azimuth_spacing_m,
                                   rotation_px, tilt_px})};
}

// Dense refinement of (heading, depression, u0, v0): Gauss-Newton on the
// log-intensity difference of every usable reference pixel. The 3-D point X
// of reference pixel c moves to c + P_q(X) - P_q0(X) in the observed image
// (P_q: the affine camera of the parameters q, P_q0 the reference's). The
// observed log image there is predicted as 10 log10(sum_k g_k B_k(c) + floor),
// B_k the box-filtered intensity of class k (LogIntensity's filter, which is
// linear) and g_k = 10^(a_k / 10) the class's fitted gain: the scene's
// materials are known to a few dB only, and a mismatch moves a class's
// returns by one factor, in mixed pixels too. The gains carry a weak prior
// (a_k ~ N(0, 10 dB)) so that a class seen in few pixels stays determined.
// Pixels: valid reference pixels at least 2 px inside the image; residuals
// are Huber-weighted (1.345 robust sigmas). `rms_px` of the result is the
// robust RMS residual in dB. nullopt when fewer than 64 pixels are usable or
// the normal equations are singular.
std::optional<KnownSpacingResection> DenseRefine(const Reference& ref, const cv::Mat& obs_log,
                                                 const Eigen::Vector3d& xc, const SensorModel& model,
                                                 double heading_deg, double depression_deg, int iterations,
                                                 int filter_px, double floor) {
  const int w = model.width, h = model.height;
  const int classes = static_cast<int>(ref.class_intensity.size());
  if (classes == 0) return std::nullopt;
  std::vector<cv::Mat> box(classes);
  for (int k = 0; k < classes; ++k) box[k] = BoxMean(ref.class_intensity[k], filter_px);
  cv::Mat gx, gy;  // gradients of the observed log image, dB per pixel
  cv::Sobel(obs_log, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(obs_log, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  struct Sample { Eigen::Vector3d d; Eigen::Vector2d c0; };
  std::vector<Sample> samples;
  std::vector<double> class_box;  // classes values per sample
  const Eigen::Vector3d l0 = sensor::LookDirection(heading_deg, depression_deg, model.look_side);
  const Eigen::Vector3d h0 = sensor::FlightDirection(heading_deg);
  for (int y = 2; y < h - 2; ++y)
    for (int x = 2; x < w - 2; ++x) {
      if (ref.valid.at<uint8_t>(y, x) == 0) continue;
      const cv::Vec3f p = ref.points.at<cv::Vec3f>(y, x);
      const Eigen::Vector3d d = Eigen::Vector3d(p[0], p[1], p[2]) - xc;
      // c0 = c - P_q0(X): P_q0 images Xc at the image centre.
      const Eigen::Vector2d c0(x - (w - 1) / 2.0 - d.dot(l0) / model.range_spacing_m,
                               y - (h - 1) / 2.0 - d.dot(h0) / model.azimuth_spacing_m);
      samples.push_back({d, c0});
      for (int k = 0; k < classes; ++k) class_box.push_back(std::max(0.0f, box[k].at<float>(y, x)));
    }
  if (samples.size() < 64) return std::nullopt;
  // Parameters: heading, depression (deg), u0, v0 (px), a_k (dB) per class.
  const int np = 4 + classes;
  Eigen::VectorXd q = Eigen::VectorXd::Zero(np);
  q << heading_deg, depression_deg, (w - 1) / 2.0, (h - 1) / 2.0, Eigen::VectorXd::Zero(classes);
  constexpr double kGainPriorDb = 10.0;
  constexpr double kEps = 1e-6;
  constexpr double kDbPerNeper = 10.0 / M_LN10;
  KnownSpacingResection out;  // sigma stays zero: the pixels are correlated
  double rms = 0;
  Eigen::MatrixXd normal(np, np);
  Eigen::VectorXd rhs(np), gains(classes);
  // One row per used sample (filled in place, no allocation per pixel); the
  // normal equations are then one weighted product J^T W J.
  Eigen::MatrixXd jac(static_cast<Eigen::Index>(samples.size()), np);
  Eigen::VectorXd residual(static_cast<Eigen::Index>(samples.size()));
  for (int it = 0; it < iterations; ++it) {
    const Eigen::Vector3d l = sensor::LookDirection(q[0], q[1], model.look_side);
    const Eigen::Vector3d hh = sensor::FlightDirection(q[0]);
    const Eigen::Vector3d dl_dh = (sensor::LookDirection(q[0] + kEps, q[1], model.look_side) - l) / kEps;
    const Eigen::Vector3d dl_dd = (sensor::LookDirection(q[0], q[1] + kEps, model.look_side) - l) / kEps;
    const Eigen::Vector3d dh_dh = (sensor::FlightDirection(q[0] + kEps) - hh) / kEps;
    for (int k = 0; k < classes; ++k) gains[k] = std::pow(10.0, q[4 + k] / 10.0);
    Eigen::Index used = 0;
    for (size_t i = 0; i < samples.size(); ++i) {
      const Sample& s = samples[i];
      const double ox = s.c0.x() + q[2] + s.d.dot(l) / model.range_spacing_m;
      const double oy = s.c0.y() + q[3] + s.d.dot(hh) / model.azimuth_spacing_m;
      if (ox < 1 || oy < 1 || ox > w - 2.001 || oy > h - 2.001) continue;
      const double* b = class_box.data() + i * classes;
      double sum = floor;
      for (int k = 0; k < classes; ++k) sum += gains[k] * b[k];
      // The observed log image and its gradients at (ox, oy): one set of
      // bilinear weights for the three.
      const int x0 = static_cast<int>(std::floor(ox)), y0 = static_cast<int>(std::floor(oy));
      const double fx = ox - x0, fy = oy - y0;
      const double w00 = (1 - fy) * (1 - fx), w01 = (1 - fy) * fx, w10 = fy * (1 - fx), w11 = fy * fx;
      auto at = [&](const cv::Mat& m) {
        const float* r0 = m.ptr<float>(y0) + x0;
        const float* r1 = m.ptr<float>(y0 + 1) + x0;
        return w00 * r0[0] + w01 * r0[1] + w10 * r1[0] + w11 * r1[1];
      };
      const double ogx = at(gx), ogy = at(gy);
      auto j = jac.row(used);
      j[0] = ogx * s.d.dot(dl_dh) / model.range_spacing_m + ogy * s.d.dot(dh_dh) / model.azimuth_spacing_m;
      j[1] = ogx * s.d.dot(dl_dd) / model.range_spacing_m;
      j[2] = ogx;
      j[3] = ogy;
      for (int k = 0; k < classes; ++k) j[4 + k] = -gains[k] * b[k] / sum;
      residual[used] = at(obs_log) - kDbPerNeper * std::log(sum);
      ++used;
    }
    if (used < 64) return std::nullopt;
    const auto r = residual.head(used);
    std::vector<double> a(static_cast<size_t>(used));
    for (Eigen::Index i = 0; i < used; ++i) a[i] = std::abs(r[i]);
    std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
    const double sigma = std::max(1.4826 * a[a.size() / 2], 1e-3);
    const double huber = 1.345 * sigma;
    // Huber weights; the normal equations J^T W J and J^T W r in one pass of
    // the (used x np) matrix.
    const Eigen::VectorXd wt =
        r.array().abs().unaryExpr([huber](double v) { return v <= huber ? 1.0 : huber / v; }).matrix();
    const Eigen::MatrixXd weighted = wt.cwiseSqrt().asDiagonal() * jac.topRows(used);
    normal.setZero();
    normal.selfadjointView<Eigen::Lower>().rankUpdate(weighted.transpose());
    normal = normal.selfadjointView<Eigen::Lower>();
    rhs = -(jac.topRows(used).transpose() * wt.cwiseProduct(r));
    const double wsum = wt.sum();
    const double wr2 = wt.dot(r.cwiseProduct(r));
    // The gains' prior, in units of the pixel residuals' variance.
    const double prior_weight = sigma * sigma / (kGainPriorDb * kGainPriorDb);
    for (int k = 0; k < classes; ++k) {
      normal(4 + k, 4 + k) += prior_weight;
      rhs[4 + k] -= prior_weight * q[4 + k];
    }
    const Eigen::VectorXd step = normal.ldlt().solve(rhs);
    if (!step.allFinite()) return std::nullopt;
    q += step;
    rms = std::sqrt(wr2 / std::max(wsum, 1.0));
    // Settled: the step moves no pixel by more than kDenseSettledPx (the
    // rotation at the image edge, the range rescaling of the depression
    // change at the image edge, the shift), as StepTo measures a pose update.
    const double step_px = std::max({std::abs(step[0]) * kDeg * 0.5 * std::max(w, h),
                                     std::abs(step[1]) * kDeg * std::tan(q[1] * kDeg) * 0.5 * w,
                                     std::abs(step[2]), std::abs(step[3])});
    if (step_px < kDenseSettledPx) break;
  }
  if (!(q[1] > 1.0 && q[1] < 89.0)) return std::nullopt;
  out.heading_deg = q[0];
  out.depression_deg = q[1];
  out.u0 = q[2];
  out.v0 = q[3];
  out.rms_px = rms;
  return out;
}

}  // namespace

Eigen::Vector3d NavPose::LookDirection(sensor::LookSide side) const {
  return sensor::LookDirection(heading_deg, depression_deg, side);
}

Eigen::Vector3d NavPose::SensorPosition(sensor::LookSide side) const {
  return centre_enu - slant_range_m * LookDirection(side);
}

void SensorModel::Check() const {
  if (!(range_spacing_m > 0.0) || !std::isfinite(range_spacing_m)) throw ConfigError("must be > 0", "range_spacing_m");
  if (!(azimuth_spacing_m > 0.0) || !std::isfinite(azimuth_spacing_m)) throw ConfigError("must be > 0", "azimuth_spacing_m");
  if (width < 48 || height < 48) throw ConfigError("image must be at least 48 x 48 pixels", "width/height");
}

void LocateOptions::Check() const {
  if (filter_px < 1 || filter_px > 15) throw ConfigError("must be in [1, 15]", "filter_px");
  MatchOptions m;
  m.patch_px = patch_px;
  m.step_px = step_px;
  m.search_px = std::min(initial_search_px, refine_search_px);
  m.Check();
  if (initial_search_px < refine_search_px) throw ConfigError("must be >= refine_search_px", "initial_search_px");
  if (max_iterations < 1) throw ConfigError("must be >= 1", "max_iterations");
  if (!(ransac_threshold_px > 0.0)) throw ConfigError("must be > 0", "ransac_threshold_px");
  if (min_matches < 6) throw ConfigError("must be >= 6", "min_matches");
  if (dense_renders < 0) throw ConfigError("must be >= 0", "dense_renders");
  if (dense_iterations < 1) throw ConfigError("must be >= 1", "dense_iterations");
  if (polish_evaluations < 0) throw ConfigError("must be >= 0", "polish_evaluations");
  if (!(reference_floor > 0.0) || !std::isfinite(reference_floor)) throw ConfigError("must be > 0", "reference_floor");
}

sensor::SarGeometryOptions AffineGeometryOptions(const NavPose& pose, const SensorModel& model) {
  sensor::SarGeometryOptions o;
  o.heading_deg = pose.heading_deg;
  o.depression_deg = pose.depression_deg;
  o.look_side = model.look_side;
  o.slant_range_m = pose.slant_range_m;
  o.range_spacing_m = model.range_spacing_m;
  o.azimuth_spacing_m = model.azimuth_spacing_m;
  o.mode = sensor::ProjectionMode::kAffine;
  o.width = model.width;
  o.height = model.height;
  return o;
}

sensor::SarGeometry GeometryOf(const NavPose& pose, const SensorModel& model) {
  return sensor::SarGeometry(AffineGeometryOptions(pose, model), pose.centre_enu, (model.width - 1) / 2.0,
                             (model.height - 1) / 2.0, model.width, model.height);
}

std::optional<Eigen::Vector3d> SurfaceAlongNormal(const render::EmbreeScene& embree, const Eigen::Vector3d& base,
                                                  const Eigen::Vector3d& n_up) {
  const Eigen::AlignedBox3d& box = embree.bounds();
  if (!(n_up.z() > 1e-6)) return std::nullopt;
  const double t0 = (box.max().z() + 100.0 - base.z()) / n_up.z();
  const Eigen::Vector3d start = base + t0 * n_up;
  const auto hit = embree.Intersect(start.cast<float>(), (-n_up).cast<float>(), 0.0f,
                                    std::numeric_limits<float>::infinity());
  if (!hit) return std::nullopt;
  return start - double(hit->t) * n_up;
}

std::optional<Eigen::Vector3d> SurfaceBelow(const render::EmbreeScene& embree, double x, double y) {
  return SurfaceAlongNormal(embree, Eigen::Vector3d(x, y, 0.0), Eigen::Vector3d::UnitZ());
}

Reference RenderReference(const NavScene& scene, const NavPose& pose, const SensorModel& model) {
  Reference ref{GeometryOf(pose, model), {}, {}, {}, {}, {}};
  render::RenderOptions ro;
  ro.rays_per_cell = scene.rays_per_cell;
  ro.max_bounces = scene.bounces;
  ro.record_contributions = true;
  render::SarImage image = render::RenderSar(*scene.embree, *scene.mesh, *scene.materials, ref.geometry, ro);
  ref.intensity = std::move(image.intensity);
  const int w = model.width, h = model.height;
  cv::Mat sum(h, w, CV_64FC3, cv::Scalar::all(0)), weight(h, w, CV_64F, cv::Scalar(0));
  // Intensity per (pixel, class of the last hit), every bounce.
  int class_count = 0;
  for (const render::Contribution& c : image.contributions) class_count = std::max(class_count, c.class_id + 1);
  std::vector<double> class_weight(size_t(w) * h * class_count, 0.0);
  std::vector<double> class_total(class_count, 0.0);
  // One pass: every bounce's intensity by class, and the single-bounce
  // hits' intensity-weighted mean point.
  for (const render::Contribution& c : image.contributions) {
    const int x = static_cast<int>(std::lround(ref.geometry.ColumnOfRange(c.range_m)));
    const int y = static_cast<int>(std::lround(ref.geometry.RowOfAlongTrack(c.azimuth_m)));
    if (x < 0 || y < 0 || x >= w || y >= h) continue;
    class_weight[(size_t(y) * w + x) * class_count + c.class_id] += c.intensity;
    class_total[c.class_id] += c.intensity;
    if (c.bounces != 1) continue;
    const double wt = double(c.intensity) + 1e-9;
    cv::Vec3d& s = sum.at<cv::Vec3d>(y, x);
    for (int k = 0; k < 3; ++k) s[k] += wt * c.hit_enu[k];
    weight.at<double>(y, x) += wt;
  }
  for (int k = 0; k < class_count; ++k) {
    if (!(class_total[k] > 0)) continue;
    ref.class_ids.push_back(k);
    ref.class_intensity.emplace_back(h, w, CV_32F, cv::Scalar(0));
  }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double* cw = class_weight.data() + (size_t(y) * w + x) * class_count;
      double total = 0;
      for (int k = 0; k < class_count; ++k) total += cw[k];
      if (!(total > 0)) continue;
      const double pixel = ref.intensity[size_t(y) * w + x];
      for (size_t i = 0; i < ref.class_ids.size(); ++i)
        ref.class_intensity[i].at<float>(y, x) = static_cast<float>(pixel * cw[ref.class_ids[i]] / total);
    }
  ref.points = cv::Mat(h, w, CV_32FC3, cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  ref.valid = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double wt = weight.at<double>(y, x);
      if (wt <= 0) continue;
      const cv::Vec3d s = sum.at<cv::Vec3d>(y, x) / wt;
      ref.points.at<cv::Vec3f>(y, x) = cv::Vec3f(float(s[0]), float(s[1]), float(s[2]));
      if ((image.mask[size_t(y) * w + x] & render::kMaskLayover) == 0) ref.valid.at<uint8_t>(y, x) = 255;
    }
  return ref;
}

ControlMatches MatchReference(const Reference& reference, const cv::Mat& observed_log, Matcher matcher,
                              const MatchOptions& match, int filter_px, double ransac_threshold_px,
                              double reference_floor) {
  ControlMatches out;
  const cv::Mat ref_log = LogIntensity(reference.intensity, reference.geometry.width(),
                                       reference.geometry.height(), filter_px, reference_floor);
  const std::vector<Correspondence> corr = Match(matcher, ref_log, observed_log, match, reference.valid);
  out.raw = static_cast<int>(corr.size());
  if (corr.size() < 6) return out;
  std::vector<mvg::PointMatch> pairs;
  for (const Correspondence& c : corr) pairs.push_back({c.observed, c.reference});
  mvg::RegistrationOptions ro;
  ro.type = mvg::TransformType::kAffine;
  ro.threshold_px = ransac_threshold_px;
  ro.seed = 7;
  const auto reg = mvg::RegisterControlPoints(pairs, ro);
  if (!reg) return out;
  for (int i : reg->inliers) {
    const Correspondence& c = corr[i];
    const int x = static_cast<int>(std::lround(c.reference.x()));
    const int y = static_cast<int>(std::lround(c.reference.y()));
    const cv::Vec3f p = reference.points.at<cv::Vec3f>(y, x);
    if (!std::isfinite(p[0])) continue;
    const Eigen::Vector3d world(p[0], p[1], p[2]);
    // The mean hit projects near, not exactly at, the pixel centre: move the
    // observed pixel by the same sub-pixel offset.
    const Eigen::Vector2d offset = reference.geometry.Project(world) - c.reference;
    out.world.push_back(world);
    out.observed.push_back(c.observed + offset);
  }
  return out;
}

namespace {

// The polish: Nelder-Mead on -NCC over (heading, depression, shift along
// l, along h) from `pose`, about `options.polish_evaluations` evaluations
// (a shrink takes 4 at once). The best vertex's pose, or `pose` when that
// vertex leaves the scene. `renders` counts the references rendered.
NavPose PolishPose(const NavScene& scene, const SensorModel& model, const NavPose& pose, const cv::Mat& obs_log,
                   const LocateOptions& options, const ReferenceSource& source, int* renders) {
  auto cost = [&](const Eigen::Vector4d& q) {
    const auto p = Moved(scene, pose, model, q[0], q[1], q[2], q[3]);
    if (!p) return 2.0;
    ++*renders;
    return -Similarity(source(*p), obs_log, options.filter_px, options.reference_floor);
  };
  std::vector<Eigen::Vector4d> simplex(5, Eigen::Vector4d::Zero());
  const Eigen::Vector4d steps(0.05, 0.1, 0.3 * model.range_spacing_m, 0.3 * model.azimuth_spacing_m);
  for (int k = 0; k < 4; ++k) simplex[k + 1][k] = steps[k];
  std::vector<double> f(5);
  for (int k = 0; k < 5; ++k) f[k] = cost(simplex[k]);
  int evaluations = 5;
  while (evaluations < options.polish_evaluations) {
    std::vector<int> order{0, 1, 2, 3, 4};
    std::sort(order.begin(), order.end(), [&](int i, int j) { return f[i] < f[j]; });
    std::vector<Eigen::Vector4d> s2;
    std::vector<double> f2;
    for (int i : order) { s2.push_back(simplex[i]); f2.push_back(f[i]); }
    simplex = s2;
    f = f2;
    Eigen::Vector4d centroid = Eigen::Vector4d::Zero();
    for (int k = 0; k < 4; ++k) centroid += simplex[k] / 4.0;
    const Eigen::Vector4d xr = centroid + (centroid - simplex[4]);
    const double fr = cost(xr);
    ++evaluations;
    if (fr < f[0]) {
      const Eigen::Vector4d xe = centroid + 2.0 * (centroid - simplex[4]);
      const double fe = cost(xe);
      ++evaluations;
      if (fe < fr) { simplex[4] = xe; f[4] = fe; } else { simplex[4] = xr; f[4] = fr; }
    } else if (fr < f[3]) {
      simplex[4] = xr; f[4] = fr;
    } else {
      const Eigen::Vector4d xc = centroid + 0.5 * (simplex[4] - centroid);
      const double fc = cost(xc);
      ++evaluations;
      if (fc < f[4]) { simplex[4] = xc; f[4] = fc; }
      else {
        for (int k = 1; k < 5; ++k) { simplex[k] = simplex[0] + 0.5 * (simplex[k] - simplex[0]); f[k] = cost(simplex[k]); }
        evaluations += 4;
      }
    }
  }
  const int best = static_cast<int>(std::min_element(f.begin(), f.end()) - f.begin());
  if (const auto p = Moved(scene, pose, model, simplex[best][0], simplex[best][1], simplex[best][2],
                           simplex[best][3])) {
    return *p;
  }
  return pose;
}

}  // namespace

LocateResult Locate(const NavScene& scene, const SensorModel& model, const std::vector<float>& observed,
                    const NavPose& prior, const LocateOptions& options) {
  return Locate(scene, model, observed, prior, options,
                [&](const NavPose& pose) { return RenderReference(scene, pose, model); });
}

LocateResult Locate(const NavScene& scene, const SensorModel& model, const std::vector<float>& observed,
                    const NavPose& prior, const LocateOptions& options, const ReferenceSource& source) {
  options.Check();
  model.Check();
  if (observed.size() != size_t(model.width) * size_t(model.height)) {
    throw InputError("observed image is not width x height", "nav::Locate");
  }
  Stopwatch clock;
  LocateResult result;
  result.pose = prior;
  const cv::Mat obs_log = LogIntensity(observed, model.width, model.height, options.filter_px);
  NavPose pose = prior;
  int search = options.initial_search_px;
  double last_update_px = std::numeric_limits<double>::infinity();
  // The last reference rendered, the pose it was rendered at and how far
  // (px) the pose moved since: the dense stage's first fit and the result's
  // similarity reuse it when that move is below kReferenceReusePx.
  std::optional<Reference> last_ref;
  NavPose last_ref_pose = pose;
  double moved_since_last_ref_px = 0.0;
  const auto render_at = [&](const NavPose& at) -> const Reference& {
    last_ref.emplace(source(at));
    last_ref_pose = at;
    moved_since_last_ref_px = 0.0;
    ++result.renders;
    return *last_ref;
  };
  for (int it = 0; it < options.max_iterations; ++it) {
    const Reference& ref = render_at(pose);
    if (it == 0) result.prior_similarity = Similarity(ref, obs_log, options.filter_px, options.reference_floor);
    MatchOptions mo;
    mo.patch_px = options.patch_px;
    mo.step_px = options.step_px;
    mo.search_px = search;
    const ControlMatches cm = MatchReference(ref, obs_log, options.matcher, mo, options.filter_px,
                                             options.ransac_threshold_px, options.reference_floor);
    result.iterations = it + 1;
    result.matches = cm.raw;
    result.inliers = static_cast<int>(cm.world.size());
    if (result.inliers < options.min_matches) {
      result.failure_reason = "too few consistent matches between the image and the reference (" +
                              std::to_string(result.inliers) + " after RANSAC of " + std::to_string(cm.raw) +
                              ", at least " + std::to_string(options.min_matches) + " needed)";
      break;
    }
    const auto res = ResectKnownSpacing(cm.world, cm.observed, pose.centre_enu, model, pose.heading_deg,
                                        pose.depression_deg);
    if (!res) {
      result.failure_reason = "the matches determine no camera (degenerate control points)";
      break;
    }
    const auto step = StepTo(scene, pose, model, *res);
    if (!step) {
      result.failure_reason = "the resected pose's line of sight leaves the scene";
      break;
    }
    result.rms_px = res->rms_px;
    result.heading_sigma_deg = res->sigma[0];
    result.depression_sigma_deg = res->sigma[1];
    result.position_sigma_lhn_m = Eigen::Vector3d(res->sigma[2] * model.range_spacing_m,
                                                  res->sigma[3] * model.azimuth_spacing_m,
                                                  pose.slant_range_m * res->sigma[1] * kDeg);
    last_update_px = step->update_px;
    moved_since_last_ref_px = step->update_px;
    pose = step->pose;
    search = last_update_px > options.refine_search_px - 1 ? options.initial_search_px : options.refine_search_px;
    if (last_update_px < 0.1) break;
  }
  // Dense stage: from inside its basin (the patch stage's last update below
  // 2 px; infinite when the patch stage found no camera). Each fit starts
  // from the pose its reference was rendered at: the first fit takes the
  // patch stage's last reference when the pose moved less than
  // kReferenceReusePx since (the fit moves it on from there).
  for (int k = 0; k < options.dense_renders && last_update_px < 2.0; ++k) {
    const bool reuse = k == 0 && last_ref && moved_since_last_ref_px < kReferenceReusePx;
    const Reference& ref = reuse ? *last_ref : render_at(pose);
    const NavPose base = last_ref_pose;
    const auto res = DenseRefine(ref, obs_log, base.centre_enu, model, base.heading_deg, base.depression_deg,
                                 options.dense_iterations, options.filter_px, options.reference_floor);
    if (!res) break;
    const auto step = StepTo(scene, base, model, *res);
    if (!step) break;
    pose = step->pose;
    last_update_px = step->update_px;
    moved_since_last_ref_px = step->update_px;
    result.dense_renders = k + 1;
    result.dense_rms_db = res->rms_px;
    if (last_update_px < 0.02) break;
  }
  result.converged = last_update_px < 0.5;
  if (result.converged) {
    result.failure_reason.clear();
  } else if (result.failure_reason.empty()) {
    result.failure_reason = "the pose update did not settle below 0.5 px in " + std::to_string(result.iterations) +
                            " iterations (last " + std::to_string(last_update_px) + " px)";
  }

  if (options.polish_evaluations > 0 && result.converged) {
    last_ref.reset();  // the polish moves the pose by its own rule
    pose = PolishPose(scene, model, pose, obs_log, options, source, &result.renders);
  }
  result.pose = pose;
  result.sensor_enu = pose.SensorPosition(model.look_side);
  if (last_ref && moved_since_last_ref_px < kReferenceReusePx) {
    result.similarity = Similarity(*last_ref, obs_log, options.filter_px, options.reference_floor);
  } else {
    result.similarity = Similarity(source(pose), obs_log, options.filter_px, options.reference_floor);
    ++result.renders;
  }
  result.seconds = clock.ElapsedSeconds();
  return result;
}

}  // namespace gissar::nav

namespace gissar::nav {

std::optional<NavPose> PoseFromSensor(const NavScene& scene, const Eigen::Vector3d& sensor_enu,
                                      double heading_deg, double slant_range_m,
                                      double depression_guess_deg, sensor::LookSide look_side) {
  NavPose p;
  p.heading_deg = heading_deg;
  p.slant_range_m = slant_range_m;
  p.depression_deg = depression_guess_deg;
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d c = sensor_enu + slant_range_m * sensor::LookDirection(heading_deg, p.depression_deg, look_side);
    const auto ground = SurfaceBelow(*scene.embree, c.x(), c.y());
    if (!ground) return std::nullopt;
    const double s = (sensor_enu.z() - ground->z()) / slant_range_m;
    if (!(s > std::sin(1.0 * M_PI / 180) && s < std::sin(89.0 * M_PI / 180))) return std::nullopt;
    const double next = std::asin(s) * 180.0 / M_PI;
    p.centre_enu = *ground;
    const bool done = std::abs(next - p.depression_deg) < 1e-6;
    p.depression_deg = next;
    if (done) break;
  }
  // Xc: the surface point on the final line of sight at range R (horizontal
  // position from the line of sight, height from the surface).
  const Eigen::Vector3d c = sensor_enu + slant_range_m * sensor::LookDirection(heading_deg, p.depression_deg, look_side);
  const auto ground = SurfaceBelow(*scene.embree, c.x(), c.y());
  if (!ground) return std::nullopt;
  p.centre_enu = *ground;
  return p;
}

}  // namespace gissar::nav

namespace gissar::nav {

StoredReference MakeStoredReference(const NavScene& scene, const sensor::SarGeometry& geometry,
                                    std::vector<float> intensity, const std::vector<uint8_t>& mask) {
  const int w = geometry.width(), h = geometry.height();
  if (intensity.size() != size_t(w) * size_t(h)) {
    throw InputError("stored image is not width x height of its geometry", "nav::MakeStoredReference");
  }
  if (!mask.empty() && mask.size() != intensity.size()) {
    throw InputError("stored mask is not width x height of its geometry", "nav::MakeStoredReference");
  }
  for (float& v : intensity) if (!std::isfinite(v) || v < 0.0f) v = 0.0f;
  StoredReference out{geometry, std::move(intensity), cv::Mat(h, w, CV_32FC3, cv::Scalar::all(std::numeric_limits<float>::quiet_NaN())),
                      cv::Mat(h, w, CV_8U, cv::Scalar(0)), 0};
  const Eigen::Vector3d l = geometry.look_direction(), hh = geometry.flight_direction();
  const Eigen::Vector3d n_up = UpNormal(geometry);
  const double dr = geometry.range_spacing_m(), da = geometry.azimuth_spacing_m();
  const Eigen::AlignedBox3d box = scene.mesh->Bounds();
  const float inf = std::numeric_limits<float>::infinity();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (!mask.empty() && mask[size_t(y) * w + x] != 0) continue;
      const Eigen::Vector3d base = geometry.scene_centre() + (x - geometry.u0()) * dr * l + (y - geometry.v0()) * da * hh;
      if (!(n_up.z() > 1e-6)) continue;
      Eigen::Vector3d start = base + ((box.max().z() + 100.0 - base.z()) / n_up.z()) * n_up;
      // Down the iso-range line: the first surface point that sees the sensor.
      for (int k = 0; k < 8; ++k) {
        const auto hit = scene.embree->Intersect(start.cast<float>(), (-n_up).cast<float>(), 0.0f, inf);
        if (!hit) break;
        const Eigen::Vector3d p = start - double(hit->t) * n_up;
        const Eigen::Vector3d towards_sensor = -l;
        const auto blocker = scene.embree->Intersect((p + 0.5 * towards_sensor).cast<float>(),
                                                     towards_sensor.cast<float>(), 0.0f, inf);
        if (!blocker) {
          out.points.at<cv::Vec3f>(y, x) = cv::Vec3f(float(p.x()), float(p.y()), float(p.z()));
          out.valid.at<uint8_t>(y, x) = 255;
          ++out.valid_pixels;
          break;
        }
        start = p - 0.5 * n_up;
      }
    }
  return out;
}

Reference WarpStoredReference(const StoredReference& stored, const NavPose& pose, const SensorModel& model) {
  Reference ref{GeometryOf(pose, model), {}, {}, {}, {}, {}};
  const int w = model.width, h = model.height;
  const int sw = stored.geometry.width(), sh = stored.geometry.height();
  ref.intensity.assign(size_t(w) * h, 0.0f);
  ref.points = cv::Mat(h, w, CV_32FC3, cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  ref.valid = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  ref.class_ids = {0};
  ref.class_intensity = {cv::Mat(h, w, CV_32F, cv::Scalar(0))};
  // The pose's camera is affine (GeometryOf): SarGeometry::Project as its
  // two dot products, inlined in the per-pixel loops below.
  const sensor::SarGeometry& camera = ref.geometry;
  GISSAR_CHECK(camera.mode() == sensor::ProjectionMode::kAffine);
  const Eigen::Vector3d xc = camera.scene_centre();
  const Eigen::Vector3d l_per_px = camera.look_direction() / camera.range_spacing_m();
  const Eigen::Vector3d h_per_px = camera.flight_direction() / camera.azimuth_spacing_m();
  const auto project = [&](const cv::Vec3f& q) {
    const Eigen::Vector3d d = Eigen::Vector3d(q[0], q[1], q[2]) - xc;
    return Eigen::Vector2d(d.dot(l_per_px) + camera.u0(), d.dot(h_per_px) + camera.v0());
  };
  // Least-squares affine map stored pixel -> pose pixel over the valid points.
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> atb = Eigen::Matrix<double, 3, 2>::Zero();
  const int stride = std::max(1, std::min(sw, sh) / 64);
  int used = 0;
  for (int y = 0; y < sh; y += stride)
    for (int x = 0; x < sw; x += stride) {
      if (stored.valid.at<uint8_t>(y, x) == 0) continue;
      const Eigen::Vector2d p = project(stored.points.at<cv::Vec3f>(y, x));
      const Eigen::Vector3d a(x, y, 1.0);
      ata += a * a.transpose();
      atb += a * p.transpose();
      ++used;
    }
  if (used < 16) return ref;  // nothing to match: every pixel invalid
  const Eigen::Matrix<double, 3, 2> m = ata.ldlt().solve(atb);  // p = m^T [x y 1]
  Eigen::Matrix2d a;
  a << m(0, 0), m(1, 0), m(0, 1), m(1, 1);
  const Eigen::Vector2d b(m(2, 0), m(2, 1));
  if (!(std::abs(a.determinant()) > 1e-9) || !a.allFinite()) return ref;
  const Eigen::Matrix2d a_inv = a.inverse();
  float* out = ref.intensity.data();
  cv::Mat& cls = ref.class_intensity[0];
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector2d p(x, y);
      Eigen::Vector2d c = a_inv * (p - b);
      for (int k = 0; k < 2; ++k) {
        const int cx = static_cast<int>(std::lround(c.x())), cy = static_cast<int>(std::lround(c.y()));
        if (cx < 0 || cy < 0 || cx >= sw || cy >= sh || stored.valid.at<uint8_t>(cy, cx) == 0) break;
        // The stored pixel's point moved by the sub-pixel part of c (the
        // affine map's local scale) before projecting.
        const Eigen::Vector2d at = project(stored.points.at<cv::Vec3f>(cy, cx)) + a * (c - Eigen::Vector2d(cx, cy));
        c += a_inv * (p - at);
      }
      if (!(c.x() >= 0.0 && c.y() >= 0.0 && c.x() <= sw - 1 && c.y() <= sh - 1)) continue;
      const int x0 = std::min(sw - 2, static_cast<int>(std::floor(c.x())));
      const int y0 = std::min(sh - 2, static_cast<int>(std::floor(c.y())));
      const double fx = c.x() - x0, fy = c.y() - y0;
      const float* r0 = stored.intensity.data() + size_t(y0) * sw;
      const float* r1 = r0 + sw;
      const double v = (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
      out[size_t(y) * w + x] = static_cast<float>(v);
      cls.at<float>(y, x) = static_cast<float>(v);
      const int cx = static_cast<int>(std::lround(c.x())), cy = static_cast<int>(std::lround(c.y()));
      if (stored.valid.at<uint8_t>(cy, cx) == 0) continue;
      ref.points.at<cv::Vec3f>(y, x) = stored.points.at<cv::Vec3f>(cy, cx);
      ref.valid.at<uint8_t>(y, x) = 255;
    }
  return ref;
}

}  // namespace gissar::nav
