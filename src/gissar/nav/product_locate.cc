#include "gissar/nav/product_locate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "gissar/image/quicklook.h"
#include "gissar/image/radiometry.h"
#include "gissar/render/product_renderer.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"

namespace gissar::nav {
namespace {

constexpr double kDeg = M_PI / 180.0;
// Side lobes: the best correlation further than this from the peak (pixels).
constexpr int kPeakExclusionPx = 3;
// Resection residuals below 3 x this (multilooked pixels) are never outliers.
constexpr double kOutlierFloorPx = 0.5;
// At a fix the NCC of the image with the last reference peaks within this
// many multilooked pixels of zero shift (whatever the matcher).
constexpr double kMaxNccShiftAtFixPx = 1.0;

// Geodetic up at an ECEF point.
Eigen::Vector3d GeodeticUp(const Eigen::Vector3d& ecef) {
  const Eigen::Vector3d llh = geo::LocalFrame::GeodeticFromEcef(ecef);
  const double lon = llh[0] * kDeg, lat = llh[1] * kDeg;
  return {std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
}

// One control point: a ground point (ECEF) and the zero-Doppler time and
// slant range at which the observed image shows it.
struct ControlPoint {
  Eigen::Vector3d ground_ecef;
  double time_s = 0.0;
  double range_m = 0.0;
};

// The MAP resection of the track offset from control points (see the header).
struct Resection {
  Eigen::Vector4d theta = Eigen::Vector4d::Zero();
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  std::vector<int> used;  // indices of the control points kept
  double rms_px = 0.0;
};

class TrackResection {
 public:
  TrackResection(const TrackVectors& prior, const TrackFrame& frame, const sensor::RadarGrid& grid,
                 const std::vector<ControlPoint>& points, const ProductLocateOptions& options, double point_sigma_px)
      : prior_(prior), frame_(frame), grid_(grid), points_(points), options_(options), point_sigma_px_(point_sigma_px) {}

  // Residuals (time, range) in multilooked pixels of the points in `used`;
  // nullopt when geo2rdr fails for one of them.
  std::optional<Eigen::VectorXd> Residuals(const Eigen::Vector4d& theta, const std::vector<int>& used) const {
    const sensor::Orbit orbit = DisplaceTrack(prior_, frame_, TrackOffset::FromVector(theta)).ToOrbit();
    Eigen::VectorXd r(2 * used.size());
    for (size_t k = 0; k < used.size(); ++k) {
      const ControlPoint& p = points_[used[k]];
      const auto rc = sensor::Geo2Rdr(orbit, p.ground_ecef, p.time_s);
      if (!rc) return std::nullopt;
      r[2 * k] = (rc->time_s - p.time_s) / grid_.dt_s;
      r[2 * k + 1] = (rc->range_m - p.range_m) / grid_.dr_m;
    }
    return r;
  }

  // `estimated`: the components solved for; the others stay at `start`
  // (held at the prior) and enter the covariance with the prior's sigma.
  std::optional<Resection> Solve(const Eigen::Vector4d& start,
                                 const std::array<bool, 4>& estimated = {true, true, true, true}) const {
    Resection out;
    out.theta = start;
    for (int i = 0; i < static_cast<int>(points_.size()); ++i) out.used.push_back(i);
    const Eigen::Vector4d sigma = options_.prior_sigma.AsVector();
    const Eigen::Vector4d step(0.5, 0.5, 0.5, 0.002);
    const double w = 1.0 / point_sigma_px_;
    Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
    for (int round = 0; round < 3; ++round) {
      for (int gn = 0; gn < 8; ++gn) {
        const auto r0 = Residuals(out.theta, out.used);
        if (!r0) return std::nullopt;
        Eigen::MatrixXd jac(r0->size(), 4);
        for (int k = 0; k < 4; ++k) {
          Eigen::Vector4d t = out.theta;
          t[k] += step[k];
          const auto rk = Residuals(t, out.used);
          if (!rk) return std::nullopt;
          jac.col(k) = (*rk - *r0) / step[k];
        }
        normal = w * w * jac.transpose() * jac;
        Eigen::Vector4d rhs = -w * w * jac.transpose() * *r0;
        for (int k = 0; k < 4; ++k) {
          normal(k, k) += 1.0 / (sigma[k] * sigma[k]);
          rhs[k] -= out.theta[k] / (sigma[k] * sigma[k]);
        }
        Eigen::Matrix4d solve = normal;
        for (int k = 0; k < 4; ++k) {
          if (estimated[k]) continue;
          solve.row(k).setZero();
          solve.col(k).setZero();
          solve(k, k) = 1.0;
          rhs[k] = 0.0;
        }
        const Eigen::Vector4d delta = solve.ldlt().solve(rhs);
        out.theta += delta;
        if (std::abs(delta[0]) + std::abs(delta[1]) + std::abs(delta[2]) < 1e-3 && std::abs(delta[3]) < 1e-6) break;
      }
      // Drop points whose residual exceeds 3 x max(match sigma, RMS) and solve again.
      const auto r = Residuals(out.theta, out.used);
      if (!r) return std::nullopt;
      double sum = 0.0;
      for (size_t k = 0; k < out.used.size(); ++k) sum += (*r)[2 * k] * (*r)[2 * k] + (*r)[2 * k + 1] * (*r)[2 * k + 1];
      out.rms_px = std::sqrt(sum / std::max<size_t>(1, out.used.size()));
      const double limit = 3.0 * std::max(kOutlierFloorPx, out.rms_px);
      std::vector<int> kept;
      for (size_t k = 0; k < out.used.size(); ++k) {
        if (std::hypot((*r)[2 * k], (*r)[2 * k + 1]) <= limit) kept.push_back(out.used[k]);
      }
      if (kept.size() == out.used.size() || kept.size() < 4) break;
      out.used = kept;
    }
    // Covariance: the inverse normal matrix, with the match sigma raised to
    // the residual RMS when the matches scatter more than assumed.
    const double scale = 1.0;  // the points share one shift measurement: its sigma is the error model
    Eigen::Matrix4d data = normal;
    const Eigen::Vector4d sigma2 = sigma.cwiseProduct(sigma);
    for (int k = 0; k < 4; ++k) data(k, k) -= 1.0 / sigma2[k];
    Eigen::Matrix4d scaled = data / scale;
    for (int k = 0; k < 4; ++k) scaled(k, k) += 1.0 / sigma2[k];
    std::vector<int> e, h;
    for (int k = 0; k < 4; ++k) (estimated[k] ? e : h).push_back(k);
    if (h.empty()) {
      out.covariance = scaled.inverse();
      return out;
    }
    // Held components: the estimate of the others is conditional on their
    // prior values, x_e = f(x_h); its error takes theirs through
    // B = -N_ee^-1 D_eh: C_ee = N_ee^-1 + B S_h B^T, C_eh = B S_h, C_hh = S_h.
    const int ne = static_cast<int>(e.size()), nh = static_cast<int>(h.size());
    Eigen::MatrixXd n_ee(ne, ne), d_eh(ne, nh), s_h = Eigen::MatrixXd::Zero(nh, nh);
    for (int i = 0; i < ne; ++i) {
      for (int j = 0; j < ne; ++j) n_ee(i, j) = scaled(e[i], e[j]);
      for (int j = 0; j < nh; ++j) d_eh(i, j) = data(e[i], h[j]);
    }
    for (int j = 0; j < nh; ++j) s_h(j, j) = sigma2[h[j]];
    const Eigen::MatrixXd n_inv = ne > 0 ? Eigen::MatrixXd(n_ee.inverse()) : Eigen::MatrixXd(0, 0);
    const Eigen::MatrixXd b = -n_inv * d_eh;
    const Eigen::MatrixXd c_ee = n_inv + b * s_h * b.transpose(), c_eh = b * s_h;
    out.covariance.setZero();
    for (int i = 0; i < ne; ++i) {
      for (int j = 0; j < ne; ++j) out.covariance(e[i], e[j]) = c_ee(i, j);
      for (int j = 0; j < nh; ++j) out.covariance(e[i], h[j]) = out.covariance(h[j], e[i]) = c_eh(i, j);
    }
    for (int j = 0; j < nh; ++j) out.covariance(h[j], h[j]) = s_h(j, j);
    return out;
  }

 private:
  const TrackVectors& prior_;
  const TrackFrame& frame_;
  const sensor::RadarGrid& grid_;
  const std::vector<ControlPoint>& points_;
  const ProductLocateOptions& options_;
  double point_sigma_px_;
};

// Parabolic sub-pixel offset of a peak from its two neighbours.
double ParabolicOffset(double left, double centre, double right) {
  const double denominator = left - 2.0 * centre + right;
  if (!(std::abs(denominator) > 1e-12)) return 0.0;
  return std::clamp(0.5 * (left - right) / denominator, -0.5, 0.5);
}

cv::Mat GradientMagnitude(const cv::Mat& log_image) {
  cv::Mat smooth, gx, gy, magnitude;
  cv::GaussianBlur(log_image, smooth, cv::Size(3, 3), 0.0);
  cv::Sobel(smooth, gx, CV_32F, 1, 0);
  cv::Sobel(smooth, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, magnitude);
  return magnitude;
}

// Quantises an image to `levels` equally populated levels (CV_8U).
cv::Mat Quantise(const cv::Mat& image, int levels) {
  std::vector<float> values(image.begin<float>(), image.end<float>());
  std::sort(values.begin(), values.end());
  std::vector<float> edges;
  for (int k = 1; k < levels; ++k) edges.push_back(values[values.size() * k / levels]);
  cv::Mat out(image.size(), CV_8U);
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const float v = image.at<float>(y, x);
      out.at<uint8_t>(y, x) = static_cast<uint8_t>(std::upper_bound(edges.begin(), edges.end(), v) - edges.begin());
    }
  return out;
}

cv::Mat MutualInformationScores(const cv::Mat& reference, const cv::Mat& observed) {
  constexpr int kLevels = 16;
  const cv::Mat ref_q = Quantise(reference, kLevels), obs_q = Quantise(observed, kLevels);
  cv::Mat scores(reference.rows - observed.rows + 1, reference.cols - observed.cols + 1, CV_32F);
  const double n = double(observed.rows) * observed.cols;
  for (int v = 0; v < scores.rows; ++v)
    for (int u = 0; u < scores.cols; ++u) {
      std::array<double, kLevels * kLevels> joint{};
      std::array<double, kLevels> pr{}, po{};
      for (int y = 0; y < observed.rows; ++y) {
        const uint8_t* o = obs_q.ptr<uint8_t>(y);
        const uint8_t* r = ref_q.ptr<uint8_t>(y + v) + u;
        for (int x = 0; x < observed.cols; ++x) joint[r[x] * kLevels + o[x]] += 1.0;
      }
      for (int a = 0; a < kLevels; ++a)
        for (int b = 0; b < kLevels; ++b) pr[a] += joint[a * kLevels + b], po[b] += joint[a * kLevels + b];
      double mi = 0.0;
      for (int a = 0; a < kLevels; ++a)
        for (int b = 0; b < kLevels; ++b) {
          const double p = joint[a * kLevels + b];
          if (p > 0) mi += p / n * std::log(p * n / (pr[a] * po[b]));
        }
      scores.at<float>(v, u) = static_cast<float>(mi);
    }
  return scores;
}

cv::Mat PhaseCorrelationScores(const cv::Mat& reference, const cv::Mat& observed) {
  const int h = cv::getOptimalDFTSize(reference.rows + observed.rows);
  const int w = cv::getOptimalDFTSize(reference.cols + observed.cols);
  cv::Mat ref_pad(h, w, CV_32F, cv::Scalar(0)), obs_pad(h, w, CV_32F, cv::Scalar(0));
  cv::Mat(reference - cv::mean(reference)[0]).copyTo(ref_pad(cv::Rect(0, 0, reference.cols, reference.rows)));
  cv::Mat(observed - cv::mean(observed)[0]).copyTo(obs_pad(cv::Rect(0, 0, observed.cols, observed.rows)));
  cv::Mat fr, fo, cross;
  cv::dft(ref_pad, fr, cv::DFT_COMPLEX_OUTPUT);
  cv::dft(obs_pad, fo, cv::DFT_COMPLEX_OUTPUT);
  cv::mulSpectrums(fr, fo, cross, 0, /*conjB=*/true);
  std::vector<cv::Mat> planes;
  cv::split(cross, planes);
  cv::Mat magnitude;
  cv::magnitude(planes[0], planes[1], magnitude);
  magnitude += 1e-12f;
  planes[0] /= magnitude;
  planes[1] /= magnitude;
  cv::merge(planes, cross);
  cv::Mat correlation;
  cv::idft(cross, correlation, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  return correlation(cv::Rect(0, 0, reference.cols - observed.cols + 1, reference.rows - observed.rows + 1)).clone();
}

}  // namespace

ShiftMatcher ParseShiftMatcher(const std::string& text, const std::string& option) {
  return kShiftMatchers.Parse(text, option);
}

std::string ToString(ShiftMatcher matcher) { return std::string(kShiftMatchers.Name(matcher)); }

cv::Mat ShiftScores(ShiftMatcher matcher, const cv::Mat& reference, const cv::Mat& observed) {
  if (reference.type() != CV_32F || observed.type() != CV_32F || reference.rows < observed.rows ||
      reference.cols < observed.cols) {
    throw InputError("the reference must be a CV_32F image at least as large as the observed one", "nav::ShiftScores");
  }
  cv::Mat scores;
  switch (matcher) {
    case ShiftMatcher::kNcc:
      cv::matchTemplate(reference, observed, scores, cv::TM_CCOEFF_NORMED);
      return scores;
    case ShiftMatcher::kGradient:
      cv::matchTemplate(GradientMagnitude(reference), GradientMagnitude(observed), scores, cv::TM_CCOEFF_NORMED);
      return scores;
    case ShiftMatcher::kPhase: return PhaseCorrelationScores(reference, observed);
    case ShiftMatcher::kMutualInformation: return MutualInformationScores(reference, observed);
  }
  return scores;
}

void ProductLocateOptions::Check() const {
  auto need = [](bool ok, const char* field) {
    if (!ok) throw ConfigError("out of range", std::string("ProductLocateOptions::") + field);
  };
  need(looks_range >= 1 && looks_range <= 64, "looks_range");
  need(looks_azimuth >= 1 && looks_azimuth <= 64, "looks_azimuth");
  need(filter_px >= 1 && filter_px <= 15, "filter_px");
  const Eigen::Vector4d s = prior_sigma.AsVector();
  need(s.minCoeff() > 0.0 && s.allFinite(), "prior_sigma");
  need(search_sigmas > 0.0 && search_sigmas <= 10.0, "search_sigmas");
  need(refine_search_px >= 1 && refine_search_px <= 32, "refine_search_px");
  need(max_iterations >= 1 && max_iterations <= 20, "max_iterations");
  need(max_rms_px > 0.0, "max_rms_px");
  need(shift_sigma_px > 0.0, "shift_sigma_px");
  need(min_peak_margin >= 0.0, "min_peak_margin");
  need(min_peak_ncc >= 0.0 && min_peak_ncc < 1.0, "min_peak_ncc");
  need(reference_floor > 0.0, "reference_floor");
  need(min_reference_contrast_db >= 0.0, "min_reference_contrast_db");
  need(min_landmark_contrast_db >= 0.0, "min_landmark_contrast_db");
  need(min_landmark_margin_db >= 0.0, "min_landmark_margin_db");
  need(landmark_sigma_px > 0.0, "landmark_sigma_px");
  need(terrain_horizontal_sigma_m >= 0.0 && std::isfinite(terrain_horizontal_sigma_m), "terrain_horizontal_sigma_m");
}

TrackFrame TrackFrameAt(const sensor::Orbit& orbit, double time_s) {
  const sensor::OrbitState s = orbit.Interpolate(time_s);
  TrackFrame f;
  f.time_s = time_s;
  f.origin_ecef = s.position_m;
  f.up = GeodeticUp(s.position_m);
  f.along = (s.velocity_mps - s.velocity_mps.dot(f.up) * f.up).normalized();
  f.cross = f.along.cross(f.up);
  return f;
}

TrackVectors DisplaceTrack(const TrackVectors& track, const TrackFrame& frame, const TrackOffset& offset) {
  const Eigen::Matrix3d rot = Eigen::AngleAxisd(-offset.heading_deg * kDeg, frame.up).toRotationMatrix();
  const Eigen::Vector3d shift = offset.along_m * frame.along + offset.cross_m * frame.cross + offset.up_m * frame.up;
  TrackVectors out;
  out.time_s = track.time_s;
  out.position_m.reserve(track.position_m.size());
  out.velocity_mps.reserve(track.velocity_mps.size());
  for (size_t i = 0; i < track.time_s.size(); ++i) {
    out.position_m.push_back(frame.origin_ecef + rot * (track.position_m[i] - frame.origin_ecef) + shift);
    out.velocity_mps.push_back(rot * track.velocity_mps[i]);
  }
  return out;
}

double TrackAngleDeg(const sensor::Orbit& orbit, double time_s) {
  const sensor::OrbitState s = orbit.Interpolate(time_s);
  const Eigen::Vector3d llh = geo::LocalFrame::GeodeticFromEcef(s.position_m);
  const double lon = llh[0] * kDeg, lat = llh[1] * kDeg;
  const Eigen::Vector3d east(-std::sin(lon), std::cos(lon), 0.0);
  const Eigen::Vector3d north(-std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat));
  double bearing = std::atan2(s.velocity_mps.dot(east), s.velocity_mps.dot(north)) / kDeg;
  return bearing < 0.0 ? bearing + 360.0 : bearing;
}

sensor::RadarGrid MultilookGrid(const sensor::RadarGrid& grid, int la, int lr) {
  sensor::RadarGrid g = grid;
  g.t0_s = grid.t0_s + 0.5 * (la - 1) * grid.dt_s;
  g.dt_s = grid.dt_s * la;
  g.rows = grid.rows / la;
  g.r0_m = grid.r0_m + 0.5 * (lr - 1) * grid.dr_m;
  g.dr_m = grid.dr_m * lr;
  g.cols = grid.cols / lr;
  return g;
}

namespace {

// The observed image's grid multilooked by the options' looks: the image must
// be rows x cols of its grid and keep at least 12 lines and bins.
sensor::RadarGrid CheckedMultilookGrid(const ProductObservation& observed, const ProductLocateOptions& options) {
  const sensor::RadarGrid& full = observed.grid;
  if (observed.intensity.size() != size_t(full.rows) * size_t(full.cols)) {
    throw InputError("observed image is not rows x cols of its grid", "nav::LocateProduct");
  }
  const sensor::RadarGrid grid = MultilookGrid(full, options.looks_azimuth, options.looks_range);
  if (grid.rows < 12 || grid.cols < 12) {
    throw ConfigError("the multilooked image has fewer than 12 lines or bins", "--looks");
  }
  return grid;
}

// The observed image multilooked onto `grid` (non-finite pixels 0), as the
// filtered log intensity the references are matched with.
cv::Mat ObservedLog(const ProductObservation& observed, const sensor::RadarGrid& grid,
                    const ProductLocateOptions& options) {
  const sensor::RadarGrid& full = observed.grid;
  std::vector<float> observed_ml =
      image::Multilook(observed.intensity, full.rows, full.cols, options.looks_azimuth, options.looks_range);
  for (float& v : observed_ml) {
    if (!std::isfinite(v)) v = 0.0f;
  }
  return LogIntensity(observed_ml, grid.cols, grid.rows, options.filter_px);
}

// `grid` grown by `pad_rows` lines and `pad_cols` bins on each side.
sensor::RadarGrid PaddedGrid(const sensor::RadarGrid& grid, int pad_rows, int pad_cols) {
  sensor::RadarGrid ref_grid = grid;
  ref_grid.t0_s -= pad_rows * grid.dt_s;
  ref_grid.rows += 2 * pad_rows;
  ref_grid.r0_m -= pad_cols * grid.dr_m;
  ref_grid.cols += 2 * pad_cols;
  return ref_grid;
}

// The observed (full-resolution) intensity at line y, bin x: 0 where it is
// not a positive finite number.
struct PositiveIntensity {
  const std::vector<float>& intensity;
  int cols = 0;
  double operator()(int y, int x) const {
    const float v = intensity[size_t(y) * cols + x];
    return std::isfinite(v) && v > 0.0f ? double(v) : 0.0;
  }
};

// A landmark's search window, lines [r0, r1] x bins [c0, c1]: its brightest
// pixel (x, y), the window's median and the brightest pixel further than
// kPeakExclusionPx from the brightest.
struct WindowPeak {
  int r0 = 0, r1 = 0, c0 = 0, c1 = 0;
  int x = 0, y = 0;
  double best = 0.0, median = 0.0, second = 0.0;
};

WindowPeak BrightestInWindow(const PositiveIntensity& value, int r0, int r1, int c0, int c1) {
  WindowPeak peak{r0, r1, c0, c1};
  int bx = c0, by = r0;
  std::vector<double> window;
  for (int y = r0; y <= r1; ++y)
    for (int x = c0; x <= c1; ++x) {
      window.push_back(value(y, x));
      if (value(y, x) > value(by, bx)) bx = x, by = y;
    }
  peak.x = bx;
  peak.y = by;
  peak.best = value(by, bx);
  std::nth_element(window.begin(), window.begin() + window.size() / 2, window.end());
  peak.median = window[window.size() / 2];
  double second = 0.0;
  for (int y = r0; y <= r1; ++y)
    for (int x = c0; x <= c1; ++x) {
      if (std::abs(x - bx) > kPeakExclusionPx || std::abs(y - by) > kPeakExclusionPx) second = std::max(second, value(y, x));
    }
  peak.second = second;
  return peak;
}

// Why a landmark's peak cannot be a control point ("" when it can).
std::string LandmarkRejection(const WindowPeak& peak, const LandmarkRecord& rec, const ProductLocateOptions& options) {
  char note[200] = "";
  if (!(peak.best > 0.0)) {
    std::snprintf(note, sizeof note, "no signal in its search window");
  } else if (peak.x == peak.c0 || peak.x == peak.c1 || peak.y == peak.r0 || peak.y == peak.r1) {
    std::snprintf(note, sizeof note, "its brightest pixel is on the border of its search window or the image");
  } else if (rec.contrast_db < options.min_landmark_contrast_db) {
    std::snprintf(note, sizeof note, "no distinct peak (%.1f dB over the window's median < %.1f dB)",
                  rec.contrast_db, options.min_landmark_contrast_db);
  } else if (rec.margin_db < options.min_landmark_margin_db) {
    std::snprintf(note, sizeof note, "ambiguous peak (%.1f dB over the next brightest pixel > 3 px away < %.1f dB)",
                  rec.margin_db, options.min_landmark_margin_db);
  }
  return note;
}

// The control points the landmarks give, the index in result.landmarks of
// each one's landmark, and whether any landmark's window meets the image.
struct LandmarkPeaks {
  std::vector<ControlPoint> points;
  std::vector<int> owners;
  bool any_in_image = false;
};

// The whole-image shift of the observed image over a padded reference:
// ncc(v, u) scores the observed pixel (x, y) on reference pixel (x + u, y + v);
// `best` and (u, v) the chosen matcher's peak (whole and sub-pixel); the NCC
// map's own peak, its value and the best NCC away from it (-1: none).
struct ShiftPeak {
  cv::Mat ncc;
  cv::Point best;
  double u = 0.0, v = 0.0;
  cv::Point ncc_best;
  double peak = 0.0, second = -1.0;
};

// One product fix (see the header): the observed image multilooked, the
// prior track and its frame at the image's centre line, the search window
// the prior's sigmas give, and the result as the phases fill it in.
class ProductFix {
 public:
  ProductFix(const NavScene& scene, const geo::LocalFrame& frame, const ProductObservation& observed,
             const TrackVectors& prior_track, const ProductLocateOptions& options, const sensor::RadarGrid& grid);

