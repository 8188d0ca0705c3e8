// Commands of the affine SAR camera: `gissar fmatrix`, `resect`, `register`
// and `epipolar`. Each options struct is the single source of truth of its
// flags and is recorded in the JSON output.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/util/reporter.h"

namespace gissar::pipeline {

struct FmatrixRequest {
  std::string matches;                      // CSV with columns x1,y1,x2,y2
  // Pixel spacings (m per pixel) of images 1 and 2 (calibrated F): slant
  // range (R1, R2) and along track (A1, A2); both or neither.
  std::optional<Eigen::Vector2d> range_spacing_m;
  std::optional<Eigen::Vector2d> azimuth_spacing_m;
  std::optional<Eigen::Vector2d> depressions;  // of images 1 and 2 (degrees)
  double threshold_px = 1.5;                // RANSAC inlier threshold (Gold Standard distance)
  bool robust = true;                       // RANSAC + refit, or one Gold Standard fit
  uint64_t seed = 1;
  std::string json_out;
  // Pictures (--plot PREFIX): PREFIX_kvd.png (the KvD diagram: rho axis phi,
  // cyclorotation theta, scale s, heading change) and, when both images are
  // given (--image1/--image2, any GDAL rasters), PREFIX_epipolar.png (the pair
  // with the matches, inliers green with their epipolar lines, outliers red).
  std::string plot_prefix;
  std::string image1, image2;
  void Check() const;
  nlohmann::json ToJson() const;
};

// Estimates F and its KvD decomposition (heading change with depressions).
// Writes `json_out` (and the pictures of `plot_prefix`) and returns the JSON
// ("converged": true). Throws InputError for bad or degenerate matches (fewer
// than 4, NaN, collinear/coplanar so that F is undetermined, no RANSAC
// model), ConfigError for bad options and for two outputs naming the same
// file (the JSON, PREFIX_kvd.png, PREFIX_epipolar.png: the message names
// both flags). With RANSAC, the consensus must beat chance
// (mvg::TestConsensus, false-alarm rate mvg::kConsensusAlpha over the
// samples drawn; the figures in "consensus"): otherwise no result, the JSON
// written with "converged": false, a "reason", no F and no pictures (the
// CLI exits 3).
nlohmann::json RunFmatrix(const FmatrixRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

struct ResectRequest {
  std::string points;                        // CSV with columns X,Y,Z,x,y (ENU m, pixels)
  Eigen::Vector3d center_enu_m = Eigen::Vector3d::Zero();  // scene centre Xc, ENU metres
  std::optional<double> slant_range_m;       // measured range to Xc: sensor position
  std::string json_out;
  void Check() const;
  nlohmann::json ToJson() const;
};

// Affine resection constrained to the SAR camera form: heading, depression,
// pixel spacings, principal point, RMS, 1-sigma errors.
nlohmann::json RunResect(const ResectRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

struct RegisterRequest {
  std::string fixed;       // raster
  std::string moving;      // raster
  std::string points;      // CSV x1,y1 (fixed), x2,y2 (moving)
  std::string transform = "affine";  // a name of mvg::kTransformTypes
  double threshold_px = 2.0;
  bool robust = true;
  std::string out_prefix;  // PREFIX.tif, PREFIX_composite.png, PREFIX.json
  void Check() const;
  nlohmann::json ToJson() const;
};

// Fits the transform to the control points, warps the moving image onto the
// fixed grid and writes it with a green (fixed) / magenta (moving) composite.
nlohmann::json RunRegister(const RegisterRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

struct EpipolarRequest {
  std::string matches, image1, image2, out_png;
  double threshold_px = 1.5;
  uint64_t seed = 1;
  void Check() const;
};

// Draws the image pair with the matches and their epipolar lines.
void RunEpipolar(const EpipolarRequest& options);

struct CompositeRequest {
  std::string green, magenta;  // co-registered rasters of one size, band 1 linear intensity
  std::string out_png;
  void Check() const;
};

// Green/magenta composite of two co-registered images (e.g. a real image and
// its simulation, or a registered pair), each dB-stretched on its own: grey
// where they agree. Throws InputError when the sizes differ.
void RunComposite(const CompositeRequest& options);

}  // namespace gissar::pipeline
