// The thin-plate spline of `gdalwarp -tps`, fitted and evaluated without
// GDAL's transformer, for callers that fit many splines and evaluate each at
// many points (the GCP refinement of simulated images).
//
// The interpolant is GDAL's (alg/thinplatespline.cpp): through nodes p_j
// with values v_j,
//   f(p) = a0 + a1 x + a2 y + sum_j c_j phi(|p - p_j|^2),  phi(d) = d ln d,
// with sum_j c_j = sum_j c_j x_j = sum_j c_j y_j = 0 and f(p_j) = v_j
// exactly. That interpolant is unique for nodes not all on one line, so this
// class and GDAL's transformer give the same values up to rounding
// (thin_plate_spline_test.cc compares them). It is also unchanged by a
// translation and a uniform scaling of the nodes (phi's ln-scale term is a
// quadratic that the side conditions turn into a constant), which lets the
// fit work in centred, unit-scaled coordinates.
//
// Fit: only the forward spline (GDAL's transformer also solves the reverse
// one), by the null-space method: with P = [1 x y] = Q R, the coefficients
// are c = Q2 w with (Q2' K Q2) w = Q2' v, a positive definite system (phi is
// conditionally positive definite of order 2), solved by Cholesky in
// n^3 / 3 operations instead of the general solve's 2 n^3 / 3 (blocked,
// its panels and trailing updates in parallel).
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

namespace gissar::geo {

class ThinPlateSpline {
 public:
  // The spline through `nodes` (any planar coordinates, e.g. pixel/line)
  // with two values each (e.g. longitude/latitude). nullopt when there are
  // fewer than 3 nodes, the nodes lie on one line or coincide, or the
  // system is too ill-conditioned to interpolate its nodes to about 1e-9 of
  // the values' spread (GDAL's general solver, with its own special cases,
  // is then the fallback). CHECKs nodes.size() == values.size().
  static std::optional<ThinPlateSpline> Fit(const std::vector<Eigen::Vector2d>& nodes,
                                            const std::vector<Eigen::Vector2d>& values);

  // The spline's two values at `point` (non-finite point: NaN).
  Eigen::Vector2d operator()(const Eigen::Vector2d& point) const;
  // The same at every point, in parallel; out[i] is the value at points[i].
  std::vector<Eigen::Vector2d> Evaluate(const std::vector<Eigen::Vector2d>& points) const;

  int node_count() const { return n_; }

 private:
  friend class IncrementalThinPlateSpline;
  ThinPlateSpline() = default;
  // Sets the nodes (fit coordinates, n x 2) and their kernel coefficients.
  void AssignNodes(const Eigen::MatrixX2d& nodes, const Eigen::MatrixX2d& coefficients);
  // Nodes in the fit's coordinates: (p - centre_) * inv_scale_.
  Eigen::Vector2d centre_ = Eigen::Vector2d::Zero();
  double inv_scale_ = 1.0;
  int n_ = 0;
  std::vector<double> x_, y_;      // scaled node coordinates, padded to a multiple of 8
  std::vector<double> c0_, c1_;    // kernel coefficients of the two values
  Eigen::Matrix<double, 3, 2> affine_ = Eigen::Matrix<double, 3, 2>::Zero();  // a0, a1, a2 per value (scaled p)
  Eigen::Vector2d offset_ = Eigen::Vector2d::Zero();  // mean value, added back
};

// The spline through a node set that grows (GCPs added in rounds), each
// round's fit extending the last one's factorisation instead of starting
// again: about 2 m^2 k operations for k nodes added to m instead of
// (m + k)^3 / 3.
//
// The null space of P' is spanned here by z_i = e_i - sum_a lambda_ia e_a for
// every node i but three anchors a (lambda_i: node i's barycentric
// coordinates in the anchors' triangle, so that P' z_i = 0). Unlike an
// orthonormal basis it stays a basis when nodes are appended, so M = Z' K Z
// only gains rows and columns and its Cholesky factor only gains a block
// row. The anchors are three far-apart nodes of the first batch (the
// farthest from the batch's centre, the farthest from that one, and the one
// spanning the largest triangle with both): the barycentric coordinates of
// later nodes in the same domain stay bounded, and M about as well
// conditioned as with an orthonormal basis. The spline is the interpolant
// ThinPlateSpline::Fit computes (it is unique), equal to it up to rounding.
class IncrementalThinPlateSpline {
 public:
  // Appends nodes with their values (CHECKs equal sizes). False, leaving
  // the spline as it was, when a node or value is not finite, when the
  // first batch has fewer than 3 nodes or they lie on one line, or when the
  // extended system is not positive definite (e.g. a repeated node).
  bool Add(const std::vector<Eigen::Vector2d>& nodes, const std::vector<Eigen::Vector2d>& values);
  // The spline through every node added so far; nullopt before a
  // successful Add, or when it does not interpolate its nodes to 1e-8 of
  // the values' spread (ThinPlateSpline::Fit's test: then use Fit or GDAL's
  // transformer).
  std::optional<ThinPlateSpline> Spline() const;
  int node_count() const { return static_cast<int>(px_.size()); }

 private:
  // Fit coordinates of every node, the three anchors first, and values
  // minus offset_.
  std::vector<double> px_, py_;
  std::vector<Eigen::Vector2d> values_;
  Eigen::Vector2d centre_ = Eigen::Vector2d::Zero(), offset_ = Eigen::Vector2d::Zero();
  double inv_scale_ = 1.0;
  // lambda = to_barycentric_ * (1, x, y); the kernel among the anchors.
  Eigen::Matrix3d to_barycentric_ = Eigen::Matrix3d::Zero(), anchor_kernel_ = Eigen::Matrix3d::Zero();
  // Per basis node i (node 3 + i): barycentric coordinates, kernel to the
  // anchors.
  std::vector<Eigen::Vector3d> lambda_, anchor_phi_;
  int m_ = 0;               // basis size: node_count() - 3
  Eigen::MatrixXd factor_;  // lower Cholesky factor of M in the top-left m_ x m_ (spare capacity beyond)
  Eigen::MatrixX2d rhs_;    // Z' v, m_ rows used
};

}  // namespace gissar::geo
