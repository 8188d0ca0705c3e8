#include "gissar/material/scattering.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::material {
namespace {

using cd = std::complex<double>;

bool IsFinite(const Eigen::Vector3d& x) { return x.allFinite(); }

void CheckPermittivity(cd eps, const char* where) {
  if (!std::isfinite(eps.real()) || !std::isfinite(eps.imag()) || !(eps.real() >= 1.0) || !(eps.imag() <= 0.0)) {
    throw ConfigError("permittivity must be finite with eps' >= 1 and loss eps'' >= 0 (stored as (eps', -eps'')), "
                      "got (" + std::to_string(eps.real()) + ", " + std::to_string(eps.imag()) + ")",
                      where);
  }
}

void CheckIncidence(double incidence_rad, const char* where) {
  if (!std::isfinite(incidence_rad) || incidence_rad < 0.0 || incidence_rad > 0.5 * M_PI) {
    throw ConfigError("incidence must be in [0, pi/2] rad, got " + std::to_string(incidence_rad), where);
  }
}

// Fresnel amplitudes from cos(incidence) in [0, 1] (no angle round trip).
FresnelAmplitudes FresnelFromCos(cd eps, double c) {
  const double s2 = std::max(0.0, 1.0 - c * c);
  const cd q = std::sqrt(eps - s2);  // principal root: Re q > 0, Im q <= 0 for Im eps <= 0
  return {(c - q) / (c + q), (eps * c - q) / (eps * c + q)};
}

Eigen::Vector3d UnitOrThrow(const Eigen::Vector3d& x, const std::string& what, const std::string& where) {
  const double n = x.norm();
  if (!IsFinite(x) || !(n > 0.0) || !std::isfinite(n)) {
    throw InputError(what + " must be a finite non-zero vector", where);
  }
  return x / n;
}

// Uniform in (0, 1) from the top 53 bits of one raw output.
double OpenUnit(std::mt19937_64& rng) { return (static_cast<double>(rng() >> 11) + 0.5) * 0x1.0p-53; }

// Circular complex normal with E|z|^2 = 1: |z|^2 ~ Exp(1), uniform phase.
cd UnitComplexNormal(std::mt19937_64& rng) {
  const double u1 = OpenUnit(rng);
  const double u2 = OpenUnit(rng);
  return std::polar(std::sqrt(-std::log(u1)), 2.0 * M_PI * u2);
}

void CheckCorrelation(double rho, const char* key) {
  if (!std::isfinite(rho) || rho < 0.0 || rho > 1.0) {
    throw ConfigError(std::string("HH-VV correlation must be in [0, 1], got ") + std::to_string(rho), key);
  }
}

}  // namespace

ScatteringMatrix MakeScatteringMatrix(cd hh, cd hv, cd vh, cd vv) {
  ScatteringMatrix s;
  s << hh, hv, vh, vv;
  return s;
}

cd Channel(const ScatteringMatrix& s, Polarization pol) {
  switch (pol) {
    case Polarization::kHH: return s(0, 0);
    case Polarization::kHV: return s(0, 1);
    case Polarization::kVH: return s(1, 0);
    default: return s(1, 1);
  }
}

double ChannelRcs(const ScatteringMatrix& s, Polarization pol) { return 4.0 * M_PI * std::norm(Channel(s, pol)); }

Eigen::Vector3cd PauliVector(const ScatteringMatrix& s) {
  const double r = 1.0 / std::sqrt(2.0);
  return Eigen::Vector3cd(r * (s(0, 0) + s(1, 1)), r * (s(0, 0) - s(1, 1)), r * (s(0, 1) + s(1, 0)));
}

Eigen::Vector3cd LexicographicVector(const ScatteringMatrix& s) {
  const cd cross = 0.5 * (s(0, 1) + s(1, 0));
  return Eigen::Vector3cd(s(0, 0), std::sqrt(2.0) * cross, s(1, 1));
}

Eigen::Matrix3cd Coherency3(const ScatteringMatrix& s) {
  const Eigen::Vector3cd k = PauliVector(s);
  return k * k.adjoint();
}

Eigen::Matrix3cd Covariance3(const ScatteringMatrix& s) {
  const Eigen::Vector3cd k = LexicographicVector(s);
  return k * k.adjoint();
}

