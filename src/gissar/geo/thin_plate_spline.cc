#include "gissar/geo/thin_plate_spline.h"
#include "gissar/geo/thin_plate_spline_kernels.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <Eigen/QR>

#include "gissar/util/check.h"

// The four-lane helpers below are internal and always inlined; GCC's note
// that a 32-byte vector return changes the ABI without AVX does not apply.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace gissar::geo {
namespace {

// Doubles four or eight at a time (GCC/Clang vector extensions: SSE2 pairs
// on the x86-64 baseline, one AVX or AVX-512 register where the compiler may
// use it); I4/I8 hold their bit patterns (wrapping adds, logical shifts).
using V4 = double __attribute__((vector_size(32)));
using I4 = unsigned long long __attribute__((vector_size(32)));
using V8 = double __attribute__((vector_size(64)));
using I8 = unsigned long long __attribute__((vector_size(64)));
constexpr int kLanes = 4;
// Node arrays are padded to a multiple of this (zero coefficients), so that
// either width runs over whole vectors.
constexpr int kPadding = 8;

template <class V>
[[gnu::always_inline]] inline V Broadcast(double v) {
  V out = {};
  return out + v;
}

// Natural logarithm of positive normal doubles, to about 1 ulp: the argument
// reduction and the polynomial of fdlibm's __ieee754_log (x = 2^k m, m in
// [sqrt(1/2), sqrt(2)), log(m) = f - s (f - R(s^2)) with s = f / (2 + f)),
// without branches so that the lanes run together. I: V's bit patterns.
template <class V, class I>
[[gnu::always_inline]] inline V LogN(V x) {
  I bits;
  std::memcpy(&bits, &x, sizeof(bits));
  // Shift the exponent so that mantissas from sqrt(1/2) up count in the next
  // binade, then rebuild m in [sqrt(1/2), sqrt(2)).
  const I t = bits + (0x3ff0000000000000ULL - 0x3fe6a09e667f3bcdULL);
  const I m_bits = (t & 0x000fffffffffffffULL) + 0x3fe6a09e667f3bcdULL;
  // The biased exponent as a double without an int64 -> double conversion
  // (none in SSE2): the integer in the low mantissa bits of 2^52.
  const I k_bits = (t >> 52) | 0x4330000000000000ULL;
  V m, k;
  std::memcpy(&m, &m_bits, sizeof(m));
  std::memcpy(&k, &k_bits, sizeof(k));
  k -= Broadcast<V>(4503599627370496.0 + 1023.0);
  const V f = m - 1.0;
  const V s = f / (f + 2.0);
  const V z = s * s;
  const V w = z * z;
  const V t1 = w * (3.999999999940941908e-01 + w * (2.222219843214978396e-01 + w * 1.531383769920937332e-01));
  const V t2 = z * (6.666666666666735130e-01 +
                    w * (2.857142874366239149e-01 + w * (1.818357216161805012e-01 + w * 1.479819860511658591e-01)));
  const V r = t1 + t2;
  const V hfsq = 0.5 * f * f;
  constexpr double kLn2Hi = 6.93147180369123816490e-01, kLn2Lo = 1.90821492927058770002e-10;
  return k * kLn2Hi - ((hfsq - (s * (hfsq + r) + k * kLn2Lo)) - f);
}

// phi(d) = d ln d for squared distances (0 at d = 0).
template <class V, class I>
[[gnu::always_inline]] inline V PhiN(V d) {
  const V tiny = Broadcast<V>(std::numeric_limits<double>::min());
  return d * LogN<V, I>(d > tiny ? d : tiny);
}

inline double Phi(double d) { return d > 0.0 ? d * std::log(d) : 0.0; }

// Cholesky factor of the symmetric positive definite `a` (its lower
// triangle read), written over a's lower triangle: right-looking and
// blocked, each panel's solve and the trailing update split over threads
// (Eigen's LLT runs on one). False when `a` is not positive definite.
bool CholeskyInPlace(Eigen::MatrixXd& a) {
  constexpr int kBlock = 96, kGrain = 64;
  const int n = static_cast<int>(a.rows());
  for (int k = 0; k < n; k += kBlock) {
    const int kb = std::min(kBlock, n - k);
    Eigen::Ref<Eigen::MatrixXd> a11 = a.block(k, k, kb, kb);
    const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> diagonal(a11);  // in place
    if (diagonal.info() != Eigen::Success) return false;
    const int m = n - k - kb;
    if (m == 0) break;
    // Panel: A21 <- A21 L11^-T.
    tbb::parallel_for(tbb::blocked_range<int>(0, m, kGrain), [&](const tbb::blocked_range<int>& rows) {
      auto panel = a.block(k + kb + rows.begin(), k, rows.size(), kb);
      a11.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(panel);
    });
    // Trailing update of the lower triangle: A22 -= A21 A21', by column blocks.
    tbb::parallel_for(tbb::blocked_range<int>(0, m, kGrain), [&](const tbb::blocked_range<int>& cols) {
      const int j0 = k + kb + cols.begin(), jb = cols.size();
      const auto panel_rows = a.block(j0, k, n - j0, kb);
      const auto panel_cols = a.block(j0, k, jb, kb);
      a.block(j0, j0, n - j0, jb).noalias() -= panel_rows * panel_cols.transpose();
    });
  }
  return true;
}

// sum_j c_j phi(|q - p_j|^2) for both values over `count` nodes (a multiple
// of the width of V).
template <class V, class I>
[[gnu::always_inline]] inline void KernelSumsN(const double* xs, const double* ys, const double* c0s,
                                               const double* c1s, size_t count, double qx_value, double qy_value,
                                               double* sums) {
  constexpr size_t kWidth = sizeof(V) / sizeof(double);
  const V qx = Broadcast<V>(qx_value), qy = Broadcast<V>(qy_value);
  V s0 = {}, s1 = {};
  for (size_t j = 0; j < count; j += kWidth) {
    V x, y, c0, c1;
    std::memcpy(&x, xs + j, sizeof(x));
    std::memcpy(&y, ys + j, sizeof(y));
    std::memcpy(&c0, c0s + j, sizeof(c0));
    std::memcpy(&c1, c1s + j, sizeof(c1));
    const V dx = x - qx, dy = y - qy;
    const V phi = PhiN<V, I>(dx * dx + dy * dy);
    s0 += c0 * phi;
    s1 += c1 * phi;
  }
  double t0 = 0.0, t1 = 0.0;
  for (size_t lane = 0; lane < kWidth; ++lane) {
    t0 += s0[lane];
    t1 += s1[lane];
  }
  sums[0] = t0;
  sums[1] = t1;
}

}  // namespace

