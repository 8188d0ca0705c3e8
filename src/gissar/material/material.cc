#include "gissar/material/material.h"

#include <algorithm>
#include <bit>
#include <map>
#include <mutex>
#include <cctype>
#include <cmath>
#include <fstream>
#include <optional>
#include <stdexcept>

#include "gissar/util/error.h"

namespace gissar::material {
namespace {

using cd = std::complex<double>;
constexpr double kDeg = M_PI / 180.0;
constexpr double kGravity = 9.81;  // m/s^2
constexpr double kLightSpeed = 299792458.0;

// Fresnel power reflectivities (H, V) of a half-space of permittivity eps
// at incidence theta (radians).
std::pair<double, double> Fresnel(cd eps, double theta) {
  const double c = std::cos(theta), s2 = std::sin(theta) * std::sin(theta);
  const cd root = std::sqrt(eps - s2);
  const double gh = std::norm((c - root) / (c + root));
  const double gv = std::norm((eps * c - root) / (eps * c + root));
  return {gh, gv};
}

// Oh, Sarabandi & Ulaby (1992), IEEE TGRS 30(2) 370-381: the empirical
// model of bare-soil backscatter from the Fresnel reflectivities and ks.
double OhSigma0(cd eps, double rms_height_m, double theta, double wavelength_m, Polarization pol) {
  const double ks = 2.0 * M_PI / wavelength_m * rms_height_m;
  const cd root = std::sqrt(eps);
  const double gamma0 = std::norm((1.0 - root) / (1.0 + root));
  const auto [gh, gv] = Fresnel(eps, theta);
  const double g = 0.7 * (1.0 - std::exp(-0.65 * std::pow(ks, 1.8)));
  const double sqrt_p =
      std::max(1e-6, 1.0 - std::pow(2.0 * theta / M_PI, 1.0 / (3.0 * gamma0)) * std::exp(-ks));
  const double q = 0.23 * std::sqrt(gamma0) * (1.0 - std::exp(-ks));
  const double c3 = std::pow(std::cos(theta), 3.0);
  const double vv = g * c3 * (gv + gh) / sqrt_p;
  switch (pol) {
    case Polarization::kVV:
      return vv;
    case Polarization::kHH:
      return g * sqrt_p * c3 * (gv + gh);
    default:
      return q * vv;
  }
}

// First-order small-perturbation (Bragg) coefficients g_HH, g_VV
// (Valenzuela 1978).
std::pair<cd, cd> BraggCoefficients(cd eps, double theta) {
  const double c = std::cos(theta), s2 = std::sin(theta) * std::sin(theta);
  const cd root = std::sqrt(eps - s2);
  const cd ghh = (eps - 1.0) / ((c + root) * (c + root));
  const cd gvv = (eps - 1.0) * (eps * (1.0 + s2) - s2) / ((eps * c + root) * (eps * c + root));
  return {ghh, gvv};
}

// Two-scale sea/water backscatter: Bragg (SPM) on the Elfouhaily spectrum
// averaged over the large-scale slopes in the incidence plane, plus the
// geometric-optics (Kirchhoff) quasi-specular term; Cox & Munk (1954)
// clean-surface mean-square slope.
double BraggSigma0(const Material& m, double theta, double wavelength_m, Polarization pol) {
  const cd eps = WaterPermittivity(wavelength_m, m.salinity_psu);
  const double k = 2.0 * M_PI / wavelength_m;
  const double mss = 0.003 + 0.00512 * m.wind_speed_m_s;
  const double s = std::sqrt(0.5 * mss);  // slope std per direction
  auto spm = [&](double t) {
    t = std::max(std::abs(t), 10.0 * kDeg);  // SPM is not valid near nadir
    const auto [ghh, gvv] = BraggCoefficients(eps, t);
    const double b = ElfouhailyCurvature(2.0 * k * std::sin(t), m.wind_speed_m_s);
    // sigma0 = 16 pi k^4 cos^4 |g|^2 Psi(K) (Wright 1968, Valenzuela 1978)
    // with the isotropic Elfouhaily spectrum Psi(K) = B(K) / (2 pi K^4),
    // K = 2 k sin(theta): cos^4 |g|^2 B / (2 sin^4).
    const double geom = std::pow(std::cos(t), 4.0) / (2.0 * std::pow(std::sin(t), 4.0)) * b;
    switch (pol) {
      case Polarization::kVV:
        return std::norm(gvv) * geom;
      case Polarization::kHH:
        return std::norm(ghh) * geom;
      default:
        return 0.5 * mss * std::norm(gvv - ghh) * geom;  // out-of-plane tilts
    }
  };
  constexpr int kSteps = 41;
  double sum = 0.0, wsum = 0.0;
  for (int i = 0; i < kSteps; ++i) {
    const double z = -3.0 + 6.0 * i / (kSteps - 1);
    const double w = std::exp(-0.5 * z * z);
    sum += w * spm(theta - std::atan(z * s));
    wsum += w;
  }
  double sigma = sum / wsum;
  if (pol == Polarization::kHH || pol == Polarization::kVV) {
    const cd root = std::sqrt(eps);
    const double r0 = std::norm((1.0 - root) / (1.0 + root));
    const double t2 = std::tan(theta) * std::tan(theta);
    sigma += r0 * std::exp(-t2 / mss) / (mss * std::pow(std::cos(theta), 4.0));
  }
  return sigma;
}

double TableSigma0(const std::vector<std::pair<double, double>>& table, double theta_deg) {
  if (theta_deg <= table.front().first) return std::pow(10.0, table.front().second / 10.0);
  if (theta_deg >= table.back().first) return std::pow(10.0, table.back().second / 10.0);
  const auto it = std::upper_bound(table.begin(), table.end(), theta_deg,
                                   [](double v, const std::pair<double, double>& p) { return v < p.first; });
  const auto& [x1, y1] = *it;
  const auto& [x0, y0] = *(it - 1);
  const double db = y0 + (y1 - y0) * (theta_deg - x0) / (x1 - x0);
  return std::pow(10.0, db / 10.0);
}

constexpr double kTableStepDeg = Sigma0Table::kStepDeg;
constexpr int kTableSamples = Sigma0Table::kSamples;

}  // namespace

double FresnelReflectivity(std::complex<double> eps, double cos_incidence, Polarization pol) {
  if (!(cos_incidence > 0.0)) return 0.0;
  const double theta = std::acos(std::min(1.0, cos_incidence));
  const auto [gh, gv] = Fresnel(eps, theta);
  switch (pol) {
    case Polarization::kHH: return gh;
    case Polarization::kVV: return gv;
    default: return 0.5 * (gh + gv);
  }
}

double VerticalTeShare(const Eigen::Vector3d& dir, const Eigen::Vector3d& normal) {
  Eigen::Vector3d s = dir.cross(normal);
  const double s_norm = s.norm();
  if (!(s_norm > 1e-9)) return 0.5;  // normal incidence: TE and TM reflect alike
  s /= s_norm;
  Eigen::Vector3d h = dir.cross(Eigen::Vector3d::UnitZ());
  if (!(h.norm() > 1e-9)) h = dir.cross(Eigen::Vector3d::UnitX());
  h.normalize();
  const double hs = h.dot(s);
  return std::clamp(1.0 - hs * hs, 0.0, 1.0);
}

double OrientedFresnelReflectivity(std::complex<double> eps, double cos_incidence, const Eigen::Vector3d& dir_in,
                                   const Eigen::Vector3d& dir_out, const Eigen::Vector3d& normal, Polarization pol) {
  if (!(cos_incidence > 0.0)) return 0.0;
  const double theta = std::acos(std::min(1.0, cos_incidence));
  const auto [gh, gv] = Fresnel(eps, theta);  // |Gamma_TE|^2, |Gamma_TM|^2
  const double t = 0.5 * (VerticalTeShare(dir_in, normal) + VerticalTeShare(dir_out, normal));
  switch (pol) {
    case Polarization::kHH: return gh * (1.0 - t) + gv * t;
    case Polarization::kVV: return gh * t + gv * (1.0 - t);
    default: return 0.5 * (gh + gv);
  }
}

double Material::MirrorReflectivity(double cos_incidence, const Eigen::Vector3d& dir_in,
                                    const Eigen::Vector3d& dir_out, const Eigen::Vector3d& normal,
                                    double wavelength_m, Polarization pol) const {
  if (!(mirror > 0.0)) return 0.0;
  return mirror * OrientedFresnelReflectivity(EffectivePermittivity(wavelength_m), cos_incidence, dir_in, dir_out,
                                              normal, pol);
}

std::complex<double> Material::EffectivePermittivity(double wavelength_m) const {
  return model == ScatteringModel::kBragg ? WaterPermittivity(wavelength_m, salinity_psu) : permittivity;
}

double Material::MirrorReflectivity(double cos_incidence, double wavelength_m, Polarization pol) const {
  if (!(mirror > 0.0)) return 0.0;
  return mirror * FresnelReflectivity(EffectivePermittivity(wavelength_m), cos_incidence, pol);
}

double Material::BistaticSigma0(double cos_in, double cos_out, double cos_spec) const {
  if (!(cos_in > 0.0) || !(cos_out > 0.0)) return 0.0;
  double value = diffuse * cos_in * cos_out;
  if (specular > 0.0 && cos_spec > 0.0) {
    value += specular * std::pow(std::min(1.0, cos_spec), 1.0 / roughness) * std::sqrt(cos_in * cos_out);
  }
  return 4.0 * value * std::pow(10.0, gain_db / 10.0);
}

double PathRcsPerArea(const std::vector<PathVertex>& vertices, int scatter, const Eigen::Vector3d& to_source,
                      const Eigen::Vector3d& to_receiver, double wavelength_m, Polarization pol) {
  const int n = static_cast<int>(vertices.size());
  if (n == 0 || scatter < 0 || scatter >= n) throw std::invalid_argument("PathRcsPerArea: bad path or scatter index");
  double value = 1.0;
  for (int i = 0; i < n; ++i) {
    const PathVertex& v = vertices[i];
    if (v.material == nullptr) throw std::invalid_argument("PathRcsPerArea: vertex without material");
    // Unit directions from this vertex back along the incoming segment and
    // on along the outgoing one.
    const Eigen::Vector3d back = i == 0 ? to_source : (vertices[i - 1].point - v.point).normalized();
    const Eigen::Vector3d on = i == n - 1 ? to_receiver : (vertices[i + 1].point - v.point).normalized();
    const double cos_in = v.normal.dot(back), cos_out = v.normal.dot(on);
    if (!(cos_in > 0.0) || !(cos_out > 0.0)) return 0.0;
    if (i == scatter) {
      const Eigen::Vector3d mirror_dir = 2.0 * cos_in * v.normal - back;  // mirror image of the incident ray
      value *= v.material->BistaticSigma0(cos_in, cos_out, mirror_dir.dot(on));
    } else {
      // Incidence: half the angle between the two directions (exact for a
      // mirror geometry, where back . on = cos(2 theta)).
      const double cos_half = std::sqrt(std::max(0.0, 0.5 * (1.0 + back.dot(on))));
      value *= v.material->MirrorReflectivity(cos_half, -back, on, v.normal, wavelength_m, pol);
    }
  }
  return value;
}

Polarization ParsePolarization(const std::string& text, const std::string& option) {
  return kPolarizations.Parse(text, option);
}

std::vector<Polarization> ParsePolarizationList(const std::string& text, const std::string& option) {
  std::string lower = text;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == "quad") return {Polarization::kHH, Polarization::kHV, Polarization::kVH, Polarization::kVV};
  std::vector<Polarization> channels;
  size_t start = 0;
  while (true) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::optional<Polarization> found = kPolarizations.Find(item);
    if (!found) throw ConfigError(kPolarizations.UnknownMessage(item) + ", a comma list of them, or quad", option);
    const Polarization pol = *found;
    if (std::find(channels.begin(), channels.end(), pol) != channels.end()) {
      throw ConfigError("channel " + ToString(pol) + " is given twice in '" + text + "'", option);
    }
    channels.push_back(pol);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return channels;
}

