#include "gissar/nav/matching.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "gissar/util/error.h"

namespace gissar::nav {
namespace {

void CheckPair(const cv::Mat& a, const cv::Mat& b, const cv::Mat& valid) {
  if (a.empty() || a.type() != CV_32F || b.type() != CV_32F || a.size() != b.size()) {
    throw InputError("matching needs two non-empty CV_32F images of the same size", "nav::Match");
  }
  if (!valid.empty() && (valid.type() != CV_8U || valid.size() != a.size())) {
    throw InputError("valid mask must be CV_8U of the image size", "nav::Match");
  }
}

// Offset of the extremum of a parabola through (-1, a), (0, b), (1, c).
double ParabolaPeak(double a, double b, double c) {
  const double d = a - 2.0 * b + c;
  if (std::abs(d) < 1e-12) return 0.0;
  return std::clamp(0.5 * (a - c) / d, -0.5, 0.5);
}

// Grid of patch centres at least `half` pixels inside the image.
std::vector<cv::Point> GridCentres(cv::Size size, int half, int step, const cv::Mat& valid) {
  std::vector<cv::Point> centres;
  for (int y = half; y < size.height - half; y += step) {
    for (int x = half; x < size.width - half; x += step) {
      if (!valid.empty() && valid.at<uint8_t>(y, x) == 0) continue;
      centres.emplace_back(x, y);
    }
  }
  return centres;
}

}  // namespace

Matcher ParseMatcher(const std::string& text, const std::string& option) { return kMatchers.Parse(text, option); }

std::string ToString(Matcher matcher) { return std::string(kMatchers.Name(matcher)); }

void MatchOptions::Check() const {
  if (patch_px < 7 || patch_px % 2 == 0) throw ConfigError("must be odd and >= 7", "patch_px");
  if (step_px < 1) throw ConfigError("must be >= 1", "step_px");
  if (search_px < 1) throw ConfigError("must be >= 1", "search_px");
  if (!std::isfinite(min_score)) throw ConfigError("must be finite", "min_score");
  if (!(min_contrast_db >= 0.0)) throw ConfigError("must be >= 0", "min_contrast_db");
}

cv::Mat BoxMean(const cv::Mat& image, int filter_px) {
  if (filter_px <= 1) return image.clone();
  cv::Mat filtered;
  cv::boxFilter(image, filtered, CV_32F, cv::Size(filter_px, filter_px), cv::Point(-1, -1), true,
                cv::BORDER_REFLECT);
  return filtered;
}

cv::Mat LogIntensity(const std::vector<float>& intensity, int width, int height, int filter_px,
                     double floor) {
  if (width <= 0 || height <= 0 || intensity.size() != size_t(width) * size_t(height)) {
    throw InputError("intensity size does not match width x height", "nav::LogIntensity");
  }
  cv::Mat filtered = BoxMean(cv::Mat(height, width, CV_32F, const_cast<float*>(intensity.data())), filter_px);
  cv::max(filtered, 0.0, filtered);
  filtered += floor;
  cv::Mat out;
  cv::log(filtered, out);
  out *= 10.0 / std::log(10.0);
  return out;
}

double ImageNcc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  CheckPair(a, b, mask);
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  int64_t n = 0;
  for (int y = 0; y < a.rows; ++y) {
    const float* pa = a.ptr<float>(y);
    const float* pb = b.ptr<float>(y);
    const uint8_t* pm = mask.empty() ? nullptr : mask.ptr<uint8_t>(y);
    for (int x = 0; x < a.cols; ++x) {
      if (pm != nullptr && pm[x] == 0) continue;
      sa += pa[x]; sb += pb[x]; saa += double(pa[x]) * pa[x]; sbb += double(pb[x]) * pb[x];
      sab += double(pa[x]) * pb[x];
      ++n;
    }
  }
  if (n < 2) return 0.0;
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n, cab = sab - sa * sb / n;
  if (va <= 1e-12 || vb <= 1e-12) return 0.0;
  return cab / std::sqrt(va * vb);
}

