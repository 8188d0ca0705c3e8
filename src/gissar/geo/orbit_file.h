// Orbits and radar grids of any sensor, from plain files: the state vectors of
// a satellite's or an aircraft's track (CSV, JSON or an ESA Earth Explorer
// orbit file such as Sentinel-1's AUX_POEORB/RESORB .EOF) and the radar grid of
// the image to simulate (JSON). Together they stand in for a NISAR RSLC's
// geometry (geo::RslcProduct without an image), so `simulate --orbit
// --radar-grid` renders on the same zero-Doppler grid as `--product`.
//
// Frames and units: positions ECEF (WGS84) metres, velocities ECEF metres per
// second, times UTC (POSIX seconds, no leap seconds: util/utc_time.h).
//
// File formats (docs/geometry.md, "Orbits and radar grids from files"):
//  - CSV: a header naming the columns time_utc,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps
//    (any order, no other column); one state vector per row; '#' comments.
//  - JSON: {"state_vectors": [{"time_utc": "...", "position_m": [x, y, z],
//    "velocity_mps": [vx, vy, vz]}, ...]}.
//  - EOF XML: Earth_Explorer_File/Data_Block/List_of_OSVs/OSV with UTC, X, Y,
//    Z, VX, VY, VZ.
//  - Radar grid JSON: starting_range_m, range_spacing_m, sensing_start_utc,
//    azimuth_time_interval_s, width, length, look_side ("left"/"right"),
//    wavelength_m; all required, no other key.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/rslc_product.h"

namespace gissar::geo {

struct StateVectors {
  std::vector<double> utc_s;                  // POSIX seconds, strictly increasing
  std::vector<Eigen::Vector3d> position_m;    // ECEF
  std::vector<Eigen::Vector3d> velocity_mps;  // ECEF
  std::string format;                         // "csv", "json" or "eof"
};

// Fewest state vectors accepted (the cubic Hermite interpolation of
// sensor::Orbit needs two; four give a check of the spacing).
inline constexpr int kMinStateVectors = 4;
// A spacing larger than this multiple of the median spacing is a gap.
inline constexpr double kMaxStateVectorGapRatio = 3.0;

// Reads state vectors; the format follows the extension (.csv, .json, .eof or
// .xml), else the first character. Throws InputError naming the file (and row
// or element) when it is missing or malformed, a value is not finite, there
// are fewer than kMinStateVectors vectors, the times are not strictly
// increasing or a spacing exceeds kMaxStateVectorGapRatio x the median.
StateVectors ReadStateVectors(const std::filesystem::path& path);

struct RadarGridSpec {
  double starting_range_m = 0.0;         // slant range of column 0, > 0
  double range_spacing_m = 0.0;          // > 0
  std::string sensing_start_utc;         // zero-Doppler time of row 0
  double azimuth_time_interval_s = 0.0;  // > 0
  int width = 0;                         // columns (range bins), >= 1
  int length = 0;                        // rows (azimuth lines), >= 1
  bool look_left = false;
  double wavelength_m = 0.0;             // > 0
};

// Reads a radar grid JSON. Throws InputError naming the file and the key for
// a missing, unknown, mistyped or out-of-range key.
RadarGridSpec ReadRadarGrid(const std::filesystem::path& path);

// A product without an image: the grid of `grid` and the orbit of `vectors`
// (times as seconds since epoch_utc = midnight UTC of the sensing start's
// day), no attitude. Throws InputError naming `orbit_source` when the orbit
// does not cover the grid's zero-Doppler times (first to last line).
RslcProduct ProductFromOrbit(const StateVectors& vectors, const std::string& orbit_source,
                             const RadarGridSpec& grid, const std::string& grid_source);

// Writes `vectors` as CSV (time_utc with microseconds), for tests and users
// converting tracks. Throws IoError.
void WriteStateVectorsCsv(const std::filesystem::path& path, const StateVectors& vectors);

}  // namespace gissar::geo