std::string ToString(const std::vector<Polarization>& channels) {
  if (channels == std::vector<Polarization>{Polarization::kHH, Polarization::kHV, Polarization::kVH,
                                            Polarization::kVV}) {
    return "quad";
  }
  std::string out;
  for (const Polarization pol : channels) out += (out.empty() ? "" : ",") + ToString(pol);
  return out;
}

std::string ToString(Polarization pol) { return std::string(kPolarizations.Name(pol)); }

std::string ToString(ScatteringModel model) { return std::string(kScatteringModels.Name(model)); }

std::complex<double> WaterPermittivity(double wavelength_m, double salinity_psu) {
  // Debye relaxation at 20 deg C; static permittivity and relaxation time
  // fall linearly with salinity (Klein & Swift 1977 at 35 psu: 71.6,
  // 9.0 ps, 4.8 S/m).
  const double f = salinity_psu / 35.0;
  const double eps_s = 80.1 - f * (80.1 - 71.6);
  const double tau = 9.36e-12 - f * (9.36e-12 - 9.0e-12);
  const double sigma_ionic = 4.8 * f;
  constexpr double kEpsInf = 4.9, kEps0 = 8.854187817e-12;
  const double omega = 2.0 * M_PI * kLightSpeed / wavelength_m;
  cd eps = kEpsInf + (eps_s - kEpsInf) / cd(1.0, omega * tau);
  eps -= cd(0.0, sigma_ionic / (omega * kEps0));
  return eps;
}