std::vector<Correspondence> DenseNccMatch(const cv::Mat& ref, const cv::Mat& obs,
                                          const MatchOptions& options, const cv::Mat& valid) {
  CheckPair(ref, obs, valid);
  options.Check();
  const int half = options.patch_px / 2;
  // One patch: its best match in the search window, or none.
  const auto match_patch = [&](const cv::Point& c) -> std::optional<Correspondence> {
    const cv::Rect tpl_rect(c.x - half, c.y - half, options.patch_px, options.patch_px);
    const cv::Mat tpl = ref(tpl_rect);
    cv::Scalar mean, stddev;
    cv::meanStdDev(tpl, mean, stddev);
    if (stddev[0] < options.min_contrast_db) return std::nullopt;
    // Search window clipped to the observed image.
    const cv::Rect search = cv::Rect(tpl_rect.x - options.search_px, tpl_rect.y - options.search_px,
                                     options.patch_px + 2 * options.search_px,
                                     options.patch_px + 2 * options.search_px) &
                            cv::Rect(0, 0, obs.cols, obs.rows);
    if (search.width < options.patch_px + 2 || search.height < options.patch_px + 2) return std::nullopt;
    cv::Mat result;
    cv::matchTemplate(obs(search), tpl, result, cv::TM_CCOEFF_NORMED);
    double best = 0;
    cv::Point at;
    cv::minMaxLoc(result, nullptr, &best, nullptr, &at);
    if (!(best >= options.min_score)) return std::nullopt;
    // A peak on the window border is a truncated search: not a match.
    if (at.x == 0 || at.y == 0 || at.x == result.cols - 1 || at.y == result.rows - 1) return std::nullopt;
    const double dx = ParabolaPeak(result.at<float>(at.y, at.x - 1), best, result.at<float>(at.y, at.x + 1));
    const double dy = ParabolaPeak(result.at<float>(at.y - 1, at.x), best, result.at<float>(at.y + 1, at.x));
    Correspondence m;
    m.reference = Eigen::Vector2d(c.x, c.y);
    m.observed = Eigen::Vector2d(search.x + at.x + dx + half, search.y + at.y + dy + half);
    m.score = best;
    return m;
  };
  // The patches in parallel (each its own OpenCV call), kept in grid order:
  // the same matches as one after the other.
  const std::vector<cv::Point> centres = GridCentres(ref.size(), half, options.step_px, valid);
  std::vector<std::optional<Correspondence>> found(centres.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, centres.size()), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t i = range.begin(); i < range.end(); ++i) found[i] = match_patch(centres[i]);
  });
  std::vector<Correspondence> out;
  for (const std::optional<Correspondence>& m : found) {
    if (m) out.push_back(*m);
  }
  return out;
}

namespace {

cv::Mat Edges(const cv::Mat& log_image) {
  // Canny on the 8-bit stretch (2..98 %) of the smoothed log image, with
  // thresholds from the median gradient (scale free).
  cv::Mat smooth;
  cv::GaussianBlur(log_image, smooth, cv::Size(5, 5), 1.2);
  std::vector<float> values(smooth.begin<float>(), smooth.end<float>());
  std::sort(values.begin(), values.end());
  const float lo = values[values.size() * 2 / 100], hi = values[values.size() * 98 / 100];
  cv::Mat u8;
  smooth.convertTo(u8, CV_8U, 255.0 / std::max(1e-6f, hi - lo), -lo * 255.0 / std::max(1e-6f, hi - lo));
  cv::Mat edges;
  cv::Canny(u8, edges, 40, 100, 3, true);
  return edges;
}

}  // namespace

