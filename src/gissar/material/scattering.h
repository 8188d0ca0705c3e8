// Polarimetric scattering matrices (docs/radiometry.md, "Polarimetry:
// scattering matrices"): the 2 x 2 complex matrix S of a target in the
// backscatter-alignment (BSA) convention, its Pauli and lexicographic
// vectors and their outer products (T3, C3), rotation about the line of
// sight, the radar's H/V basis, complex Fresnel amplitudes, chains of
// specular (mirror) bounces traced in each surface's own plane of incidence
// and expressed in the radar's H/V basis, the closed-form matrices of the
// canonical reflectors, and random single-bounce matrices drawn from a
// material's sigma0 laws.
//
// Conventions (binding for every caller):
//  - Channels HH, HV, VH, VV: first letter transmit, second receive.
//    S = [[S_HH, S_HV], [S_VH, S_VV]]: row = transmit, column = receive, so
//    S(0, 1) = S_HV (transmit H, receive V).
//  - Frame: a local Cartesian frame with +z up (ENU). The line of sight l is
//    the unit vector from the antenna to the scatterer. h = up x l
//    (normalised), v = l x h; (h, v, l) is right-handed (h x v = l). Seen
//    from the radar looking along l, h points left and v up.
//  - BSA: transmit and receive both use the H/V basis of their own antenna's
//    line of sight; the received voltage of receive polarisation e_r for a
//    scattered field E is e_r . E (no reversal of h for the returning wave).
//  - Phase of a return with two-way path 2R: exp(-j 4 pi R / lambda)
//    (engineering time convention exp(+j omega t); a lossy permittivity is
//    eps' - j eps'', stored as (eps', -eps'') as in material.h).
//  - Rotation angle psi (and a reflector's roll): right-handed about the line
//    of sight l, turning h towards v: clockwise as seen from the radar,
//    counter-clockwise as seen from the target looking back along its
//    boresight. A dihedral whose fold is turned by psi from h towards v has
//    S = [[cos 2psi, sin 2psi], [sin 2psi, -cos 2psi]].
#pragma once

#include <complex>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "gissar/material/material.h"
#include "gissar/material/reflector.h"

