#include "gissar/mvg/affine_fundamental.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_set>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "gissar/mvg/random.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

// (a, b, c, d, e) of an affine F.
struct Coefficients {
  double a, b, c, d, e;
};

Coefficients Read(const Eigen::Matrix3d& f) {
  return {f(0, 2), f(1, 2), f(2, 0), f(2, 1), f(2, 2)};
}

Eigen::Matrix3d FromCoefficients(double a, double b, double c, double d, double e) {
  Eigen::Matrix3d f = Eigen::Matrix3d::Zero();
  f(0, 2) = a;
  f(1, 2) = b;
  f(2, 0) = c;
  f(2, 1) = d;
  f(2, 2) = e;
  return f;
}

// The Gold Standard fit to the matches selected by `index(i)`, i < count.
// Inputs are already validated.
template <typename IndexFn>
std::optional<Eigen::Matrix3d> GoldStandard(const std::vector<PointMatch>& matches, int count,
                                            IndexFn index) {
  Eigen::Matrix<double, Eigen::Dynamic, 4> data(count, 4);
  for (int i = 0; i < count; ++i) {
    const PointMatch& m = matches[index(i)];
    data.row(i) << m.p2.x(), m.p2.y(), m.p1.x(), m.p1.y();
  }
  const Eigen::RowVector4d centroid = data.colwise().mean();
  data.rowwise() -= centroid;
  const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 4>> svd(data, Eigen::ComputeFullV);
  const Eigen::Vector4d sv = svd.singularValues();
  if (!(sv(0) > 0.0) || sv(2) <= kRankTolerance * sv(0)) return std::nullopt;
  const Eigen::Vector4d n = svd.matrixV().col(3);
  const double e = -n.dot(centroid.transpose());
  return NormalizeAffineFundamental(FromCoefficients(n(0), n(1), n(2), n(3), e));
}

void CheckMatchCount(size_t count) {
  if (count < 4) {
    throw InputError(
        "the affine fundamental matrix needs at least 4 matches, got " + std::to_string(count),
        "matches");
  }
}

double Residual(const Coefficients& k, const PointMatch& m) {
  return k.a * m.p2.x() + k.b * m.p2.y() + k.c * m.p1.x() + k.d * m.p1.y() + k.e;
}

// Number of samples needed so that one is all-inlier with probability
// `confidence`, for inlier ratio `w` and sample size 4.
int RequiredIterations(double w, double confidence, int max_iterations) {
  if (w >= 1.0) return 0;
  const double all_inlier = std::pow(w, 4);
  if (all_inlier <= 0.0) return max_iterations;
  const double denom = std::log1p(-all_inlier);
  if (denom >= 0.0) return max_iterations;
  const double n = std::ceil(std::log1p(-confidence) / denom);
  if (!(n < static_cast<double>(max_iterations))) return max_iterations;
  return std::max(0, static_cast<int>(n));
}

// Samples whose support reaches this fraction of the best sample's support
// are locally optimised (refitted).
constexpr double kLocalOptimisationFraction = 0.9;

uint64_t HashIndices(const std::vector<int>& indices) {
  uint64_t h = 1469598103934665603ull;  // FNV-1a over the index values
  for (int i : indices) {
    h ^= static_cast<uint64_t>(static_cast<uint32_t>(i));
    h *= 1099511628211ull;
  }
  return h;
}

// Support of a model: inliers (|GS residual| < threshold) and the MSAC
// score, the sum over all matches of min(r^2, threshold^2) (lower is better).
struct Support {
  std::vector<int> inliers;
  double score = 0.0;
};

Support Score(const Eigen::Matrix3d& f, const std::vector<PointMatch>& matches, double threshold) {
  const Coefficients k = Read(f);
  const double norm = std::sqrt(k.a * k.a + k.b * k.b + k.c * k.c + k.d * k.d);
  const double t2 = threshold * threshold;
  Support out;
  for (size_t i = 0; i < matches.size(); ++i) {
    const double r = Residual(k, matches[i]) / norm;
    if (std::abs(r) < threshold) out.inliers.push_back(static_cast<int>(i));
    out.score += std::min(r * r, t2);
  }
  return out;
}

