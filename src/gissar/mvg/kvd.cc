#include "gissar/mvg/kvd.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <string>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "gissar/mvg/affine_fundamental.h"
#include "gissar/util/error.h"

namespace gissar::mvg {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kRadToDeg = 180.0 / M_PI;

// Into (-180, 180].
double Wrap180(double deg) {
  double w = std::fmod(deg, 360.0);
  if (w <= -180.0) w += 360.0;
  if (w > 180.0) w -= 360.0;
  return w;
}

// Into (-90, 90] (an axis direction, defined modulo 180).
double Wrap90(double deg) {
  double w = std::fmod(deg, 180.0);
  if (w <= -90.0) w += 180.0;
  if (w > 90.0) w -= 180.0;
  return w;
}

std::string Num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

void CheckAngle(double deg, const char* what) {
  if (!std::isfinite(deg)) throw InputError("angle must be finite, got " + Num(deg), what);
}

void CheckDepression(double deg, const char* what) {
  if (!std::isfinite(deg) || deg <= 0.0 || deg >= 90.0) {
    throw InputError("depression must be in (0, 90) degrees, got " + Num(deg), what);
  }
}

// theta(dpsi) - theta_target, wrapped to (-180, 180].
double ThetaMismatch(double dpsi, double theta_deg, double dep1, double dep2, LookSide look1,
                     LookSide look2) {
  return Wrap180(SarKvd(dpsi, dep1, dep2, look1, look2).theta_deg - theta_deg);
}

// Rotation about the unit axis [cos phi, sin phi, 0] by rho (radians).
Eigen::Matrix3d AxisRotation(double phi_rad, double rho_rad) {
  const Eigen::Vector3d axis(std::cos(phi_rad), std::sin(phi_rad), 0.0);
  return Eigen::AngleAxisd(rho_rad, axis).toRotationMatrix();
}

// Three-view consistency: with R1 = I, R12 = R_rho(phi12, rho12) Rz(theta12)
// and R13 likewise, R23 = R13 R12' must be a rotation about u23 after
// removing its cyclorotation theta23.
struct ThreeViewProblem {
  double theta12, phi12, theta13, phi13, theta23, phi23;  // radians
  Eigen::Matrix3d rz12, rz13, rz23_inv;
  Eigen::Vector3d u23;

