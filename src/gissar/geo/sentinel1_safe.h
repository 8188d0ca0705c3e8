// Sentinel-1 Level-1 products in the SAFE layout (a directory NAME.SAFE, or a
// .zip holding one, read through GDAL's /vsizip/): the manifest, and per
// swath and polarisation the product annotation (orbit state vectors,
// zero-Doppler timing, range sampling, bursts, geolocation grid, GRD slant <->
// ground range polynomials), the calibration LUTs (sigma0, beta0, gamma0, DN)
// and the noise LUTs (range and azimuth). Element names follow ESA's
// "Sentinel-1 Product Specification" (S1-RS-MDA-52-7441) and its XSD
// (support/s1-level-1-*.xsd). XML is parsed by libxml2 (no network, no entity
// expansion). Only annotations are read: the measurement TIFFs are not opened.
// See docs/sentinel1.md.
//
// Conventions: every time is seconds since the product's epoch, `epoch_utc`
// = midnight UTC of the day of the first annotation's first line (the same
// epoch as geo::ProductFromOrbit); UTC without leap seconds (util/utc_time.h).
// Positions and velocities ECEF (WGS84) metres and metres per second. Lines
// and pixels are 0-based with pixel centres at integers, as in the
// annotations; in an IW/EW SLC the annotation's `line` numbers count lines
// across the concatenated bursts of the measurement (burst b, 0-based, starts
// at line b x lines_per_burst). Slant-range time is two-way, seconds.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/orbit_file.h"
#include "gissar/geo/rslc_product.h"

