#include "gissar/material/scattering.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "gissar/util/error.h"

namespace gissar::material {
namespace {

using cd = std::complex<double>;
constexpr double kDeg = M_PI / 180.0;

double Db20(double amplitude) { return 20.0 * std::log10(amplitude); }
double PhaseDeg(cd z) { return std::arg(z) / kDeg; }

// A line of sight looking down at `depression_deg` towards compass bearing
// `azimuth_deg` (ENU: x east, y north, z up).
Eigen::Vector3d LineOfSight(double azimuth_deg, double depression_deg) {
  const double az = azimuth_deg * kDeg, de = depression_deg * kDeg;
  return {std::sin(az) * std::cos(de), std::cos(az) * std::cos(de), -std::sin(de)};
}

// Right-handed rotation by `angle_rad` about the unit `axis`.
Eigen::Vector3d Turn(const Eigen::Vector3d& x, const Eigen::Vector3d& axis, double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, axis.normalized()) * x;
}

// A face of a reflector: a plane (point, normal) and its material.
struct Face {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
  bool conductor = true;
  cd permittivity{1.0, 0.0};
};

// The mirror path of a plane wave along `los` entering at `entry` (on
// faces[0]) and meeting the faces' planes in the given order: each next
// point is the intersection of the mirror ray with the next plane.
std::vector<Bounce> MirrorPath(const Eigen::Vector3d& los, const Eigen::Vector3d& entry,
                               const std::vector<Face>& faces) {
  std::vector<Bounce> path;
  Eigen::Vector3d p = entry, d = los.normalized();
  for (size_t i = 0; i < faces.size(); ++i) {
    const Eigen::Vector3d n = faces[i].normal.normalized();
    if (i > 0) p += (faces[i].point - p).dot(n) / d.dot(n) * d;
    path.push_back(faces[i].conductor ? Bounce::Conductor(p, n) : Bounce::Dielectric(p, n, faces[i].permittivity));
    d -= 2.0 * d.dot(n) * n;
  }
  return path;
}

// Compares every channel of `got` with `want` after removing their common
// phase (the phase of the Frobenius product <want, got>): within `db_tol` in
// magnitude and `deg_tol` in phase where |want| > 1e-6 of its norm, below
// 1e-9 of the norm elsewhere. Returns the common phase (deg).
double ExpectChannelsMatch(const ScatteringMatrix& got, const ScatteringMatrix& want, double db_tol, double deg_tol) {
  const cd inner = (want.conjugate().cwiseProduct(got)).sum();
  const double common = std::arg(inner);
  const ScatteringMatrix aligned = got * std::polar(1.0, -common);
  const double norm = want.norm();
  for (int t = 0; t < 2; ++t) {
    for (int r = 0; r < 2; ++r) {
      const cd g = aligned(t, r), w = want(t, r);
      if (std::abs(w) > 1e-6 * norm) {
        EXPECT_NEAR(Db20(std::abs(g) / std::abs(w)), 0.0, db_tol) << "channel (" << t << ", " << r << ")";
        EXPECT_NEAR(PhaseDeg(g / w), 0.0, deg_tol) << "channel (" << t << ", " << r << ")";
      } else {
        EXPECT_LT(std::abs(g), 1e-9 * norm) << "channel (" << t << ", " << r << ")";
      }
    }
  }
  return common / kDeg;
}

// The dihedral of the tests: fold through `apex`, turned by psi about the
// line of sight from h towards v, faces at +-45 deg to the line of sight
// (normals (-l +- v') / sqrt 2, v' the turned v): face 0 below the fold
// (seen from the radar), face 1 above it.
std::vector<Face> DihedralFaces(const Eigen::Vector3d& los, const Eigen::Vector3d& apex, double psi_rad) {
  const PolarizationBasis b = HvBasis(los);
  const Eigen::Vector3d v_turned = -std::sin(psi_rad) * b.h + std::cos(psi_rad) * b.v;
  return {{apex, (-los + v_turned) / std::sqrt(2.0)}, {apex, (-los - v_turned) / std::sqrt(2.0)}};
}

// ---------------------------------------------------------------- basis

// Looking north at 30 deg depression: l = (0, cos 30, -sin 30),
// h = z x l / |z x l| = (-1, 0, 0) (west: left as seen from the radar),
// v = l x h = (0, sin 30, cos 30) (up, tilted forward).
TEST(ScatteringTest, HvBasisFollowsUpCrossLineOfSight) {
  const Eigen::Vector3d l = LineOfSight(0.0, 30.0);
  const PolarizationBasis b = HvBasis(l);
  EXPECT_NEAR((b.h - Eigen::Vector3d(-1, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((b.v - Eigen::Vector3d(0, 0.5, std::sqrt(3.0) / 2)).norm(), 0.0, 1e-15);
  // Right-handed (h, v, l), h horizontal, unit vectors, at a generic look.
  const Eigen::Vector3d l2 = LineOfSight(123.0, 41.0) * 7.0;  // any length
  const PolarizationBasis b2 = HvBasis(l2);
  EXPECT_NEAR(b2.h.z(), 0.0, 1e-15);
  EXPECT_NEAR(b2.h.norm(), 1.0, 1e-15);
  EXPECT_NEAR(b2.v.norm(), 1.0, 1e-15);
  EXPECT_NEAR((b2.h.cross(b2.v) - l2.normalized()).norm(), 0.0, 1e-15);
  EXPECT_GT(b2.v.z(), 0.0);
}

// Vertical line of sight: up is replaced by east. Nadir (l = -z):
// h = x x (-z) = +y (north), v = (-z) x y = +x (east); the limit of a radar
// looking east as its depression tends to 90 deg.
TEST(ScatteringTest, HvBasisFallbackForVerticalLineOfSight) {
  const PolarizationBasis nadir = HvBasis(Eigen::Vector3d(0, 0, -1));
  EXPECT_NEAR((nadir.h - Eigen::Vector3d(0, 1, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((nadir.v - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-15);
  const PolarizationBasis near = HvBasis(LineOfSight(90.0, 90.0 - 1e-4));
  EXPECT_NEAR((near.h - nadir.h).norm(), 0.0, 1e-5);
  EXPECT_NEAR((near.v - nadir.v).norm(), 0.0, 1e-5);
  const PolarizationBasis zenith = HvBasis(Eigen::Vector3d(0, 0, 2));
  EXPECT_NEAR((zenith.h.cross(zenith.v) - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-15);
  EXPECT_THROW(HvBasis(Eigen::Vector3d::Zero()), InputError);
  EXPECT_THROW(HvBasis(Eigen::Vector3d(NAN, 0, 1)), InputError);
}

// ---------------------------------------------------------------- matrices

TEST(ScatteringTest, ChannelsFollowTransmitThenReceive) {
  const ScatteringMatrix s = MakeScatteringMatrix(1.0, 2.0, 3.0, 4.0);
  EXPECT_EQ(Channel(s, Polarization::kHH), cd(1.0));
  EXPECT_EQ(Channel(s, Polarization::kHV), cd(2.0));  // row = transmit H, column = receive V
  EXPECT_EQ(s(0, 1), cd(2.0));
  EXPECT_EQ(Channel(s, Polarization::kVH), cd(3.0));
  EXPECT_EQ(Channel(s, Polarization::kVV), cd(4.0));
  EXPECT_NEAR(ChannelRcs(s, Polarization::kVV), 4 * M_PI * 16, 1e-12);
}

// Rotation by psi turns (1, 0) = h into (cos psi, sin psi), towards v, and
// turns the 0 deg dihedral into the closed form of DihedralMatrix(psi).
TEST(ScatteringTest, RotationSenseAndDihedralClosedForm) {
  const Eigen::Vector2d turned = Rotation(30 * kDeg) * Eigen::Vector2d(1, 0);
  EXPECT_NEAR(turned.x(), std::cos(30 * kDeg), 1e-15);
  EXPECT_NEAR(turned.y(), std::sin(30 * kDeg), 1e-15);
  for (double psi_deg : {0.0, 10.0, 22.5, 45.0, 70.0, -30.0}) {
    const double psi = psi_deg * kDeg;
    const ScatteringMatrix s = Rotate(DihedralMatrix(0.0), psi);
    EXPECT_NEAR((s - DihedralMatrix(psi)).norm(), 0.0, 1e-15) << psi_deg;
    EXPECT_NEAR(s(0, 0).real(), std::cos(2 * psi), 1e-15);
    EXPECT_NEAR(s(0, 1).real(), std::sin(2 * psi), 1e-15);
    EXPECT_NEAR(s(1, 0).real(), std::sin(2 * psi), 1e-15);
    EXPECT_NEAR(s(1, 1).real(), -std::cos(2 * psi), 1e-15);
    // Roll does nothing to a trihedral or a plate.
    EXPECT_NEAR((Rotate(TrihedralMatrix(), psi) - TrihedralMatrix()).norm(), 0.0, 1e-15);
    EXPECT_NEAR((Rotate(PlateMatrix(), psi) - PlateMatrix()).norm(), 0.0, 1e-15);
  }
}

// Trihedral k = (2, 0, 0)/sqrt 2, T3 = diag(2, 0, 0); dihedral 0 deg
// k = (0, 2, 0)/sqrt 2; dihedral 45 deg (S_HV = S_VH = 1) k = (0, 0, 2)/sqrt 2.
TEST(ScatteringTest, PauliVectorAndCoherencyOfCanonicalTargets) {
  const struct {
    ScatteringMatrix s;
    int component;
  } cases[] = {{TrihedralMatrix(), 0}, {PlateMatrix(), 0}, {DihedralMatrix(0.0), 1}, {DihedralMatrix(45 * kDeg), 2}};
  for (const auto& c : cases) {
    const Eigen::Vector3cd k = PauliVector(c.s);
    const Eigen::Matrix3cd t3 = Coherency3(c.s);
    EXPECT_NEAR(std::abs(k(c.component)), std::sqrt(2.0), 1e-15);
    EXPECT_NEAR(t3(c.component, c.component).real(), 2.0, 1e-15);
    EXPECT_NEAR(t3.norm(), 2.0, 1e-15);  // nothing outside that one element
    const Eigen::Matrix3cd c3 = Covariance3(c.s);
    EXPECT_NEAR(c3.trace().real(), t3.trace().real(), 1e-15);  // both the span
  }
  // C3 of the 45 deg dihedral: only (sqrt 2 S_HV)^2 = 2 in the middle.
  const Eigen::Matrix3cd c3 = Covariance3(DihedralMatrix(45 * kDeg));
  EXPECT_NEAR(c3(1, 1).real(), 2.0, 1e-15);
  EXPECT_NEAR(c3.norm(), 2.0, 1e-15);
  // Trihedral C3: HH = VV in phase, (1, 0, 1) (1, 0, 1)^H.
  const Eigen::Matrix3cd c3t = Covariance3(TrihedralMatrix());
  EXPECT_NEAR(c3t(0, 2).real(), 1.0, 1e-15);
}

// sigma = 4 pi |S|^2 in the canonical normalisation; a dihedral at 45 deg
// roll puts its whole RCS into HV (and VH).
TEST(ScatteringTest, ReflectorMatrixCarriesThePeakRcs) {
  const double a = 1.0, lambda = 0.0555;
  const double dihedral = 8 * M_PI * std::pow(a, 4) / (lambda * lambda);
  const ScatteringMatrix d0 = ReflectorMatrix(ReflectorType::kDihedral, a, lambda, 0.0);
  EXPECT_NEAR(ChannelRcs(d0, Polarization::kHH) / dihedral, 1.0, 1e-12);
  EXPECT_NEAR(ChannelRcs(d0, Polarization::kVV) / dihedral, 1.0, 1e-12);
  EXPECT_NEAR(std::abs(PhaseDeg(d0(0, 0) * std::conj(d0(1, 1)))), 180.0, 1e-9);
  const ScatteringMatrix d45 = ReflectorMatrix(ReflectorType::kDihedral, a, lambda, 45 * kDeg);
  EXPECT_NEAR(ChannelRcs(d45, Polarization::kHV) / dihedral, 1.0, 1e-12);
  EXPECT_NEAR(ChannelRcs(d45, Polarization::kVH) / dihedral, 1.0, 1e-12);
  EXPECT_LT(ChannelRcs(d45, Polarization::kHH) / dihedral, 1e-30);
  const ScatteringMatrix t = ReflectorMatrix(ReflectorType::kTrihedral, a, lambda, 20 * kDeg);
  EXPECT_NEAR(ChannelRcs(t, Polarization::kHH) / (4 * M_PI / (3 * lambda * lambda)), 1.0, 1e-12);
  EXPECT_NEAR(PhaseDeg(t(0, 0) * std::conj(t(1, 1))), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(t(0, 1)), 0.0, 1e-12);
  const ScatteringMatrix sq = ReflectorMatrix(ReflectorType::kTrihedralSquare, a, lambda, 0.0);
  EXPECT_NEAR(ChannelRcs(sq, Polarization::kVV) / (12 * M_PI / (lambda * lambda)), 1.0, 1e-12);
  const ScatteringMatrix p = ReflectorMatrix(ReflectorType::kPlate, 0.5, lambda, 0.0);
  EXPECT_NEAR(ChannelRcs(p, Polarization::kHH) / (4 * M_PI * std::pow(0.5, 4) / (lambda * lambda)), 1.0, 1e-12);
  EXPECT_THROW(ReflectorMatrix(ReflectorType::kPlate, 0.0, lambda, 0.0), ConfigError);
  EXPECT_THROW(ReflectorMatrix(ReflectorType::kPlate, 1.0, -1.0, 0.0), ConfigError);
}

// ---------------------------------------------------------------- Fresnel

TEST(ScatteringTest, FresnelAmplitudes) {
  // Normal incidence, eps = 4 (sqrt = 2): r_h = (1 - 2)/(1 + 2) = -1/3,
  // r_v = (4 - 2)/(4 + 2) = +1/3: equal magnitudes, opposite signs in the
  // (p, p') convention (the same tangential reflection).
  const FresnelAmplitudes n0 = FresnelCoefficients(4.0, 0.0);
  EXPECT_NEAR(std::abs(n0.r_h - cd(-1.0 / 3)), 0.0, 1e-15);
  EXPECT_NEAR(std::abs(n0.r_v - cd(1.0 / 3)), 0.0, 1e-15);
  const FresnelAmplitudes lossy0 = FresnelCoefficients({15.0, -3.0}, 0.0);
  EXPECT_NEAR(std::abs(lossy0.r_h), std::abs(lossy0.r_v), 1e-15);
  // Perfect-conductor limit: eps = 1e12 gives r_h -> -1, r_v -> +1 (the
  // error of r_v is about 2 / (sqrt(eps) cos t): 1.2e-5 at 80 deg).
  for (double deg : {0.0, 40.0, 80.0}) {
    const FresnelAmplitudes big = FresnelCoefficients(1e12, deg * kDeg);
    EXPECT_NEAR(std::abs(big.r_h - PerfectConductorAmplitudes().r_h), 0.0, 2e-5) << deg;
    EXPECT_NEAR(std::abs(big.r_v - PerfectConductorAmplitudes().r_v), 0.0, 2e-5) << deg;
  }
  // Brewster angle of eps = 4: atan 2 = 63.435 deg, r_v = 0; r_v changes
  // sign across it (+1/3 at nadir).
  const double brewster = std::atan(2.0);
  EXPECT_LT(std::abs(FresnelCoefficients(4.0, brewster).r_v), 1e-15);
  EXPECT_GT(FresnelCoefficients(4.0, brewster - 5 * kDeg).r_v.real(), 0.0);
  EXPECT_LT(FresnelCoefficients(4.0, brewster + 5 * kDeg).r_v.real(), 0.0);
  EXPECT_GT(std::abs(FresnelCoefficients(4.0, brewster).r_h), 0.5);
  // eps = 15 - 3j at 40 deg, q = sqrt(eps - sin^2 40) (by hand):
  // r_h = -0.669694 + 0.028023j, r_v = 0.505397 - 0.035780j; the powers are
  // FresnelReflectivity's (material.h).
  const FresnelAmplitudes f40 = FresnelCoefficients({15.0, -3.0}, 40 * kDeg);
  EXPECT_NEAR(std::abs(f40.r_h - cd(-0.6696941, 0.0280229)), 0.0, 1e-6);
  EXPECT_NEAR(std::abs(f40.r_v - cd(0.5053970, -0.0357795)), 0.0, 1e-6);
  EXPECT_NEAR(std::norm(f40.r_h), FresnelReflectivity({15.0, -3.0}, std::cos(40 * kDeg), Polarization::kHH), 1e-12);
  EXPECT_NEAR(std::norm(f40.r_v), FresnelReflectivity({15.0, -3.0}, std::cos(40 * kDeg), Polarization::kVV), 1e-12);
  EXPECT_THROW(FresnelCoefficients({15.0, 3.0}, 0.1), ConfigError);  // gain, not loss
  EXPECT_THROW(FresnelCoefficients(0.5, 0.1), ConfigError);
  EXPECT_THROW(FresnelCoefficients(4.0, 2.0), ConfigError);
}

// ---------------------------------------------------------------- chains

// A plate at normal incidence: one bounce, S = r_h I (HH = VV, same sign);
// perfect conductor: -I = PlateMatrix().
TEST(ScatteringTest, PlateAtNormalIncidenceIsDiagonal) {
  const Eigen::Vector3d l = LineOfSight(75.0, 35.0);
  const Eigen::Vector3d c(3.0, -2.0, 1.0);
  const SpecularChain pec = TraceSpecularChain(l, {Bounce::Conductor(c, -l)}, c);
  EXPECT_NEAR((pec.s - PlateMatrix()).norm(), 0.0, 1e-14);
  EXPECT_NEAR((pec.outgoing_direction + l).norm(), 0.0, 1e-15);
  EXPECT_NEAR(pec.excess_path_m, 0.0, 1e-14);
  const SpecularChain diel = TraceSpecularChain(l, {Bounce::Dielectric(c, -l, 4.0)}, c);
  EXPECT_NEAR(std::abs(diel.s(0, 0) - cd(-1.0 / 3)), 0.0, 1e-14);
  EXPECT_NEAR(std::abs(diel.s(1, 1) - cd(-1.0 / 3)), 0.0, 1e-14);
  EXPECT_NEAR(std::abs(diel.s(0, 1)) + std::abs(diel.s(1, 0)), 0.0, 1e-14);
  // A point 0.2 m behind the phase centre along the line of sight: 0.4 m
  // more two-way path.
  const SpecularChain behind = TraceSpecularChain(l, {Bounce::Conductor(c + 0.2 * l, -l)}, c);
  EXPECT_NEAR(behind.excess_path_m, 0.4, 1e-14);
}

// A horizontal mirror seen bistatically (forward specular): the plane of
// incidence is vertical, s = the transmitter's -h, and BSA's receive h
// (its own line of sight) is the transmit h reversed: S_HH = -r_h,
// S_VV = r_v, no cross-polarisation.
TEST(ScatteringTest, GroundMirrorInBistaticBsa) {
  const cd eps(6.0, -1.0);
  const Eigen::Vector3d l = LineOfSight(30.0, 40.0);
  const Eigen::Vector3d o = Eigen::Vector3d::Zero();
  const SpecularChain g = TraceSpecularChain(l, {Bounce::Dielectric(o, Eigen::Vector3d::UnitZ(), eps)}, o);
  const FresnelAmplitudes r = FresnelCoefficients(eps, 50 * kDeg);
  EXPECT_NEAR(std::abs(g.s(0, 0) + r.r_h), 0.0, 1e-14);
  EXPECT_NEAR(std::abs(g.s(1, 1) - r.r_v), 0.0, 1e-14);
  EXPECT_NEAR(std::abs(g.s(0, 1)) + std::abs(g.s(1, 0)), 0.0, 1e-14);
  EXPECT_NEAR(g.outgoing_direction.z(), std::sin(40 * kDeg), 1e-15);
}

// The dihedral from two perfectly conducting faces meeting at a right angle,
// the line of sight perpendicular to the fold, the fold turned by psi about
// the line of sight: the closed form [[cos 2psi, sin 2psi], [sin 2psi,
// -cos 2psi]] within 0.1 dB and 1 deg, the same common phase (0), for either
// order of the faces; every ray has the fold's path length.
TEST(ScatteringTest, DihedralChainMatchesClosedForm) {
  const Eigen::Vector3d l = LineOfSight(40.0, 30.0);
  const Eigen::Vector3d apex(10.0, 20.0, 5.0);
  for (double psi_deg : {0.0, 22.5, 45.0, -30.0, 67.5}) {
    const double psi = psi_deg * kDeg;
    const std::vector<Face> faces = DihedralFaces(l, apex, psi);
    const PolarizationBasis b = HvBasis(l);
    const Eigen::Vector3d fold = std::cos(psi) * b.h + std::sin(psi) * b.v;
    // Entry on face 0 (extends from the fold along -(l + v')/sqrt 2) and
    // on face 1 (along (-l + v')/sqrt 2).
    const Eigen::Vector3d v_turned = -std::sin(psi) * b.h + std::cos(psi) * b.v;
    const Eigen::Vector3d entry0 = apex + 0.3 * fold - 0.4 * (l + v_turned) / std::sqrt(2.0);
    const Eigen::Vector3d entry1 = apex - 0.2 * fold + 0.25 * (-l + v_turned) / std::sqrt(2.0);
    const SpecularChain a = TraceSpecularChain(l, MirrorPath(l, entry0, faces), apex);
    const SpecularChain c = TraceSpecularChain(l, MirrorPath(l, entry1, {faces[1], faces[0]}), apex);
    const ScatteringMatrix want = DihedralMatrix(psi);
    for (const SpecularChain* chain : {&a, &c}) {
      EXPECT_NEAR((chain->outgoing_direction + l).norm(), 0.0, 1e-14);
      EXPECT_NEAR(chain->excess_path_m, 0.0, 1e-14);
      const double common_deg = ExpectChannelsMatch(chain->s, want, 0.1, 1.0);
      EXPECT_NEAR(common_deg, 0.0, 1e-9) << psi_deg;
      EXPECT_NEAR((chain->s - want).norm(), 0.0, 1e-14) << psi_deg;
    }
    if (psi_deg == 22.5) {
      std::printf("dihedral 22.5 deg chain: HH %.4f dB %.2f deg, HV %.4f dB %.2f deg, VH %.4f dB %.2f deg, "
                  "VV %.4f dB %.2f deg\n",
                  Db20(std::abs(a.s(0, 0))), PhaseDeg(a.s(0, 0)), Db20(std::abs(a.s(0, 1))), PhaseDeg(a.s(0, 1)),
                  Db20(std::abs(a.s(1, 0))), PhaseDeg(a.s(1, 0)), Db20(std::abs(a.s(1, 1))), PhaseDeg(a.s(1, 1)));
    }
    // The scaled reflector matrix is the unit chain times sqrt(sigma / 4 pi).
    const double amp = std::sqrt(8 * M_PI / (0.0555 * 0.0555) / (4 * M_PI));
    EXPECT_NEAR((ReflectorMatrix(ReflectorType::kDihedral, 1.0, 0.0555, psi) - amp * a.s).norm() / amp, 0.0, 1e-12);
  }
}

// Plain dihedral (fold horizontal, perpendicular to the line of sight):
// HH/VV 0 dB, phase 180 deg; HV = 0.
TEST(ScatteringTest, PlainDihedralHhVvPhaseIs180) {
  const Eigen::Vector3d l = LineOfSight(200.0, 45.0);
  const Eigen::Vector3d apex = Eigen::Vector3d::Zero();
  const std::vector<Face> faces = DihedralFaces(l, apex, 0.0);
  const PolarizationBasis b = HvBasis(l);
  const SpecularChain d = TraceSpecularChain(l, MirrorPath(l, apex - 0.5 * (l + b.v) / std::sqrt(2.0), faces), apex);
  EXPECT_NEAR(Db20(std::abs(d.s(0, 0) / d.s(1, 1))), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(PhaseDeg(d.s(0, 0) * std::conj(d.s(1, 1)))), 180.0, 1e-9);
  EXPECT_LT(std::abs(d.s(0, 1)) + std::abs(d.s(1, 0)), 1e-14);
}

// Three mutually perpendicular perfectly conducting plates, the line of
// sight along the boresight into the corner (the corner turned arbitrarily
// about it): S = I (HH/VV 0 dB, 0 deg; HV = 0) for either order of faces,
// and every ray has the apex's path length.
TEST(ScatteringTest, TrihedralChainIsIdentity) {
  const Eigen::Vector3d l = LineOfSight(250.0, 35.26);
  const Eigen::Vector3d apex(-4.0, 7.0, 2.0);
  const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(17 * kDeg, -l)) *
                               Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(1, 1, 1).normalized(), -l);
  const Eigen::Matrix3d axes = q.toRotationMatrix();  // columns: the faces' normals
  const std::vector<Face> faces = {{apex, axes.col(0)}, {apex, axes.col(1)}, {apex, axes.col(2)}};
  // Entry on the face x = 0 at (0, 0.2, 0.5), order x, y, z; and on y = 0
  // at (0.5, 0, 0.2), order y, z, x (corner coordinates).
  const SpecularChain a = TraceSpecularChain(l, MirrorPath(l, apex + axes * Eigen::Vector3d(0, 0.2, 0.5), faces), apex);
  const SpecularChain c = TraceSpecularChain(
      l, MirrorPath(l, apex + axes * Eigen::Vector3d(0.5, 0, 0.2), {faces[1], faces[2], faces[0]}), apex);
  for (const SpecularChain* t : {&a, &c}) {
    EXPECT_NEAR((t->outgoing_direction + l).norm(), 0.0, 1e-14);
    EXPECT_NEAR(t->excess_path_m, 0.0, 1e-14);
    EXPECT_NEAR(Db20(std::abs(t->s(0, 0) / t->s(1, 1))), 0.0, 1e-12);
    EXPECT_NEAR(PhaseDeg(t->s(0, 0) * std::conj(t->s(1, 1))), 0.0, 1e-9);
    EXPECT_LT(std::abs(t->s(0, 1)) + std::abs(t->s(1, 0)), 1e-14);
    ExpectChannelsMatch(t->s, TrihedralMatrix(), 0.1, 1.0);
    EXPECT_NEAR((t->s - TrihedralMatrix()).norm(), 0.0, 1e-14);
  }
  std::printf("trihedral chain: HH/VV %.2e dB, %.2e deg; |HV| %.1e\n", Db20(std::abs(a.s(0, 0) / a.s(1, 1))),
              PhaseDeg(a.s(0, 0) * std::conj(a.s(1, 1))), std::abs(a.s(0, 1)));
}

// Reciprocity: the reversed path gives the transpose. A trihedral with three
// different lossy faces seen 20-odd degrees off its boresight: one path has
// S_HV != S_VH, its reverse (entering where it left) the transpose, and the
// monostatic return (the sum) S_HV = S_VH. A bistatic two-bounce path with
// non-perpendicular lossy faces gives the transpose too.
TEST(ScatteringTest, ReversedPathGivesTranspose) {
  const Eigen::Vector3d apex(1.0, 2.0, 0.5);
  const Eigen::Matrix3d axes =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  const Eigen::Vector3d l = -(axes * Eigen::Vector3d(0.5, 0.7, 1.0)).normalized();
  const std::vector<Face> faces = {{apex, axes.col(0), false, {5.0, -2.0}},
                                   {apex, axes.col(1), false, {12.0, -4.0}},
                                   {apex, axes.col(2), false, {3.0, -0.5}}};
  const std::vector<Bounce> path = MirrorPath(l, apex + axes * Eigen::Vector3d(0.0, 0.3, 0.6), faces);
  const SpecularChain forward = TraceSpecularChain(l, path, apex);
  const SpecularChain reverse = TraceReversedSpecularChain(l, path, apex);
  EXPECT_NEAR((forward.outgoing_direction + l).norm(), 0.0, 1e-14);  // monostatic
  EXPECT_NEAR((reverse.outgoing_direction + l).norm(), 0.0, 1e-14);
  EXPECT_NEAR((reverse.s - forward.s.transpose()).norm(), 0.0, 1e-14);
  EXPECT_NEAR(reverse.excess_path_m, forward.excess_path_m, 1e-14);
  const double asym = std::abs(forward.s(0, 1) - forward.s(1, 0));
  EXPECT_GT(asym, 1e-3);  // one path alone is not symmetric
  const ScatteringMatrix mono = forward.s + reverse.s;
  EXPECT_LT(std::abs(mono(0, 1) - mono(1, 0)), 1e-6 * mono.norm());
  std::printf("lossy trihedral off boresight: one path |HV - VH| = %.4f (|S| = %.4f), path + reverse %.1e\n", asym,
              forward.s.norm(), std::abs(mono(0, 1) - mono(1, 0)));

  // Bistatic: two lossy faces at 70 deg to each other, generic look.
  const Eigen::Vector3d l2 = LineOfSight(10.0, 25.0);
  const Eigen::Vector3d n1 = Turn(-l2, Eigen::Vector3d(1, 2, 0.5), 0.5);
  const Eigen::Vector3d p1(0.0, 0.0, 0.0);
  Eigen::Vector3d d1 = l2 - 2 * l2.dot(n1) * n1;
  const Eigen::Vector3d p2 = p1 + 1.7 * d1;
  const Eigen::Vector3d n2 = Turn(-d1, Eigen::Vector3d(-0.2, 0.4, 1.0), 0.6);
  const std::vector<Bounce> bi = {Bounce::Dielectric(p1, n1, {7.0, -1.5}), Bounce::Dielectric(p2, n2, {20.0, -6.0})};
  const SpecularChain f2 = TraceSpecularChain(l2, bi, p1);
  const SpecularChain r2 = TraceReversedSpecularChain(l2, bi, p1);
  EXPECT_GT((f2.outgoing_direction + l2).norm(), 0.1);  // bistatic
  EXPECT_NEAR((r2.outgoing_direction + l2).norm(), 0.0, 1e-14);
  EXPECT_NEAR((r2.s - f2.s.transpose()).norm(), 0.0, 1e-14);
  EXPECT_NEAR(r2.excess_path_m, f2.excess_path_m, 1e-12);
  EXPECT_GT(std::abs(f2.s(0, 1) - f2.s(1, 0)), 1e-3);
}

TEST(ScatteringTest, ChainRejectsBadPaths) {
  const Eigen::Vector3d l = LineOfSight(0.0, 30.0);
  const Eigen::Vector3d o = Eigen::Vector3d::Zero();
  EXPECT_THROW(TraceSpecularChain(l, {}, o), InputError);
  EXPECT_THROW(TraceSpecularChain(l, {Bounce::Conductor(o, l)}, o), InputError);  // from behind
  EXPECT_THROW(TraceSpecularChain(l, {Bounce::Conductor(o, Eigen::Vector3d::Zero())}, o), InputError);
  EXPECT_THROW(TraceSpecularChain(Eigen::Vector3d::Zero(), {Bounce::Conductor(o, -l)}, o), InputError);
  // The second point is not on the mirror ray (which runs back along -l).
  EXPECT_THROW(TraceSpecularChain(l, {Bounce::Conductor(o, -l), Bounce::Conductor(Eigen::Vector3d(1, 0, 0), l)}, o),
               InputError);
  EXPECT_THROW(TraceSpecularChain(l, {Bounce::Dielectric(o, -l, {4.0, 1.0})}, o), ConfigError);
}

TEST(ScatteringTest, PathPhase) {
  const double lambda = 0.0555;
  // Two-way path of one wavelength (R = lambda / 2): exp(-j 2 pi) = 1; a
  // quarter wavelength: exp(-j pi / 2) = -j.
  EXPECT_NEAR(std::abs(PathPhase(lambda, lambda) - cd(1.0)), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(PathPhase(0.25 * lambda, lambda) - cd(0.0, -1.0)), 0.0, 1e-12);
  // 2R = 25 225 225 wavelengths + lambda / 4 (1 400 000 m, a spaceborne
  // range): still -j (2R is rounded to ~2e-10 m, 4e-9 cycle).
  EXPECT_NEAR(std::abs(PathPhase(25225225.25 * lambda, lambda) - cd(0.0, -1.0)), 0.0, 1e-6);
  EXPECT_THROW(PathPhase(1.0, 0.0), ConfigError);
  EXPECT_THROW(PathPhase(NAN, lambda), InputError);
}

// ---------------------------------------------------------------- Bragg

// SPM amplitudes, g_HH = (eps - 1)/(cos t + q)^2, g_VV = (eps - 1)((eps - 1)
// sin^2 t + eps)/(eps cos t + q)^2, q = sqrt(eps - sin^2 t).
// eps = 4, 30 deg: q = sqrt(15)/2, cos = sqrt(3)/2:
//   g_HH = 3 / ((sqrt 3 + sqrt 15)/2)^2 = 12 / (18 + 6 sqrt 5) = (3 - sqrt 5)/2 = 0.381966,
//   g_VV = (57/4) / ((4 sqrt 3 + sqrt 15)/2)^2 = 57 / (63 + 24 sqrt 5) = 19 (63 - 24 sqrt 5)/363 = 0.488576,
//   HH/VV = 0.781795: -2.1381 dB, 0 deg.
// eps = 4, 45 deg: q = sqrt 3.5 = 1.870829, cos = 0.707107:
//   g_HH = 3 / 2.577936^2 = 0.451416, g_VV = 3 * 5.5 / 4.699256^2 = 0.747181, -4.3770 dB, 0 deg.
// eps = 15 - 3j (the same formula in complex arithmetic):
//   30 deg: g_HH = 0.635983 - 0.029929j, g_VV = 0.921174 - 0.055561j: -3.2241 dB, +0.757 deg;
//   45 deg: g_HH = 0.690474 - 0.026744j, g_VV = 1.494216 - 0.101909j: -6.7190 dB, +1.684 deg.
TEST(ScatteringTest, BraggRatioMatchesSpmClosedForm) {
  const struct {
    cd eps;
    double deg, ratio_db, phase_deg;
    cd hh, vv;
  } cases[] = {
      {4.0, 30.0, -2.13814, 0.0, (3.0 - std::sqrt(5.0)) / 2, 19.0 * (63.0 - 24.0 * std::sqrt(5.0)) / 363.0},
      {4.0, 45.0, -4.37697, 0.0, 0.451416, 0.747181},
      {{15.0, -3.0}, 30.0, -3.22409, 0.7573, {0.635983, -0.029929}, {0.921174, -0.055561}},
      {{15.0, -3.0}, 45.0, -6.71897, 1.6835, {0.690474, -0.026744}, {1.494216, -0.101909}},
  };
  for (const auto& c : cases) {
    const BraggAmplitudes g = SmallPerturbationAmplitudes(c.eps, c.deg * kDeg);
    EXPECT_NEAR(std::abs(g.g_hh - c.hh), 0.0, 2e-6) << c.deg;
    EXPECT_NEAR(std::abs(g.g_vv - c.vv), 0.0, 2e-6) << c.deg;
    EXPECT_NEAR(Db20(std::abs(g.g_hh / g.g_vv)), c.ratio_db, 1e-4) << c.deg;
    EXPECT_NEAR(PhaseDeg(g.g_hh / g.g_vv), c.phase_deg, 1e-3) << c.deg;
  }
  // Nadir: g_HH = g_VV = (eps - 1)/(1 + sqrt eps)^2 = 1/3 for eps = 4 (HH =
  // VV in BSA, as for the plate).
  const BraggAmplitudes g0 = SmallPerturbationAmplitudes(4.0, 0.0);
  EXPECT_NEAR(std::abs(g0.g_hh - cd(1.0 / 3)), 0.0, 1e-15);
  EXPECT_NEAR(std::abs(g0.g_vv - cd(1.0 / 3)), 0.0, 1e-15);
}

// ---------------------------------------------------------------- random S

// 200 000 seeded samples of a law with sigma0 HH -13 dB, HV -24 dB,
// VV -11 dB and rho = 0.7 exp(j 25 deg): the multilooked C3 matches the law
// (the standard error of each power is 1/sqrt(N) = 0.01 dB; tolerance
// 0.05 dB; of |rho| ~ (1 - |rho|^2)/sqrt(N) = 0.001; of arg rho ~0.1 deg).
TEST(ScatteringTest, RandomSamplesReproduceTheCovariance) {
  PolarimetricSigma0 law;
  law.sigma0_hh = std::pow(10.0, -1.3);
  law.sigma0_hv = std::pow(10.0, -2.4);
  law.sigma0_vv = std::pow(10.0, -1.1);
  law.rho_hh_vv = std::polar(0.7, 25 * kDeg);
  std::mt19937_64 rng(20240611);
  constexpr int kN = 200000;
  Eigen::Matrix3cd c3 = Eigen::Matrix3cd::Zero();
  cd hh_hv(0.0);
  for (int i = 0; i < kN; ++i) {
    const ScatteringMatrix s = DrawScatteringMatrix(law, rng);
    ASSERT_EQ(s(0, 1), s(1, 0));
    c3 += Covariance3(s);
    hh_hv += s(0, 0) * std::conj(s(0, 1));
  }
  c3 /= kN;
  hh_hv /= kN;
  const double hh = c3(0, 0).real(), hv = c3(1, 1).real() / 2.0, vv = c3(2, 2).real();
  const cd rho = c3(0, 2) / std::sqrt(hh * vv);
  const double e_hh = 10 * std::log10(hh / law.sigma0_hh), e_hv = 10 * std::log10(hv / law.sigma0_hv),
               e_vv = 10 * std::log10(vv / law.sigma0_vv);
  EXPECT_NEAR(e_hh, 0.0, 0.05);
  EXPECT_NEAR(e_hv, 0.0, 0.05);
  EXPECT_NEAR(e_vv, 0.0, 0.05);
  EXPECT_NEAR(std::abs(rho), 0.7, 0.005);
  EXPECT_NEAR(PhaseDeg(rho), 25.0, 0.5);
  // <HH VV*> itself against rho sqrt(s_hh s_vv), in dB.
  EXPECT_NEAR(10 * std::log10(std::abs(c3(0, 2)) / (0.7 * std::sqrt(law.sigma0_hh * law.sigma0_vv))), 0.0, 0.05);
  // Cross-pol uncorrelated with co-pol.
  EXPECT_LT(std::abs(hh_hv) / std::sqrt(hh * hv), 0.01);
  EXPECT_LT(std::abs(c3(1, 2)) / std::sqrt(2 * hv * vv), 0.01);
  std::printf("C3 of %d samples: HH %+.4f dB, HV %+.4f dB, VV %+.4f dB, |rho| %.4f (0.7), arg %.3f deg (25)\n", kN,
              e_hh, e_hv, e_vv, std::abs(rho), PhaseDeg(rho));

  // The same seed gives the same samples.
  std::mt19937_64 a(7), b(7);
  EXPECT_EQ(DrawScatteringMatrix(law, a), DrawScatteringMatrix(law, b));
  // Bad laws.
  PolarimetricSigma0 bad = law;
  bad.rho_hh_vv = 1.1;
  EXPECT_THROW(DrawScatteringMatrix(bad, rng), ConfigError);
  bad = law;
  bad.sigma0_hv = -1.0;
  EXPECT_THROW(DrawScatteringMatrix(bad, rng), ConfigError);
}

TEST(ScatteringTest, PolarimetricLawOfMaterials) {
  const double lambda = 0.0555, cos30 = std::cos(30 * kDeg);
  Material soil;
  soil.model = ScatteringModel::kOh;
  const PolarimetricSigma0 s = PolarimetricLaw(soil, cos30, lambda);
  EXPECT_EQ(s.sigma0_hh, soil.Sigma0(cos30, lambda, Polarization::kHH));
  EXPECT_EQ(s.sigma0_vv, soil.Sigma0(cos30, lambda, Polarization::kVV));
  EXPECT_EQ(s.sigma0_hv, soil.Sigma0(cos30, lambda, Polarization::kHV));
  EXPECT_EQ(s.rho_hh_vv, cd(kSurfaceHhVvCorrelation));
  HhVvCorrelation custom;
  custom.surface = 0.5;
  EXPECT_EQ(PolarimetricLaw(soil, cos30, lambda, custom).rho_hh_vv, cd(0.5));
  custom.surface = 1.5;
  EXPECT_THROW(PolarimetricLaw(soil, cos30, lambda, custom), ConfigError);

  // Water cloud: an opaque canopy gives the canopy's 1/3, a transparent one
  // (optical depth 0: the canopy term vanishes) the soil's 0.7; between, a
  // power-weighted mix.
  Material forest;
  forest.model = ScatteringModel::kWaterCloud;
  forest.canopy_optical_depth = 50.0;
  EXPECT_NEAR(PolarimetricLaw(forest, cos30, lambda).rho_hh_vv.real(), kCanopyHhVvCorrelation, 1e-12);
  forest.canopy_optical_depth = 0.0;
  EXPECT_NEAR(PolarimetricLaw(forest, cos30, lambda).rho_hh_vv.real(), kSurfaceHhVvCorrelation, 1e-12);
  forest.canopy_optical_depth = 0.3;
  const double mixed = PolarimetricLaw(forest, cos30, lambda).rho_hh_vv.real();
  EXPECT_GT(mixed, kCanopyHhVvCorrelation + 0.01);
  EXPECT_LT(mixed, kSurfaceHhVvCorrelation - 0.01);

  // Bragg water: |rho| = 1, phase arg(g_HH g_VV*) of Debye water.
  Material water;
  water.model = ScatteringModel::kBragg;
  const PolarimetricSigma0 w = PolarimetricLaw(water, cos30, lambda);
  const BraggAmplitudes g = SmallPerturbationAmplitudes(water.EffectivePermittivity(lambda), 30 * kDeg);
  EXPECT_NEAR(std::abs(w.rho_hh_vv), 1.0, 1e-12);
  EXPECT_NEAR(std::arg(w.rho_hh_vv), std::arg(g.g_hh * std::conj(g.g_vv)), 1e-12);
  EXPECT_GT(std::abs(std::arg(w.rho_hh_vv)), 0.0);  // lossy water: a small non-zero phase
  EXPECT_EQ(PolarimetricLaw(water, -0.1, lambda).sigma0_vv, 0.0);
}


// SpecularReflectionOperator is TraceSpecularChain's per-vertex operator:
// the product of the operators of a dielectric-and-conductor dihedral
// chain, read in the BSA bases, is the chain's S; a bistatic reflection
// through the bisector facet leaves along the requested direction.
TEST(ScatteringTest, ReflectionOperatorComposesTheChain) {
  const Eigen::Vector3d l = LineOfSight(40.0, 30.0);
  const Eigen::Vector3d apex(1.0, 2.0, 0.5);
  std::vector<Face> faces = DihedralFaces(l, apex, 22.5 * kDeg);
  faces[0].conductor = false;
  faces[0].permittivity = cd(7.0, -1.5);
  const PolarizationBasis b = HvBasis(l);
  const std::vector<Bounce> path = MirrorPath(l, apex - 0.4 * (l + b.v) / std::sqrt(2.0), faces);
  const SpecularChain chain = TraceSpecularChain(l, path, apex);
  Eigen::Matrix3cd field = Eigen::Matrix3cd::Identity();
  Eigen::Vector3d d = l;
  for (const Bounce& bounce : path) {
    const double cos_i = -d.dot(bounce.normal);
    const FresnelAmplitudes r = bounce.perfect_conductor ? PerfectConductorAmplitudes()
                                                         : FresnelCoefficients(bounce.permittivity, std::acos(cos_i));
    field = SpecularReflectionOperator(d, bounce.normal, r) * field;
    d = (d + 2.0 * cos_i * bounce.normal).normalized();
  }
  const PolarizationBasis rx = HvBasis(-d);
  const Eigen::Vector3d et[2] = {b.h, b.v}, er[2] = {rx.h, rx.v};
  for (int t = 0; t < 2; ++t) {
    for (int r = 0; r < 2; ++r) {
      const cd s = er[r].cast<cd>().dot(field * et[t].cast<cd>());
      EXPECT_NEAR(std::abs(s - chain.s(t, r)), 0.0, 1e-14) << t << r;
    }
  }
  // Bistatic facet: incoming l, outgoing towards (0, 0, 1) turned a bit.
  const Eigen::Vector3d out = Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
  const Eigen::Matrix3cd op = SpecularReflectionOperator(l, (out - l).normalized(), PerfectConductorAmplitudes());
  // A perfect conductor keeps the transverse field's norm and sends it
  // across `out`.
  for (const Eigen::Vector3d& e : {b.h, b.v}) {
    const Eigen::Vector3cd f = op * e.cast<cd>();
    EXPECT_NEAR(f.norm(), 1.0, 1e-14);
    EXPECT_NEAR(std::abs(f.dot(out.cast<cd>())), 0.0, 1e-14);
  }
  EXPECT_THROW(SpecularReflectionOperator(l, l, PerfectConductorAmplitudes()), InputError);
}

// The unit reflector matrices: the canonical matrices without amplitude.
TEST(ScatteringTest, UnitReflectorMatrices) {
  EXPECT_EQ(UnitReflectorMatrix(ReflectorType::kTrihedralSquare, 0.3), TrihedralMatrix());
  EXPECT_EQ(UnitReflectorMatrix(ReflectorType::kPlate, 0.3), PlateMatrix());
  const ScatteringMatrix d45 = UnitReflectorMatrix(ReflectorType::kDihedral, 45 * kDeg);
  EXPECT_NEAR(std::abs(d45(0, 0)), 0.0, 1e-15);
  EXPECT_NEAR(std::abs(d45(1, 1)), 0.0, 1e-15);
  EXPECT_NEAR(d45(0, 1).real(), 1.0, 1e-15);
  const double amp = std::sqrt(PeakRcs(ReflectorType::kDihedral, 0.7, 0.03) / (4 * M_PI));
  EXPECT_NEAR((ReflectorMatrix(ReflectorType::kDihedral, 0.7, 0.03, 0.4) -
               amp * UnitReflectorMatrix(ReflectorType::kDihedral, 0.4)).norm(), 0.0, 1e-12 * amp);
  EXPECT_THROW(UnitReflectorMatrix(ReflectorType::kDihedral, NAN), ConfigError);
}

}  // namespace
}  // namespace gissar::material