double ElfouhailyCurvature(double k, double u10) {
  if (!(u10 > 0.0) || !(k > 0.0)) return 0.0;
  constexpr double kOmega = 0.84;  // inverse wave age, fully developed sea
  constexpr double kCm = 0.23;     // m/s, minimum phase speed
  constexpr double kKm = 370.0;    // rad/m
  const double kp = kGravity * kOmega * kOmega / (u10 * u10);
  const double cp = std::sqrt(kGravity / kp);
  const double c = std::sqrt(kGravity / k * (1.0 + (k / kKm) * (k / kKm)));
  // Long waves.
  const double alpha_p = 6e-3 * std::sqrt(kOmega);
  const double gamma = kOmega <= 1.0 ? 1.7 : 1.7 + 6.0 * std::log(kOmega);
  const double sigma_j = 0.08 * (1.0 + 4.0 * std::pow(kOmega, -3.0));
  const double big_gamma = std::exp(-std::pow(std::sqrt(k / kp) - 1.0, 2.0) / (2.0 * sigma_j * sigma_j));
  const double lpm = std::exp(-1.25 * (kp / k) * (kp / k));
  const double jp = std::pow(gamma, big_gamma);
  const double fp = lpm * jp * std::exp(-kOmega / std::sqrt(10.0) * (std::sqrt(k / kp) - 1.0));
  const double bl = 0.5 * alpha_p * (cp / c) * fp;
  // Short waves; friction velocity from the Wu (1982) drag coefficient.
  const double ustar = std::sqrt((0.8 + 0.065 * u10) * 1e-3) * u10;
  const double alpha_m = std::max(1e-5, ustar <= kCm ? 0.01 * (1.0 + std::log(ustar / kCm))
                                                      : 0.01 * (1.0 + 3.0 * std::log(ustar / kCm)));
  const double fm = std::exp(-0.25 * std::pow(k / kKm - 1.0, 2.0));
  const double bh = 0.5 * alpha_m * (kCm / c) * fm * lpm * jp;
  return bl + bh;
}

