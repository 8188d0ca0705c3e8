// Radar reflection properties per scene class.
//
// Single bounce (monostatic backscatter) is a scattering law in calibrated
// terms: the backscattering coefficient sigma0(theta_l, lambda, pol), m^2 of
// radar cross section per m^2 of surface, at local incidence theta_l (from
// the surface normal), wavelength lambda and polarisation. The laws are
// physical surface and volume models with documented parameters
// (docs/radiometry.md): Oh et al. 1992 for soil, roads and buildings,
// two-scale Bragg scattering on an Elfouhaily et al. 1997 wind-sea spectrum
// for water and sea, the water-cloud model (Attema & Ulaby 1978) for
// vegetation, a user table of (incidence, dB) pairs, or the legacy
// Lambertian+specular law (sigma0 = 4 cos(theta) times the returned share).
//
// Later bounces (bistatic) use the RaySAR-style terms written as a
// reciprocal bistatic scattering coefficient (BistaticSigma0: a Lambertian
// diffuse share and a specular cone whose width follows `roughness`,
// symmetric in the incident and scattered directions), and a mirror share
// that continues the ray with the Fresnel reflectivity of the class's
// permittivity (MirrorReflectivity). Energy: diffuse + mirror <= 1.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/scene/scene_config.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/enum_table.h"

namespace gissar::material {

enum class Polarization { kHH, kHV, kVH, kVV };
// The channels, first letter transmit (docs/conventions.md, "Polarimetry");
// read case-insensitively, written in capitals.
inline constexpr auto kPolarizations = util::MakeEnumTable<Polarization>(
    "channel",
    {{Polarization::kHH, "HH"}, {Polarization::kHV, "HV"}, {Polarization::kVH, "VH"}, {Polarization::kVV, "VV"}},
    util::EnumCase::kInsensitive);
// The four channel names in quad order (HH, HV, VH, VV), from kPolarizations.
inline constexpr std::array<const char*, 4> kQuadChannelNames = [] {
  std::array<const char*, 4> out{};
  for (size_t i = 0; i < out.size(); ++i) out[i] = kPolarizations.Entries()[i].name.data();
  return out;
}();
// kPolarizations.Parse: "HH", "HV", "VH", "VV" (case-insensitive); throws
// ConfigError naming `option` and the channels otherwise.
Polarization ParsePolarization(const std::string& text, const std::string& option);
std::string ToString(Polarization pol);
// The channels of a `--polarization` value (docs/conventions.md,
// "Polarimetry"): one channel, a comma list ("HH,VV", any order, each at
// most once, kept in the given order) or "quad" (HH, HV, VH, VV), case-
// insensitive. Throws ConfigError naming `option` and the unknown or
// repeated channel.
std::vector<Polarization> ParsePolarizationList(const std::string& text, const std::string& option);
// The same list written back: "quad" for the four channels in quad order,
// else the channels joined with commas.
std::string ToString(const std::vector<Polarization>& channels);

enum class ScatteringModel { kLambert, kTable, kOh, kBragg, kWaterCloud };
// The `model` key of a materials file.
inline constexpr auto kScatteringModels = util::MakeEnumTable<ScatteringModel>(
    "scattering model", {{ScatteringModel::kLambert, "lambert"},
                         {ScatteringModel::kTable, "table"},
                         {ScatteringModel::kOh, "oh"},
                         {ScatteringModel::kBragg, "bragg"},
                         {ScatteringModel::kWaterCloud, "water_cloud"}});
std::string ToString(ScatteringModel model);

// Relative permittivity of water by a single Debye relaxation at 20 deg C
// (Klein & Swift 1977 parameters; fresh water salinity 0, sea water 35 psu
// with ionic conductivity 4.8 S/m), eps' - j eps'' returned as
// (eps', -eps''). wavelength_m > 0.
std::complex<double> WaterPermittivity(double wavelength_m, double salinity_psu);

// Elfouhaily et al. (1997) omnidirectional curvature spectrum B(k) of a
// wind sea (fully developed, Omega = 0.84) at wavenumber k (rad/m) for a
// 10 m wind speed u10 (m/s). The short-wave amplitude alpha_m is floored at
// 1e-5 (calm water below the capillary threshold).
double ElfouhailyCurvature(double k_rad_m, double u10_m_s);

// Fresnel power reflectivity |Gamma_p|^2 of a smooth half-space of relative
// permittivity eps (eps' - j eps'', stored as (eps', -eps'')) at
// cos(incidence) `cos_incidence` in (0, 1]: |Gamma_h|^2 for HH, |Gamma_v|^2
// for VV, and their mean for HV/VH (the rotation of the polarisation basis
// along a multi-bounce path is not modelled). 0 for cos_incidence <= 0.
double FresnelReflectivity(std::complex<double> eps, double cos_incidence, Polarization pol);

// Share of the power of the radar's vertically polarised field on a ray of
// unit direction `dir` that is perpendicular (TE) to the plane of incidence
// of a surface of unit normal `normal`: 1 - (H . s)^2, with H = dir x z
// normalised (the radar's horizontal polarisation; a vertical ray takes x
// for z) and s = dir x normal normalised (the TE direction). 0 on
// horizontal surfaces (V is TM: the plane of incidence is vertical) and on
// walls seen broadside; on a vertical wall at horizontal aspect phi from the
// ray, seen at depression delta: sin^2 phi / (sin^2 delta + cos^2 delta
// sin^2 phi). The share of H is 1 minus it. At normal incidence (no plane of
// incidence) 0.5. Either sign of `dir` or `normal` gives the same value.
double VerticalTeShare(const Eigen::Vector3d& dir, const Eigen::Vector3d& normal);

// Fresnel power reflectivity of a smooth half-space for the radar's
// polarisation `pol` carried by a ray of unit direction `dir_in` that leaves
// as `dir_out` (propagation directions), the H/V basis projected on the
// surface's TE/TM directions: |Gamma_TE|^2 t + |Gamma_TM|^2 (1 - t) for V,
// the complement for H (t: VerticalTeShare, averaged over `dir_in` and the
// reversed outgoing ray -dir_out so that a path and its reverse get the same
// value; the two agree on horizontal and vertical surfaces), the mean of H
// and V for HV/VH. Gamma at cos(incidence) `cos_incidence`.
double OrientedFresnelReflectivity(std::complex<double> eps, double cos_incidence, const Eigen::Vector3d& dir_in,
                                   const Eigen::Vector3d& dir_out, const Eigen::Vector3d& normal, Polarization pol);

struct Material {
  std::string name = "default";
  // Bistatic (later-bounce) terms and the legacy single-bounce law.
  // Lambertian reflectivity: returns diffuse * cos(theta) of the incident
  // power at local incidence theta.
  double diffuse = 1.0;
  // Specular highlight strength: returns specular * cos(2 theta)^(1/roughness)
  // towards the radar, zero beyond theta = 45 deg.
  double specular = 0.0;
  // In (0, 1]: small values give a narrow cone (smooth surface).
  double roughness = 1.0;
  // Coherent (mirror) share: the fraction of the smooth-surface Fresnel
  // reflection that continues as a mirror-reflected ray (1 = a perfectly
  // smooth surface; MirrorReflectivity).
  double mirror = 0.0;