// Gold Standard refits from `inliers`, re-selecting the inliers under each
// refit, until the set is stable (or max_refits). std::nullopt when the
// first refit is degenerate.
std::optional<RobustFundamentalFit> Refit(const std::vector<PointMatch>& matches,
                                          std::vector<int> inliers, const RansacOptions& options) {
  std::optional<Eigen::Matrix3d> f = EstimateAffineFundamental(matches, inliers);
  if (!f) return std::nullopt;
  RobustFundamentalFit fit;
  fit.refits = 1;
  for (;;) {
    std::vector<int> next = Score(*f, matches, options.threshold_px).inliers;
    if (next == inliers) {
      fit.refit_converged = true;
      break;
    }
    if (next.size() < 4 || fit.refits >= options.max_refits) break;
    const std::optional<Eigen::Matrix3d> refit = EstimateAffineFundamental(matches, next);
    if (!refit) break;
    f = refit;
    inliers = std::move(next);
    ++fit.refits;
  }
  fit.f = *f;
  fit.inliers = std::move(inliers);
  return fit;
}

}  // namespace

void CheckAffineFundamental(const Eigen::Matrix3d& f, const std::string& what) {
  if (!f.allFinite()) throw InputError("fundamental matrix has a non-finite entry", what);
  const double scale = f.norm();
  if (f.topLeftCorner<2, 2>().cwiseAbs().maxCoeff() > 1e-9 * scale) {
    throw InputError("not an affine fundamental matrix: its top-left 2x2 block must be zero", what);
  }
  const Coefficients k = Read(f);
  if (k.a == 0.0 && k.b == 0.0 && k.c == 0.0 && k.d == 0.0) {
    throw InputError("affine fundamental matrix has a zero (a, b, c, d) part", what);
  }
}

Eigen::Matrix3d NormalizeAffineFundamental(const Eigen::Matrix3d& f) {
  CheckAffineFundamental(f, "F");
  Coefficients k = Read(f);
  const double norm = std::sqrt(k.a * k.a + k.b * k.b + k.c * k.c + k.d * k.d);
  k = {k.a / norm, k.b / norm, k.c / norm, k.d / norm, k.e / norm};
  constexpr double kSmall = 1e-6;
  double sign_source = k.b;
  if (std::abs(k.c) >= kSmall) {
    sign_source = k.c;
  } else if (std::abs(k.d) >= kSmall) {
    sign_source = k.d;
  } else if (std::abs(k.a) >= kSmall) {
    sign_source = k.a;
  }
  const double sign = sign_source < 0.0 ? -1.0 : 1.0;
  return sign * FromCoefficients(k.a, k.b, k.c, k.d, k.e);
}

double AffineFundamentalDistance(const Eigen::Matrix3d& f, const Eigen::Matrix3d& g) {
  const Eigen::Matrix3d fn = NormalizeAffineFundamental(f);
  const Eigen::Matrix3d gn = NormalizeAffineFundamental(g);
  return std::min((fn - gn).norm(), (fn + gn).norm());
}

std::optional<Eigen::Matrix3d> FundamentalFromCameras(const AffineMatrix& p1,
                                                      const AffineMatrix& p2) {
  CheckAffineCamera(p1, "camera 1");
  CheckAffineCamera(p2, "camera 2");
  Eigen::Matrix<double, 4, 3> a;
  a.topRows<2>() = p1.block<2, 3>(0, 0);
  a.bottomRows<2>() = p2.block<2, 3>(0, 0);
  const Eigen::JacobiSVD<Eigen::Matrix<double, 4, 3>> svd(a);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(0) > 0.0) || sv(2) <= kRankTolerance * sv(0)) return std::nullopt;
  // Left null vector from the 3x3 minors: n_i = (-1)^i det(A without row i).
  Eigen::Vector4d n;
  for (int i = 0; i < 4; ++i) {
    Eigen::Matrix3d minor;
    int r = 0;
    for (int j = 0; j < 4; ++j) {
      if (j == i) continue;
      minor.row(r++) = a.row(j);
    }
    n(i) = ((i % 2 == 0) ? 1.0 : -1.0) * minor.determinant();
  }
  const Eigen::Vector4d t(p1(0, 3), p1(1, 3), p2(0, 3), p2(1, 3));
  const double e = -n.dot(t);
  // n multiplies (x1, y1, x2, y2): (c, d, a, b).
  return NormalizeAffineFundamental(FromCoefficients(n(2), n(3), n(0), n(1), e));
}

std::optional<Eigen::Matrix3d> EstimateAffineFundamental(const std::vector<PointMatch>& matches) {
  CheckMatchCount(matches.size());
  CheckFinite(matches, "matches");
  return GoldStandard(matches, static_cast<int>(matches.size()), [](int i) { return i; });
}

