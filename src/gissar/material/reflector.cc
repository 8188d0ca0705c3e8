#include "gissar/material/reflector.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>

#include "gissar/util/error.h"
#include "gissar/util/number_text.h"

namespace gissar::material {
namespace {

constexpr double kDeg = M_PI / 180.0;

double Sinc(double x) { return std::abs(x) < 1e-12 ? 1.0 : std::sin(x) / x; }

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

}  // namespace

std::string ToString(ReflectorType type) { return std::string(kReflectorTypes.Name(type)); }

ReflectorType ParseReflectorType(const std::string& name, const std::string& where) {
  return kReflectorTypes.Parse<InputError>(name, where);
}

std::vector<ReflectorSpec> ReadReflectorsCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError("cannot read reflectors file", path);
  // The columns: the seven required ones in their default order, then the
  // optional roll.
  static const char* const kNames[8] = {"type",          "lon",   "lat",
                                        "apex_height_m", "size_m", "boresight_azimuth_deg",
                                        "boresight_elevation_deg", "roll_deg"};
  constexpr int kRequired = 7;
  const std::string listing = "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg";
  auto split = [](const std::string& t) {
    std::vector<std::string> fields;
    std::stringstream ss(t);
    std::string f;
    while (std::getline(ss, f, ',')) fields.push_back(Trim(f));
    return fields;
  };
  // column[k]: the field index of name k (-1: absent).
  int column[8] = {0, 1, 2, 3, 4, 5, 6, -1};
  size_t field_count = kRequired;
  std::vector<ReflectorSpec> out;
  std::string line;
  bool header = true;
  int row = 0;
  while (std::getline(in, line)) {
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    if (header) {
      header = false;
      // The header line: it starts with "type" or another column's name
      // (a row starts with a reflector type).
      const std::vector<std::string> names = split(t);
      const bool named = !names.empty() && std::find(std::begin(kNames), std::end(kNames), names[0]) != std::end(kNames);
      if (t.rfind("type", 0) == 0 || named) {
        std::fill(std::begin(column), std::end(column), -1);
        for (size_t i = 0; i < names.size(); ++i) {
          const auto* known = std::find(std::begin(kNames), std::end(kNames), names[i]);
          if (known == std::end(kNames)) {
            throw InputError("unknown column '" + names[i] + "' (" + listing + "[,roll_deg])", path + " header");
          }
          int& at = column[known - std::begin(kNames)];
          if (at >= 0) throw InputError("column '" + names[i] + "' appears twice", path + " header");
          at = static_cast<int>(i);
        }
        for (int k = 0; k < kRequired; ++k) {
          if (column[k] < 0) {
            throw InputError(std::string("missing column '") + kNames[k] + "' (" + listing + "[,roll_deg])",
                             path + " header");
          }
        }
        field_count = names.size();
        continue;
      }
    }
    ++row;
    const std::vector<std::string> fields = split(t);
    const std::string where = path + " row " + std::to_string(row);
    if (fields.size() != field_count) {
      throw InputError("expected " + std::to_string(field_count) + " fields (" +
                           (field_count == kRequired ? listing : std::string("as the header names")) + "), got " +
                           std::to_string(fields.size()),
                       where);
    }
    ReflectorSpec r;
    r.row = row;
    r.type = ParseReflectorType(fields[size_t(column[0])], where);
    double v[7] = {0, 0, 0, 0, 0, 0, 0};  // lon .. roll_deg
    for (int k = 1; k < 8; ++k) {
      if (column[k] < 0) continue;  // roll_deg absent: 0
      const std::string& field = fields[size_t(column[k])];
      const std::optional<double> value = util::ParseFiniteNumber(field);
      if (!value) throw InputError(std::string(kNames[k]) + " must be a number, got '" + field + "'", where);
      v[k - 1] = *value;
    }
    r.lon_deg = v[0], r.lat_deg = v[1], r.apex_height_m = v[2], r.size_m = v[3];
    r.boresight_azimuth_deg = v[4], r.boresight_elevation_deg = v[5], r.roll_deg = v[6];
    if (!(r.size_m > 0.0)) throw InputError("size_m must be > 0", where);
    if (std::abs(r.lat_deg) > 90.0) throw InputError("lat must be in [-90, 90]", where);
    if (std::abs(r.boresight_elevation_deg) > 90.0) {
      throw InputError("boresight_elevation_deg must be in [-90, 90]", where);
    }
    if (std::abs(r.roll_deg) > 360.0) throw InputError("roll_deg must be in [-360, 360]", where);
    out.push_back(r);
  }
  return out;
}

double PeakRcs(ReflectorType type, double a, double lambda) {
  const double a4 = a * a * a * a, l2 = lambda * lambda;
  switch (type) {
    case ReflectorType::kTrihedralSquare: return 12.0 * M_PI * a4 / l2;
    case ReflectorType::kDihedral: return 8.0 * M_PI * a4 / l2;
    case ReflectorType::kPlate: return 4.0 * M_PI * a4 / l2;
    default: return 4.0 * M_PI * a4 / (3.0 * l2);
  }
}

Eigen::Vector3d BoresightVector(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kDeg, el = elevation_deg * kDeg;
  return {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)};
}

double ReflectorRcs(ReflectorType type, double a, double lambda, const Eigen::Vector3d& boresight,
                    const Eigen::Vector3d& to_sensor) {
  const Eigen::Vector3d b = boresight.normalized(), s = to_sensor.normalized();
  const double cos_psi = std::clamp(b.dot(s), -1.0, 1.0);
  if (cos_psi <= 0.0) return 0.0;
  const double psi = std::acos(cos_psi);
  // Offsets: elevation difference, and the horizontal bearing difference
  // measured on the unit sphere (great-circle component).
  const double el_b = std::asin(std::clamp(b.z(), -1.0, 1.0)), el_s = std::asin(std::clamp(s.z(), -1.0, 1.0));
  const double epsilon = el_s - el_b;
  const double sin_alpha = std::clamp(std::sqrt(std::max(0.0, 1.0 - cos_psi * cos_psi -
                                                                    std::pow(std::sin(epsilon), 2.0))),
                                      0.0, 1.0);
  const double k = 2.0 * M_PI / lambda;
  const double peak = PeakRcs(type, a, lambda);
  switch (type) {
    case ReflectorType::kPlate:
      return peak * cos_psi * cos_psi * std::pow(Sinc(k * a * sin_alpha) * Sinc(k * a * std::sin(epsilon)), 2.0);
    case ReflectorType::kDihedral: {
      if (std::abs(epsilon) >= 45.0 * kDeg) return 0.0;
      const double f = std::sin(45.0 * kDeg - std::abs(epsilon)) / std::sin(45.0 * kDeg);
      return peak * f * f * (1.0 - sin_alpha * sin_alpha) * std::pow(Sinc(k * a * sin_alpha), 2.0);
    }
    default: {
      constexpr double kEdgeOn = 54.7356 * kDeg;
      if (psi >= kEdgeOn) return 0.0;
      const double g = cos_psi * (1.0 - psi / kEdgeOn);
      return peak * g * g;
    }
  }
}

}  // namespace gissar::material