  bool HasLandmarks() const { return scene_.landmarks != nullptr && !scene_.landmarks->empty(); }
  LandmarkPeaks FindLandmarkPeaks();
  ProductLocateResult ResectLandmarks(const LandmarkPeaks& peaks);
  void MatchRelief();
  void JudgeReliefFix();
  void AddTerrainVariance();
  ProductLocateResult Finish();

 private:
  render::ProductImage RenderReference(const sensor::Orbit& orbit, const sensor::RadarGrid& g) const;
  void Fail(const std::string& why);
  void MeasureLandmark(const render::SceneReflector& landmark, int half_rows, int half_cols, LandmarkPeaks& peaks);
  void RecordLandmarkResiduals(const TrackResection& resection, const LandmarkPeaks& peaks);
  double ZeroShiftNcc(const Eigen::Vector4d& at, double* contrast);
  bool ReliefIteration(int it);
  bool ReferenceHasStructure(const cv::Mat& ref_log);
  ShiftPeak MeasureShift(const cv::Mat& ref_log) const;
  bool RecordFirstPeak(const ShiftPeak& shift, float zero_shift, int pad_rows, int pad_cols);
  std::vector<ControlPoint> ReliefControlPoints(const render::ProductImage& ref, int rw, const ShiftPeak& shift) const;
  bool ResectShift(const std::vector<ControlPoint>& points, int it);