namespace gissar::geo {

// One burst of an IW/EW SLC swath (swathTiming/burstList/burst).
struct Sentinel1Burst {
  int number = 0;               // 1-based, in the order of the burst list
  double azimuth_time_s = 0.0;  // zero-Doppler time of the burst's first line
  double sensing_time_s = 0.0;
  int first_line = 0;           // measurement line of the burst's first line
  // Per line of the burst (lines_per_burst values): first and last valid
  // range sample, -1 on a line without valid samples.
  std::vector<int> first_valid_sample, last_valid_sample;
  // First and last line (within the burst, 0-based) with valid samples;
  // -1 when none.
  int first_valid_line = -1, last_valid_line = -1;
};

// One point of geolocationGrid/geolocationGridPointList.
struct Sentinel1GridPoint {
  double azimuth_time_s = 0.0;        // zero-Doppler time
  double slant_range_time_s = 0.0;    // two-way
  int line = 0, pixel = 0;
  double latitude_deg = 0.0, longitude_deg = 0.0, height_m = 0.0;  // WGS84, ellipsoidal
  double incidence_angle_deg = 0.0, elevation_angle_deg = 0.0;
};

// One record of coordinateConversion/coordinateConversionList (GRD only):
// ground range = sum_k srgr[k] (R - sr0_m)^k and slant range R = sum_k
// grsr[k] (G - gr0_m)^k, metres, valid at azimuth_time_s.
struct Sentinel1RangeConversion {
  double azimuth_time_s = 0.0;
  double slant_range_time_s = 0.0;
  double sr0_m = 0.0, gr0_m = 0.0;
  std::vector<double> srgr, grsr;
};

// One swathProcParams of imageAnnotation/processingInformation/
// swathProcParamsList (an SLC lists its swath; a GRD each swath it merged):
// the bands the processor kept, Hz, and its looks. Resolution follows the
// processing bandwidth in an SLC and the look bandwidth in a multilooked GRD.
struct Sentinel1SwathProcessing {
  std::string swath;
  double range_processing_bandwidth_hz = 0.0, range_look_bandwidth_hz = 0.0;
  double azimuth_processing_bandwidth_hz = 0.0, azimuth_look_bandwidth_hz = 0.0;
  int range_looks = 1, azimuth_looks = 1;
  std::string range_window, azimuth_window;  // windowType ("Hamming")
  double range_window_coefficient = 0.0, azimuth_window_coefficient = 0.0;
};

// A LUT given as vectors at a few lines, each over a few pixels (the
// calibration and the noise range vectors).
struct Sentinel1LineVectors {
  std::vector<double> azimuth_time_s;       // per vector
  std::vector<int> line;                    // per vector, non-decreasing
  std::vector<std::vector<int>> pixel;      // per vector, strictly increasing
  std::vector<std::vector<double>> values;  // per vector, one per pixel
  // Bilinear value at (line, pixel), as ESA specifies for the calibration
  // vectors: linear in pixel along the two vectors that bracket the line,
  // then linear in line between them; clamped to the first/last vector and
  // pixel beyond the table (nearest edge value). Throws InputError when the
  // table is empty.
  double At(double line, double pixel) const;
};

// calibration-*.xml: the LUTs A with calibrated value = |DN|^2 / A^2.
struct Sentinel1Calibration {
  std::string file;  // path inside the SAFE
  double absolute_calibration_constant = 1.0;
  Sentinel1LineVectors sigma0, beta0, gamma0, dn;
};

// One noiseAzimuthVector: a LUT along lines for a block of the image.
struct Sentinel1NoiseAzimuthBlock {
  std::string swath;
  int first_azimuth_line = 0, last_azimuth_line = 0, first_range_sample = 0, last_range_sample = 0;
  std::vector<int> line;       // strictly increasing
  std::vector<double> values;  // one per line
};

// noise-*.xml: thermal noise power (in |DN|^2) = range LUT x azimuth LUT.
// Products of IPF < 2.9 have only `noiseVectorList` (read as the range LUT,
// no azimuth blocks).
struct Sentinel1Noise {
  std::string file;
  Sentinel1LineVectors range;
  std::vector<Sentinel1NoiseAzimuthBlock> azimuth;
  // Range LUT x azimuth LUT at (line, pixel): the range LUT bilinear as
  // Sentinel1LineVectors::At, the azimuth LUT linear in line within the block
  // holding the pixel (1 where no block holds it).
  double At(double line, double pixel) const;
};

// The annotation of one swath and polarisation (annotation/*.xml).
struct Sentinel1Annotation {
  std::string file;          // path inside the SAFE ("annotation/s1b-iw1-slc-vv-....xml")
  std::string mission;       // adsHeader/missionId ("S1A", "S1B")
  std::string product_type;  // adsHeader/productType ("SLC", "GRD")
  std::string mode;          // adsHeader/mode ("IW", "EW", "WV"; the beam "S1".."S6" for stripmap)
  std::string swath;         // adsHeader/swath ("IW1", "S3", "IW" for an IW GRD)
  std::string polarization;  // adsHeader/polarisation ("VV", ...)
  std::string pass;          // productInformation/pass ("Ascending", "Descending")
  double radar_frequency_hz = 0.0;
  double range_sampling_rate_hz = 0.0;
  double wavelength_m = 0.0;                // c / radar_frequency_hz
  double first_line_time_s = 0.0;           // productFirstLineUtcTime
  double last_line_time_s = 0.0;            // productLastLineUtcTime
  double slant_range_time_s = 0.0;          // two-way, first sample
  double range_pixel_spacing_m = 0.0;       // slant (SLC) or ground (GRD) range
  double azimuth_pixel_spacing_m = 0.0;
  double azimuth_time_interval_s = 0.0;
  int number_of_samples = 0, number_of_lines = 0;
  bool look_left = false;                   // Sentinel-1 looks right
  RslcOrbit orbit;                          // generalAnnotation/orbitList, type "annotation"
  int lines_per_burst = 0, samples_per_burst = 0;  // 0 when no bursts
  std::vector<Sentinel1Burst> bursts;       // empty for SM and GRD
  std::vector<Sentinel1GridPoint> geolocation_grid;
  std::vector<Sentinel1RangeConversion> range_conversion;  // GRD only
  // processingInformation/swathProcParamsList; empty when not annotated.
  std::vector<Sentinel1SwathProcessing> processing;