double Material::Backscatter(double cos_incidence) const {
  if (cos_incidence <= 0.0) return 0.0;
  double value = diffuse * cos_incidence;
  if (specular > 0.0) {
    const double cos_mirror = 2.0 * cos_incidence * cos_incidence - 1.0;  // cos(2 theta)
    if (cos_mirror > 0.0) value += specular * std::pow(cos_mirror, 1.0 / roughness);
  }
  return value;
}

double Material::Sigma0(double cos_incidence, double wavelength_m, Polarization pol) const {
  if (cos_incidence <= 0.0) return 0.0;
  const double theta = std::acos(std::min(1.0, cos_incidence));
  double sigma = 0.0;
  switch (model) {
    case ScatteringModel::kLambert:
      sigma = 4.0 * cos_incidence * Backscatter(cos_incidence);
      if (pol == Polarization::kHV || pol == Polarization::kVH) sigma = 0.0;
      break;
    case ScatteringModel::kTable:
      sigma = TableSigma0(sigma0_db, theta / kDeg);
      break;
    case ScatteringModel::kOh:
      sigma = OhSigma0(permittivity, rms_height_m, theta, wavelength_m, pol);
      break;
    case ScatteringModel::kBragg:
      sigma = BraggSigma0(*this, theta, wavelength_m, pol);
      break;
    case ScatteringModel::kWaterCloud: {
      const bool cross = pol == Polarization::kHV || pol == Polarization::kVH;
      const double gamma = std::pow(10.0, (cross ? canopy_cross_gamma_db : canopy_gamma_db) / 10.0);
      const double tau2 = std::exp(-2.0 * canopy_optical_depth / cos_incidence);
      sigma = gamma * cos_incidence * (1.0 - tau2) +
              tau2 * OhSigma0(permittivity, rms_height_m, theta, wavelength_m, pol);
      break;
    }
  }
  return sigma * std::pow(10.0, gain_db / 10.0);
}