  const NavScene& scene_;
  const geo::LocalFrame& frame_;
  const ProductObservation& observed_;
  const TrackVectors& prior_track_;
  const ProductLocateOptions& options_;
  const sensor::RadarGrid& full_;  // the observed image's grid
  const sensor::RadarGrid grid_;   // multilooked
  const int la_, width_, height_;
  Stopwatch clock_;
  ProductLocateResult result_;
  const cv::Mat observed_log_;
  const sensor::Orbit prior_orbit_;
  TrackFrame track_frame_;
  double centre_range_m_ = 0.0;
  double azimuth_m_ = 0.0;  // azimuth pixel on the ground (multilooked)
  Eigen::Vector4d sigma_;
  double k_ = 0.0;
  int search_rows_ = 0, search_cols_ = 0;
  render::RenderOptions ro_;
  Eigen::Vector4d theta_ = Eigen::Vector4d::Zero();
  double last_update_px_ = std::numeric_limits<double>::infinity();
};

ProductFix::ProductFix(const NavScene& scene, const geo::LocalFrame& frame, const ProductObservation& observed,
                       const TrackVectors& prior_track, const ProductLocateOptions& options,
                       const sensor::RadarGrid& grid)
    : scene_(scene),
      frame_(frame),
      observed_(observed),
      prior_track_(prior_track),
      options_(options),
      full_(observed.grid),
      grid_(grid),
      la_(options.looks_azimuth),
      width_(grid.cols),
      height_(grid.rows),
      observed_log_(ObservedLog(observed, grid, options)),
      prior_orbit_(prior_track.ToOrbit()) {
  result_.fix_time_s = grid_.TimeOfRow(0.5 * (height_ - 1));
  track_frame_ = TrackFrameAt(prior_orbit_, result_.fix_time_s);
  const sensor::OrbitState centre_state = prior_orbit_.Interpolate(result_.fix_time_s);
  centre_range_m_ = grid_.RangeOfCol(0.5 * (width_ - 1));
  // Azimuth pixel on the ground (m): the velocity scaled to the ground's
  // distance from the Earth's centre (the sensor's radius less its height
  // above the ellipsoid): about the aircraft speed, 0.9 x for a satellite.
  const double sensor_radius = centre_state.position_m.norm();
  const double ground_radius = sensor_radius - geo::LocalFrame::GeodeticFromEcef(centre_state.position_m)[2];
  azimuth_m_ = grid_.dt_s * centre_state.velocity_mps.norm() * ground_radius / sensor_radius;
  result_.cell_m = std::max(azimuth_m_, grid_.dr_m);

  sigma_ = options_.prior_sigma.AsVector();
  k_ = options_.search_sigmas;
  search_rows_ = static_cast<int>(
      std::ceil(k_ * std::hypot(sigma_[0], centre_range_m_ * sigma_[3] * kDeg) / azimuth_m_) + 3);
  search_cols_ = static_cast<int>(std::ceil(k_ * std::hypot(sigma_[1], sigma_[2]) / grid_.dr_m) + 3);

  ro_.rays_per_cell = scene_.rays_per_cell;
  ro_.max_bounces = scene_.bounces;
  ro_.wavelength_m = grid_.wavelength_m;
  if (scene_.landmarks != nullptr) ro_.reflectors = *scene_.landmarks;
}

// A reference: the terrain's returns plus the landmarks' point returns (an
// impulse response of one pixel of the reference's grid).
render::ProductImage ProductFix::RenderReference(const sensor::Orbit& orbit, const sensor::RadarGrid& g) const {
  render::ProductImage img = render::RenderProduct(*scene_.embree, *scene_.mesh, *scene_.materials, frame_, orbit, g, ro_);
  if (!img.image.points.empty()) {
    image::SensorEffects psf;
    psf.range_resolution_px = psf.azimuth_resolution_px = 1.0;
    image::AddPointIntensities(img.image, psf);
  }
  return img;
}

void ProductFix::Fail(const std::string& why) {
  result_.converged = false;
  result_.failure_reason = why;
}

ProductLocateResult ProductFix::Finish() {
  result_.correction = TrackOffset::FromVector(theta_);
  result_.track = DisplaceTrack(prior_track_, track_frame_, result_.correction);
  result_.sensor_ecef = result_.track.ToOrbit().Interpolate(result_.fix_time_s).position_m;
  result_.seconds = clock_.ElapsedSeconds();
  return result_;
}

// Every landmark's record, and a control point from each whose search window
// at the prior shows a distinct peak.
LandmarkPeaks ProductFix::FindLandmarkPeaks() {
  const double az_full_m = azimuth_m_ / la_;
  const int half_rows =
      static_cast<int>(std::ceil(k_ * std::hypot(sigma_[0], centre_range_m_ * sigma_[3] * kDeg) / az_full_m)) + 2;
  const int half_cols = static_cast<int>(std::ceil(k_ * std::hypot(sigma_[1], sigma_[2]) / full_.dr_m)) + 2;
  LandmarkPeaks peaks;
  for (const render::SceneReflector& landmark : *scene_.landmarks) MeasureLandmark(landmark, half_rows, half_cols, peaks);
  return peaks;
}

// One landmark: predicted on the prior track, its peak searched for in a
// window of the full-resolution image, judged, and located to sub-pixel.
void ProductFix::MeasureLandmark(const render::SceneReflector& landmark, int half_rows, int half_cols,
                                 LandmarkPeaks& peaks) {
  LandmarkRecord rec;
  rec.row = landmark.row;
  const Eigen::Vector3d llh = frame_.GeodeticFromEnu(landmark.apex_enu);
  const Eigen::Vector3d ecef = geo::LocalFrame::EcefFromGeodetic(llh[0], llh[1], llh[2]);
  const auto rc = sensor::Geo2Rdr(prior_orbit_, ecef, result_.fix_time_s);
  if (!rc) {
    rec.note = "no zero-Doppler time on the prior track";
    result_.landmarks.push_back(rec);
    return;
  }
  const double pr = (rc->time_s - full_.t0_s) / full_.dt_s, pc = (rc->range_m - full_.r0_m) / full_.dr_m;
  rec.predicted_px = {pc, pr};
  const int r0 = std::max(0, static_cast<int>(std::floor(pr)) - half_rows);
  const int r1 = std::min(full_.rows - 1, static_cast<int>(std::ceil(pr)) + half_rows);
  const int c0 = std::max(0, static_cast<int>(std::floor(pc)) - half_cols);
  const int c1 = std::min(full_.cols - 1, static_cast<int>(std::ceil(pc)) + half_cols);
  if (r1 - r0 < 2 || c1 - c0 < 2) {
    rec.note = "outside the image at the prior track";
    result_.landmarks.push_back(rec);
    return;
  }
  rec.in_image = peaks.any_in_image = true;
  const PositiveIntensity value{observed_.intensity, full_.cols};
  const WindowPeak peak = BrightestInWindow(value, r0, r1, c0, c1);
  const int bx = peak.x, by = peak.y;
  const double best = peak.best, median = peak.median, second = peak.second;
  rec.contrast_db = best > 0.0 && median > 0.0 ? 10.0 * std::log10(best / median) : 0.0;
  rec.margin_db = best > 0.0 && second > 0.0 ? 10.0 * std::log10(best / second)
                                             : std::numeric_limits<double>::infinity();
  const std::string note = LandmarkRejection(peak, rec, options_);
  if (!note.empty()) {
    rec.note = note;
    result_.landmarks.push_back(rec);
    return;
  }
  // Sub-pixel peak: a parabola through the dB values of the neighbours.
  auto db = [&](int y, int x) { return 10.0 * std::log10(std::max(value(y, x), best * 1e-6)); };
  const double dx = ParabolicOffset(db(by, bx - 1), db(by, bx), db(by, bx + 1));
  const double dy = ParabolicOffset(db(by - 1, bx), db(by, bx), db(by + 1, bx));
  rec.peak_px = {bx + dx, by + dy};
  rec.used = true;
  ControlPoint cp;
  cp.ground_ecef = ecef;
  cp.time_s = full_.TimeOfRow(by + dy);
  cp.range_m = full_.RangeOfCol(bx + dx);
  peaks.points.push_back(cp);
  peaks.owners.push_back(static_cast<int>(result_.landmarks.size()));
  result_.landmarks.push_back(rec);
}

// Landmark mode: the track offset resected from the landmarks' peaks alone
// (along and cross track; up and heading held at the prior).
ProductLocateResult ProductFix::ResectLandmarks(const LandmarkPeaks& peaks) {
  result_.source = "landmarks";
  result_.from_image = {true, true, false, false};
  result_.iterations = 1;
  if (peaks.points.empty()) {
    std::string why = "no landmark in the image has a usable peak:";
    for (const LandmarkRecord& rec : result_.landmarks) {
      if (rec.in_image) why += " row " + std::to_string(rec.row) + ": " + rec.note + ";";
    }
    why.pop_back();
    Fail(why);
    return Finish();
  }
  const TrackResection resection(prior_track_, track_frame_, full_, peaks.points, options_, options_.landmark_sigma_px);
  const auto solved = resection.Solve(theta_, result_.from_image);
  if (!solved) {
    Fail("geo2rdr failed for a landmark (it lies outside the orbit's span)");
    return Finish();
  }
  theta_ = solved->theta;
  result_.covariance = solved->covariance;
  result_.control_points = static_cast<int>(solved->used.size());
  RecordLandmarkResiduals(resection, peaks);
  // The references at the prior and at the fix (landmarks rendered):
  // whole-image NCC at zero shift, for the record.
  try {
    result_.prior_similarity = ZeroShiftNcc(Eigen::Vector4d::Zero(), &result_.reference_contrast_db);
    result_.similarity = ZeroShiftNcc(theta_, nullptr);
  } catch (const InputError&) {
    // No reference (the DEM does not reach the grid): the landmarks still fix the track.
  }
  result_.peak_ncc = result_.peak_margin = std::numeric_limits<double>::quiet_NaN();
  if (!(result_.rms_px <= options_.max_rms_px)) {
    Fail("the landmarks disagree (resection RMS " + std::to_string(result_.rms_px) + " px > " +
         std::to_string(options_.max_rms_px) + ")");
  } else {
    result_.converged = true;
  }
  return Finish();
}

// Each landmark's residual at the fix and their RMS (over all control points,
// outliers included).
void ProductFix::RecordLandmarkResiduals(const TrackResection& resection, const LandmarkPeaks& peaks) {
  const std::vector<ControlPoint>& points = peaks.points;
  std::vector<int> all(points.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  const auto residuals = resection.Residuals(theta_, all);
  double sum = 0.0;
  for (size_t i = 0; residuals && i < points.size(); ++i) {
    // Residuals are predicted minus observed (time, range) pixels.
    result_.landmarks[peaks.owners[i]].residual_px = {-(*residuals)[2 * i + 1], -(*residuals)[2 * i]};
    sum += (*residuals)[2 * i] * (*residuals)[2 * i] + (*residuals)[2 * i + 1] * (*residuals)[2 * i + 1];
  }
  result_.rms_px = residuals ? std::sqrt(sum / points.size()) : std::numeric_limits<double>::infinity();
}

// The whole-image NCC at zero shift of the observed image with the reference
// at track offset `at` (and that reference's log-intensity spread).
double ProductFix::ZeroShiftNcc(const Eigen::Vector4d& at, double* contrast) {
  const sensor::Orbit orbit = DisplaceTrack(prior_track_, track_frame_, TrackOffset::FromVector(at)).ToOrbit();
  const render::ProductImage ref = RenderReference(orbit, grid_);
  ++result_.renders;
  const cv::Mat ref_log = LogIntensity(ref.image.intensity, width_, height_, options_.filter_px, options_.reference_floor);
  if (contrast != nullptr) {
    cv::Scalar mean, sd;
    cv::meanStdDev(ref_log, mean, sd);
    *contrast = sd[0];
  }
  cv::Mat ncc;
  cv::matchTemplate(ref_log, observed_log_, ncc, cv::TM_CCOEFF_NORMED);
  return double(ncc.at<float>(0, 0));
}

// Relief mode: render a padded reference at the current track, find the
// whole-image shift, resect it into a track offset; until the update settles.
void ProductFix::MatchRelief() {
  for (int it = 0; it < options_.max_iterations; ++it) {
    if (!ReliefIteration(it)) break;
  }
}

// One relief iteration; false when the iterations stop (a failure, or the
// update has settled).
bool ProductFix::ReliefIteration(int it) {
  const TrackVectors track = DisplaceTrack(prior_track_, track_frame_, TrackOffset::FromVector(theta_));
  const sensor::Orbit orbit = track.ToOrbit();
  const int pad_rows = it == 0 ? search_rows_ : options_.refine_search_px;
  const int pad_cols = it == 0 ? search_cols_ : options_.refine_search_px;
  const sensor::RadarGrid ref_grid = PaddedGrid(grid_, pad_rows, pad_cols);
  if (ref_grid.r0_m <= 0.0) {
    Fail("the prior's search range reaches the sensor (prior sigmas too large for this image)");
    return false;
  }
  std::optional<render::ProductImage> ref;
  try {
    ref = RenderReference(orbit, ref_grid);
  } catch (const InputError& e) {
    Fail(std::string("no reference at this track: ") + e.what());
    return false;
  }
  ++result_.renders;
  result_.iterations = it + 1;
  const int rw = ref_grid.cols, rh = ref_grid.rows;
  const cv::Mat ref_log = LogIntensity(ref->image.intensity, rw, rh, options_.filter_px, options_.reference_floor);
  if (it == 0 && !ReferenceHasStructure(ref_log)) return false;
  const ShiftPeak shift = MeasureShift(ref_log);
  const float zero_shift = shift.ncc.at<float>(pad_rows, pad_cols);
  if (it == 0 && !RecordFirstPeak(shift, zero_shift, pad_rows, pad_cols)) return false;
  result_.similarity = zero_shift;
  result_.ncc_shift_px = {double(shift.ncc_best.x - pad_cols), double(shift.ncc_best.y - pad_rows)};
  const std::vector<ControlPoint> points = ReliefControlPoints(*ref, rw, shift);
  if (static_cast<int>(points.size()) < 4) {
    Fail("the reference has no ground points where the image matched");
    return false;
  }
  return ResectShift(points, it);
}

// The first reference's log-intensity spread (recorded); false (a failure)
// when it is too flat to match.
bool ProductFix::ReferenceHasStructure(const cv::Mat& ref_log) {
  cv::Scalar mean, sd;
  cv::meanStdDev(ref_log, mean, sd);
  result_.reference_contrast_db = sd[0];
  if (sd[0] < options_.min_reference_contrast_db) {
    char why[300];
    std::snprintf(why, sizeof why,
                  "the reference has no structure to match (its log intensity varies by %.2f dB < %.2f dB: "
                  "flat terrain and no landmark in the image; give point landmarks, --reflectors)",
                  sd[0], options_.min_reference_contrast_db);
    Fail(why);
    return false;
  }
  return true;
}

// Whole-image shift: the observed image slid over the padded reference; the
// shift the chosen matcher's peak (sub-pixel by parabolas), and whether the
// images correlate at all from the NCC map: its peak and the side lobes.
ShiftPeak ProductFix::MeasureShift(const cv::Mat& ref_log) const {
  ShiftPeak shift;
  cv::Mat& ncc = shift.ncc;
  cv::matchTemplate(ref_log, observed_log_, ncc, cv::TM_CCOEFF_NORMED);
  const cv::Mat scores =
      options_.matcher == ShiftMatcher::kNcc ? ncc : ShiftScores(options_.matcher, ref_log, observed_log_);
  cv::Point& best = shift.best;
  double best_score = 0.0;
  cv::minMaxLoc(scores, nullptr, &best_score, nullptr, &best);
  auto at = [&](int y, int x) {
    return double(scores.at<float>(std::clamp(y, 0, scores.rows - 1), std::clamp(x, 0, scores.cols - 1)));
  };
  shift.u = best.x + ParabolicOffset(at(best.y, best.x - 1), best_score, at(best.y, best.x + 1));
  shift.v = best.y + ParabolicOffset(at(best.y - 1, best.x), best_score, at(best.y + 1, best.x));
  cv::Point& ncc_best = shift.ncc_best;
  double peak = 0.0;
  cv::minMaxLoc(ncc, nullptr, &peak, nullptr, &ncc_best);
  shift.peak = peak;
  // The best score away from the peak (beyond the exclusion radius): a
  // peak that does not stand out of its side lobes is no fix.
  double second = -1.0;
  for (int y = 0; y < ncc.rows; ++y)
    for (int x = 0; x < ncc.cols; ++x) {
      if (std::abs(x - ncc_best.x) <= kPeakExclusionPx && std::abs(y - ncc_best.y) <= kPeakExclusionPx) continue;
      second = std::max(second, double(ncc.at<float>(y, x)));
    }
  shift.second = second;
  return shift;
}

// The first iteration's correlation at the prior (recorded); false (a
// failure) when the images do not correlate or the peak is ambiguous.
bool ProductFix::RecordFirstPeak(const ShiftPeak& shift, float zero_shift, int pad_rows, int pad_cols) {
  const double peak = shift.peak, second = shift.second;
  result_.prior_similarity = zero_shift;
  result_.peak_ncc = peak;
  result_.peak_margin = second > -1.0 ? peak - second : std::numeric_limits<double>::quiet_NaN();
  result_.first_shift_px = {shift.u - pad_cols, shift.v - pad_rows};
  if (peak < options_.min_peak_ncc) {
    Fail("the real image does not correlate with the simulation (whole-image NCC peak " + std::to_string(peak) +
         " < " + std::to_string(options_.min_peak_ncc) + ")");
    return false;
  }
  if (second > -1.0 && peak - second < options_.min_peak_margin) {
    Fail("the correlation peak is ambiguous (NCC " + std::to_string(peak) + ", best elsewhere " +
         std::to_string(second) + ": the scene has too little relief or structure to match)");
    return false;
  }
  return true;
}

// Control points: a grid of reference pixels with a ground point, where the
// shift puts them in the observed image. They carry one shift measurement
// together (their sigma is shift_sigma_px x sqrt(n)).
std::vector<ControlPoint> ProductFix::ReliefControlPoints(const render::ProductImage& ref, int rw,
                                                          const ShiftPeak& shift) const {
  std::vector<ControlPoint> points;
  const int grid_step = std::max(1, std::min(width_, height_) / 8);
  for (int yo = grid_step / 2; yo < height_; yo += grid_step)
    for (int xo = grid_step / 2; xo < width_; xo += grid_step) {
      const int xr = xo + shift.best.x, yr = yo + shift.best.y;
      const size_t p = size_t(yr) * rw + xr;
      if (!std::isfinite(ref.height_m[p]) || (ref.image.mask[p] & render::kMaskLayover) != 0) continue;
      ControlPoint cp;
      cp.ground_ecef = geo::LocalFrame::EcefFromGeodetic(ref.lon_deg_exact[p], ref.lat_deg_exact[p], ref.height_m[p]);
      cp.time_s = grid_.TimeOfRow(yr - shift.v);
      cp.range_m = grid_.RangeOfCol(xr - shift.u);
      points.push_back(cp);
    }
  return points;
}

// The track offset resected from the matched points, and how far the update
// moves their images; false when the iterations stop.
bool ProductFix::ResectShift(const std::vector<ControlPoint>& points, int it) {
  const TrackResection resection(prior_track_, track_frame_, grid_, points, options_,
                                  options_.shift_sigma_px * std::sqrt(double(points.size())));
  const auto solved = resection.Solve(theta_);
  if (!solved) {
    Fail("geo2rdr failed for a matched ground point (it lies outside the orbit's span)");
    return false;
  }
  result_.control_points = static_cast<int>(solved->used.size());
  result_.rms_px = solved->rms_px;
  result_.covariance = solved->covariance;
  // The update in pixels: how far it moves the matched points' images.
  const auto before = resection.Residuals(theta_, solved->used);
  const auto after = resection.Residuals(solved->theta, solved->used);
  last_update_px_ = (before && after) ? std::sqrt((*after - *before).squaredNorm() / solved->used.size())
                                      : std::numeric_limits<double>::infinity();
  theta_ = solved->theta;
  return !(last_update_px_ < 0.1 && it > 0);
}

// A relief fix that did not fail: converged, unless the resection does not
// fit, the image still shifts against the last reference, or the update has
// not settled.
void ProductFix::JudgeReliefFix() {
  if (!result_.failure_reason.empty()) return;
  if (result_.rms_px > options_.max_rms_px) {
    Fail("the image shift is not a track offset (resection RMS " + std::to_string(result_.rms_px) + " px > " +
         std::to_string(options_.max_rms_px) + ")");
  } else if (result_.ncc_shift_px.cwiseAbs().maxCoeff() > kMaxNccShiftAtFixPx) {
    Fail("the fix does not explain the image: at the fix the whole-image NCC still peaks " +
         std::to_string(result_.ncc_shift_px.norm()) + " px away");
  } else if (!(last_update_px_ < 0.5)) {
    Fail("the fix did not settle (last update " + std::to_string(last_update_px_) + " px)");
  } else {
    result_.converged = true;
  }
}

// The terrain's horizontal error moves the matched pattern as a whole: it
// adds to the along- and cross-track variance of the relief fix.
void ProductFix::AddTerrainVariance() {
  const double map_variance = options_.terrain_horizontal_sigma_m * options_.terrain_horizontal_sigma_m;
  result_.covariance(0, 0) += map_variance;
  result_.covariance(1, 1) += map_variance;
}

}  // namespace

ProductLocateResult LocateProduct(const NavScene& scene, const geo::LocalFrame& frame,
                                  const ProductObservation& observed, const TrackVectors& prior_track,
                                  const ProductLocateOptions& options) {
  options.Check();
  const sensor::RadarGrid grid = CheckedMultilookGrid(observed, options);
  ProductFix fix(scene, frame, observed, prior_track, options, grid);
  // Landmark mode (see the header): when a landmark's search window at the
  // prior meets the observed image, the landmarks alone fix the track.
  if (fix.HasLandmarks()) {
    const LandmarkPeaks peaks = fix.FindLandmarkPeaks();
    if (peaks.any_in_image) return fix.ResectLandmarks(peaks);
  }
  // Relief mode: whole-image shifts against rendered references, iterated.
  fix.MatchRelief();
  fix.JudgeReliefFix();
  fix.AddTerrainVariance();
  return fix.Finish();
}

}  // namespace gissar::nav
