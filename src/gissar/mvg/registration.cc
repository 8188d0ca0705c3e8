#include "gissar/mvg/registration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_set>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>

#include "gissar/mvg/random.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

constexpr double kRankTol = 1e-9;

bool IsPolynomial(TransformType type) {
  return type == TransformType::kPolynomial2 || type == TransformType::kPolynomial3;
}

int TermCount(TransformType type) { return type == TransformType::kPolynomial2 ? 6 : 10; }

// Monomials (1, u, v, u², uv, v²[, u³, u²v, uv², v³]).
Eigen::VectorXd Terms(TransformType type, const Eigen::Vector2d& u) {
  Eigen::VectorXd t(TermCount(type));
  const double x = u.x(), y = u.y();
  t(0) = 1.0;
  t(1) = x;
  t(2) = y;
  t(3) = x * x;
  t(4) = x * y;
  t(5) = y * y;
  if (type == TransformType::kPolynomial3) {
    t(6) = x * x * x;
    t(7) = x * x * y;
    t(8) = x * y * y;
    t(9) = y * y * y;
  }
  return t;
}

// Centroid and RMS distance from it of the selected points.
struct Normalisation {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double scale = 1.0;
  Eigen::Matrix3d Matrix() const {  // p -> (p - centre) / scale
    Eigen::Matrix3d t = Eigen::Matrix3d::Identity();
    t(0, 0) = t(1, 1) = 1.0 / scale;
    t.block<2, 1>(0, 2) = -centre / scale;
    return t;
  }
};

Normalisation Normalise(const std::vector<Eigen::Vector2d>& p, const std::vector<int>& subset) {
  Normalisation n;
  for (int i : subset) n.centre += p[i];
  n.centre /= static_cast<double>(subset.size());
  double sum = 0.0;
  for (int i : subset) sum += (p[i] - n.centre).squaredNorm();
  n.scale = std::sqrt(sum / static_cast<double>(subset.size()));
  return n;
}

bool FullRank(const Eigen::MatrixXd& a) {
  const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXd>(a).singularValues();
  return sv.size() > 0 && sv(0) > 0.0 && sv(sv.size() - 1) > kRankTol * sv(0);
}

// Least-squares similarity in complex form: to = q from + t with q = s e^(i a),
// q = sum(conj(u) w) / sum(|u|²) for the centred points u, w (the 2-D case of
// Umeyama's closed form).
std::optional<PlaneTransform> FitSimilarity(const std::vector<Eigen::Vector2d>& from,
                                            const std::vector<Eigen::Vector2d>& to,
                                            const std::vector<int>& subset) {
  const Normalisation ns = Normalise(from, subset);
  const Normalisation nd = Normalise(to, subset);
  if (!(ns.scale > 0.0) || !(nd.scale > 0.0)) return std::nullopt;
  double re = 0.0, im = 0.0, norm = 0.0;
  for (int i : subset) {
    const Eigen::Vector2d u = from[i] - ns.centre;
    const Eigen::Vector2d w = to[i] - nd.centre;
    re += u.x() * w.x() + u.y() * w.y();
    im += u.x() * w.y() - u.y() * w.x();
    norm += u.squaredNorm();
  }
  const double qr = re / norm, qi = im / norm;
  if (!(std::hypot(qr, qi) > 0.0)) return std::nullopt;
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m.topLeftCorner<2, 2>() << qr, -qi, qi, qr;
  m.block<2, 1>(0, 2) = nd.centre - m.topLeftCorner<2, 2>() * ns.centre;
  return PlaneTransform::FromMatrix(TransformType::kSimilarity, m);
}

std::optional<PlaneTransform> FitAffine(const std::vector<Eigen::Vector2d>& from,
                                        const std::vector<Eigen::Vector2d>& to,
                                        const std::vector<int>& subset) {
  const int n = static_cast<int>(subset.size());
  const Normalisation ns = Normalise(from, subset);
  if (!(ns.scale > 0.0)) return std::nullopt;
  Eigen::MatrixXd a(n, 3), b(n, 2);
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d u = (from[subset[k]] - ns.centre) / ns.scale;
    a.row(k) << u.x(), u.y(), 1.0;
    b.row(k) = to[subset[k]].transpose();
  }
  if (!FullRank(a)) return std::nullopt;
  const Eigen::MatrixXd x = a.colPivHouseholderQr().solve(b);  // 3 x 2
  Eigen::Matrix3d mn = Eigen::Matrix3d::Identity();
  mn.topRows<2>() = x.transpose();
  const Eigen::Matrix3d m = mn * ns.Matrix();
  if (std::abs(m.topLeftCorner<2, 2>().determinant()) <=
      kRankTol * m.topLeftCorner<2, 2>().squaredNorm()) {
    return std::nullopt;
  }
  return PlaneTransform::FromMatrix(TransformType::kAffine, m);
}