namespace internal {

// GCC function multi-versioning; clang 14 (the fuzz build, scripts/fuzz.sh)
// refuses a clone of two features, so there the kernels are compiled for
// the baseline only.
#if defined(__clang__)
#define GISSAR_AVX2_FMA_CLONES
#else
#define GISSAR_AVX2_FMA_CLONES __attribute__((target_clones("avx2,fma", "default")))
#endif

// KernelSumsN four lanes at a time, compiled for AVX2 + FMA and for the
// x86-64 baseline, the loader picking the one the CPU runs (GCC function
// multi-versioning); eight lanes with AVX-512.
GISSAR_AVX2_FMA_CLONES void KernelSums4(const double* xs, const double* ys,
                                                                        const double* c0s, const double* c1s,
                                                                        size_t count, double qx, double qy,
                                                                        double* sums) {
  KernelSumsN<V4, I4>(xs, ys, c0s, c1s, count, qx, qy, sums);
}
__attribute__((target("avx512f,fma"))) void KernelSums8(const double* xs, const double* ys, const double* c0s,
                                                         const double* c1s, size_t count, double qx, double qy,
                                                         double* sums) {
  KernelSumsN<V8, I8>(xs, ys, c0s, c1s, count, qx, qy, sums);
}
bool HasAvx512() {
  static const bool avx512 = __builtin_cpu_supports("avx512f");
  return avx512;
}

}  // namespace internal