Eigen::Matrix2d Rotation(double psi_rad) {
  const double c = std::cos(psi_rad), s = std::sin(psi_rad);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

ScatteringMatrix Rotate(const ScatteringMatrix& s, double psi_rad) {
  const Eigen::Matrix2cd r = Rotation(psi_rad).cast<cd>();
  return r * s * r.transpose();
}

PolarizationBasis HvBasis(const Eigen::Vector3d& line_of_sight) {
  const Eigen::Vector3d l = UnitOrThrow(line_of_sight, "line of sight", "HvBasis");
  Eigen::Vector3d h = Eigen::Vector3d::UnitZ().cross(l);
  if (!(h.norm() >= 1e-9)) h = Eigen::Vector3d::UnitX().cross(l);  // vertical: east replaces up
  h.normalize();
  const Eigen::Vector3d v = l.cross(h);
  GISSAR_CHECK_MSG(std::abs(v.norm() - 1.0) < 1e-9, "v = l x h not unit: " << v.norm());
  return {h, v};
}

FresnelAmplitudes FresnelCoefficients(cd permittivity, double incidence_rad) {
  CheckPermittivity(permittivity, "FresnelCoefficients");
  CheckIncidence(incidence_rad, "FresnelCoefficients");
  return FresnelFromCos(permittivity, std::cos(incidence_rad));
}

FresnelAmplitudes PerfectConductorAmplitudes() { return {cd(-1.0, 0.0), cd(1.0, 0.0)}; }

Bounce Bounce::Conductor(const Eigen::Vector3d& point_m, const Eigen::Vector3d& normal) {
  Bounce b;
  b.point_m = point_m;
  b.normal = normal;
  b.perfect_conductor = true;
  return b;
}

Bounce Bounce::Dielectric(const Eigen::Vector3d& point_m, const Eigen::Vector3d& normal, cd permittivity) {
  Bounce b;
  b.point_m = point_m;
  b.normal = normal;
  b.perfect_conductor = false;
  b.permittivity = permittivity;
  return b;
}

SpecularChain TraceSpecularChain(const Eigen::Vector3d& line_of_sight, const std::vector<Bounce>& bounces,
                                 const Eigen::Vector3d& phase_centre_m) {
  constexpr const char* kWhere = "TraceSpecularChain";
  if (bounces.empty()) throw InputError("a specular chain needs at least one bounce", kWhere);
  if (!IsFinite(phase_centre_m)) throw InputError("phase centre must be finite", kWhere);
  const Eigen::Vector3d l = UnitOrThrow(line_of_sight, "line of sight", kWhere);
  Eigen::Vector3d d = l;
  Eigen::Matrix3cd field = Eigen::Matrix3cd::Identity();  // incident field -> field after the bounces
  double excess = 0.0;
  for (size_t k = 0; k < bounces.size(); ++k) {
    const Bounce& b = bounces[k];
    const std::string at = std::string(kWhere) + ", bounce " + std::to_string(k);
    if (!IsFinite(b.point_m)) throw InputError("point must be finite", at);
    const Eigen::Vector3d n = UnitOrThrow(b.normal, "normal", at);
    if (k == 0) {
      excess += l.dot(b.point_m - phase_centre_m);
    } else {
      const Eigen::Vector3d seg = b.point_m - bounces[k - 1].point_m;
      const double len = seg.norm();
      if (len >= 1e-9 && !(seg.dot(d) >= (1.0 - 1e-6) * len)) {
        throw InputError("point is not on the mirror ray from the previous bounce", at);
      }
      excess += len;
    }
    const double cos_i = -d.dot(n);
    if (!(cos_i > 0.0)) throw InputError("the wave meets the face from behind or at grazing (d . n >= 0)", at);
    FresnelAmplitudes r = PerfectConductorAmplitudes();
    if (!b.perfect_conductor) {
      CheckPermittivity(b.permittivity, at.c_str());
      r = FresnelFromCos(b.permittivity, std::min(1.0, cos_i));
    }
    field = SpecularReflectionOperator(d, n, r) * field;
    d = (d + 2.0 * cos_i * n).normalized();
  }
  excess -= d.dot(bounces.back().point_m - phase_centre_m);

  const PolarizationBasis tx = HvBasis(l);
  const PolarizationBasis rx = HvBasis(-d);
  const Eigen::Vector3d et[2] = {tx.h, tx.v};
  const Eigen::Vector3d er[2] = {rx.h, rx.v};
  SpecularChain out;
  for (int t = 0; t < 2; ++t) {
    const Eigen::Vector3cd e = field * et[t].cast<cd>();
    for (int r = 0; r < 2; ++r) out.s(t, r) = er[r].cast<cd>().dot(e);  // real e_r: no conjugate matters
  }
  out.outgoing_direction = d;
  out.excess_path_m = excess;
  return out;
}

SpecularChain TraceReversedSpecularChain(const Eigen::Vector3d& line_of_sight, const std::vector<Bounce>& bounces,
                                         const Eigen::Vector3d& phase_centre_m) {
  const SpecularChain forward = TraceSpecularChain(line_of_sight, bounces, phase_centre_m);
  const std::vector<Bounce> reversed(bounces.rbegin(), bounces.rend());
  return TraceSpecularChain(-forward.outgoing_direction, reversed, phase_centre_m);
}

Eigen::Matrix3cd SpecularReflectionOperator(const Eigen::Vector3d& d_in, const Eigen::Vector3d& n_in,
                                            const FresnelAmplitudes& r) {
  constexpr const char* kWhere = "SpecularReflectionOperator";
  const Eigen::Vector3d d = UnitOrThrow(d_in, "direction", kWhere);
  const Eigen::Vector3d n = UnitOrThrow(n_in, "normal", kWhere);
  const double cos_i = -d.dot(n);
  if (!(cos_i > 0.0)) throw InputError("the wave meets the face from behind or at grazing (d . n >= 0)", kWhere);
  const Eigen::Vector3d d_out = d + 2.0 * cos_i * n;
  Eigen::Vector3d s = d.cross(n);
  if (s.norm() < 1e-12) {
    s = HvBasis(d).h;  // normal incidence: any direction across d (r_v = -r_h there)
  } else {
    s.normalize();
  }
  const Eigen::Vector3d p_in = s.cross(d);
  const Eigen::Vector3d p_out = s.cross(d_out);
  return r.r_h * (s * s.transpose()).cast<cd>() + r.r_v * (p_out * p_in.transpose()).cast<cd>();
}

ScatteringMatrix UnitReflectorMatrix(ReflectorType type, double roll_rad) {
  if (!std::isfinite(roll_rad)) throw ConfigError("roll must be finite", "UnitReflectorMatrix");
  switch (type) {
    case ReflectorType::kDihedral: return DihedralMatrix(roll_rad);
    case ReflectorType::kPlate: return PlateMatrix();
    default: return TrihedralMatrix();
  }
}

cd PathPhase(double two_way_path_m, double wavelength_m) {
  if (!std::isfinite(wavelength_m) || !(wavelength_m > 0.0)) {
    throw ConfigError("wavelength must be positive and finite", "PathPhase");
  }
  if (!std::isfinite(two_way_path_m)) throw InputError("path length must be finite", "PathPhase");
  const double cycles = std::fmod(two_way_path_m / wavelength_m, 1.0);
  return std::polar(1.0, -2.0 * M_PI * cycles);
}

ScatteringMatrix TrihedralMatrix() { return ScatteringMatrix::Identity(); }

ScatteringMatrix DihedralMatrix(double roll_rad) {
  const double c = std::cos(2.0 * roll_rad), s = std::sin(2.0 * roll_rad);
  return MakeScatteringMatrix(c, s, s, -c);
}

ScatteringMatrix PlateMatrix() { return -ScatteringMatrix::Identity(); }

ScatteringMatrix ReflectorMatrix(ReflectorType type, double size_m, double wavelength_m, double roll_rad) {
  if (!std::isfinite(size_m) || !(size_m > 0.0)) {
    throw ConfigError("reflector size must be positive", "ReflectorMatrix");
  }
  if (!std::isfinite(wavelength_m) || !(wavelength_m > 0.0)) {
    throw ConfigError("wavelength must be positive and finite", "ReflectorMatrix");
  }
  if (!std::isfinite(roll_rad)) throw ConfigError("roll must be finite", "ReflectorMatrix");
  ScatteringMatrix unit;
  switch (type) {
    case ReflectorType::kDihedral: unit = DihedralMatrix(0.0); break;
    case ReflectorType::kPlate: unit = PlateMatrix(); break;
    default: unit = TrihedralMatrix(); break;
  }
  const double amplitude = std::sqrt(PeakRcs(type, size_m, wavelength_m) / (4.0 * M_PI));
  return amplitude * Rotate(unit, roll_rad);
}

BraggAmplitudes SmallPerturbationAmplitudes(cd permittivity, double incidence_rad) {
  CheckPermittivity(permittivity, "SmallPerturbationAmplitudes");
  CheckIncidence(incidence_rad, "SmallPerturbationAmplitudes");
  const double c = std::cos(incidence_rad), s2 = std::sin(incidence_rad) * std::sin(incidence_rad);
  const cd eps = permittivity;
  const cd q = std::sqrt(eps - s2);
  const cd ghh = (eps - 1.0) / ((c + q) * (c + q));
  const cd gvv = (eps - 1.0) * ((eps - 1.0) * s2 + eps) / ((eps * c + q) * (eps * c + q));
  return {ghh, gvv};
}

PolarimetricSigma0 PolarimetricLaw(const Material& material, double cos_incidence, double wavelength_m,
                                   const HhVvCorrelation& correlations) {
  CheckCorrelation(correlations.surface, "surface");
  CheckCorrelation(correlations.canopy, "canopy");
  CheckCorrelation(correlations.bragg, "bragg");
  if (!std::isfinite(wavelength_m) || !(wavelength_m > 0.0)) {
    throw ConfigError("wavelength must be positive and finite", "PolarimetricLaw");
  }
  PolarimetricSigma0 law;
  if (!(cos_incidence > 0.0)) return law;
  cos_incidence = std::min(1.0, cos_incidence);
  law.sigma0_hh = material.Sigma0(cos_incidence, wavelength_m, Polarization::kHH);
  law.sigma0_vv = material.Sigma0(cos_incidence, wavelength_m, Polarization::kVV);
  law.sigma0_hv = 0.5 * (material.Sigma0(cos_incidence, wavelength_m, Polarization::kHV) +
                         material.Sigma0(cos_incidence, wavelength_m, Polarization::kVH));
  const double co = std::sqrt(law.sigma0_hh * law.sigma0_vv);
  if (!(co > 0.0)) return law;
  switch (material.model) {
    case ScatteringModel::kBragg: {
      const BraggAmplitudes g =
          SmallPerturbationAmplitudes(material.EffectivePermittivity(wavelength_m), std::acos(cos_incidence));
      law.rho_hh_vv = std::polar(correlations.bragg, std::arg(g.g_hh * std::conj(g.g_vv)));
      break;
    }
    case ScatteringModel::kWaterCloud: {
      // The ground term of the water-cloud sum: the Oh law of the same
      // parameters (and gain) times the two-way canopy transmissivity.
      Material ground = material;
      ground.model = ScatteringModel::kOh;
      const double tau2 = std::exp(-2.0 * material.canopy_optical_depth / cos_incidence);
      const double g_hh = tau2 * ground.Sigma0(cos_incidence, wavelength_m, Polarization::kHH);
      const double g_vv = tau2 * ground.Sigma0(cos_incidence, wavelength_m, Polarization::kVV);
      const double c_hh = std::max(0.0, law.sigma0_hh - g_hh);
      const double c_vv = std::max(0.0, law.sigma0_vv - g_vv);
      const double rho =
          (correlations.canopy * std::sqrt(c_hh * c_vv) + correlations.surface * std::sqrt(g_hh * g_vv)) / co;
      law.rho_hh_vv = std::min(1.0, rho);
      break;
    }
    default:
      law.rho_hh_vv = correlations.surface;
      break;
  }
  return law;
}

ScatteringMatrix DrawScatteringMatrix(const PolarimetricSigma0& law, std::mt19937_64& rng) {
  const double sigmas[3] = {law.sigma0_hh, law.sigma0_hv, law.sigma0_vv};
  for (double s : sigmas) {
    if (!std::isfinite(s) || s < 0.0) throw ConfigError("sigma0 must be finite and >= 0", "DrawScatteringMatrix");
  }
  const double rho_abs = std::abs(law.rho_hh_vv);
  if (!std::isfinite(rho_abs) || rho_abs > 1.0 + 1e-12) {
    throw ConfigError("HH-VV correlation must have magnitude <= 1", "DrawScatteringMatrix");
  }
  const cd z1 = UnitComplexNormal(rng), z2 = UnitComplexNormal(rng), z3 = UnitComplexNormal(rng);
  // S_VV = sqrt(s_vv) (rho* z1 + sqrt(1 - |rho|^2) z2): E[S_HH S_VV*] = rho sqrt(s_hh s_vv).
  const cd hh = std::sqrt(law.sigma0_hh) * z1;
  const cd vv = std::sqrt(law.sigma0_vv) *
                (std::conj(law.rho_hh_vv) * z1 + std::sqrt(std::max(0.0, 1.0 - rho_abs * rho_abs)) * z2);
  const cd hv = std::sqrt(law.sigma0_hv) * z3;
  return MakeScatteringMatrix(hh, hv, hv, vv);
}

}  // namespace gissar::material
