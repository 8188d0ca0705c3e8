// Canonical radar reflectors (docs/radiometry.md): trihedral corner
// reflectors (triangular and square faces), dihedrals and flat plates, with
// their physical-optics radar cross section at boresight and its fall-off
// away from it, and the reflector CSV of the command line.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/util/enum_table.h"

namespace gissar::material {

enum class ReflectorType { kTrihedral, kTrihedralSquare, kDihedral, kPlate };
// The `type` column of a reflectors CSV (docs/conventions.md).
inline constexpr auto kReflectorTypes = util::MakeEnumTable<ReflectorType>(
    "reflector type", {{ReflectorType::kTrihedral, "trihedral"},
                       {ReflectorType::kTrihedralSquare, "trihedral_square"},
                       {ReflectorType::kDihedral, "dihedral"},
                       {ReflectorType::kPlate, "plate"}});
std::string ToString(ReflectorType type);
// The type named `name` (kReflectorTypes). Throws InputError naming `where`
// (the file row) and the types for any other name.
ReflectorType ParseReflectorType(const std::string& name, const std::string& where);

// One row of a reflectors CSV:
// type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg[,roll_deg]
// type: trihedral, trihedral_square, dihedral, plate; size_m = a, the leg
// (trihedral) or side (dihedral plates, plate) length; apex (phase centre)
// height above the ground; boresight: from the reflector towards the
// sensor, compass bearing and elevation above the horizontal; roll_deg
// (optional, default 0): the reflector turned about its boresight, in the
// sense of scattering.h (turning the radar's h towards v: counter-clockwise
// as seen from the reflector looking back along its boresight); a
// dihedral's fold is horizontal at roll 0. It changes the polarimetric
// matrix only (material::ReflectorMatrix), not the RCS pattern.
struct ReflectorSpec {
  ReflectorType type = ReflectorType::kTrihedral;
  double lon_deg = 0.0, lat_deg = 0.0;
  double apex_height_m = 0.0;
  double size_m = 1.0;
  double boresight_azimuth_deg = 0.0;
  double boresight_elevation_deg = 0.0;
  double roll_deg = 0.0;
  int row = 0;  // 1-based data row in the file (header excluded), for messages
};

// Reads a reflectors CSV: an optional header line (the first non-comment
// line when it starts with "type" or another column's name) naming the
// columns, then one reflector
// per line; blank lines and lines starting with '#' skipped. The header
// names the seven columns above in any order, optionally roll_deg; every
// row has the header's number of fields. Without a header the rows are the
// seven columns in the order above (roll 0). Throws IoError when the file
// cannot be read, InputError naming the file for a header with an unknown,
// repeated or missing column, and InputError naming the file and the row
// for an unknown type, a missing or non-numeric field, size <= 0, latitude
// outside [-90, 90], elevation outside [-90, 90] or a roll outside
// [-360, 360].
std::vector<ReflectorSpec> ReadReflectorsCsv(const std::string& path);

// Peak (boresight) radar cross section, m^2, of size a at wavelength lambda:
// triangular trihedral 4 pi a^4 / (3 lambda^2), square trihedral
// 12 pi a^4 / lambda^2, dihedral 8 pi a^4 / lambda^2, plate 4 pi a^4 / lambda^2.
double PeakRcs(ReflectorType type, double size_m, double wavelength_m);

// Unit boresight vector (ENU) of a compass bearing and an elevation.
Eigen::Vector3d BoresightVector(double azimuth_deg, double elevation_deg);

// Radar cross section (m^2) seen from the unit direction `to_sensor`
// (ENU, from the reflector) for a reflector whose boresight is `boresight`:
// the peak times a physical-optics pattern of the off-boresight angles
// (horizontal offset alpha, vertical offset epsilon, total psi):
//  - plate: cos^2(psi) sinc^2(k a sin alpha) sinc^2(k a sin epsilon);
//  - dihedral (fold horizontal): (sin(45 deg - |epsilon|) / sin 45 deg)^2 for
//    |epsilon| < 45 deg (the doubly-reflecting area) times
//    cos^2(alpha) sinc^2(k a sin alpha);
//  - trihedrals: effective area (cos psi (1 - psi / 54.74 deg))^2 for psi
//    below 54.74 deg, where one face turns edge-on.
// k = 2 pi / lambda, sinc x = sin x / x. 0 behind the reflector.
double ReflectorRcs(ReflectorType type, double size_m, double wavelength_m, const Eigen::Vector3d& boresight,
                    const Eigen::Vector3d& to_sensor);

}  // namespace gissar::material
