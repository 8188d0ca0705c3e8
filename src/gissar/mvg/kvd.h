// Koenderink-van Doorn (KvD) decomposition of the relative pose of two
// affine views, and its reading for SAR (heading change from the
// cyclorotation theta and the two depression angles).
//
// The relative rotation of views 1 -> 2 is R_rel = R2 R1' (R = [l; h; n] of
// each view, affine_camera.h), decomposed as R_rel = R_rho(phi) Rz(theta):
// a rotation theta about the viewing direction (cyclorotation), then a
// rotation rho (turn out of the image plane) about the axis
// [cos phi, sin phi, 0], plus an image scale s. From an affine F =
// [0 0 a; 0 0 b; c d e] (calibrated, K2' F K1, for metric meaning):
//   s = sqrt((c² + d²) / (a² + b²)),
//   phi = atan2(b, a) wrapped to (-90, 90],
//   theta = wrap180(atan2(b, a) - atan2(d, c) + 180).
// rho is NOT recoverable from two views: (a, b, c, d) do not depend on it
// (the bas-relief ambiguity). With known SAR depressions |rho| follows from
// the camera model; a third view fixes rho up to the Necker reversal (a
// common sign flip of all rho).
//
// Angles are in degrees. Failures: a matrix that is not an affine F (or not a
// rotation), or a non-finite or out-of-range angle, throws gissar::InputError;
// a configuration without an answer gives std::nullopt or an empty vector.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/mvg/affine_camera.h"

