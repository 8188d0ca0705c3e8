// Pose fixes from a real zero-Doppler SAR product (issue 23): the observed
// image is the product's own detected image; the references are simulated
// in the product's range-Doppler geometry (render/product_renderer.h) along
// a track displaced from the prior; the correction is the rigid track offset
// that makes the matched ground points fall, by geo2rdr, where the real image
// shows them. docs/navigation.md ("Real images") has the design and figures.
//
// Track offset (TrackOffset): a rigid motion of a whole track in the frame of
// its state at a reference time t_ref (TrackFrame): `along` the horizontal
// direction of the velocity, `cross` horizontal to its right, `up` the
// geodetic vertical at the sensor (metres), and `heading_deg`, a rotation of
// the track about the vertical through the sensor at t_ref, clockwise seen
// from above (the velocity rotates with it: the track angle changes). The
// same four numbers are CONVENTIONS.md's `--prior-offset-track
// ALONG,CROSS,UP` and `--prior-heading-offset`.
//
// What a zero-Doppler chip observes (docs/navigation.md): the zero-Doppler
// time of each ground point (along-track position, and the heading through
// the shear it causes across the swath) and its slant range (the position
// along the line of sight). The component across the line of sight in the
// cross-track plane and most of the heading are hardly observed from a chip:
// the estimate is regularised by the prior's one-sigma errors (a MAP
// estimate), so unobserved directions stay at the prior and the covariance
// says so.
//
// Point landmarks (NavScene::landmarks: corner reflectors and any reflectors
// CSV row, placed on the terrain) are rendered in every reference. Where one
// falls in the observed image they drive the fix (LocateProduct, "landmark
// mode"): the brightest pixel of the observed image in the prior's search
// window around the landmark's predicted pixel (geo2rdr on the current
// track), with a sub-pixel (parabolic, dB) peak, is the landmark's observed
// zero-Doppler time and slant range; the along- and cross-track offsets are
// resected from those (MAP), while up and heading, which a point (or a few
// points) on flat ground cannot separate from them, are held at the prior
// (their covariance is the prior's; the cross-track estimate carries the
// prior's vertical error through the line of sight). docs/navigation.md
// ("Landmarks where the terrain is flat").
//
// Failures: bad options throw ConfigError; an observed image of the wrong
// size throws InputError; a fix without enough consistent matches returns
// `converged == false` with a reason (never throws for image content).
#pragma once

#include <array>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "gissar/geo/local_frame.h"
#include "gissar/nav/locate.h"
#include "gissar/nav/matching.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/sensor/range_doppler.h"