std::optional<PlaneTransform> FitProjective(const std::vector<Eigen::Vector2d>& from,
                                            const std::vector<Eigen::Vector2d>& to,
                                            const std::vector<int>& subset) {
  const int n = static_cast<int>(subset.size());
  const Normalisation ns = Normalise(from, subset);
  const Normalisation nd = Normalise(to, subset);
  if (!(ns.scale > 0.0) || !(nd.scale > 0.0)) return std::nullopt;
  std::vector<Eigen::Vector2d> u(n), w(n);
  for (int k = 0; k < n; ++k) {
    u[k] = (from[subset[k]] - ns.centre) / ns.scale;
    w[k] = (to[subset[k]] - nd.centre) / nd.scale;
  }
  // Normalised DLT.
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(2 * n, 9);
  for (int k = 0; k < n; ++k) {
    const double x = u[k].x(), y = u[k].y(), xp = w[k].x(), yp = w[k].y();
    a.row(2 * k) << 0, 0, 0, -x, -y, -1, yp * x, yp * y, yp;
    a.row(2 * k + 1) << x, y, 1, 0, 0, 0, -xp * x, -xp * y, -xp;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::VectorXd sv = svd.singularValues();
  if (!(sv(0) > 0.0) || sv(7) <= kRankTol * sv(0)) return std::nullopt;
  const Eigen::VectorXd h = svd.matrixV().col(8);
  Eigen::Matrix3d hn;
  hn << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  if (std::abs(hn.determinant()) <= kRankTol * std::pow(hn.norm(), 3)) return std::nullopt;
  // Gauss-Newton / Levenberg-Marquardt on the transfer error in the
  // normalised target frame (a uniform scaling of the pixel error).
  if (n > 4 && std::abs(hn(2, 2)) > 1e-8 * hn.norm()) {
    hn /= hn(2, 2);
    auto residuals = [&](const Eigen::Matrix3d& m, Eigen::VectorXd* r,
                         Eigen::Matrix<double, Eigen::Dynamic, 8>* j) {
      r->resize(2 * n);
      if (j != nullptr) j->setZero(2 * n, 8);
      for (int k = 0; k < n; ++k) {
        const Eigen::Vector3d q = m * u[k].homogeneous();
        const double x = u[k].x(), y = u[k].y();
        const double px = q.x() / q.z(), py = q.y() / q.z();
        (*r)(2 * k) = px - w[k].x();
        (*r)(2 * k + 1) = py - w[k].y();
        if (j == nullptr) continue;
        const double iw = 1.0 / q.z();
        j->row(2 * k) << x * iw, y * iw, iw, 0, 0, 0, -x * px * iw, -y * px * iw;
        j->row(2 * k + 1) << 0, 0, 0, x * iw, y * iw, iw, -x * py * iw, -y * py * iw;
      }
    };
    auto apply = [](const Eigen::Matrix3d& m, const Eigen::Matrix<double, 8, 1>& d) {
      Eigen::Matrix3d out = m;
      for (int i = 0; i < 8; ++i) out(i / 3, i % 3) += d(i);
      return out;
    };
    Eigen::VectorXd r;
    Eigen::Matrix<double, Eigen::Dynamic, 8> j;
    residuals(hn, &r, &j);
    double cost = r.squaredNorm();
    double lambda = 1e-3;
    for (int it = 0; it < 50 && cost > 0.0; ++it) {
      const Eigen::Matrix<double, 8, 8> jtj = j.transpose() * j;
      const Eigen::Matrix<double, 8, 1> jtr = j.transpose() * r;
      bool accepted = false;
      for (int tries = 0; tries < 20 && !accepted; ++tries) {
        Eigen::Matrix<double, 8, 8> aa = jtj;
        aa.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
        const Eigen::Matrix<double, 8, 1> step = aa.ldlt().solve(-jtr);
        const Eigen::Matrix3d trial = apply(hn, step);
        Eigen::VectorXd rt;
        residuals(trial, &rt, nullptr);
        if (rt.allFinite() && rt.squaredNorm() < cost) {
          const double gain = cost - rt.squaredNorm();
          hn = trial;
          residuals(hn, &r, &j);
          cost = r.squaredNorm();
          lambda = std::max(lambda / 10.0, 1e-12);
          accepted = true;
          if (gain <= 1e-15 * (cost + gain)) it = 50;
        } else {
          lambda *= 10.0;
        }
      }
      if (!accepted) break;
    }
  }
  const Eigen::Matrix3d m = nd.Matrix().inverse() * hn * ns.Matrix();
  if (!m.allFinite()) return std::nullopt;
  return PlaneTransform::FromMatrix(TransformType::kProjective, m);
}

std::optional<PlaneTransform> FitPolynomial(TransformType type,
                                            const std::vector<Eigen::Vector2d>& from,
                                            const std::vector<Eigen::Vector2d>& to,
                                            const std::vector<int>& subset) {
  const int n = static_cast<int>(subset.size());
  const Normalisation ns = Normalise(from, subset);
  if (!(ns.scale > 0.0)) return std::nullopt;
  const int t = TermCount(type);
  Eigen::MatrixXd a(n, t), b(n, 2);
  for (int k = 0; k < n; ++k) {
    a.row(k) = Terms(type, (from[subset[k]] - ns.centre) / ns.scale).transpose();
    b.row(k) = to[subset[k]].transpose();
  }
  if (!FullRank(a)) return std::nullopt;
  const Eigen::MatrixXd x = a.colPivHouseholderQr().solve(b);  // t x 2
  return PlaneTransform::FromPolynomial(type, ns.centre, ns.scale, x.transpose());
}

void CheckPairs(TransformType type, size_t from_size, size_t to_size, size_t used) {
  if (from_size != to_size) {
    throw InputError("point lists differ in length: " + std::to_string(from_size) + " vs " +
                         std::to_string(to_size),
                     "control points");
  }
  const size_t need = static_cast<size_t>(MinimumControlPoints(type));
  if (used < need) {
    throw InputError("a " + ToString(type) + " transform needs at least " + std::to_string(need) +
                         " point pairs, got " + std::to_string(used),
                     "control points");
  }
}

// Transfer error |T(from) - to| of every pair.
std::vector<double> TransferErrors(const PlaneTransform& t,
                                   const std::vector<Eigen::Vector2d>& from,
                                   const std::vector<Eigen::Vector2d>& to) {
  std::vector<double> e(from.size());
  for (size_t i = 0; i < from.size(); ++i) {
    const double d = (t.Apply(from[i]) - to[i]).norm();
    e[i] = std::isfinite(d) ? d : std::numeric_limits<double>::infinity();
  }
  return e;
}

struct Support {
  std::vector<int> inliers;
  double score = 0.0;  // MSAC: sum of min(e², threshold²)
};

Support Score(const std::vector<double>& errors, double threshold) {
  Support s;
  const double t2 = threshold * threshold;
  for (size_t i = 0; i < errors.size(); ++i) {
    if (errors[i] < threshold) s.inliers.push_back(static_cast<int>(i));
    s.score += std::min(errors[i] * errors[i], t2);
  }
  return s;
}

double RmsOver(const std::vector<double>& v, const std::vector<int>& subset) {
  if (subset.empty()) return 0.0;
  double sum = 0.0;
  for (int i : subset) sum += v[i] * v[i];
  return std::sqrt(sum / static_cast<double>(subset.size()));
}

uint64_t HashIndices(const std::vector<int>& indices) {
  uint64_t h = 1469598103934665603ull;
  for (int i : indices) {
    h ^= static_cast<uint64_t>(static_cast<uint32_t>(i));
    h *= 1099511628211ull;
  }
  return h;
}

cv::Mat ToDisplay8U(const cv::Mat& image) {
  if (image.depth() == CV_8U) return image;
  cv::Mat f;
  image.convertTo(f, CV_64F);
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  for (int r = 0; r < f.rows; ++r) {
    const double* row = f.ptr<double>(r);
    for (int c = 0; c < f.cols; ++c) {
      if (std::isfinite(row[c])) {
        lo = std::min(lo, row[c]);
        hi = std::max(hi, row[c]);
      }
    }
  }
  cv::Mat out(f.size(), CV_8UC1, cv::Scalar(0));
  if (!(hi >= lo)) return out;
  const double gain = hi > lo ? 255.0 / (hi - lo) : 0.0;
  for (int r = 0; r < f.rows; ++r) {
    const double* in = f.ptr<double>(r);
    uint8_t* o = out.ptr<uint8_t>(r);
    for (int c = 0; c < f.cols; ++c) {
      if (std::isfinite(in[c])) o[c] = cv::saturate_cast<uint8_t>((in[c] - lo) * gain);
    }
  }
  return out;
}

}  // namespace