std::optional<Eigen::Matrix3d> EstimateAffineFundamental(const std::vector<PointMatch>& matches,
                                                         const std::vector<int>& subset) {
  CheckMatchCount(subset.size());
  for (int i : subset) {
    if (i < 0 || static_cast<size_t>(i) >= matches.size()) {
      throw InputError("match index " + std::to_string(i) + " out of range [0, " +
                           std::to_string(matches.size()) + ")",
                       "subset");
    }
    if (!matches[i].p1.allFinite() || !matches[i].p2.allFinite()) {
      throw InputError("match has a non-finite coordinate (NaN or infinity)",
                       "matches, match " + std::to_string(i));
    }
  }
  return GoldStandard(matches, static_cast<int>(subset.size()),
                      [&subset](int i) { return subset[i]; });
}

std::optional<Eigen::Matrix3d> SolveAffineFundamentalMinimal(const PointMatch& m0,
                                                             const PointMatch& m1,
                                                             const PointMatch& m2,
                                                             const PointMatch& m3) {
  const std::vector<PointMatch> sample = {m0, m1, m2, m3};
  CheckFinite(sample, "minimal sample");
  return GoldStandard(sample, 4, [](int i) { return i; });
}

void RansacOptions::Check() const {
  if (!std::isfinite(threshold_px) || threshold_px <= 0.0) {
    throw ConfigError("RANSAC threshold must be a positive number of pixels", "threshold_px");
  }
  CheckSamplingBudget(confidence, max_iterations, min_iterations, max_refits);
}

std::optional<RobustFundamentalFit> EstimateAffineFundamentalRansac(
    const std::vector<PointMatch>& matches, const RansacOptions& options) {
  options.Check();
  CheckMatchCount(matches.size());
  CheckFinite(matches, "matches");
  const int n = static_cast<int>(matches.size());
  const size_t min_support = static_cast<size_t>(std::min(5, n));
  std::mt19937 rng(options.seed);

  std::optional<RobustFundamentalFit> best;
  double best_score = std::numeric_limits<double>::infinity();
  size_t best_sample_support = 0;
  std::unordered_set<uint64_t> refitted;  // hashes of the inlier sets already refitted
  int needed = options.max_iterations;
  int iterations = 0;
  while (iterations < std::max(needed, options.min_iterations)) {
    ++iterations;
    const std::array<int, 4> s = SampleDistinct<4>(rng, n);
    const std::optional<Eigen::Matrix3d> f = GoldStandard(matches, 4, [&s](int i) { return s[i]; });
    if (!f) continue;
    const Support support = Score(*f, matches, options.threshold_px);
    const size_t count = support.inliers.size();
    // Local optimisation of every promising sample: one whose support is
    // within kLocalOptimisationFraction of the best sample's, and whose
    // inlier set has not been refitted before.
    if (count < min_support ||
        static_cast<double>(count) < kLocalOptimisationFraction * best_sample_support) {
      continue;
    }
    best_sample_support = std::max(best_sample_support, count);
    if (!refitted.insert(HashIndices(support.inliers)).second) continue;
    std::optional<RobustFundamentalFit> fit = Refit(matches, support.inliers, options);
    if (!fit || fit->inliers.size() < min_support) continue;
    const double score = Score(fit->f, matches, options.threshold_px).score;
    if (score < best_score) {
      fit->f_ransac = *f;
      fit->ransac_inliers = support.inliers;
      best_score = score;
      best = std::move(fit);
      const double w = static_cast<double>(best->inliers.size()) / n;
      needed = std::min(needed, RequiredIterations(w, options.confidence, options.max_iterations));
    }
  }
  if (!best) return std::nullopt;
  best->iterations = iterations;
  return best;
}

double GoldStandardResidual(const Eigen::Matrix3d& f, const PointMatch& match) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  return Residual(k, match) / std::sqrt(k.a * k.a + k.b * k.b + k.c * k.c + k.d * k.d);
}

double EpipolarResidual1(const Eigen::Matrix3d& f, const PointMatch& match) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double norm = std::hypot(k.c, k.d);
  if (norm == 0.0) throw InputError("F has a zero (c, d) part: no epipolar lines in image 1", "F");
  return Residual(k, match) / norm;
}