namespace gissar::mvg {

struct KvdParameters {
  double s = 1.0;          // scale of image 2 relative to image 1 (1 for calibrated SAR views)
  double theta_deg = 0.0;  // cyclorotation, (-180, 180]
  double phi_deg = 0.0;    // direction of the rho axis in the image, (-90, 90]
  // Always false: the two-view F does not depend on rho.
  bool rho_recoverable = false;
};

// KvD parameters of an affine F by the formulas above (pass K2' F K1 for
// metric values; theta and phi are the same for pixel F when the pixels are
// square). Throws InputError when `f` is not an affine F or its (a, b) or
// (c, d) part is zero.
KvdParameters KvdFromFundamental(const Eigen::Matrix3d& f);

// Full decomposition of a known relative rotation (ground truth):
// rho = acos(R33) with sign flipped together with phi when
// phi = atan2(R13, -R23) is wrapped to (-90, 90]; theta = angle of
// R_rho(phi)' R_rel about z. Throws InputError unless `r_rel` is a finite
// rotation matrix (orthonormal to 1e-9, determinant +1).
struct KvdRotation {
  double theta_deg = 0.0;  // (-180, 180]
  double phi_deg = 0.0;    // (-90, 90]
  double rho_deg = 0.0;    // [-180, 180]
};
KvdRotation KvdFromRotation(const Eigen::Matrix3d& r_rel);

// R_rho(phi) Rz(theta) with R_rho the rotation by rho about
// [cos phi, sin phi, 0] (no validation; angles in degrees).
Eigen::Matrix3d RotationFromKvd(double theta_deg, double phi_deg, double rho_deg);

// The KvD rotation of two SAR views that differ in heading by
// `heading_change_deg` (view 2 minus view 1, clockwise positive) with
// depressions `depression1_deg`, `depression2_deg`: R2 R1' with R from
// SarRotation. Throws InputError for a non-finite angle or a depression
// outside (0, 90).
KvdRotation SarKvd(double heading_change_deg, double depression1_deg, double depression2_deg,
                   LookSide look1 = LookSide::kRight, LookSide look2 = LookSide::kRight);

// Closed form for equal depressions delta: tan(theta/2) = cos(delta)
// tan(dpsi/2), so dpsi = 2 atan(tan(theta/2) / cos(delta)), in (-180, 180].
// Throws as SarKvd.
double HeadingChangeEqualDepressionDeg(double theta_deg, double depression_deg);

// Closed form for equal depressions: |rho| = acos(sin²(delta) cos(dpsi) +
// cos²(delta)). Throws as SarKvd.
double RhoMagnitudeEqualDepressionDeg(double heading_change_deg, double depression_deg);

// |rho| = acos(n1 . n2) of two SAR views from the camera model (any
// depressions; equals the closed form above when they are equal).
double RhoMagnitudeDeg(double heading_change_deg, double depression1_deg, double depression2_deg,
                       LookSide look1 = LookSide::kRight, LookSide look2 = LookSide::kRight);

// Every heading change dpsi in (-180, 180] whose SAR KvD theta (SarKvd)
// equals `theta_deg`, sorted by |dpsi|: the 1-D root finding of
// theta(dpsi) - theta_deg (scan in 0.25 degree steps, then bisection to
// 1e-12 degrees). For equal depressions there is exactly one (the closed
// form). Throws as SarKvd.
std::vector<double> HeadingChangeCandidatesDeg(double theta_deg, double depression1_deg,
                                               double depression2_deg,
                                               LookSide look1 = LookSide::kRight,
                                               LookSide look2 = LookSide::kRight);

// The SAR reading of a two-view KvD decomposition.
struct SarRelativePose {
  double heading_change_deg = 0.0;  // view 2 minus view 1, clockwise positive
  double rho_abs_deg = 0.0;         // |rho| from the camera model, not from F
  double phi_model_deg = 0.0;       // phi the model predicts at that heading change
  // phi measured minus phi_model_deg, wrapped to (-90, 90]: a consistency
  // check of the depressions (0 without noise).
  double phi_residual_deg = 0.0;
  int candidates = 0;  // number of heading changes consistent with theta
};

// Heading change (the candidate of smallest |dpsi| when theta allows more
// than one; `candidates` says how many) and |rho| of a measured KvD
// decomposition (from a calibrated F) for known depressions and look sides.
// std::nullopt when no heading change reproduces theta. Throws as SarKvd.
std::optional<SarRelativePose> InterpretKvdForSar(const KvdParameters& kvd, double depression1_deg,
                                                  double depression2_deg,
                                                  LookSide look1 = LookSide::kRight,
                                                  LookSide look2 = LookSide::kRight);

// rho of each pair of three views, relative to that pair's (wrapped) phi:
// R_ij = R_j R_i' = R_rho(phi_ij, rho_ij) Rz(theta_ij).
struct ThreeViewRho {
  double rho12_deg = 0.0;
  double rho13_deg = 0.0;
  double rho23_deg = 0.0;
  // Norm of the consistency residual R23 Rz(-theta23) u23 - u23 (unitless,
  // 0 for an exact solution), u23 = [cos phi23, sin phi23, 0].
  double residual = 0.0;
};

// rho from three views: `k12`, `k13`, `k23` are the KvD parameters of the
// calibrated F of the pairs (1, 2), (1, 3), (2, 3), each F_ij taking image i
// as its "image 1" ([x_j] F_ij [x_i] = 0). Solves R13 = R23 R12 for
// (rho12, rho13) (two equations in two unknowns: a scan of the torus in
// 2-degree steps, then Gauss-Newton to a residual below `tolerance`).
// Solutions come in Necker pairs (rho -> -rho for all three); all are
// returned, sorted by decreasing |rho12| (then |rho13|), the positive rho12
// first, so each pair is adjacent. Empty when no solution exists
// (inconsistent input) or a solution is not isolated (a one-parameter
// family: the views are degenerate for this purpose, as when all viewing
// directions n_i lie in one plane, e.g. equal headings). Throws InputError
// for a non-finite angle or a tolerance <= 0.
std::vector<ThreeViewRho> RecoverRhoFromThreeViews(const KvdParameters& k12,
                                                   const KvdParameters& k13,
                                                   const KvdParameters& k23,
                                                   double tolerance = 1e-9);

}  // namespace gissar::mvg
