// NISAR-format RSLC products (HDF5, JPL D-102268 layout, as written by ISCE3
// and by the UAVSAR-to-NISAR converter): the radar grid (zero-Doppler azimuth
// time and slant range), the orbit state vectors, the attitude, the carrier
// and look side, and one SLC layer, read through libhdf5. The geometry
// maths lives in sensor/range_doppler.h; this is only the reader (and a
// writer of minimal products for tests and synthetic data).
//
// Conventions: all times are seconds since the product's reference epoch
// (`epoch_utc`, the "seconds since ..." of the zeroDopplerTime units; the
// orbit and attitude times are converted to it when their own epoch
// differs). Positions and velocities are ECEF (WGS84) metres and metres per
// second. Images are row-major: row = azimuth line (time increasing), column
// = slant-range bin (range increasing).
#pragma once

#include <complex>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace gissar::geo {

struct RslcOrbit {
  std::vector<double> time_s;                // strictly increasing
  std::vector<Eigen::Vector3d> position_m;   // ECEF
  std::vector<Eigen::Vector3d> velocity_mps; // ECEF
  std::string type;                          // "POE", "MOE", ... as stored
};

struct RslcAttitude {
  std::vector<double> time_s;
  std::vector<Eigen::Vector4d> quaternion;  // (q0, q1, q2, q3) as stored
  std::vector<Eigen::Vector3d> euler_deg;   // as stored (may be all zero)
};

// A 2-D calibration look-up table of the product
// (metadata/calibrationInformation): values on a (zero-Doppler time, slant
// range) grid. The beta0 LUT is read as the linear factor that turns |DN|^2
// into beta0 (beta0 = LUT x |DN|^2; NISAR RSLCs are beta0-calibrated by
// design and store 1 there).
struct RslcCalibrationLut {
  std::string dataset;                // HDF5 path of the values
  std::vector<double> time_s;         // seconds since the product's epoch, increasing
  std::vector<double> slant_range_m;  // increasing
  std::vector<double> values;         // time_s.size() x slant_range_m.size(), row-major
  // Bilinear value at (time_s, slant_range_m), clamped to the table's
  // extent (the edge value beyond it; a single row or column is constant
  // along that axis).
  double At(double time_s, double slant_range_m) const;
};

struct RslcProduct {
  std::string path;
  std::string mission;              // identification/missionId (may be empty)
  std::string product_version;      // identification/productVersion
  std::string epoch_utc;            // reference epoch of every time, "YYYY-MM-DD hh:mm:ss"
  std::string frequency = "A";      // frequency band read ("A" or "B")
  std::string polarization = "HH";  // SLC layer read
  std::vector<std::string> polarizations;  // layers listed for that band
  // Radar grid: line i at zero_doppler_time_s[i], bin j at slant_range_m[j].
  std::vector<double> zero_doppler_time_s;  // strictly increasing, uniform
  std::vector<double> slant_range_m;        // strictly increasing, uniform
  double center_frequency_hz = 0.0;         // processedCenterFrequency
  double wavelength_m = 0.0;                // c / center_frequency_hz
  // swaths/frequencyX/processedRangeBandwidth and processedAzimuthBandwidth
  // (Hz) where the product states them (positive); NaN where it does not
  // (the impulse response's resolutions of `simulate --product` follow them,
  // pipeline/product_simulate.h).
  double processed_range_bandwidth_hz = std::numeric_limits<double>::quiet_NaN();
  double processed_azimuth_bandwidth_hz = std::numeric_limits<double>::quiet_NaN();
  bool look_left = false;                   // identification/lookDirection
  RslcOrbit orbit;
  RslcAttitude attitude;                    // empty when the product has none
  // SLC amplitude |s| of the layer, rows x cols (read when requested).
  std::vector<float> amplitude;
  // The complex SLC of the layer, rows x cols, as stored (non-finite
  // samples kept); read with RslcReadOptions::read_complex.
  std::vector<std::complex<float>> slc;
  // The polarisation layers the band really holds as datasets, in the
  // order HH, HV, VH, VV (listOfPolarizations may list more than a cropped
  // file keeps).
  std::vector<std::string> stored_polarizations;
  // metadata/calibrationInformation/geometry/beta0 with its axes, read with
  // RslcReadOptions::read_calibration when the product has it.
  std::optional<RslcCalibrationLut> beta0_lut;

  int rows() const { return static_cast<int>(zero_doppler_time_s.size()); }
  int cols() const { return static_cast<int>(slant_range_m.size()); }
  double azimuth_spacing_s() const;  // mean line spacing, seconds
  double range_spacing_m() const;    // mean bin spacing, metres
};

struct RslcReadOptions {
  std::string frequency = "A";
  std::string polarization = "HH";
  bool read_amplitude = true;
  // Memory budget (--max-memory), bytes; 0 = none. Checked from the dataset
  // shapes before anything large is read: every 1-D/2-D metadata array (8 B
  // per value) and the radar grid at `bytes_per_pixel` per pixel (what the
  // caller will allocate for it). Over it: ConfigError naming --max-memory.
  int64_t max_bytes = 0;
  double bytes_per_pixel = 12.0;  // the complex SLC read and its amplitude
  // Keep the complex layer in RslcProduct::slc (8 bytes per pixel more).
  bool read_complex = false;
  // Read the beta0 calibration LUT (RslcProduct::beta0_lut) when present:
  // the values under metadata/calibrationInformation/geometry/beta0 and its
  // axes zeroDopplerTime and slantRange (in geometry/, or in
  // calibrationInformation/ as in older products). A LUT present but
  // malformed (shape not matching its axes, axes not increasing, values not
  // finite or <= 0) is an InputError naming the dataset.
  bool read_calibration = false;
};

// Speed of light in vacuum, m/s.
inline constexpr double kSpeedOfLightMps = 299792458.0;

// Reads an RSLC product. Throws InputError naming the file (and the HDF5
// path) when the file is missing, is not HDF5, is not a NISAR RSLC (no
// /science/<band>/SLC or /RSLC group), lacks a required dataset (orbit,
// zeroDopplerTime, slantRange, the requested polarization, the centre
// frequency, the look direction), when the grids are not strictly
// increasing and uniform (to 1e-6 relative), when values are not finite, when
// the orbit has fewer than 4 state vectors or does not cover the grid's
// time span, or when the SLC layer's shape does not match the grid.
RslcProduct ReadRslcProduct(const std::filesystem::path& path, const RslcReadOptions& options = {});

// Writes a minimal NISAR-layout RSLC (LSAR, SLC group, frequencyA) holding
// the grid, orbit (omitted when `product.orbit` is empty), look direction,
// centre frequency, the processed bandwidths (when not NaN) and the
// amplitude as a complex64 layer with zero phase.
// For tests and synthetic data. Throws IoError on failure.
void WriteRslcProduct(const std::filesystem::path& path, const RslcProduct& product);

}  // namespace gissar::geo