  // Single-bounce law and its parameters.
  ScatteringModel model = ScatteringModel::kLambert;
  // kTable: (incidence deg, sigma0 dB) pairs, incidence strictly increasing
  // in [0, 90]; linear interpolation in dB, constant beyond the ends.
  std::vector<std::pair<double, double>> sigma0_db = {};
  // kOh, and the ground under a kWaterCloud canopy: relative permittivity
  // eps' - j eps'' stored as (eps', -eps''), rms height (metres).
  std::complex<double> permittivity{6.0, -1.0};
  double rms_height_m = 0.01;
  // kBragg: 10 m wind speed and salinity (0 fresh water, 35 sea).
  double wind_speed_m_s = 3.0;
  double salinity_psu = 0.0;
  // kWaterCloud: gamma of an opaque canopy, co- and cross-polarised (dB),
  // and the canopy's one-way optical depth at nadir (B V2).
  double canopy_gamma_db = -6.5;
  double canopy_cross_gamma_db = -12.5;
  double canopy_optical_depth = 1.0;
  // Offset of every return of the class (dB; 0 = the law as given).
  double gain_db = 0.0;
  // Where the law's numbers come from (free text, recorded in sidecars).
  std::string source = {};

  // Legacy single-bounce returned share for cos(local incidence)
  // `cos_incidence` (values <= 0: back face, returns 0).
  double Backscatter(double cos_incidence) const;

  // sigma0 (linear, m^2/m^2) at cos(local incidence) `cos_incidence` for
  // `wavelength_m` and `pol`; 0 for cos_incidence <= 0.
  double Sigma0(double cos_incidence, double wavelength_m, Polarization pol) const;