void Material::Check() const {
  const std::pair<const char*, double> coefficients[] = {
      {"diffuse", diffuse}, {"specular", specular}, {"mirror", mirror}};
  for (const auto& [key, value] : coefficients) {
    if (!std::isfinite(value) || value < 0.0 || value > 1.0) {
      throw ConfigError(std::string(key) + " must be in [0, 1], is " + std::to_string(value),
                        "material " + name);
    }
  }
  if (!std::isfinite(roughness) || roughness <= 0.0 || roughness > 1.0) {
    throw ConfigError("roughness must be in (0, 1], is " + std::to_string(roughness),
                      "material " + name);
  }
  if (diffuse + mirror > 1.0 + 1e-12) {
    throw ConfigError("diffuse + mirror must be <= 1 (albedo above 1 creates energy), is " +
                          std::to_string(diffuse + mirror),
                      "material " + name);
  }
  if (model == ScatteringModel::kTable) {
    if (sigma0_db.empty()) throw ConfigError("sigma0_db needs at least one row", "material " + name);
    for (size_t i = 0; i < sigma0_db.size(); ++i) {
      const auto& [inc, db] = sigma0_db[i];
      if (!std::isfinite(inc) || inc < 0.0 || inc > 90.0 || !std::isfinite(db) ||
          (i > 0 && !(inc > sigma0_db[i - 1].first))) {
        throw ConfigError("sigma0_db row " + std::to_string(i) +
                              ": incidence must increase within [0, 90] deg and dB be finite",
                          "material " + name);
      }
    }
  }
  if (!(permittivity.real() >= 1.0) || !(permittivity.imag() <= 0.0) || !std::isfinite(permittivity.real()) ||
      !std::isfinite(permittivity.imag())) {
    throw ConfigError("permittivity must have eps' >= 1 and loss eps'' >= 0", "material " + name);
  }
  if (!(rms_height_m > 0.0 && rms_height_m < 1.0)) {
    throw ConfigError("rms_height_m must be in (0, 1) m", "material " + name);
  }
  if (!(wind_speed_m_s >= 0.0 && wind_speed_m_s <= 50.0)) {
    throw ConfigError("wind_speed_m_s must be in [0, 50]", "material " + name);
  }
  if (!(salinity_psu >= 0.0 && salinity_psu <= 45.0)) {
    throw ConfigError("salinity_psu must be in [0, 45]", "material " + name);
  }
  if (!(canopy_optical_depth >= 0.0 && canopy_optical_depth < 100.0) || !std::isfinite(canopy_gamma_db) ||
      !std::isfinite(canopy_cross_gamma_db) || !std::isfinite(gain_db)) {
    throw ConfigError("canopy/gain parameters must be finite (optical depth >= 0)", "material " + name);
  }
}