  bool is_grd() const { return product_type == "GRD"; }
  // Slant-range sample spacing c / (2 fs), metres.
  double slant_range_spacing_m() const;
  double SlantRangeOfTime(double two_way_time_s) const { return 0.5 * kSpeedOfLightMps * two_way_time_s; }
  // GRD: ground range (metres from the first pixel) of slant range `range_m`
  // at `azimuth_time_s`, and the inverse, with the srgr/grsr polynomials of
  // the record nearest in time. Nearest, not interpolated: the records (1 s
  // apart) follow the terrain height, so at a fixed slant range they differ
  // by up to ~100 m of ground range, and the annotated geolocation grid
  // matches the nearest record (its pixels to 0.006 px in the bundled IW GRD)
  // but not a linear interpolation between records (up to 1.5 px off).
  // Throws InputError naming the file when the product has no records.
  double GroundRangeOfSlantRange(double range_m, double azimuth_time_s) const;
  double SlantRangeOfGroundRange(double ground_range_m, double azimuth_time_s) const;
  // The burst with 1-based `number`; throws InputError naming --burst and the
  // file for a GRD ("a GRD has no bursts"), a product without bursts or a
  // number out of range.
  const Sentinel1Burst& Burst(int number) const;
  // The burst (1-based) whose lines span `azimuth_time_s` (the last one
  // starting at or before it); 0 when the product has no bursts.
  int BurstOfTime(double azimuth_time_s) const;
};

// One swath/polarisation entry of the manifest.
struct Sentinel1Entry {
  std::string swath, polarization;     // upper case ("IW1", "VV")
  std::string annotation_file;         // paths inside the SAFE, "" when not listed
  std::string calibration_file, noise_file, measurement_file;
  bool annotation_present = false;     // the annotation file exists
};

struct Sentinel1Product {
  std::string path;           // as given
  std::string root;           // GDAL path of the SAFE directory (/vsizip/... for a .zip)
  std::string name;           // "S1B_IW_SLC__1SDV_....SAFE"
  std::string mission;        // "S1A" / "S1B" (manifest familyName + number)
  std::string mode;           // manifest instrumentMode/mode
  std::string product_type;   // manifest productType ("SLC", "GRD")
  std::string epoch_utc;      // "YYYY-MM-DDT00:00:00Z"
  double epoch_unix_s = 0.0;  // POSIX seconds of epoch_utc
  std::vector<Sentinel1Entry> entries;  // ordered by swath, then polarisation

  // The entry of (swath, polarization) ("" = the only one, or the first
  // with its annotation present, in that order); throws InputError naming
  // --swath / --polarization and listing the ones the product has.
  const Sentinel1Entry& Entry(const std::string& swath, const std::string& polarization) const;
};

// Opens a SAFE (directory, its manifest.safe, or a .zip holding one SAFE
// directory) and reads its manifest. Throws InputError naming the file and
// field when the path is missing, is not a SAFE, the manifest is missing or
// not well-formed XML, lists no product annotation, or is not Sentinel-1.
Sentinel1Product OpenSentinel1(const std::filesystem::path& path);

// True when `path` is to be read as a SAFE: a name ending in .SAFE or .zip,
// a manifest.safe, or a directory holding one (whether it really is a
// Sentinel-1 product is OpenSentinel1's check).
bool IsSentinel1Path(const std::filesystem::path& path);

// Reads the annotation, calibration or noise of an entry. Throws InputError
// naming the file (path inside the SAFE) and the element for a missing file
// (the manifest lists it but the SAFE lacks it), malformed or truncated XML,
// a missing or non-numeric required element, a count attribute that does
// not match the values, times not increasing, fewer than kMinStateVectors
// orbit vectors or an orbit that does not cover the product's lines.
Sentinel1Annotation ReadSentinel1Annotation(const Sentinel1Product& product, const Sentinel1Entry& entry);
Sentinel1Calibration ReadSentinel1Calibration(const Sentinel1Product& product, const Sentinel1Entry& entry);
Sentinel1Noise ReadSentinel1Noise(const Sentinel1Product& product, const Sentinel1Entry& entry);

// Replaces the annotation's orbit by state vectors read from a file (an EOF
// orbit, geo::ReadStateVectors), converted to the product's epoch; only the
// vectors within 60 s of the product's lines are kept. Throws InputError
// naming `source` when they do not cover the product's first to last line.
void ReplaceSentinel1Orbit(Sentinel1Annotation& annotation, const Sentinel1Product& product,
                           const StateVectors& vectors, const std::string& source);

// The parsers behind the readers, on a document held in memory (also the
// fuzz target's entry, fuzz/fuzz_sentinel1_xml.cc): the same checks; `file`
// names the document in errors; times are seconds since `epoch_unix_s`
// (for the annotation, 0 = midnight of its first line's day).
Sentinel1Annotation ParseSentinel1Annotation(const std::string& xml, const std::string& file,
                                             double epoch_unix_s = 0.0);
Sentinel1Calibration ParseSentinel1Calibration(const std::string& xml, const std::string& file,
                                               double epoch_unix_s);
Sentinel1Noise ParseSentinel1Noise(const std::string& xml, const std::string& file, double epoch_unix_s);

}  // namespace gissar::geo