double EpipolarResidual2(const Eigen::Matrix3d& f, const PointMatch& match) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double norm = std::hypot(k.a, k.b);
  if (norm == 0.0) throw InputError("F has a zero (a, b) part: no epipolar lines in image 2", "F");
  return Residual(k, match) / norm;
}

FundamentalResiduals ComputeResiduals(const Eigen::Matrix3d& f,
                                      const std::vector<PointMatch>& matches) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double gs_norm = std::sqrt(k.a * k.a + k.b * k.b + k.c * k.c + k.d * k.d);
  const double n1 = std::hypot(k.c, k.d);
  const double n2 = std::hypot(k.a, k.b);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  FundamentalResiduals out;
  out.gs_px.reserve(matches.size());
  out.epi1_px.reserve(matches.size());
  out.epi2_px.reserve(matches.size());
  for (const PointMatch& m : matches) {
    const double r = Residual(k, m);
    out.gs_px.push_back(r / gs_norm);
    out.epi1_px.push_back(n1 > 0.0 ? r / n1 : nan);
    out.epi2_px.push_back(n2 > 0.0 ? r / n2 : nan);
  }
  return out;
}

double RootMeanSquare(const std::vector<double>& values) {
  if (values.empty()) return 0.0;
  double sum = 0.0;
  for (double v : values) sum += v * v;
  return std::sqrt(sum / static_cast<double>(values.size()));
}

double RootMeanSquare(const std::vector<double>& values, const std::vector<int>& subset) {
  if (subset.empty()) return 0.0;
  double sum = 0.0;
  for (int i : subset) {
    GISSAR_CHECK(i >= 0 && static_cast<size_t>(i) < values.size());
    sum += values[i] * values[i];
  }
  return std::sqrt(sum / static_cast<double>(subset.size()));
}

Eigen::Matrix3d CalibrateFundamental(const Eigen::Matrix3d& f, const Eigen::Matrix3d& k1,
                                     const Eigen::Matrix3d& k2) {
  CheckAffineFundamental(f, "F");
  for (const Eigen::Matrix3d* k : {&k1, &k2}) {
    const std::string what = (k == &k1) ? "K1" : "K2";
    if (!k->allFinite()) throw InputError("intrinsic matrix has a non-finite entry", what);
    if ((*k)(1, 0) != 0.0 || (*k)(2, 0) != 0.0 || (*k)(2, 1) != 0.0 || (*k)(2, 2) != 1.0 ||
        (*k)(0, 0) == 0.0 || (*k)(1, 1) == 0.0) {
      throw InputError("intrinsic matrix must be [sx k u0; 0 sy v0; 0 0 1] with sx, sy != 0", what);
    }
  }
  Eigen::Matrix3d out = k2.transpose() * f * k1;
  out.topLeftCorner<2, 2>().setZero();
  return NormalizeAffineFundamental(out);
}

Eigen::Vector2d EpipoleDirection1(const Eigen::Matrix3d& f) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double norm = std::hypot(k.c, k.d);
  if (norm == 0.0) throw InputError("F has a zero (c, d) part: no epipole in image 1", "F");
  return Eigen::Vector2d(-k.d, k.c) / norm;
}

Eigen::Vector2d EpipoleDirection2(const Eigen::Matrix3d& f) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double norm = std::hypot(k.a, k.b);
  if (norm == 0.0) throw InputError("F has a zero (a, b) part: no epipole in image 2", "F");
  return Eigen::Vector2d(-k.b, k.a) / norm;
}

Eigen::Vector3d EpipolarLineInImage2(const Eigen::Matrix3d& f, const Eigen::Vector2d& x1) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double norm = std::hypot(k.a, k.b);
  if (norm == 0.0) throw InputError("F has a zero (a, b) part: no epipolar lines in image 2", "F");
  return Eigen::Vector3d(k.a, k.b, k.c * x1.x() + k.d * x1.y() + k.e) / norm;
}

Eigen::Vector3d EpipolarLineInImage1(const Eigen::Matrix3d& f, const Eigen::Vector2d& x2) {
  CheckAffineFundamental(f, "F");
  const Coefficients k = Read(f);
  const double norm = std::hypot(k.c, k.d);
  if (norm == 0.0) throw InputError("F has a zero (c, d) part: no epipolar lines in image 1", "F");
  return Eigen::Vector3d(k.c, k.d, k.a * x2.x() + k.b * x2.y() + k.e) / norm;
}

}  // namespace gissar::mvg