nlohmann::json Material::ToJson() const {
  nlohmann::json j = {{"model", ToString(model)}, {"diffuse", diffuse}, {"specular", specular},
                      {"roughness", roughness}, {"mirror", mirror}, {"gain_db", gain_db}};
  switch (model) {
    case ScatteringModel::kTable: {
      nlohmann::json rows = nlohmann::json::array();
      for (const auto& [inc, db] : sigma0_db) rows.push_back({inc, db});
      j["sigma0_db"] = rows;
      break;
    }
    case ScatteringModel::kWaterCloud:
      j["canopy_gamma_db"] = canopy_gamma_db;
      j["canopy_cross_gamma_db"] = canopy_cross_gamma_db;
      j["canopy_optical_depth"] = canopy_optical_depth;
      [[fallthrough]];
    case ScatteringModel::kOh:
      j["permittivity"] = {permittivity.real(), -permittivity.imag()};
      j["rms_height_m"] = rms_height_m;
      break;
    case ScatteringModel::kBragg:
      j["wind_speed_m_s"] = wind_speed_m_s;
      j["salinity_psu"] = salinity_psu;
      break;
    default:
      break;
  }
  if (!source.empty()) j["source"] = source;
  return j;
}

Sigma0Table::Sigma0Table(const Material& material, double wavelength_m, Polarization pol)
    : samples_(kTableSamples + 1) {
  for (int i = 0; i <= kTableSamples; ++i) {
    const double theta = i * kTableStepDeg * kDeg;
    samples_[i] = i == kTableSamples ? 0.0f
                                     : static_cast<float>(material.Sigma0(std::cos(theta), wavelength_m, pol));
  }
  // The fast table read from the angle table, not from the law: a law can
  // cost microseconds per evaluation (water's Fresnel terms), and the
  // tracer builds its tables at every render.
  fast_.resize(kFastSamples + 1);
  for (int i = 0; i <= kFastSamples; ++i) {
    const double s = double(i) / kFastSamples;
    fast_[i] = static_cast<float>((*this)(1.0 - s * s));
  }
}

// The Sigma0Tables of one set of materials, by (wavelength bits, polarisation).
struct MaterialTable::TableCache {
  static constexpr size_t kMaxEntries = 8;
  std::mutex mutex;
  std::map<std::pair<uint64_t, int>, std::vector<Sigma0Table>> tables;
};

MaterialTable::MaterialTable()
    : materials_(1, DefaultMaterial(scene::kClassDefault)), tables_(std::make_shared<TableCache>()) {}

void MaterialTable::Set(scene::ClassId id, Material material) {
  material.Check();
  if (id >= materials_.size()) materials_.resize(size_t(id) + 1, materials_[0]);
  materials_[id] = std::move(material);
  tables_ = std::make_shared<TableCache>();  // other copies keep theirs
}

const Material& MaterialTable::Get(scene::ClassId id) const {
  return id < materials_.size() ? materials_[id] : materials_[0];
}

std::vector<Sigma0Table> MaterialTable::Tables(double wavelength_m, Polarization pol) const {
  const std::pair<uint64_t, int> key{std::bit_cast<uint64_t>(wavelength_m), static_cast<int>(pol)};
  {
    std::lock_guard<std::mutex> lock(tables_->mutex);
    const auto found = tables_->tables.find(key);
    if (found != tables_->tables.end()) return found->second;
  }
  std::vector<Sigma0Table> tables;
  tables.reserve(materials_.size());
  for (const Material& m : materials_) tables.emplace_back(m, wavelength_m, pol);
  std::lock_guard<std::mutex> lock(tables_->mutex);
  if (tables_->tables.size() >= TableCache::kMaxEntries) tables_->tables.clear();
  tables_->tables.emplace(key, tables);
  return tables;
}