std::vector<Correspondence> ChamferMatch(const cv::Mat& ref, const cv::Mat& obs,
                                         const MatchOptions& options, const cv::Mat& valid) {
  CheckPair(ref, obs, valid);
  options.Check();
  const cv::Mat ref_edges = Edges(ref), obs_edges = Edges(obs);
  cv::Mat inverted = obs_edges == 0, dist;
  cv::distanceTransform(inverted, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const float cap = 10.0f;  // truncated chamfer: robust to missing edges
  cv::min(dist, cap, dist);
  const int half = options.patch_px / 2;
  const int s = options.search_px;
  std::vector<Correspondence> out;
  for (const cv::Point& c : GridCentres(ref.size(), half, options.step_px, valid)) {
    std::vector<cv::Point> pts;
    for (int y = c.y - half; y <= c.y + half; ++y)
      for (int x = c.x - half; x <= c.x + half; ++x)
        if (ref_edges.at<uint8_t>(y, x) != 0) pts.emplace_back(x, y);
    if (static_cast<int>(pts.size()) < options.patch_px) continue;
    cv::Mat cost(2 * s + 1, 2 * s + 1, CV_32F, cv::Scalar(cap));
    for (int dy = -s; dy <= s; ++dy) {
      for (int dx = -s; dx <= s; ++dx) {
        double sum = 0;
        int n = 0;
        for (const cv::Point& p : pts) {
          const int x = p.x + dx, y = p.y + dy;
          if (x < 0 || y < 0 || x >= obs.cols || y >= obs.rows) continue;
          sum += dist.at<float>(y, x);
          ++n;
        }
        if (n * 2 >= static_cast<int>(pts.size())) cost.at<float>(dy + s, dx + s) = float(sum / n);
      }
    }
    double best;
    cv::Point at;
    cv::minMaxLoc(cost, &best, nullptr, &at, nullptr);
    if (at.x == 0 || at.y == 0 || at.x == cost.cols - 1 || at.y == cost.rows - 1) continue;
    if (best > 2.0) continue;
    const double ox = ParabolaPeak(cost.at<float>(at.y, at.x - 1), best, cost.at<float>(at.y, at.x + 1));
    const double oy = ParabolaPeak(cost.at<float>(at.y - 1, at.x), best, cost.at<float>(at.y + 1, at.x));
    Correspondence m;
    m.reference = Eigen::Vector2d(c.x, c.y);
    m.observed = Eigen::Vector2d(c.x + at.x - s + ox, c.y + at.y - s + oy);
    m.score = -best;
    out.push_back(m);
  }
  return out;
}

namespace {

struct Keypoint {
  cv::Point pt;
  float response;
};

// SAR-Harris: ratio-of-local-means gradient (difference of log means over
// half windows), structure tensor, Harris response, non-maximum suppression.
std::vector<Keypoint> SarHarris(const cv::Mat& log_image, int max_points, int border) {
  const int r = 3;  // half-window side of the ratio
  cv::Mat mean;
  cv::boxFilter(log_image, mean, CV_32F, cv::Size(2 * r + 1, 2 * r + 1), cv::Point(-1, -1), true,
                cv::BORDER_REFLECT);
  // G_x = mean(right) - mean(left) in dB = 10 log10 of the ratio of means
  // of the (already log) image's half windows; likewise G_y.
  cv::Mat gx(log_image.size(), CV_32F, cv::Scalar(0)), gy(log_image.size(), CV_32F, cv::Scalar(0));
  for (int y = r + 1; y < log_image.rows - r - 1; ++y) {
    for (int x = r + 1; x < log_image.cols - r - 1; ++x) {
      gx.at<float>(y, x) = mean.at<float>(y, x + r + 1) - mean.at<float>(y, x - r - 1);
      gy.at<float>(y, x) = mean.at<float>(y + r + 1, x) - mean.at<float>(y - r - 1, x);
    }
  }
  cv::Mat xx = gx.mul(gx), yy = gy.mul(gy), xy = gx.mul(gy);
  cv::GaussianBlur(xx, xx, cv::Size(0, 0), 2.0);
  cv::GaussianBlur(yy, yy, cv::Size(0, 0), 2.0);
  cv::GaussianBlur(xy, xy, cv::Size(0, 0), 2.0);
  cv::Mat response = xx.mul(yy) - xy.mul(xy) - 0.04 * (xx + yy).mul(xx + yy);
  cv::Mat dilated;
  cv::dilate(response, dilated, cv::Mat::ones(7, 7, CV_8U));
  std::vector<Keypoint> points;
  for (int y = border; y < response.rows - border; ++y)
    for (int x = border; x < response.cols - border; ++x) {
      const float v = response.at<float>(y, x);
      if (v > 0 && v >= dilated.at<float>(y, x)) points.push_back({cv::Point(x, y), v});
    }
  std::sort(points.begin(), points.end(), [](const Keypoint& a, const Keypoint& b) { return a.response > b.response; });
  if (static_cast<int>(points.size()) > max_points) points.resize(max_points);
  return points;
}

cv::Mat Describe(const cv::Mat& log_image, const std::vector<Keypoint>& points, int half) {
  const int side = 2 * half + 1;
  cv::Mat desc(static_cast<int>(points.size()), side * side, CV_32F);
  for (size_t i = 0; i < points.size(); ++i) {
    cv::Mat patch = log_image(cv::Rect(points[i].pt.x - half, points[i].pt.y - half, side, side)).clone();
    cv::Scalar m, s;
    cv::meanStdDev(patch, m, s);
    patch = (patch - m[0]) / std::max(1e-6, s[0]);
    patch.reshape(1, 1).copyTo(desc.row(static_cast<int>(i)));
  }
  return desc;
}

// Index of the nearest and the two smallest squared distances per row.
void Nearest(const cv::Mat& a, const cv::Mat& b, std::vector<int>& index, std::vector<double>& d1,
             std::vector<double>& d2) {
  index.assign(a.rows, -1);
  d1.assign(a.rows, std::numeric_limits<double>::infinity());
  d2.assign(a.rows, std::numeric_limits<double>::infinity());
  for (int i = 0; i < a.rows; ++i)
    for (int j = 0; j < b.rows; ++j) {
      const double d = cv::norm(a.row(i), b.row(j), cv::NORM_L2SQR);
      if (d < d1[i]) { d2[i] = d1[i]; d1[i] = d; index[i] = j; }
      else if (d < d2[i]) d2[i] = d;
    }
}

}  // namespace

std::vector<Correspondence> FeatureMatch(const cv::Mat& ref, const cv::Mat& obs,
                                         const MatchOptions& options, const cv::Mat& valid) {
  CheckPair(ref, obs, valid);
  options.Check();
  const int half = options.patch_px / 2;
  const int max_points = std::max(50, ref.rows * ref.cols / (options.step_px * options.step_px) * 2);
  std::vector<Keypoint> kr = SarHarris(ref, max_points, half + 1);
  if (!valid.empty()) {
    std::erase_if(kr, [&](const Keypoint& k) { return valid.at<uint8_t>(k.pt) == 0; });
  }
  const std::vector<Keypoint> ko = SarHarris(obs, max_points, half + 1);
  if (kr.size() < 2 || ko.size() < 2) return {};
  const cv::Mat dr = Describe(ref, kr, half), dob = Describe(obs, ko, half);
  std::vector<int> fwd, bwd;
  std::vector<double> f1, f2, b1, b2;
  Nearest(dr, dob, fwd, f1, f2);
  Nearest(dob, dr, bwd, b1, b2);
  std::vector<Correspondence> out;
  const double ratio = 0.9;
  for (size_t i = 0; i < kr.size(); ++i) {
    const int j = fwd[i];
    if (j < 0 || bwd[j] != static_cast<int>(i)) continue;            // cross-check
    if (!(std::sqrt(f1[i]) < ratio * std::sqrt(f2[i]))) continue;    // Lowe's ratio test
    const cv::Point d = ko[j].pt - kr[i].pt;
    if (std::abs(d.x) > options.search_px || std::abs(d.y) > options.search_px) continue;
    Correspondence m;
    m.reference = Eigen::Vector2d(kr[i].pt.x, kr[i].pt.y);
    m.observed = Eigen::Vector2d(ko[j].pt.x, ko[j].pt.y);
    m.score = 1.0 - std::sqrt(f1[i] / f2[i]);
    out.push_back(m);
  }
  return out;
}

std::vector<Correspondence> Match(Matcher matcher, const cv::Mat& reference_log,
                                  const cv::Mat& observed_log, const MatchOptions& options,
                                  const cv::Mat& valid) {
  switch (matcher) {
    case Matcher::kNcc: return DenseNccMatch(reference_log, observed_log, options, valid);
    case Matcher::kChamfer: return ChamferMatch(reference_log, observed_log, options, valid);
    case Matcher::kFeatures: return FeatureMatch(reference_log, observed_log, options, valid);
  }
  return {};
}

}  // namespace gissar::nav