namespace gissar::material {

// Row = transmit (0 = H, 1 = V), column = receive.
using ScatteringMatrix = Eigen::Matrix2cd;

// S from its four channels.
ScatteringMatrix MakeScatteringMatrix(std::complex<double> hh, std::complex<double> hv, std::complex<double> vh,
                                      std::complex<double> vv);
// The channel `pol` of S (HV = S(0, 1): transmit H, receive V).
std::complex<double> Channel(const ScatteringMatrix& s, Polarization pol);
// Radar cross section of one channel, m^2, of a matrix in the canonical
// normalisation (ReflectorMatrix): sigma = 4 pi |S_pq|^2.
double ChannelRcs(const ScatteringMatrix& s, Polarization pol);

// Pauli vector k = (S_HH + S_VV, S_HH - S_VV, S_HV + S_VH) / sqrt 2. The
// third component is 2 S_HV / sqrt 2 under reciprocity (S_HV = S_VH);
// otherwise it uses the mean of the two cross-polarised channels.
Eigen::Vector3cd PauliVector(const ScatteringMatrix& s);
// Lexicographic vector (S_HH, sqrt 2 S_X, S_VV), S_X = (S_HV + S_VH) / 2
// (= S_HV under reciprocity).
Eigen::Vector3cd LexicographicVector(const ScatteringMatrix& s);
// Coherency T3 = k k^H (Pauli) and covariance C3 = k_L k_L^H
// (lexicographic) of one matrix; average them over looks for a multilooked
// estimate. trace T3 = trace C3 = span = |S_HH|^2 + |S_VV|^2 + 2 |S_X|^2.
Eigen::Matrix3cd Coherency3(const ScatteringMatrix& s);
Eigen::Matrix3cd Covariance3(const ScatteringMatrix& s);

// The real 2 x 2 rotation [[cos psi, -sin psi], [sin psi, cos psi]] acting
// on (h, v) components: turns h towards v by psi (radians; the sense of
// the header comment).
Eigen::Matrix2d Rotation(double psi_rad);
// S of a target turned by psi about the line of sight: R(psi) S R(psi)^T.
// Rotate(DihedralMatrix(0), psi) = DihedralMatrix(psi).
ScatteringMatrix Rotate(const ScatteringMatrix& s, double psi_rad);

// The radar's horizontal and vertical unit vectors for a line of sight
// (antenna to scatterer, any non-zero length; normalised here):
// h = up x l / |up x l|, v = l x h, up = +z. A vertical line of sight
// (|up x l| < 1e-9 after normalising) has no horizontal: up is replaced by
// east (+x), h = x x l / |x x l|, the limit of a radar looking east (right-
// looking, flying north) as its line of sight tends to the vertical; for
// nadir (l = -z) h = +y (north), v = +x (east). The same fallback axis as
// VerticalTeShare (material.h). Throws InputError for a zero or non-finite
// line of sight.
struct PolarizationBasis {
  Eigen::Vector3d h;
  Eigen::Vector3d v;
};
PolarizationBasis HvBasis(const Eigen::Vector3d& line_of_sight);

// Complex Fresnel amplitude reflection coefficients of a smooth half-space
// of relative permittivity eps (eps' - j eps'', eps' >= 1, eps'' >= 0) at
// incidence theta from the surface normal, in [0, pi/2]:
//   r_h (TE, E perpendicular to the plane of incidence) = (cos t - q) / (cos t + q),
//   r_v (TM)                                            = (eps cos t - q) / (eps cos t + q),
//   q = sqrt(eps - sin^2 t) (principal root: Im q <= 0, a decaying wave).
// r_v refers to the basis p = s x d (incident) and p' = s x d' (reflected),
// s = d x n the TE direction (d, d' propagation directions): then a perfect
// conductor has r_h = -1, r_v = +1 (PerfectConductorAmplitudes), at normal
// incidence r_v = -r_h (both describe the same tangential reflection r_h),
// and r_v = 0 at the Brewster angle atan(sqrt eps) for real eps.
// |r_h|^2, |r_v|^2 are the power reflectivities of FresnelReflectivity
// (material.h, which keeps only the powers). Throws ConfigError for a
// permittivity outside the range above or an incidence outside [0, pi/2].
struct FresnelAmplitudes {
  std::complex<double> r_h;
  std::complex<double> r_v;
};
FresnelAmplitudes FresnelCoefficients(std::complex<double> permittivity, double incidence_rad);
// The perfect-conductor limit eps -> infinity: r_h = -1, r_v = +1.
FresnelAmplitudes PerfectConductorAmplitudes();

// One mirror reflection of a specular chain.
struct Bounce {
  Eigen::Vector3d point_m = Eigen::Vector3d::Zero();   // where the ray meets the face
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();   // face normal, on the side the wave comes from
  bool perfect_conductor = true;                       // r_h = -1, r_v = +1
  std::complex<double> permittivity{1.0, 0.0};         // used when !perfect_conductor