nlohmann::json MaterialTable::ToJson() const {
  nlohmann::json j = nlohmann::json::object();
  for (const Material& m : materials_) j[m.name] = m.ToJson();
  return j;
}

Material DefaultMaterial(scene::ClassId id) {
  Material m;
  m.model = ScatteringModel::kOh;
  // The sea (its own class, separate from inland water, where the scene
  // module defines it): two-scale Bragg on salt water.
  if (id < scene::ClassNames().size() && scene::ClassNames()[id] == "sea") {
    m.name = "sea";
    m.diffuse = 0.03, m.specular = 0.9, m.roughness = 0.05, m.mirror = 0.9;
    m.model = ScatteringModel::kBragg;
    m.wind_speed_m_s = 3.0;
    m.salinity_psu = 35.0;
    m.source = "two-scale Bragg on the Elfouhaily et al. 1997 spectrum, wind 3 m/s; Debye sea water "
               "(Klein & Swift 1977, 35 psu)";
    return m;
  }
  switch (id) {
    case scene::kClassWater:
      m.name = "water";
      m.diffuse = 0.03, m.specular = 0.9, m.roughness = 0.05, m.mirror = 0.9;
      m.model = ScatteringModel::kBragg;
      m.wind_speed_m_s = 3.0;
      m.salinity_psu = 0.0;
      m.source = "two-scale Bragg on the Elfouhaily et al. 1997 spectrum, wind 3 m/s; Debye fresh water";
      break;
    case scene::kClassForest:
      m.name = "forest";
      m.diffuse = 0.85, m.specular = 0.05, m.roughness = 1.0, m.mirror = 0.0;
      m.model = ScatteringModel::kWaterCloud;
      m.canopy_gamma_db = -6.5;
      m.canopy_cross_gamma_db = -12.5;
      m.canopy_optical_depth = 1.0;
      m.permittivity = {10.0, -2.0};
      m.rms_height_m = 0.02;
      m.source = "water-cloud model (Attema & Ulaby 1978); opaque-canopy gamma -6.5 dB co-pol, -12.5 dB "
                 "cross-pol (C-band tropical forest calibration value)";
      break;
    case scene::kClassUrban:
      m.name = "urban";
      m.diffuse = 0.6, m.specular = 0.3, m.roughness = 0.3, m.mirror = 0.3;
      m.permittivity = {6.0, -0.5};
      m.rms_height_m = 0.015;
      m.source = "Oh et al. 1992, concrete/soil mix eps 6-0.5j, rms height 1.5 cm";
      break;
    case scene::kClassRoad:
      m.name = "road";
      m.diffuse = 0.12, m.specular = 0.6, m.roughness = 0.1, m.mirror = 0.5;
      m.permittivity = {4.5, -0.2};
      m.rms_height_m = 0.002;
      m.source = "Oh et al. 1992, asphalt eps 4.5-0.2j, rms height 2 mm";
      break;
    case scene::kClassBuilding:
      m.name = "building";
      m.diffuse = 0.3, m.specular = 0.6, m.roughness = 0.15, m.mirror = 0.7;
      m.permittivity = {6.0, -0.5};
      m.rms_height_m = 0.005;
      m.source = "Oh et al. 1992, concrete eps 6-0.5j, rms height 5 mm";
      break;
    default:
      m.name = "default";
      m.diffuse = 0.5, m.specular = 0.1, m.roughness = 0.6, m.mirror = 0.0;
      m.permittivity = {6.0, -1.0};
      m.rms_height_m = 0.01;
      m.source = "Oh et al. 1992, dry soil eps 6-1j, rms height 1 cm";
      break;
  }
  return m;
}