namespace {

void KernelSums(const double* xs, const double* ys, const double* c0s, const double* c1s, size_t count, double qx,
                double qy, double* sums) {
  (internal::HasAvx512() ? internal::KernelSums8 : internal::KernelSums4)(xs, ys, c0s, c1s, count, qx, qy, sums);
}

// out[j] = phi(|q - p_j|^2) for the `count` nodes (xs, ys): four at a time,
// the tail one by one. Compiled as KernelSums is.
GISSAR_AVX2_FMA_CLONES void KernelRow(const double* xs, const double* ys,
                                                                      size_t count, double qx_value,
                                                                      double qy_value, double* out) {
  const V4 qx = Broadcast<V4>(qx_value), qy = Broadcast<V4>(qy_value);
  size_t j = 0;
  for (; j + kLanes <= count; j += kLanes) {
    V4 x, y;
    std::memcpy(&x, xs + j, sizeof(x));
    std::memcpy(&y, ys + j, sizeof(y));
    const V4 dx = x - qx, dy = y - qy;
    const V4 phi = PhiN<V4, I4>(dx * dx + dy * dy);
    std::memcpy(out + j, &phi, sizeof(phi));
  }
  for (; j < count; ++j) {
    const double dx = xs[j] - qx_value, dy = ys[j] - qy_value;
    out[j] = Phi(dx * dx + dy * dy);
  }
}

}  // namespace

std::optional<ThinPlateSpline> ThinPlateSpline::Fit(const std::vector<Eigen::Vector2d>& nodes,
                                                    const std::vector<Eigen::Vector2d>& values) {
  GISSAR_CHECK(nodes.size() == values.size());
  const int n = static_cast<int>(nodes.size());
  if (n < 3) return std::nullopt;
  ThinPlateSpline s;
  Eigen::Vector2d lo = nodes[0], hi = nodes[0];
  Eigen::Vector2d mean_value = Eigen::Vector2d::Zero();
  for (int i = 0; i < n; ++i) {
    if (!nodes[i].allFinite() || !values[i].allFinite()) return std::nullopt;
    lo = lo.cwiseMin(nodes[i]);
    hi = hi.cwiseMax(nodes[i]);
    mean_value += values[i];
  }
  const double extent = (hi - lo).maxCoeff();
  if (!(extent > 0.0)) return std::nullopt;
  s.centre_ = 0.5 * (lo + hi);
  s.inv_scale_ = 1.0 / extent;
  s.offset_ = mean_value / n;
  Eigen::MatrixX2d p(n, 2), v(n, 2);
  for (int i = 0; i < n; ++i) {
    p.row(i) = ((nodes[i] - s.centre_) * s.inv_scale_).transpose();
    v.row(i) = (values[i] - s.offset_).transpose();
  }

  // Kernel matrix (symmetric, zero diagonal), rows in parallel.
  Eigen::MatrixXd k(n, n);
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16), [&](const tbb::blocked_range<int>& rows) {
    for (int i = rows.begin(); i < rows.end(); ++i) {
      for (int j = 0; j < n; ++j) k(j, i) = Phi((p.row(i) - p.row(j)).squaredNorm());
    }
  });

  // Null space of P' by a Householder QR of P = [1 x y].
  Eigen::MatrixXd pm(n, 3);
  pm.col(0).setOnes();
  pm.rightCols<2>() = p;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(pm);
  const Eigen::Matrix3d r = qr.matrixQR().topLeftCorner<3, 3>().triangularView<Eigen::Upper>();
  // Collinear nodes: P has rank < 3.
  const double r_scale = r.diagonal().cwiseAbs().maxCoeff();
  if (!(r.diagonal().cwiseAbs().minCoeff() > 1e-9 * r_scale)) return std::nullopt;
  Eigen::MatrixXd b = k;
  const auto q = qr.householderQ();
  b.applyOnTheLeft(q.adjoint());
  b.applyOnTheRight(q);
  Eigen::MatrixX2d z = v;
  z.applyOnTheLeft(q.adjoint());
  const int m = n - 3;
  Eigen::MatrixX2d w = Eigen::MatrixX2d::Zero(n, 2);
  if (m > 0) {
    Eigen::MatrixXd factor = b.bottomRightCorner(m, m);
    if (!CholeskyInPlace(factor)) return std::nullopt;
    Eigen::MatrixX2d y = z.bottomRows(m);
    factor.triangularView<Eigen::Lower>().solveInPlace(y);
    factor.triangularView<Eigen::Lower>().transpose().solveInPlace(y);
    w.bottomRows(m) = y;
  }
  // Affine part: R a = Q1' (v - K c) = z_top - (Q' K Q)_top,bottom w.
  const Eigen::Matrix<double, 3, 2> rhs = z.topRows<3>() - b.topRows<3>() * w;
  s.affine_ = r.triangularView<Eigen::Upper>().solve(rhs);
  Eigen::MatrixX2d c = w;
  c.applyOnTheLeft(q);

  // The spline must pass through its nodes.
  const Eigen::MatrixX2d residual = k * c + pm * s.affine_ - v;
  const double spread = std::max(v.cwiseAbs().maxCoeff(), std::numeric_limits<double>::min());
  if (!(residual.cwiseAbs().maxCoeff() <= 1e-8 * spread)) return std::nullopt;

  s.AssignNodes(p, c);
  return s;
}