std::string ToString(TransformType type) { return std::string(kTransformTypes.Name(type)); }

TransformType ParseTransformType(const std::string& text, const std::string& option) {
  return kTransformTypes.Parse(text, option);
}

int MinimumControlPoints(TransformType type) {
  switch (type) {
    case TransformType::kSimilarity:
      return 2;
    case TransformType::kAffine:
      return 3;
    case TransformType::kProjective:
      return 4;
    case TransformType::kPolynomial2:
      return 6;
    case TransformType::kPolynomial3:
      return 10;
  }
  return 0;
}

PlaneTransform::PlaneTransform() = default;

PlaneTransform PlaneTransform::FromMatrix(TransformType type, const Eigen::Matrix3d& matrix) {
  if (IsPolynomial(type)) {
    throw InputError("a polynomial transform has no 3x3 matrix", "transform");
  }
  if (!matrix.allFinite()) throw InputError("transform matrix has a non-finite entry", "transform");
  const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(matrix).singularValues();
  if (!(sv(2) > 1e-14 * sv(0))) throw InputError("transform matrix is singular", "transform");
  PlaneTransform t;
  t.type_ = type;
  t.matrix_ = matrix;
  if (std::abs(matrix(2, 2)) > 1e-12 * matrix.norm()) t.matrix_ /= matrix(2, 2);
  return t;
}

