// Automatic positioning: the pose of an aircraft's SAR from one observed
// image and a 3-D scene, starting from a drifted INS prior, with no GNSS and
// no manual control points (issue 7).
//
// Pose model (affine SAR geometry, docs/geometry.md): heading psi, depression
// delta and the ground point Xc (ENU metres, on the scene surface) imaged at
// the image centre ((W-1)/2, (H-1)/2); the slant range R from the sensor to
// Xc is measured by the radar's timing and held fixed. The sensor position
// is P = Xc - R l(psi, delta). Pixel spacings, image size and look side are
// the sensor's own and known.
//
// Algorithm of Locate: render the reference image at the current pose (its
// single-bounce hits give the 3-D point of every reference pixel), match it
// to the observed image (matching.h), drop outliers by a RANSAC affine map
// between the two images, resect the affine SAR camera from the control
// points (3-D point of the reference pixel, matched observed pixel) with the
// known pixel spacings (heading, depression, u0, v0 by Gauss-Newton), move the
// pose to the resected camera (new Xc: the surface point the resected camera
// images at the image centre), and iterate with a shrinking search until the
// update is below 0.1 px (at most max_iterations renders). Then the dense
// stage (dense_renders > 0): render at the pose reached (or keep the last
// reference when the pose moved less than 0.1 px since it) and fit (heading,
// depression, u0, v0) by Gauss-Newton on the log-intensity difference of
// every usable reference pixel, the reference being the sum of its classes'
// intensities each scaled by a fitted gain (the scene's materials are known
// to a few dB only); move the pose and repeat. Converged: the last update (patch stage, or dense stage
// when it ran) below 0.5 px. Optionally polish heading, depression and Xc by
// Nelder-Mead on the whole-image NCC of log intensities.
//
// Failures: bad options throw ConfigError; images of the wrong size throw
// InputError; a fix that finds too few matches or no camera returns a result
// with `converged == false` and the last pose reached (never throws for
// image content).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "gissar/material/material.h"
#include "gissar/nav/matching.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::nav {

struct NavPose {
  double heading_deg = 0.0;
  double depression_deg = 40.0;
  double slant_range_m = 10000.0;                       // sensor to Xc, measured
  Eigen::Vector3d centre_enu = Eigen::Vector3d::Zero();  // Xc, ENU metres
  // Line of sight l and sensor position Xc - R l (ENU metres).
  Eigen::Vector3d LookDirection(sensor::LookSide side) const;
  Eigen::Vector3d SensorPosition(sensor::LookSide side) const;
};

// What the sensor knows about its own image.
struct SensorModel {
  double range_spacing_m = 30.0;
  double azimuth_spacing_m = 30.0;
  int width = 160;
  int height = 160;
  sensor::LookSide look_side = sensor::LookSide::kRight;
  // Throws ConfigError naming the field for out-of-range values.
  void Check() const;
};

// The scene to render references from (not owned; must outlive the object).
struct NavScene {
  const scene::TriangleMesh* mesh = nullptr;
  const render::EmbreeScene* embree = nullptr;
  const material::MaterialTable* materials = nullptr;
  double rays_per_cell = 4.0;
  int bounces = 1;
  // Point landmarks (reflectors placed on the terrain, ENU): rendered in the
  // references of a product fix, where they drive the fix
  // (nav/product_locate.h); the affine fix (Locate) does not use them.
  const std::vector<render::SceneReflector>* landmarks = nullptr;
};

// The affine geometry options of `pose` seen by `model` (heading,
// depression, slant range, look side, spacings, size; kAffine).
sensor::SarGeometryOptions AffineGeometryOptions(const NavPose& pose, const SensorModel& model);
// The affine geometry of `pose` with Xc at the image centre.
sensor::SarGeometry GeometryOf(const NavPose& pose, const SensorModel& model);

// First surface point of the line {base + t n_up}, searched from above along
// -n_up (n_up: the slant-range-plane normal pointing up). nullopt when the
// line misses the scene.
// The search starts 100 m above the scene's bounds (EmbreeScene::bounds).
std::optional<Eigen::Vector3d> SurfaceAlongNormal(const render::EmbreeScene& embree, const Eigen::Vector3d& base,
                                                  const Eigen::Vector3d& n_up);
// The scene surface below (x, y) (vertical ray); nullopt outside the scene.
std::optional<Eigen::Vector3d> SurfaceBelow(const render::EmbreeScene& embree, double x, double y);

struct Reference {
  sensor::SarGeometry geometry;
  std::vector<float> intensity;  // linear, row-major
  cv::Mat points;                // CV_32FC3: mean single-bounce hit per pixel (ENU), NaN if none
  cv::Mat valid;                 // CV_8U: a 3-D point and no layover
  // The intensity split by the class of the last hit: class_intensity[c]
  // (CV_32F, linear) for the classes in class_ids; they sum to `intensity`.
  std::vector<int> class_ids;
  std::vector<cv::Mat> class_intensity;
};
Reference RenderReference(const NavScene& scene, const NavPose& pose, const SensorModel& model);

struct LocateOptions {
  Matcher matcher = Matcher::kNcc;
  int filter_px = 3;               // speckle box filter before the log
  int patch_px = 31;
  int step_px = 12;
  int initial_search_px = 28;      // first iteration; later iterations use refine_search_px
  int refine_search_px = 5;
  int max_iterations = 6;
  double ransac_threshold_px = 1.5;
  int min_matches = 8;
  // Renders of the dense stage after the patch iterations (0 = off). It runs
  // when the patch stage's last update was below 2 px (its basin).
  int dense_renders = 2;
  int dense_iterations = 10;       // Gauss-Newton steps per dense render
  int polish_evaluations = 0;      // Nelder-Mead evaluations (renders); 0 = off
  // Linear intensity added to the reference image before the log: the
  // observed sensor's noise floor (its NESZ as a linear sigma0), so that the
  // reference's dark areas (shadow, calm sea) read what the sensor records
  // there instead of a far lower floor. The observed image keeps 1e-4.
  double reference_floor = 1e-4;
  // Throws ConfigError naming the field for out-of-range values.
  void Check() const;
};