  static Bounce Conductor(const Eigen::Vector3d& point_m, const Eigen::Vector3d& normal);
  static Bounce Dielectric(const Eigen::Vector3d& point_m, const Eigen::Vector3d& normal,
                           std::complex<double> permittivity);
};

// A chain of mirror bounces for a plane wave (far field).
struct SpecularChain {
  // BSA matrix: transmit basis HvBasis(line_of_sight), receive basis
  // HvBasis(-outgoing_direction) (the receiver's own line of sight towards
  // the last vertex; the transmit basis again for a monostatic path).
  ScatteringMatrix s;
  // Unit propagation direction of the wave leaving the last vertex
  // (-line_of_sight for a monostatic return).
  Eigen::Vector3d outgoing_direction;
  // Path length beyond that of the phase centre: the two-way path from a
  // far transmitter to a far receiver is R_t + R_r + excess_path_m, R_t, R_r
  // their ranges to the phase centre (2R + excess_path_m monostatic). 0 for
  // every ray of a trihedral or dihedral with the phase centre on the apex
  // or the fold line.
  double excess_path_m = 0.0;
};

// Traces a plane wave arriving along `line_of_sight` (transmitter to the
// first vertex) through `bounces` in order. At each vertex the direction d
// leaves as d' = d - 2 (d . n) n and the field is reflected in the face's
// own plane of incidence: E' = r_h (E . s) s + r_v (E . p) p', s = d x n
// normalised, p = s x d, p' = s x d' (at normal incidence, s = the h of
// HvBasis(d)); r_h, r_v from FresnelCoefficients or the perfect conductor.
// The 3 x 3 field operator of the chain is the product of the per-bounce
// operators, and S(t, r) = e_r . (operator e_t) with e_t, e_r the BSA
// basis vectors above. The points give the path length only, and must lie
// on the mirror rays: the direction from one point to the next within
// 1.4e-3 rad (cos >= 1 - 1e-6) of the mirror direction (coincident points,
// < 1e-9 m apart, are accepted). Throws InputError for an empty chain, a
// zero or non-finite line of sight or normal, a non-finite point, a wave
// meeting a face from behind or at grazing (d . n >= 0), a point off the
// mirror ray; ConfigError for a bad permittivity.
SpecularChain TraceSpecularChain(const Eigen::Vector3d& line_of_sight, const std::vector<Bounce>& bounces,
                                 const Eigen::Vector3d& phase_centre_m);
// The reversed path of the same chain: transmit along the forward chain's
// -outgoing_direction, the bounces in reverse order. Reciprocity: its s is
// the transpose of the forward s, its outgoing direction -line_of_sight,
// its excess path the same. A monostatic return is the sum of a path and
// its reverse (or a path that is its own reverse), hence S_HV = S_VH.
SpecularChain TraceReversedSpecularChain(const Eigen::Vector3d& line_of_sight, const std::vector<Bounce>& bounces,
                                         const Eigen::Vector3d& phase_centre_m);

// The 3 x 3 field operator of one specular reflection (the per-vertex
// operator of TraceSpecularChain): a plane wave of unit propagation
// direction d meets a face of unit normal n (d . n < 0, the side the wave
// comes from) and leaves along d' = d - 2 (d . n) n; the field E (E . d = 0)
// becomes r_h (E . s) s + r_v (E . p) p', s = d x n normalised, p = s x d,
// p' = s x d' (normal incidence: s = HvBasis(d).h). `r` are the amplitudes
// at this vertex's incidence, acos(-d . n) (FresnelCoefficients or the
// perfect conductor). For a bistatic reflection from d into a direction
// d_out != d, pass the facet normal (d_out - d) / |d_out - d|: its mirror
// direction is d_out. Throws InputError for a non-finite or zero d or n, or
// d . n >= 0.
Eigen::Matrix3cd SpecularReflectionOperator(const Eigen::Vector3d& d, const Eigen::Vector3d& n,
                                            const FresnelAmplitudes& r);

// exp(-j 2 pi two_way_path_m / lambda) = exp(-j 4 pi R / lambda) for a
// two-way path 2R. The argument is reduced modulo one wavelength before the
// exponential. Throws ConfigError for wavelength_m <= 0 or non-finite and
// InputError for a non-finite path.
std::complex<double> PathPhase(double two_way_path_m, double wavelength_m);

// Closed-form matrices of the canonical reflectors at boresight, unit
// amplitude, phase centre on the apex (trihedral), fold line (dihedral) or
// face (plate). The signs are those of geometric optics with perfectly
// conducting faces (TraceSpecularChain with Bounce::Conductor gives the
// same matrices); the physical-optics aperture factor (a quadrature phase
// common to all three) is left out, so the matrices are real:
//   trihedral: I (S_HH = S_VV, 0 deg; roll changes nothing);
//   plate: -I (the perfect conductor's r_h at normal incidence);
//   dihedral, fold turned by roll from h towards v:
//     [[cos 2 roll, sin 2 roll], [sin 2 roll, -cos 2 roll]]
//   (roll 0: fold horizontal, S_HH = -S_VV, 180 deg; roll 45 deg: only
//   S_HV = S_VH).
ScatteringMatrix TrihedralMatrix();
ScatteringMatrix DihedralMatrix(double roll_rad);
ScatteringMatrix PlateMatrix();

// The matrix of ReflectorMatrix without its amplitude: the unit matrix of
// `type` (trihedrals I, dihedral DihedralMatrix(0), plate -I) turned by
// roll_rad, so that |S_pq|^2 is the share of the boresight RCS that channel
// pq returns (co-pol 1 at roll 0; dihedral at 45 deg: 0 co-pol, 1 HV).
// Throws ConfigError for a non-finite roll.
ScatteringMatrix UnitReflectorMatrix(ReflectorType type, double roll_rad);

// The unit matrix of `type` (triangular and square trihedrals: the
// trihedral) turned by roll_rad, scaled by sqrt(sigma / (4 pi)), sigma =
// PeakRcs(type, size_m, wavelength_m): the canonical normalisation, so
// 4 pi (|S_HH|^2 + |S_HV|^2) = sigma for any roll (ChannelRcs). Throws
// ConfigError for size_m or wavelength_m <= 0 or non-finite.
ScatteringMatrix ReflectorMatrix(ReflectorType type, double size_m, double wavelength_m, double roll_rad);

// First-order small-perturbation (Bragg) amplitudes (Valenzuela 1978; the
// same as the kBragg law of material.h):
//   g_HH = (eps - 1) / (cos t + q)^2,
//   g_VV = (eps - 1) ((eps - 1) sin^2 t + eps) / (eps cos t + q)^2,
//   q = sqrt(eps - sin^2 t). ((eps - 1) sin^2 t + eps = eps (1 + sin^2 t) -
// sin^2 t; some texts carry a common minus sign on both, which changes no
// ratio.) In BSA g_HH = g_VV at nadir; |g_HH| < |g_VV| away from it; for
// real eps HH and VV are in phase. Throws ConfigError as FresnelCoefficients.
struct BraggAmplitudes {
  std::complex<double> g_hh;
  std::complex<double> g_vv;
};
BraggAmplitudes SmallPerturbationAmplitudes(std::complex<double> permittivity, double incidence_rad);

// Second-order statistics of a distributed (single-bounce) target: the
// sigma0 of each channel (linear, m^2/m^2) and the complex HH-VV
// correlation coefficient rho = <S_HH S_VV*> / sqrt(sigma0_hh sigma0_vv)
// (|rho| <= 1; arg rho is the law's HH-VV phase). Reflection symmetry: the
// cross-polarised channel is uncorrelated with the co-polarised ones, and
// S_HV = S_VH (reciprocity).
struct PolarimetricSigma0 {
  double sigma0_hh = 0.0;
  double sigma0_hv = 0.0;
  double sigma0_vv = 0.0;
  std::complex<double> rho_hh_vv{0.0, 0.0};
};

// Default |rho_HH,VV| of the laws without a polarimetric phase model (the
// HH-VV phase difference is zero-mean, only the coherence is stated):
// rough bare soil, roads and buildings (Oh 1992, table, Lambert): 0.7,
// within the 0.6-0.9 measured over bare fields at C and L band, falling
// with roughness; a canopy (water cloud): 1/3, the HH-VV coherence of a
// cloud of randomly oriented thin dipoles (C3 proportional to
// [[1, 0, 1/3], [0, 2/3, 0], [1/3, 0, 1]], the Freeman-Durden volume);
// Bragg (water): 1, first-order SPM, HH and VV come from the same Bragg
// wave (the large-scale tilts, not modelled here, lower it).
inline constexpr double kSurfaceHhVvCorrelation = 0.7;
inline constexpr double kCanopyHhVvCorrelation = 1.0 / 3.0;
inline constexpr double kBraggHhVvCorrelation = 1.0;
struct HhVvCorrelation {
  double surface = kSurfaceHhVvCorrelation;
  double canopy = kCanopyHhVvCorrelation;
  double bragg = kBraggHhVvCorrelation;
};

// The polarimetric statistics of `material` at cos(local incidence)
// `cos_incidence` and `wavelength_m`: sigma0_hh, sigma0_vv from
// Material::Sigma0, sigma0_hv the mean of its HV and VH; rho:
//  - kOh, kTable, kLambert: correlations.surface (real: zero-mean phase);
//  - kBragg: correlations.bragg * exp(j arg(g_HH g_VV*)) at the local
//    incidence with EffectivePermittivity (SmallPerturbationAmplitudes);
//  - kWaterCloud: the canopy term (correlations.canopy) and the attenuated
//    Oh ground term (correlations.surface) add as independent scatterers:
//    rho = (rho_c sqrt(c_hh c_vv) + rho_g sqrt(g_hh g_vv)) / sqrt(hh vv).
// rho = 0 where sigma0_hh sigma0_vv = 0; everything 0 for
// cos_incidence <= 0. Throws ConfigError for a correlation outside [0, 1]
// or wavelength_m <= 0.
PolarimetricSigma0 PolarimetricLaw(const Material& material, double cos_incidence, double wavelength_m,
                                   const HhVvCorrelation& correlations = {});

// One sample of S of a distributed target: zero-mean circular complex
// Gaussian with E|S_HH|^2 = sigma0_hh, E|S_HV|^2 = E|S_VH|^2 = sigma0_hv,
// E|S_VV|^2 = sigma0_vv, E[S_HH S_VV*] = rho sqrt(sigma0_hh sigma0_vv),
// S_HV uncorrelated with S_HH, S_VV, and S_VH = S_HV. Normalisation: the
// coherent image's phasor units (|amplitude|^2 adds up to sigma0), not the
// 4 pi of ReflectorMatrix. Uses three unit complex normals, each from two
// raw 64-bit outputs of `rng` (|z|^2 = -ln u1, arg z = 2 pi u2; no
// std::normal_distribution), so a seed gives the same samples with any
// standard library. Throws
// ConfigError for a negative or non-finite sigma0 or |rho| > 1.
ScatteringMatrix DrawScatteringMatrix(const PolarimetricSigma0& law, std::mt19937_64& rng);

}  // namespace gissar::material
