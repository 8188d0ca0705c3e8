#include "gissar/geo/thin_plate_spline.h"

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

// Four doubles at a time (GCC/Clang vector extensions: SSE2 pairs on the
// x86-64 baseline, one AVX register where the compiler may use it).
using V4 = double __attribute__((vector_size(32)));
using I4 = unsigned long long __attribute__((vector_size(32)));  // bit patterns: wrapping, logical shifts
constexpr int kLanes = 4;

[[gnu::always_inline]] inline V4 Broadcast(double v) { return V4{v, v, v, v}; }

// Natural logarithm of four positive normal doubles, to about 1 ulp: the
// argument reduction and the polynomial of fdlibm's __ieee754_log (x = 2^k m,
// m in [sqrt(1/2), sqrt(2)), log(m) = f - s (f - R(s^2)) with s = f / (2 + f)),
// without branches so that the four lanes run together.
[[gnu::always_inline]] inline V4 Log4(V4 x) {
  I4 bits;
  std::memcpy(&bits, &x, sizeof(bits));
  // Shift the exponent so that mantissas from sqrt(1/2) up count in the next
  // binade, then rebuild m in [sqrt(1/2), sqrt(2)).
  const I4 t = bits + (0x3ff0000000000000ULL - 0x3fe6a09e667f3bcdULL);
  const I4 m_bits = (t & 0x000fffffffffffffULL) + 0x3fe6a09e667f3bcdULL;
  // The biased exponent as a double without an int64 -> double conversion
  // (none in SSE2): the integer in the low mantissa bits of 2^52.
  const I4 k_bits = (t >> 52) | 0x4330000000000000ULL;
  V4 m, k;
  std::memcpy(&m, &m_bits, sizeof(m));
  std::memcpy(&k, &k_bits, sizeof(k));
  k -= Broadcast(4503599627370496.0 + 1023.0);
  const V4 f = m - 1.0;
  const V4 s = f / (f + 2.0);
  const V4 z = s * s;
  const V4 w = z * z;
  const V4 t1 = w * (3.999999999940941908e-01 + w * (2.222219843214978396e-01 + w * 1.531383769920937332e-01));
  const V4 t2 = z * (6.666666666666735130e-01 +
                     w * (2.857142874366239149e-01 + w * (1.818357216161805012e-01 + w * 1.479819860511658591e-01)));
  const V4 r = t1 + t2;
  const V4 hfsq = 0.5 * f * f;
  constexpr double kLn2Hi = 6.93147180369123816490e-01, kLn2Lo = 1.90821492927058770002e-10;
  return k * kLn2Hi - ((hfsq - (s * (hfsq + r) + k * kLn2Lo)) - f);
}

// phi(d) = d ln d for four squared distances (0 at d = 0).
[[gnu::always_inline]] inline V4 Phi4(V4 d) {
  const V4 tiny = Broadcast(std::numeric_limits<double>::min());
  return d * Log4(d > tiny ? d : tiny);
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
// of kLanes). Compiled twice, for AVX2 + FMA and for the x86-64 baseline, the
// loader picking the one the CPU runs (GCC function multi-versioning).
__attribute__((target_clones("avx2,fma", "default"))) void KernelSums(const double* xs, const double* ys,
                                                                       const double* c0s, const double* c1s,
                                                                       size_t count, double qx_value,
                                                                       double qy_value, double* sums) {
  const V4 qx = Broadcast(qx_value), qy = Broadcast(qy_value);
  V4 s0 = Broadcast(0.0), s1 = Broadcast(0.0);
  for (size_t j = 0; j < count; j += kLanes) {
    V4 x, y, c0, c1;
    std::memcpy(&x, xs + j, sizeof(x));
    std::memcpy(&y, ys + j, sizeof(y));
    std::memcpy(&c0, c0s + j, sizeof(c0));
    std::memcpy(&c1, c1s + j, sizeof(c1));
    const V4 dx = x - qx, dy = y - qy;
    const V4 phi = Phi4(dx * dx + dy * dy);
    s0 += c0 * phi;
    s1 += c1 * phi;
  }
  sums[0] = (s0[0] + s0[1]) + (s0[2] + s0[3]);
  sums[1] = (s1[0] + s1[1]) + (s1[2] + s1[3]);
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

  // Nodes padded to a multiple of the vector width with zero coefficients.
  const size_t padded = (size_t(n) + kLanes - 1) / kLanes * kLanes;
  s.x_.assign(padded, 0.0);
  s.y_.assign(padded, 0.0);
  s.c0_.assign(padded, 0.0);
  s.c1_.assign(padded, 0.0);
  for (int i = 0; i < n; ++i) {
    s.x_[i] = p(i, 0);
    s.y_[i] = p(i, 1);
    s.c0_[i] = c(i, 0);
    s.c1_[i] = c(i, 1);
  }
  s.n_ = n;
  return s;
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

}  // namespace gissar::geo