struct LocateResult {
  NavPose pose;
  Eigen::Vector3d sensor_enu = Eigen::Vector3d::Zero();
  bool converged = false;
  // Why there is no fix when `converged` is false (one sentence), else empty.
  std::string failure_reason;
  int iterations = 0;
  int matches = 0;                 // correspondences of the last iteration
  int inliers = 0;                 // after RANSAC
  double rms_px = 0.0;             // resection residual of the last patch iteration
  // Dense-stage fits whose update was applied (the first may fit the patch
  // stage's last reference: `renders` counts what was rendered).
  int dense_renders = 0;
  double dense_rms_db = 0.0;       // robust RMS log-intensity residual of the last dense fit, dB
  // Whole-image NCC of the log images at the result: on the last reference
  // rendered when the final update moved no pixel by more than 0.1 px, else
  // on a render at the result.
  double similarity = 0.0;
  double prior_similarity = 0.0;   // the same at the prior
  // One-sigma errors from the resection covariance of the last patch
  // iteration (the dense stage's pixels are correlated; it gives none).
  double heading_sigma_deg = 0.0;
  double depression_sigma_deg = 0.0;
  // Sensor position sigma along l, h and n (metres): u0 and v0 sigmas times
  // the spacings, and R times the depression sigma.
  Eigen::Vector3d position_sigma_lhn_m = Eigen::Vector3d::Zero();
  int renders = 0;
  double seconds = 0.0;
};

// `observed`: linear intensity, row-major model.width x model.height.
LocateResult Locate(const NavScene& scene, const SensorModel& model,
                    const std::vector<float>& observed, const NavPose& prior,
                    const LocateOptions& options);

// Where Locate gets the reference image of a pose (the geometry of the
// returned Reference must be GeometryOf(pose, model)): RenderReference on
// the fly, or a stored reference warped to the pose (WarpStoredReference).
using ReferenceSource = std::function<Reference(const NavPose&)>;
// Locate with references from `source` (the algorithm above, every
// RenderReference replaced by `source`; `scene` still gives the surface the
// pose moves on). LocateResult::renders counts the references taken.
LocateResult Locate(const NavScene& scene, const SensorModel& model,
                    const std::vector<float>& observed, const NavPose& prior,
                    const LocateOptions& options, const ReferenceSource& source);

// A reference image made beforehand (a corridor database's simulation,
// docs/navigation.md "Fixes from a reference database"): its affine camera
// in the scene's frame, its linear intensity and the 3-D point of every
// pixel. The point of pixel (x, y) is the first surface point, from above,
// on the pixel's iso-range line {Xc + (x - u0) dr l + (y - v0) da h + t n}
// that sees the sensor (no other surface along -l); pixels flagged by the
// simulation's mask (layover, shadow, outside: any non-zero code), or whose
// line meets no lit surface, are not valid.
struct StoredReference {
  sensor::SarGeometry geometry;
  std::vector<float> intensity;  // linear, row-major geometry.width() x geometry.height()
  cv::Mat points;                // CV_32FC3, NaN where not valid
  cv::Mat valid;                 // CV_8U
  int valid_pixels = 0;
};
// `intensity` (and `mask`, kMask* codes, or empty: no mask) are row-major
// geometry.width() x geometry.height(); InputError otherwise. Non-finite or
// negative intensities read as 0.
StoredReference MakeStoredReference(const NavScene& scene, const sensor::SarGeometry& geometry,
                                    std::vector<float> intensity, const std::vector<uint8_t>& mask);
// The stored reference resampled into the camera of `pose` (GeometryOf(pose,
// model)): every pixel p takes the intensity (bilinear) and the 3-D point
// and validity (nearest) of the stored pixel c whose point the pose's camera
// images at p (P(X(c)) = p, solved from the least-squares affine map between
// the two cameras' pixels and two fixed-point corrections through the
// points). Pixels outside the stored image read 0 and are not valid. One
// class (class_ids {0}) carries the whole intensity: the dense stage then
// fits one gain. No rendering.
Reference WarpStoredReference(const StoredReference& stored, const NavPose& pose, const SensorModel& model);

// Correspondences of a matcher between a reference and the observed image
// after the RANSAC affine filter, as control points (3-D point, observed
// pixel). Exposed for the matcher comparison of `gissar evaluate`.
struct ControlMatches {
  std::vector<Eigen::Vector3d> world;
  std::vector<Eigen::Vector2d> observed;
  int raw = 0;  // correspondences before the filter
};
// `reference_floor`: LocateOptions::reference_floor.
ControlMatches MatchReference(const Reference& reference, const cv::Mat& observed_log, Matcher matcher,
                              const MatchOptions& match, int filter_px, double ransac_threshold_px,
                              double reference_floor = 1e-4);

}  // namespace gissar::nav

namespace gissar::nav {

// The pose of a sensor at `sensor_enu` flying `heading_deg` whose beam
// reaches the scene surface at slant range `slant_range_m`: the depression
// and Xc = sensor + R l on the surface, by fixed-point iteration from
// `depression_guess_deg`. nullopt when the beam leaves the scene or the
// depression leaves (1, 89) degrees.
std::optional<NavPose> PoseFromSensor(const NavScene& scene, const Eigen::Vector3d& sensor_enu,
                                      double heading_deg, double slant_range_m,
                                      double depression_guess_deg, sensor::LookSide look_side);

}  // namespace gissar::nav