namespace gissar::nav {

// State vectors of a track (ECEF metres and metres per second, times in
// seconds since the product's epoch).
struct TrackVectors {
  std::vector<double> time_s;
  std::vector<Eigen::Vector3d> position_m;
  std::vector<Eigen::Vector3d> velocity_mps;
  sensor::Orbit ToOrbit() const { return sensor::Orbit(time_s, position_m, velocity_mps); }
};

struct TrackOffset {
  double along_m = 0.0, cross_m = 0.0, up_m = 0.0;
  double heading_deg = 0.0;
  Eigen::Vector4d AsVector() const { return {along_m, cross_m, up_m, heading_deg}; }
  static TrackOffset FromVector(const Eigen::Vector4d& v) { return {v[0], v[1], v[2], v[3]}; }
};

// The frame of a track at one time: the sensor position and unit vectors
// along (horizontal velocity), cross (right of along, horizontal) and up
// (geodetic vertical), all ECEF.
struct TrackFrame {
  double time_s = 0.0;
  Eigen::Vector3d origin_ecef = Eigen::Vector3d::Zero();
  Eigen::Vector3d along = Eigen::Vector3d::UnitX(), cross = Eigen::Vector3d::UnitY(),
                  up = Eigen::Vector3d::UnitZ();
  // Components (along, cross, up) of an ECEF displacement.
  Eigen::Vector3d Components(const Eigen::Vector3d& ecef_delta) const {
    return {along.dot(ecef_delta), cross.dot(ecef_delta), up.dot(ecef_delta)};
  }
};
TrackFrame TrackFrameAt(const sensor::Orbit& orbit, double time_s);

// `track` moved by `offset` in `frame`: p' = o + R (p - o) + E (along, cross,
// up), v' = R v, where o = frame.origin_ecef and R the heading rotation about
// frame.up.
TrackVectors DisplaceTrack(const TrackVectors& track, const TrackFrame& frame, const TrackOffset& offset);

// Compass bearing (degrees clockwise from north) of the horizontal velocity
// of `orbit` at `time_s`: the track angle.
double TrackAngleDeg(const sensor::Orbit& orbit, double time_s);

// The observed product: its full-resolution zero-Doppler grid and detected
// intensity (|s|^2, rows x cols, row-major).
struct ProductObservation {
  sensor::RadarGrid grid;
  std::vector<float> intensity;
};

// How the whole-image shift between the observed image and a reference is
// scored (docs/navigation.md "Real images" compares them):
//  - kNcc: normalised cross-correlation of the log (dB) images;
//  - kGradient: the same on the gradient magnitude of the log images (edges:
//    slope breaks, shadow and layover boundaries);
//  - kPhase: phase-only correlation (whitened cross-power spectrum) of the
//    zero-mean log images;
//  - kMutualInformation: mutual information of the log images quantised to
//    16 levels each (any monotone or non-monotone radiometric relation).
enum class ShiftMatcher { kNcc, kGradient, kPhase, kMutualInformation };
inline constexpr auto kShiftMatchers = util::MakeEnumTable<ShiftMatcher>(
    "matcher for a product", {{ShiftMatcher::kNcc, "ncc"},
                              {ShiftMatcher::kGradient, "gradient"},
                              {ShiftMatcher::kPhase, "phase"},
                              {ShiftMatcher::kMutualInformation, "mi"}});
// kShiftMatchers.Parse: "ncc", "gradient", "phase", "mi"; ConfigError
// naming `option` and the matchers otherwise.
ShiftMatcher ParseShiftMatcher(const std::string& text, const std::string& option);
std::string ToString(ShiftMatcher matcher);
// Score of every placement of `observed` inside `reference` (both CV_32F log
// images, the reference at least as large): a CV_32F map of (H_ref - H_obs
// + 1) x (W_ref - W_obs + 1); map(v, u) scores observed pixel (x, y) on
// reference pixel (x + u, y + v); higher is better.
cv::Mat ShiftScores(ShiftMatcher matcher, const cv::Mat& reference, const cv::Mat& observed);

struct ProductLocateOptions {
  ShiftMatcher matcher = ShiftMatcher::kNcc;
  int looks_range = 3;    // the observed image is block-averaged (multilooked) by
  int looks_azimuth = 3;  // looks_azimuth lines x looks_range bins before matching
  int filter_px = 1;      // box filter on the multilooked intensity before the log
  TrackOffset prior_sigma{60.0, 60.0, 10.0, 0.05};
  double search_sigmas = 3.0;   // first search: this many prior sigmas (plus 3 px)
  int refine_search_px = 3;     // later iterations, multilooked pixels
  double shift_sigma_px = 0.5;  // one-sigma error of the whole-image shift (multilooked pixels)
  int max_iterations = 4;
  double max_rms_px = 0.5;      // a larger resection residual (the shift is not a track offset): no fix
  double min_peak_ncc = 0.08;   // a weaker whole-image correlation peak: no fix
  // The peak must exceed the best correlation more than 3 px away from it by
  // this much (an ambiguous peak: no fix).
  double min_peak_margin = 0.02;
  double reference_floor = 1e-4;  // as LocateOptions::reference_floor (linear intensity)
  // A reference whose log intensity (after the box filter) varies less than
  // this (standard deviation, dB) has nothing to match (flat terrain and no
  // landmark in the image): no fix, whatever the correlation says.
  double min_reference_contrast_db = 0.5;
  // Landmark mode: a landmark's observed peak must exceed the median of its
  // search window by min_landmark_contrast_db and the brightest pixel more
  // than 3 px from it by min_landmark_margin_db; its one-sigma localisation
  // error (full-resolution pixels) weighs it in the resection.
  double min_landmark_contrast_db = 10.0;
  double min_landmark_margin_db = 3.0;
  double landmark_sigma_px = 0.3;
  // The terrain's (DEM's or scene's) own absolute horizontal error, one
  // sigma per horizontal axis, metres. A relief fix matches the image
  // against the terrain, so a terrain displaced by d reads as a track
  // displaced by -d: this variance is added to the fix's along- and
  // cross-track variances (isotropic, so in any horizontal frame). A landmark
  // fix does not use it (the landmarks' own coordinates are surveyed).
  double terrain_horizontal_sigma_m = 0.0;
  void Check() const;  // ConfigError naming the field
};

// One landmark of a fix (ProductLocateResult::landmarks).
struct LandmarkRecord {
  int row = 0;             // the reflectors CSV row (render::SceneReflector::row)
  bool in_image = false;   // its search window at the prior track meets the observed image
  bool used = false;       // carried into the resection
  // Full-resolution (range, azimuth) pixels: predicted at the prior track,
  // the observed peak, and observed minus predicted at the fix (NaN: none).
  Eigen::Vector2d predicted_px = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector2d peak_px = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector2d residual_px = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  double contrast_db = std::numeric_limits<double>::quiet_NaN();  // peak over the window's median
  double margin_db = std::numeric_limits<double>::quiet_NaN();    // peak over the best pixel > 3 px away
  std::string note;        // why it was not used (empty when used)
};

// Names of the four components of a TrackOffset, in order.
inline constexpr const char* kTrackComponents[4] = {"along", "cross", "up", "heading"};

struct ProductLocateResult {
  bool converged = false;
  std::string failure_reason;  // one sentence when !converged
  TrackOffset correction;      // the estimated offset of the truth from the prior track
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();  // of `correction` (m^2, m deg, deg^2)
  TrackVectors track;          // the prior track moved by `correction`
  double fix_time_s = 0.0;     // zero-Doppler time of the image's centre line
  Eigen::Vector3d sensor_ecef = Eigen::Vector3d::Zero();  // fixed sensor position at fix_time_s
  int iterations = 0, renders = 0;
  int control_points = 0;  // ground points carrying the last shift into the resection
  double rms_px = 0.0;  // resection residual of the last iteration (multilooked pixels)
  double peak_ncc = 0.0;      // whole-image NCC of the first iteration's best shift
  double peak_margin = 0.0;   // peak_ncc minus the best NCC more than 3 px from it (NaN: none)
  double similarity = 0.0;    // whole-image NCC (log) at the fix
  double prior_similarity = 0.0;  // the same at the prior
  Eigen::Vector2d first_shift_px = Eigen::Vector2d::Zero();  // (range, azimuth) shift found first
  // (range, azimuth) peak of the whole-image NCC against the last reference
  // (integer pixels): a fix needs it within 1 px of zero, whatever the matcher.
  Eigen::Vector2d ncc_shift_px = Eigen::Vector2d::Zero();
  double cell_m = 0.0;        // larger pixel spacing of the multilooked image (m)
  double seconds = 0.0;
  // What drove the fix: "relief" (the whole-image shift) or "landmarks".
  std::string source = "relief";
  // Which components of `correction` the image constrained (true) and which
  // were held at the prior (false: its covariance row is the prior's). The
  // relief fix estimates all four (MAP, regularised by the prior); the
  // landmark fix along and cross only.
  std::array<bool, 4> from_image = {true, true, true, true};
  std::vector<LandmarkRecord> landmarks;  // every landmark of the scene
  // Standard deviation of the first reference's log intensity (dB).
  double reference_contrast_db = std::numeric_limits<double>::quiet_NaN();
};

// `scene` and `frame`: the terrain (ENU of `frame`). Throws InputError when
// the observation does not match its grid and ConfigError for bad options.
ProductLocateResult LocateProduct(const NavScene& scene, const geo::LocalFrame& frame,
                                  const ProductObservation& observed, const TrackVectors& prior_track,
                                  const ProductLocateOptions& options);

// The grid of an image multilooked by la lines x lr range bins
// (image::Multilook): partial blocks dropped, each output pixel at the
// centre of its block.
sensor::RadarGrid MultilookGrid(const sensor::RadarGrid& grid, int la, int lr);

}  // namespace gissar::nav