void ThinPlateSpline::AssignNodes(const Eigen::MatrixX2d& nodes, const Eigen::MatrixX2d& coefficients) {
  n_ = static_cast<int>(nodes.rows());
  // Padded to a multiple of the vector width with zero coefficients.
  const size_t padded = (size_t(n_) + kPadding - 1) / kPadding * kPadding;
  x_.assign(padded, 0.0);
  y_.assign(padded, 0.0);
  c0_.assign(padded, 0.0);
  c1_.assign(padded, 0.0);
  for (int i = 0; i < n_; ++i) {
    x_[i] = nodes(i, 0);
    y_[i] = nodes(i, 1);
    c0_[i] = coefficients(i, 0);
    c1_[i] = coefficients(i, 1);
  }
}

Eigen::Vector2d ThinPlateSpline::operator()(const Eigen::Vector2d& point) const {
  if (!point.allFinite()) return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  const Eigen::Vector2d q = (point - centre_) * inv_scale_;
  double sums[2];
  KernelSums(x_.data(), y_.data(), c0_.data(), c1_.data(), x_.size(), q.x(), q.y(), sums);
  Eigen::Vector2d out = offset_ + affine_.row(0).transpose() + q.x() * affine_.row(1).transpose() +
                        q.y() * affine_.row(2).transpose();
  out.x() += sums[0];
  out.y() += sums[1];
  return out;
}

std::vector<Eigen::Vector2d> ThinPlateSpline::Evaluate(const std::vector<Eigen::Vector2d>& points) const {
  std::vector<Eigen::Vector2d> out(points.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) out[i] = (*this)(points[i]);
  });
  return out;
}