PlaneTransform PlaneTransform::FromPolynomial(TransformType type, const Eigen::Vector2d& centre,
                                              double scale, const Eigen::MatrixXd& coefficients) {
  if (!IsPolynomial(type)) throw InputError("not a polynomial transform type", "transform");
  if (coefficients.rows() != 2 || coefficients.cols() != TermCount(type)) {
    throw InputError("polynomial coefficients must be 2 x " + std::to_string(TermCount(type)),
                     "transform");
  }
  if (!centre.allFinite() || !coefficients.allFinite() || !std::isfinite(scale) || scale <= 0.0) {
    throw InputError("polynomial transform has a non-finite value or a non-positive scale",
                     "transform");
  }
  PlaneTransform t;
  t.type_ = type;
  t.centre_ = centre;
  t.scale_ = scale;
  t.coefficients_ = coefficients;
  return t;
}

Eigen::Vector2d PlaneTransform::Apply(const Eigen::Vector2d& p) const {
  if (IsPolynomial(type_)) return coefficients_ * Terms(type_, (p - centre_) / scale_);
  const Eigen::Vector3d q = matrix_ * p.homogeneous();
  return q.head<2>() / q.z();
}

std::optional<Eigen::Matrix3d> PlaneTransform::Matrix() const {
  if (IsPolynomial(type_)) return std::nullopt;
  return matrix_;
}

std::optional<PlaneTransform> PlaneTransform::Inverse() const {
  if (IsPolynomial(type_)) return std::nullopt;
  return FromMatrix(type_, matrix_.inverse());
}