void ApplyOverrides(Material& m, const nlohmann::json& fields, const std::string& where,
                    const std::string& source) {
  if (!fields.is_object()) throw ConfigError("'" + where + "' must be an object", source);
  bool model_given = false;
  for (const auto& [key, value] : fields.items()) {
    const std::string at = where + "." + key;
    // (The binding through an init-capture: clang 14, the fuzz build's
    // compiler, cannot capture a structured binding.)
    auto number = [&, &value = value]() {
      if (!value.is_number()) throw ConfigError("'" + at + "' must be a number", source);
      return value.get<double>();
    };
    if (key == "model") {
      if (!value.is_string()) throw ConfigError("'" + at + "' must be a string", source);
      const std::string s = value.get<std::string>();
      const std::optional<ScatteringModel> model = kScatteringModels.Find(s);
      if (!model) throw ConfigError(kScatteringModels.UnknownMessage(s) + " at '" + at + "'", source);
      m.model = *model;
      model_given = true;
    } else if (key == "sigma0_db") {
      if (!value.is_array() || value.empty()) {
        throw ConfigError("'" + at + "' must be a list of [incidence_deg, dB] pairs", source);
      }
      m.sigma0_db.clear();
      for (const auto& row : value) {
        if (!row.is_array() || row.size() != 2 || !row[0].is_number() || !row[1].is_number()) {
          throw ConfigError("'" + at + "' must be a list of [incidence_deg, dB] pairs", source);
        }
        m.sigma0_db.emplace_back(row[0].get<double>(), row[1].get<double>());
      }
      if (!model_given) m.model = ScatteringModel::kTable;
    } else if (key == "permittivity") {
      if (!value.is_array() || value.size() != 2 || !value[0].is_number() || !value[1].is_number()) {
        throw ConfigError("'" + at + "' must be [eps', eps''] (loss positive)", source);
      }
      m.permittivity = {value[0].get<double>(), -value[1].get<double>()};
    } else if (key == "source") {
      if (!value.is_string()) throw ConfigError("'" + at + "' must be a string", source);
      m.source = value.get<std::string>();
    } else if (key == "diffuse") {
      m.diffuse = number();
    } else if (key == "specular") {
      m.specular = number();
    } else if (key == "roughness") {
      m.roughness = number();
    } else if (key == "mirror") {
      m.mirror = number();
    } else if (key == "rms_height_m") {
      m.rms_height_m = number();
    } else if (key == "wind_speed_m_s") {
      m.wind_speed_m_s = number();
    } else if (key == "salinity_psu") {
      m.salinity_psu = number();
    } else if (key == "canopy_gamma_db") {
      m.canopy_gamma_db = number();
    } else if (key == "canopy_cross_gamma_db") {
      m.canopy_cross_gamma_db = number();
    } else if (key == "canopy_optical_depth") {
      m.canopy_optical_depth = number();
    } else if (key == "gain_db") {
      m.gain_db = number();
    } else {
      throw ConfigError("unknown key '" + at + "'", source);
    }
  }
  try {
    m.Check();
  } catch (const ConfigError& e) {
    throw ConfigError("'" + where + "': " + e.message(), source);
  }
}

MaterialTable SceneMaterials(const nlohmann::json& overrides, const std::string& source) {
  MaterialTable table;
  for (int c = 0; c < scene::kClassCount; ++c) table.Set(c, DefaultMaterial(c));
  if (overrides.is_null()) return table;
  if (!overrides.is_object()) throw ConfigError("'materials' must be an object", source);
  for (const auto& [name, fields] : overrides.items()) {
    const auto id = scene::ClassIdFromName(name);
    if (!id) throw ConfigError("unknown key 'materials." + name + "' (not a class)", source);
    Material m = table.Get(*id);
    ApplyOverrides(m, fields, "materials." + name, source);
    table.Set(*id, m);
  }
  return table;
}

nlohmann::json ReadMaterialsFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError("cannot read materials file", path);
  try {
    nlohmann::json j = nlohmann::json::parse(in);
    if (!j.is_object()) throw ConfigError("a materials file is an object of class name -> parameters", path);
    return j;
  } catch (const nlohmann::json::exception& e) {
    // Not only parse_error: a number too large for a double ("1e999") is an
    // out_of_range from the parser.
    throw ConfigError(std::string("not valid JSON: ") + e.what(), path);
  }
}

}  // namespace gissar::material