bool IncrementalThinPlateSpline::Add(const std::vector<Eigen::Vector2d>& nodes,
                                     const std::vector<Eigen::Vector2d>& values) {
  GISSAR_CHECK(nodes.size() == values.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!nodes[i].allFinite() || !values[i].allFinite()) return false;
  }
  const bool first = px_.empty();
  if (nodes.empty()) return !first;
  if (first) {
    // The scaling and offset of ThinPlateSpline::Fit, from the first batch.
    if (nodes.size() < 3) return false;
    Eigen::Vector2d lo = nodes[0], hi = nodes[0], mean = Eigen::Vector2d::Zero();
    for (size_t i = 0; i < nodes.size(); ++i) {
      lo = lo.cwiseMin(nodes[i]);
      hi = hi.cwiseMax(nodes[i]);
      mean += values[i];
    }
    const double extent = (hi - lo).maxCoeff();
    if (!(extent > 0.0)) return false;
    centre_ = 0.5 * (lo + hi);
    inv_scale_ = 1.0 / extent;
    offset_ = mean / double(nodes.size());
  }
  const size_t count = nodes.size();
  std::vector<Eigen::Vector2d> p(count), v(count);
  for (size_t i = 0; i < count; ++i) {
    p[i] = (nodes[i] - centre_) * inv_scale_;
    v[i] = values[i] - offset_;
  }
  // The order in which the batch is appended: the anchors first.
  std::vector<size_t> order;
  Eigen::Matrix3d to_barycentric = to_barycentric_, anchor_kernel = anchor_kernel_;
  if (first) {
    auto farthest = [&](auto&& measure) {
      size_t best = 0;
      for (size_t i = 1; i < count; ++i) {
        if (measure(i) > measure(best)) best = i;
      }
      return best;
    };
    const size_t a0 = farthest([&](size_t i) { return p[i].squaredNorm(); });
    const size_t a1 = farthest([&](size_t i) { return (p[i] - p[a0]).squaredNorm(); });
    auto area2 = [&](size_t i) {
      const Eigen::Vector2d e1 = p[a1] - p[a0], e2 = p[i] - p[a0];
      return std::abs(e1.x() * e2.y() - e1.y() * e2.x());
    };
    const size_t a2 = farthest(area2);
    // Collinear nodes (in the unit-scaled coordinates): no spline.
    if (!(area2(a2) > 1e-9)) return false;
    const size_t anchors[3] = {a0, a1, a2};
    Eigen::Matrix3d g;
    for (int a = 0; a < 3; ++a) {
      g.col(a) << 1.0, p[anchors[a]].x(), p[anchors[a]].y();
      for (int b = 0; b < 3; ++b) anchor_kernel(a, b) = Phi((p[anchors[a]] - p[anchors[b]]).squaredNorm());
    }
    to_barycentric = g.inverse();
    order = {a0, a1, a2};
  }
  for (size_t i = 0; i < count; ++i) {
    if (!first || (i != order[0] && i != order[1] && i != order[2])) order.push_back(i);
  }
  const size_t basis_begin = first ? 3 : 0;  // the batch's first basis node in `order`
  const int k = static_cast<int>(count - basis_begin), m = m_;
  // The anchors' coordinates and values (already stored, or this batch's).
  Eigen::Vector3d anchor_x, anchor_y;
  Eigen::Matrix<double, 3, 2> anchor_v;
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector2d pa = first ? p[order[a]] : Eigen::Vector2d(px_[a], py_[a]);
    anchor_x[a] = pa.x();
    anchor_y[a] = pa.y();
    anchor_v.row(a) = (first ? v[order[a]] : values_[a]).transpose();
  }
  // The new basis nodes: barycentric coordinates, kernel to the anchors,
  // right-hand side (Z' v).
  std::vector<Eigen::Vector3d> lambda(k), anchor_phi(k);
  std::vector<double> bx(k), by(k);
  Eigen::MatrixX2d rhs(k, 2);
  for (int q = 0; q < k; ++q) {
    const Eigen::Vector2d& pq = p[order[basis_begin + q]];
    bx[q] = pq.x();
    by[q] = pq.y();
    lambda[q] = to_barycentric * Eigen::Vector3d(1.0, pq.x(), pq.y());
    for (int a = 0; a < 3; ++a) {
      anchor_phi[q][a] = Phi((pq - Eigen::Vector2d(anchor_x[a], anchor_y[a])).squaredNorm());
    }
    rhs.row(q) = v[order[basis_begin + q]].transpose() - lambda[q].transpose() * anchor_v;
  }
  // M's new block row: M_qj = z_q' K z_j
  //   = K_qj - lambda_j . kA_q - lambda_q . kA_j + lambda_q . (K_AA lambda_j),
  // against the old basis nodes (x = M21', m x k) and among the new (m22).
  Eigen::MatrixXd x(m, k), m22(k, k);
  tbb::parallel_for(tbb::blocked_range<int>(0, k, 8), [&](const tbb::blocked_range<int>& range) {
    std::vector<double> row(size_t(std::max(m, k)));
    for (int q = range.begin(); q < range.end(); ++q) {
      const Eigen::Vector3d lq = lambda[q], kq = anchor_phi[q], mq = anchor_kernel * lq;
      // Column q of M against `count` basis nodes (coordinates xs, ys).
      auto column = [&](const double* xs, const double* ys, const std::vector<Eigen::Vector3d>& lambdas,
                        const std::vector<Eigen::Vector3d>& phis, int count, auto&& out) {
        KernelRow(xs, ys, size_t(count), bx[q], by[q], row.data());
        for (int j = 0; j < count; ++j) out(j) = row[j] - lambdas[j].dot(kq) - lq.dot(phis[j]) + mq.dot(lambdas[j]);
      };
      if (m > 0) column(px_.data() + 3, py_.data() + 3, lambda_, anchor_phi_, m, [&](int j) -> double& { return x(j, q); });
      column(bx.data(), by.data(), lambda, anchor_phi, k, [&](int j) -> double& { return m22(j, q); });
    }
  });
  // Factor's new block row: L21' = L11^-1 M21' (columns in parallel), and
  // L22 = chol(M22 - L21 L21').
  if (m > 0 && k > 0) {
    const auto l11 = factor_.topLeftCorner(m, m).triangularView<Eigen::Lower>();
    tbb::parallel_for(tbb::blocked_range<int>(0, k, std::max(16, (k + 1) / 2)), [&](const tbb::blocked_range<int>& cols) {
      auto block = x.middleCols(cols.begin(), cols.size());
      l11.solveInPlace(block);
    });
    m22.selfadjointView<Eigen::Lower>().rankUpdate(x.transpose(), -1.0);  // the lower triangle, which Cholesky reads
  }
  if (k > 0 && !CholeskyInPlace(m22)) return false;

  // Commit.
  if (factor_.rows() < m + k) {
    const int capacity = std::max(m + k, 2 * int(factor_.rows()));
    Eigen::MatrixXd grown(capacity, capacity);
    grown.topLeftCorner(m, m) = factor_.topLeftCorner(m, m);
    factor_.swap(grown);
    Eigen::MatrixX2d grown_rhs(capacity, 2);
    grown_rhs.topRows(m) = rhs_.topRows(m);
    rhs_.swap(grown_rhs);
  }
  if (k > 0) {
    factor_.block(m, 0, k, m) = x.transpose();
    factor_.block(m, m, k, k) = m22.triangularView<Eigen::Lower>();
    rhs_.middleRows(m, k) = rhs;
  }
  if (first) {
    to_barycentric_ = to_barycentric;
    anchor_kernel_ = anchor_kernel;
  }
  for (size_t i : order) {
    px_.push_back(p[i].x());
    py_.push_back(p[i].y());
    values_.push_back(v[i]);
  }
  lambda_.insert(lambda_.end(), lambda.begin(), lambda.end());
  anchor_phi_.insert(anchor_phi_.end(), anchor_phi.begin(), anchor_phi.end());
  m_ = m + k;
  return true;
}