  ThreeViewProblem(const KvdParameters& k12, const KvdParameters& k13, const KvdParameters& k23)
      : theta12(k12.theta_deg * kDegToRad),
        phi12(k12.phi_deg * kDegToRad),
        theta13(k13.theta_deg * kDegToRad),
        phi13(k13.phi_deg * kDegToRad),
        theta23(k23.theta_deg * kDegToRad),
        phi23(k23.phi_deg * kDegToRad) {
    rz12 = Eigen::AngleAxisd(theta12, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    rz13 = Eigen::AngleAxisd(theta13, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    rz23_inv = Eigen::AngleAxisd(-theta23, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    u23 = Eigen::Vector3d(std::cos(phi23), std::sin(phi23), 0.0);
  }

  Eigen::Matrix3d R12(double rho12) const { return AxisRotation(phi12, rho12) * rz12; }
  Eigen::Matrix3d R13(double rho13) const { return AxisRotation(phi13, rho13) * rz13; }

  Eigen::Vector3d Residual(const Eigen::Matrix3d& r12, const Eigen::Matrix3d& r13) const {
    const Eigen::Matrix3d q = r13 * r12.transpose() * rz23_inv;
    return q * u23 - u23;
  }
  Eigen::Vector3d Residual(double rho12, double rho13) const {
    return Residual(R12(rho12), R13(rho13));
  }
  Eigen::Matrix<double, 3, 2> Jacobian(double rho12, double rho13) const {
    constexpr double kStep = 1e-6;
    Eigen::Matrix<double, 3, 2> j;
    j.col(0) = (Residual(rho12 + kStep, rho13) - Residual(rho12 - kStep, rho13)) / (2 * kStep);
    j.col(1) = (Residual(rho12, rho13 + kStep) - Residual(rho12, rho13 - kStep)) / (2 * kStep);
    return j;
  }
  // rho23 relative to phi23: the angle of Q = R23 Rz(-theta23) about u23.
  double Rho23(double rho12, double rho13) const {
    const Eigen::Matrix3d q = R13(rho13) * R12(rho12).transpose() * rz23_inv;
    const Eigen::Vector3d qz = q.col(2);
    const Eigen::Vector3d side = u23.cross(Eigen::Vector3d::UnitZ());
    return std::atan2(qz.dot(side), qz.z());
  }
};

}  // namespace

KvdParameters KvdFromFundamental(const Eigen::Matrix3d& f) {
  CheckAffineFundamental(f, "F");
  const double a = f(0, 2), b = f(1, 2), c = f(2, 0), d = f(2, 1);
  const double ab = std::hypot(a, b);
  const double cd = std::hypot(c, d);
  if (ab == 0.0 || cd == 0.0) {
    throw InputError("F has a zero (a, b) or (c, d) part: no KvD decomposition", "F");
  }
  KvdParameters k;
  k.s = cd / ab;
  const double alpha = std::atan2(b, a) * kRadToDeg;
  const double beta = std::atan2(d, c) * kRadToDeg;
  k.phi_deg = Wrap90(alpha);
  k.theta_deg = Wrap180(alpha - beta + 180.0);
  k.rho_recoverable = false;
  return k;
}

KvdRotation KvdFromRotation(const Eigen::Matrix3d& r_rel) {
  if (!r_rel.allFinite()) throw InputError("rotation matrix has a non-finite entry", "R_rel");
  if ((r_rel * r_rel.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
      std::abs(r_rel.determinant() - 1.0) > 1e-9) {
    throw InputError("not a rotation matrix", "R_rel");
  }
  double rho = std::acos(std::clamp(r_rel(2, 2), -1.0, 1.0));
  double phi = std::atan2(r_rel(0, 2), -r_rel(1, 2));
  if (phi > M_PI / 2) {
    phi -= M_PI;
    rho = -rho;
  } else if (phi <= -M_PI / 2) {
    phi += M_PI;
    rho = -rho;
  }
  const Eigen::Matrix3d rz = AxisRotation(phi, rho).transpose() * r_rel;
  KvdRotation out;
  out.theta_deg = Wrap180(std::atan2(rz(1, 0), rz(0, 0)) * kRadToDeg);
  out.phi_deg = phi * kRadToDeg;
  out.rho_deg = rho * kRadToDeg;
  return out;
}

Eigen::Matrix3d RotationFromKvd(double theta_deg, double phi_deg, double rho_deg) {
  return AxisRotation(phi_deg * kDegToRad, rho_deg * kDegToRad) *
         Eigen::AngleAxisd(theta_deg * kDegToRad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

KvdRotation SarKvd(double heading_change_deg, double depression1_deg, double depression2_deg,
                   LookSide look1, LookSide look2) {
  CheckAngle(heading_change_deg, "heading change");
  CheckDepression(depression1_deg, "depression 1");
  CheckDepression(depression2_deg, "depression 2");
  const Eigen::Matrix3d r1 = SarRotation(0.0, depression1_deg, look1);
  const Eigen::Matrix3d r2 = SarRotation(heading_change_deg, depression2_deg, look2);
  return KvdFromRotation(r2 * r1.transpose());
}

double HeadingChangeEqualDepressionDeg(double theta_deg, double depression_deg) {
  CheckAngle(theta_deg, "theta");
  CheckDepression(depression_deg, "depression");
  const double half = 0.5 * theta_deg * kDegToRad;
  return Wrap180(2.0 *
                 std::atan2(std::sin(half), std::cos(half) * std::cos(depression_deg * kDegToRad)) *
                 kRadToDeg);
}

double RhoMagnitudeEqualDepressionDeg(double heading_change_deg, double depression_deg) {
  CheckAngle(heading_change_deg, "heading change");
  CheckDepression(depression_deg, "depression");
  const double s = std::sin(depression_deg * kDegToRad);
  const double c = std::cos(depression_deg * kDegToRad);
  const double v = s * s * std::cos(heading_change_deg * kDegToRad) + c * c;
  return std::acos(std::clamp(v, -1.0, 1.0)) * kRadToDeg;
}

double RhoMagnitudeDeg(double heading_change_deg, double depression1_deg, double depression2_deg,
                       LookSide look1, LookSide look2) {
  CheckAngle(heading_change_deg, "heading change");
  CheckDepression(depression1_deg, "depression 1");
  CheckDepression(depression2_deg, "depression 2");
  const Eigen::Vector3d n1 = SarRotation(0.0, depression1_deg, look1).row(2);
  const Eigen::Vector3d n2 = SarRotation(heading_change_deg, depression2_deg, look2).row(2);
  return std::acos(std::clamp(n1.dot(n2), -1.0, 1.0)) * kRadToDeg;
}

std::vector<double> HeadingChangeCandidatesDeg(double theta_deg, double depression1_deg,
                                               double depression2_deg, LookSide look1,
                                               LookSide look2) {
  CheckAngle(theta_deg, "theta");
  CheckDepression(depression1_deg, "depression 1");
  CheckDepression(depression2_deg, "depression 2");
  constexpr double kStep = 0.25;
  constexpr int kSteps = 1440;  // 360 / kStep
  std::vector<double> roots;
  auto g = [&](double dpsi) {
    return ThetaMismatch(dpsi, theta_deg, depression1_deg, depression2_deg, look1, look2);
  };
  double x0 = -180.0;
  double g0 = g(x0);
  for (int i = 1; i <= kSteps; ++i) {
    const double x1 = -180.0 + i * kStep;
    const double g1 = g(x1);
    // A sign change away from the +-180 wrap of the mismatch brackets a root.
    if (g0 == 0.0) {
      roots.push_back(x0);
    } else if ((g0 < 0.0) != (g1 < 0.0) && g1 != 0.0 && std::abs(g0) < 90.0 &&
               std::abs(g1) < 90.0) {
      double lo = x0, hi = x1, glo = g0;
      for (int it = 0; it < 200 && hi - lo > 1e-12; ++it) {
        const double mid = 0.5 * (lo + hi);
        const double gm = g(mid);
        if (gm == 0.0) {
          lo = hi = mid;
          break;
        }
        if ((gm < 0.0) == (glo < 0.0)) {
          lo = mid;
          glo = gm;
        } else {
          hi = mid;
        }
      }
      roots.push_back(0.5 * (lo + hi));
    }
    x0 = x1;
    g0 = g1;
  }
  for (double& r : roots) r = Wrap180(r);
  std::sort(roots.begin(), roots.end(), [](double a, double b) {
    return std::abs(a) < std::abs(b) || (std::abs(a) == std::abs(b) && a > b);
  });
  roots.erase(std::unique(roots.begin(), roots.end(),
                          [](double a, double b) { return std::abs(Wrap180(a - b)) < 1e-9; }),
              roots.end());
  return roots;
}

std::optional<SarRelativePose> InterpretKvdForSar(const KvdParameters& kvd, double depression1_deg,
                                                  double depression2_deg, LookSide look1,
                                                  LookSide look2) {
  CheckAngle(kvd.phi_deg, "phi");
  const std::vector<double> candidates =
      HeadingChangeCandidatesDeg(kvd.theta_deg, depression1_deg, depression2_deg, look1, look2);
  if (candidates.empty()) return std::nullopt;
  SarRelativePose out;
  out.heading_change_deg = candidates.front();
  out.candidates = static_cast<int>(candidates.size());
  out.rho_abs_deg =
      RhoMagnitudeDeg(out.heading_change_deg, depression1_deg, depression2_deg, look1, look2);
  out.phi_model_deg =
      SarKvd(out.heading_change_deg, depression1_deg, depression2_deg, look1, look2).phi_deg;
  out.phi_residual_deg = Wrap90(kvd.phi_deg - out.phi_model_deg);
  return out;
}

std::vector<ThreeViewRho> RecoverRhoFromThreeViews(const KvdParameters& k12,
                                                   const KvdParameters& k13,
                                                   const KvdParameters& k23, double tolerance) {
  for (const KvdParameters* k : {&k12, &k13, &k23}) {
    CheckAngle(k->theta_deg, "theta");
    CheckAngle(k->phi_deg, "phi");
  }
  if (!std::isfinite(tolerance) || tolerance <= 0.0) {
    throw InputError("tolerance must be positive", "tolerance");
  }
  const ThreeViewProblem problem(k12, k13, k23);

  // Scan the torus (rho12, rho13) in 2-degree steps.
  constexpr int kGrid = 180;
  constexpr double kGridStep = 2.0 * M_PI / kGrid;
  std::vector<Eigen::Matrix3d> r12(kGrid), r13(kGrid);
  for (int i = 0; i < kGrid; ++i) {
    const double rho = -M_PI + i * kGridStep;
    r12[i] = problem.R12(rho);
    r13[i] = problem.R13(rho);
  }
  std::vector<double> cost(kGrid * kGrid);
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      cost[i * kGrid + j] = problem.Residual(r12[i], r13[j]).squaredNorm();
    }
  }
  auto at = [&](int i, int j) { return cost[((i + kGrid) % kGrid) * kGrid + (j + kGrid) % kGrid]; };

  std::vector<ThreeViewRho> solutions;
  bool degenerate = false;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      const double c = at(i, j);
      bool minimum = true;
      for (int di = -1; di <= 1 && minimum; ++di) {
        for (int dj = -1; dj <= 1 && minimum; ++dj) {
          if (di == 0 && dj == 0) continue;
          const double other = at(i + di, j + dj);
          // Ties broken by index so that a flat valley yields one seed.
          if (other < c || (other == c && (di < 0 || (di == 0 && dj < 0)))) minimum = false;
        }
      }
      if (!minimum) continue;
      // Gauss-Newton from the grid minimum.
      Eigen::Vector2d x(-M_PI + i * kGridStep, -M_PI + j * kGridStep);
      Eigen::Vector3d res = problem.Residual(x(0), x(1));
      for (int it = 0; it < 100 && res.norm() > 0.1 * tolerance; ++it) {
        const Eigen::Matrix<double, 3, 2> jac = problem.Jacobian(x(0), x(1));
        const Eigen::Vector2d step =
            jac.jacobiSvd(Eigen::ComputeFullU | Eigen::ComputeFullV).solve(-res);
        // Halve the step until the residual decreases.
        double t = 1.0;
        Eigen::Vector3d trial = problem.Residual(x(0) + step(0), x(1) + step(1));
        while (trial.norm() >= res.norm() && t > 1e-6) {
          t *= 0.5;
          trial = problem.Residual(x(0) + t * step(0), x(1) + t * step(1));
        }
        if (trial.norm() >= res.norm()) break;
        x += t * step;
        res = trial;
      }
      if (res.norm() > tolerance) continue;
      const Eigen::Matrix<double, 3, 2> jac = problem.Jacobian(x(0), x(1));
      const Eigen::Vector2d sv = jac.jacobiSvd().singularValues();
      if (!(sv(1) > 1e-6 * sv(0))) {
        degenerate = true;  // a continuum of solutions
        continue;
      }
      ThreeViewRho s;
      s.rho12_deg = Wrap180(x(0) * kRadToDeg);
      s.rho13_deg = Wrap180(x(1) * kRadToDeg);
      s.rho23_deg = Wrap180(problem.Rho23(x(0), x(1)) * kRadToDeg);
      s.residual = res.norm();
      bool duplicate = false;
      for (const ThreeViewRho& o : solutions) {
        duplicate = duplicate || (std::abs(Wrap180(o.rho12_deg - s.rho12_deg)) < 1e-6 &&
                                  std::abs(Wrap180(o.rho13_deg - s.rho13_deg)) < 1e-6);
      }
      if (!duplicate) solutions.push_back(s);
    }
  }
  if (degenerate) return {};
  // Complete the Necker pairs (the reversal of a solution is a solution).
  const size_t found = solutions.size();
  for (size_t k = 0; k < found; ++k) {
    ThreeViewRho r = solutions[k];
    r.rho12_deg = Wrap180(-r.rho12_deg);
    r.rho13_deg = Wrap180(-r.rho13_deg);
    bool present = false;
    for (const ThreeViewRho& o : solutions) {
      present = present || (std::abs(Wrap180(o.rho12_deg - r.rho12_deg)) < 1e-6 &&
                            std::abs(Wrap180(o.rho13_deg - r.rho13_deg)) < 1e-6);
    }
    if (present) continue;
    const Eigen::Vector3d res = problem.Residual(r.rho12_deg * kDegToRad, r.rho13_deg * kDegToRad);
    if (res.norm() > tolerance) continue;
    r.rho23_deg =
        Wrap180(problem.Rho23(r.rho12_deg * kDegToRad, r.rho13_deg * kDegToRad) * kRadToDeg);
    r.residual = res.norm();
    solutions.push_back(r);
  }
  // Sort so that each pair is adjacent: by |rho12| (then |rho13|), the
  // positive rho12 first.
  std::sort(solutions.begin(), solutions.end(), [](const ThreeViewRho& a, const ThreeViewRho& b) {
    const double ka = std::abs(a.rho12_deg), kb = std::abs(b.rho12_deg);
    if (std::abs(ka - kb) > 1e-9) return ka > kb;
    const double ja = std::abs(a.rho13_deg), jb = std::abs(b.rho13_deg);
    if (std::abs(ja - jb) > 1e-9) return ja > jb;
    return a.rho12_deg > b.rho12_deg;
  });
  return solutions;
}

}  // namespace gissar::mvg