std::optional<PlaneTransform> FitPlaneTransform(TransformType type,
                                                const std::vector<Eigen::Vector2d>& from,
                                                const std::vector<Eigen::Vector2d>& to) {
  std::vector<int> all(from.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return FitPlaneTransform(type, from, to, all);
}

std::optional<PlaneTransform> FitPlaneTransform(TransformType type,
                                                const std::vector<Eigen::Vector2d>& from,
                                                const std::vector<Eigen::Vector2d>& to,
                                                const std::vector<int>& subset) {
  CheckPairs(type, from.size(), to.size(), subset.size());
  for (int i : subset) {
    if (i < 0 || static_cast<size_t>(i) >= from.size()) {
      throw InputError("point index " + std::to_string(i) + " out of range", "subset");
    }
    if (!from[i].allFinite() || !to[i].allFinite()) {
      throw InputError("point pair has a non-finite coordinate (NaN or infinity)",
                       "control points, pair " + std::to_string(i));
    }
  }
  switch (type) {
    case TransformType::kSimilarity:
      return FitSimilarity(from, to, subset);
    case TransformType::kAffine:
      return FitAffine(from, to, subset);
    case TransformType::kProjective:
      return FitProjective(from, to, subset);
    case TransformType::kPolynomial2:
    case TransformType::kPolynomial3:
      return FitPolynomial(type, from, to, subset);
  }
  return std::nullopt;
}

void RegistrationOptions::Check() const {
  if (!std::isfinite(threshold_px) || threshold_px <= 0.0) {
    throw ConfigError("registration threshold must be a positive number of pixels", "threshold_px");
  }
  CheckSamplingBudget(confidence, max_iterations, min_iterations, max_refits);
}

std::optional<Registration> RegisterControlPoints(const std::vector<PointMatch>& pairs,
                                                  const RegistrationOptions& options) {
  options.Check();
  CheckPairs(options.type, pairs.size(), pairs.size(), pairs.size());
  CheckFinite(pairs, "control point pairs");
  const int n = static_cast<int>(pairs.size());
  std::vector<Eigen::Vector2d> moving(n), fixed(n);
  for (int i = 0; i < n; ++i) {
    moving[i] = pairs[i].p2;
    fixed[i] = pairs[i].p1;
  }
  std::vector<int> all(n);
  for (int i = 0; i < n; ++i) all[i] = i;

  Registration out;
  out.type = options.type;
  std::optional<PlaneTransform> forward;
  std::vector<int> inliers;
  if (!options.robust) {
    forward = FitPlaneTransform(options.type, moving, fixed, all);
    if (!forward) return std::nullopt;
    inliers = all;
  } else {
    const int k = MinimumControlPoints(options.type);
    const size_t min_support = static_cast<size_t>(std::min(k + 1, n));
    std::mt19937 rng(options.seed);
    double best_score = std::numeric_limits<double>::infinity();
    size_t best_sample_support = 0;
    std::unordered_set<uint64_t> refitted;
    int needed = options.max_iterations;
    int iterations = 0;
    while (iterations < std::max(needed, options.min_iterations)) {
      ++iterations;
      const std::vector<int> sample = SampleDistinct(rng, n, k);
      const std::optional<PlaneTransform> t =
          FitPlaneTransform(options.type, moving, fixed, sample);
      if (!t) continue;
      const Support support = Score(TransferErrors(*t, moving, fixed), options.threshold_px);
      const size_t count = support.inliers.size();
      if (count < min_support || static_cast<double>(count) < 0.9 * best_sample_support) continue;
      best_sample_support = std::max(best_sample_support, count);
      if (!refitted.insert(HashIndices(support.inliers)).second) continue;
      // Local optimisation: least-squares refits until the inlier set is stable.
      std::vector<int> set = support.inliers;
      std::optional<PlaneTransform> refit = FitPlaneTransform(options.type, moving, fixed, set);
      if (!refit) continue;
      for (int r = 1; r < options.max_refits; ++r) {
        std::vector<int> next =
            Score(TransferErrors(*refit, moving, fixed), options.threshold_px).inliers;
        if (next == set || next.size() < static_cast<size_t>(k)) break;
        const std::optional<PlaneTransform> again =
            FitPlaneTransform(options.type, moving, fixed, next);
        if (!again) break;
        refit = again;
        set = std::move(next);
      }
      const Support refit_support =
          Score(TransferErrors(*refit, moving, fixed), options.threshold_px);
      if (refit_support.score < best_score && refit_support.inliers.size() >= min_support) {
        best_score = refit_support.score;
        forward = refit;
        inliers = set;
        const double w = static_cast<double>(refit_support.inliers.size()) / n;
        const double all_inlier = std::pow(w, k);
        int required = options.max_iterations;
        if (all_inlier >= 1.0) {
          required = 0;
        } else if (all_inlier > 0.0) {
          const double v = std::ceil(std::log1p(-options.confidence) / std::log1p(-all_inlier));
          if (v < options.max_iterations) required = static_cast<int>(v);
        }
        needed = std::min(needed, required);
      }
    }
    out.iterations = iterations;
    if (!forward) return std::nullopt;
    // The refit loop ends on a stable set; make `inliers` those of the final
    // transform.
    inliers = Score(TransferErrors(*forward, moving, fixed), options.threshold_px).inliers;
    if (inliers.size() < min_support) return std::nullopt;
  }

  std::optional<PlaneTransform> backward;
  if (IsPolynomial(options.type)) {
    backward = FitPlaneTransform(options.type, fixed, moving, inliers);
  } else {
    backward = forward->Inverse();
  }
  if (!backward) return std::nullopt;
  out.moving_to_fixed = *forward;
  out.fixed_to_moving = *backward;
  out.inliers = inliers;
  out.residuals_px = TransferErrors(*forward, moving, fixed);
  out.rms_px = RmsOver(out.residuals_px, inliers);
  out.inverse_rms_px = RmsOver(TransferErrors(*backward, fixed, moving), inliers);
  return out;
}

cv::Mat WarpToFixed(const cv::Mat& moving, const Registration& registration, cv::Size fixed_size,
                    int interpolation) {
  if (moving.empty()) throw InputError("moving image is empty", "moving image");
  if (fixed_size.width <= 0 || fixed_size.height <= 0) {
    throw InputError("fixed image size must be positive", "fixed image");
  }
  cv::Mat out;
  const TransformType type = registration.moving_to_fixed.type();
  if (type == TransformType::kSimilarity || type == TransformType::kAffine ||
      type == TransformType::kProjective) {
    const Eigen::Matrix3d m = *registration.moving_to_fixed.Matrix();
    if (type == TransformType::kProjective) {
      cv::Mat h(3, 3, CV_64F);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) h.at<double>(r, c) = m(r, c);
      cv::warpPerspective(moving, out, h, fixed_size, interpolation, cv::BORDER_CONSTANT,
                          cv::Scalar::all(0));
    } else {
      cv::Mat a(2, 3, CV_64F);
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 3; ++c) a.at<double>(r, c) = m(r, c) / m(2, 2);
      cv::warpAffine(moving, out, a, fixed_size, interpolation, cv::BORDER_CONSTANT,
                     cv::Scalar::all(0));
    }
    return out;
  }
  cv::Mat map_x(fixed_size, CV_32FC1), map_y(fixed_size, CV_32FC1);
  for (int r = 0; r < fixed_size.height; ++r) {
    float* mx = map_x.ptr<float>(r);
    float* my = map_y.ptr<float>(r);
    for (int c = 0; c < fixed_size.width; ++c) {
      const Eigen::Vector2d p = registration.fixed_to_moving.Apply(Eigen::Vector2d(c, r));
      mx[c] = static_cast<float>(p.x());
      my[c] = static_cast<float>(p.y());
    }
  }
  cv::remap(moving, out, map_x, map_y, interpolation, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return out;
}

cv::Mat GreenMagentaComposite(const cv::Mat& fixed, const cv::Mat& registered_moving) {
  if (fixed.empty() || registered_moving.empty()) {
    throw InputError("composite needs two non-empty images", "composite");
  }
  if (fixed.channels() != 1 || registered_moving.channels() != 1) {
    throw InputError("composite needs single-channel images", "composite");
  }
  if (fixed.size() != registered_moving.size()) {
    throw InputError("composite images differ in size: " + std::to_string(fixed.cols) + "x" +
                         std::to_string(fixed.rows) + " vs " +
                         std::to_string(registered_moving.cols) + "x" +
                         std::to_string(registered_moving.rows),
                     "composite");
  }
  const cv::Mat g = ToDisplay8U(fixed);
  const cv::Mat m = ToDisplay8U(registered_moving);
  cv::Mat out;
  const std::vector<cv::Mat> channels = {m, g, m};  // B, G, R
  cv::merge(channels, out);
  return out;
}

}  // namespace gissar::mvg