std::optional<ThinPlateSpline> IncrementalThinPlateSpline::Spline() const {
  if (px_.empty()) return std::nullopt;
  const int m = m_, n = m + 3;
  // M alpha = Z' v; c = Z alpha: alpha on the basis nodes, minus the
  // barycentric sums on the anchors.
  Eigen::MatrixX2d alpha = rhs_.topRows(m);
  const auto l = factor_.topLeftCorner(m, m).triangularView<Eigen::Lower>();
  l.solveInPlace(alpha);
  l.transpose().solveInPlace(alpha);
  Eigen::Matrix<double, 3, 2> anchor_c = Eigen::Matrix<double, 3, 2>::Zero();
  // (K c) at the anchors, for the affine part.
  Eigen::Matrix<double, 3, 2> kc = Eigen::Matrix<double, 3, 2>::Zero();
  for (int i = 0; i < m; ++i) {
    anchor_c -= lambda_[i] * alpha.row(i);
    kc += anchor_phi_[i] * alpha.row(i);
  }
  kc += anchor_kernel_ * anchor_c;
  Eigen::Matrix<double, 3, 2> anchor_v;
  for (int a = 0; a < 3; ++a) anchor_v.row(a) = values_[a].transpose();
  // Values at the anchors: (K c)_a + [1 x_a y_a] A, and [1 x_a y_a] is row a
  // of G' = (to_barycentric_^-1)'.
  ThinPlateSpline s;
  s.affine_ = to_barycentric_.transpose() * (anchor_v - kc);
  s.centre_ = centre_;
  s.inv_scale_ = inv_scale_;
  s.offset_ = offset_;
  Eigen::MatrixX2d nodes_fit(n, 2), coefficients(n, 2);
  for (int i = 0; i < n; ++i) {
    nodes_fit.row(i) << px_[i], py_[i];
    if (i < 3) {
      coefficients.row(i) = anchor_c.row(i);
    } else {
      coefficients.row(i) = alpha.row(i - 3);
    }
  }
  s.AssignNodes(nodes_fit, coefficients);
  // The spline must pass through its nodes (Fit's test).
  std::vector<Eigen::Vector2d> nodes(n);
  double spread = std::numeric_limits<double>::min();
  for (int i = 0; i < n; ++i) {
    nodes[i] = Eigen::Vector2d(px_[i], py_[i]) / inv_scale_ + centre_;
    spread = std::max(spread, values_[i].cwiseAbs().maxCoeff());
  }
  const std::vector<Eigen::Vector2d> at_nodes = s.Evaluate(nodes);
  for (int i = 0; i < n; ++i) {
    if (!((at_nodes[i] - offset_ - values_[i]).cwiseAbs().maxCoeff() <= 1e-8 * spread)) return std::nullopt;
  }
  return s;
}

}  // namespace gissar::geo