  // The permittivity of the Fresnel terms: Debye water at `wavelength_m`
  // (WaterPermittivity with salinity_psu) for kBragg, else `permittivity`.
  std::complex<double> EffectivePermittivity(double wavelength_m) const;

  // Power carried on by the mirror ray at cos(local incidence)
  // `cos_incidence`: mirror * FresnelReflectivity(EffectivePermittivity,
  // cos_incidence, pol) (the same for either direction of travel).
  double MirrorReflectivity(double cos_incidence, double wavelength_m, Polarization pol) const;
  // The same with the polarisation basis projected on the surface's plane
  // of incidence (OrientedFresnelReflectivity): what the renderers use.
  // Equal to the above on horizontal surfaces and broadside walls.
  double MirrorReflectivity(double cos_incidence, const Eigen::Vector3d& dir_in, const Eigen::Vector3d& dir_out,
                            const Eigen::Vector3d& normal, double wavelength_m, Polarization pol) const;

  // Bistatic scattering coefficient (m^2 of RCS per m^2 of surface) from an
  // incident direction at cos(incidence) `cos_in` into a scattered direction
  // at cos(angle from the normal) `cos_out`, `cos_spec` the cosine between
  // the scattered direction and the mirror direction of the incident one:
  //   4 (diffuse cos_in cos_out + specular cos_spec^(1/roughness) sqrt(cos_in cos_out)),
  // times the class gain. Symmetric under exchanging the incident and
  // scattered directions (reciprocity); its monostatic value (cos_in =
  // cos_out, cos_spec = cos 2 theta) is the kLambert law of Sigma0. 0 when
  // either cosine is <= 0; no specular term for cos_spec <= 0.
  double BistaticSigma0(double cos_in, double cos_out, double cos_spec) const;

  // Throws ConfigError naming the material when a coefficient is negative,
  // above 1, not finite, roughness is not in (0, 1], diffuse + mirror > 1
  // (energy from nowhere), or a model parameter is out of range.
  void Check() const;
  nlohmann::json ToJson() const;
};

// A material's sigma0 sampled every 0.05 deg of local incidence for one
// wavelength and polarisation (linear interpolation): the renderers' fast
// lookup.
// acos(x) for x in [0, 1] (clamped), within 2e-8 rad (a polynomial, no
// libm call): the angle lookups of Sigma0Table (operator(), which also
// fills the renderers' Fast table).
inline double AcosOfUnitInterval(double x) {
  // Abramowitz & Stegun 4.4.46: acos x = sqrt(1 - x) (a0 + a1 x + ... + a7 x^7)
  // + e, |e| <= 2e-8, for 0 <= x <= 1.
  constexpr double a[8] = {1.5707963050, -0.2145988016, 0.0889789874, -0.0501743046,
                           0.0308918810, -0.0170881256, 0.0066700901, -0.0012624911};
  x = std::clamp(x, 0.0, 1.0);
  const double p = a[0] + x * (a[1] + x * (a[2] + x * (a[3] + x * (a[4] + x * (a[5] + x * (a[6] + x * a[7]))))));
  return std::sqrt(1.0 - x) * p;
}

class Sigma0Table {
 public:
  static constexpr double kStepDeg = 0.05;
  static constexpr int kSamples = 1800;  // 90 deg / step

  Sigma0Table() = default;
  Sigma0Table(const Material& material, double wavelength_m, Polarization pol);
  // sigma0 (linear) at cos(local incidence); 0 for cos <= 0.
  double operator()(double cos_incidence) const {
    if (cos_incidence <= 0.0 || samples_.empty()) return 0.0;
    // The angle to 2e-8 rad, 40000 times finer than the table's step.
    const double x = AcosOfUnitInterval(cos_incidence) / (kStepDeg * (M_PI / 180.0));
    const int i = std::min(kSamples - 1, static_cast<int>(x));
    const double f = x - i;
    return samples_[i] + f * (samples_[i + 1] - samples_[i]);
  }

  // The same law in float without an arc cosine, for lookups in bulk (the
  // DEM-raster engine's facets, the tracer's hits): a second table sampled uniformly in
  // s = sqrt(1 - cos) (kFastSamples steps, at most 0.028 deg apart in
  // angle: d theta / d s = 2 / sqrt(2 - s^2) <= 2), interpolated linearly.
  // Agrees with operator() to the float rounding and the two tables'
  // interpolation (material_test; it is sampled from operator()); 0 for
  // cos <= 0.
  static constexpr int kFastSamples = 4096;
  float Fast(float cos_incidence) const {
    if (!(cos_incidence > 0.0f) || fast_.empty()) return 0.0f;
    const float x = std::sqrt(std::max(0.0f, 1.0f - cos_incidence)) * float(kFastSamples);
    const int i = std::min(kFastSamples - 1, static_cast<int>(x));
    const float f = x - float(i);
    return fast_[i] + f * (fast_[i + 1] - fast_[i]);
  }

 private:
  std::vector<float> samples_;  // at theta = i * step, i = 0 .. kSamples
  std::vector<float> fast_;     // at cos = 1 - (i / kFastSamples)^2, i = 0 .. kFastSamples
};

// Materials indexed by scene::ClassId.
class MaterialTable {
 public:
  // One "default" material for class 0 (DefaultMaterial(kClassDefault)).
  MaterialTable();

  // Sets the material of class `id` (growing the table with defaults).
  void Set(scene::ClassId id, Material material);
  // The material of class `id`; the class-0 material when unset.
  const Material& Get(scene::ClassId id) const;
  size_t size() const { return materials_.size(); }
  // One Sigma0Table per class (index = ClassId). Built once per
  // (wavelength, polarisation) and kept until Set changes a material: a
  // navigation fix renders many references with one table. Thread-safe.
  std::vector<Sigma0Table> Tables(double wavelength_m, Polarization pol) const;

  nlohmann::json ToJson() const;

 private:
  struct TableCache;  // material.cc; copies share it until one calls Set
  std::vector<Material> materials_;
  std::shared_ptr<TableCache> tables_;
};

// One vertex of a multi-bounce path (far field): its point, its unit
// surface normal and its material.
struct PathVertex {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
  const Material* material = nullptr;
};

// RCS per m^2 of surface at the scattering vertex of a path on which a plane
// wave arrives from the direction `to_source` (unit, pointing from
// vertices[0] towards the source), meets vertices[0], ..., vertices[n-1] in
// order and leaves vertices[n-1] towards `to_receiver` (unit). Vertex
// `scatter` scatters with its BistaticSigma0; every other vertex is a mirror
// with its oriented MirrorReflectivity (the polarisation basis projected on
// its plane of incidence) at the half angle between its incoming and
// outgoing directions (its incidence for an exact mirror geometry). 0 when a
// direction meets a vertex from behind. Reciprocal: the reversed path
// (vertices reversed, scatter -> n-1-scatter, to_source and to_receiver
// swapped) gives the same value. Throws std::invalid_argument for an empty
// path, a scatter index out of range or a null material.
double PathRcsPerArea(const std::vector<PathVertex>& vertices, int scatter, const Eigen::Vector3d& to_source,
                      const Eigen::Vector3d& to_receiver, double wavelength_m, Polarization pol);

// The default material of each scene class (docs/radiometry.md names the
// source of every number): bare terrain (`default`) Oh 1992 on dry soil,
// forest the water-cloud model, water two-scale Bragg, urban ground, roads
// and buildings Oh 1992 with their permittivities and roughness.
Material DefaultMaterial(scene::ClassId id);

// Applies one class's overrides ({"model": "oh", "rms_height_m": 0.02, ...}
// or {"sigma0_db": [[0, -10], [90, -10]]}) to `m`. Keys: model, sigma0_db,
// permittivity ([eps', eps''], loss positive), rms_height_m, wind_speed_m_s,
// salinity_psu, canopy_gamma_db, canopy_cross_gamma_db,
// canopy_optical_depth, gain_db, source, diffuse, specular, roughness,
// mirror. Giving sigma0_db selects the table model. Throws ConfigError
// naming `where` + key and `source` for unknown keys and bad values.
void ApplyOverrides(Material& m, const nlohmann::json& fields, const std::string& where,
                    const std::string& source);

// The table of every scene class: defaults, overridden by `overrides`
// ({"water": {"diffuse": 0.02, ...}}). Throws ConfigError naming the key and
// `source` for unknown classes or keys, non-numbers and out-of-range values.
MaterialTable SceneMaterials(const nlohmann::json& overrides, const std::string& source);

// A materials file (JSON object of class name -> overrides, as above) read
// from `path`. Throws IoError / ConfigError naming the file.
nlohmann::json ReadMaterialsFile(const std::string& path);

}  // namespace gissar::material
