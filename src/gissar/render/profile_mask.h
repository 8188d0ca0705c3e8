// The layover/shadow mask of an image row from its azimuth line's profile
// (docs/performance.md, "Primary hits by profile sweep"): how each segment of
// the profile flags the pixel centres it covers. The mask phase walks the
// rows' profiles with it (RenderLayoverShadowMask); with one ray line per
// image row the tracer paints each row from the walk that finds its rays'
// hits (GridProfileSweep::LineRays::mask_row), and no profile is walked
// twice.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

#include "gissar/render/profile_sweep.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::render {

// Internal flags of the mask passes besides the mask codes: a lit surface
// covers the pixel centre; any surface does.
inline constexpr uint8_t kLitBit = 8;
inline constexpr uint8_t kCoveredBit = 16;

// A point of a profile is hidden when the horizon before it is higher than
// this (metres along n): the rounding of the double-precision profile.
inline constexpr double kProfileShadowToleranceM = 1e-6;

// The along-track coordinate (metres from the scene centre along h) of the
// line through the centres of image row r: the line the tracer casts there
// with one ray line per row (RenderSar's ray grid with one line per row: the
// same operations, so the same double, and the same profile).
inline double RowLineAlongTrack(const sensor::SarGeometry& geometry, int r) {
  const double da = geometry.azimuth_spacing_m();
  return ((-0.5 - geometry.v0()) * da + 0.5 * da) + r * da;
}

// How a row's profile segments flag its pixel centres (mask codes, kLitBit,
// kCoveredBit): the centres of row r lie on the azimuth line through it
// (RowLineAlongTrack), a centre is covered by every profile segment whose
// slant-range span holds it, and a point of a segment is hidden exactly when
// the horizon before it (the highest Elevation of the profile nearer the
// radar) is above it: the visibility ray towards the radar runs in that
// plane at constant Elevation (affine: offset e along n; exact: the angle
// seen from the line's sensor, which lies in the same plane). A lit point
// whose surface faces away from the range plane's upward normal is
// layover. In exact mode the point at a centre is placed on its segment by
// the centre's column, interpolated between the segment's ends (as the
// mask's ray pass interpolates in the projected triangle), and it is turned
// away, or flipped, by its own direction to the sensor. `sweep` must
// outlive the rule.
class ProfileMaskRule {
 public:
  ProfileMaskRule(const GridProfileSweep& sweep, const sensor::SarGeometry& geometry)
      : sweep_(&sweep),
        affine_(geometry.mode() == sensor::ProjectionMode::kAffine),
        width_(geometry.width()),
        l_(geometry.look_direction()),
        n_(geometry.range_plane_normal()),
        h_(geometry.flight_direction()),
        n_up_(geometry.UpwardRangePlaneNormal(geometry.scene_centre())),
        inv_dr_(1.0 / geometry.range_spacing_m()),
        u0_(geometry.u0()),
        range0_(geometry.slant_range_m()),
        // Exact mode: every line's sensor lies at ground coordinate
        // -range0 |l_h| (h is horizontal and normal to l); the profile must
        // lie beyond it.
        sensor_g_(-range0_ * std::hypot(l_.x(), l_.y())),
        up_sign_(n_.z() >= 0.0 ? 1.0 : -1.0) {}

  // Or-s the flags of the centres segment `s` covers into `row` (the row's
  // width() flags). False (nothing written) when, in exact mode, the
  // segment is not beyond the sensor in ground range: the rule does not
  // apply to the image.
  bool Paint(const GridProfileSweep::ProfileSegment& s, uint8_t* row) const {
    return Paint(s, Column(s.from), Column(s.to), row);
  }
  // The same with the columns of the segment's ends given (Column).
  bool Paint(const GridProfileSweep::ProfileSegment& s, double col0, double col1, uint8_t* row) const {
    if (!affine_ && !(s.from.g > sensor_g_ && s.to.g > sensor_g_)) return false;
    if (col0 == col1) return true;  // seen edge-on: covers no centre
    const int c_lo = std::max(0, static_cast<int>(std::ceil(std::min(col0, col1))));
    const int c_hi = std::min(width_ - 1, static_cast<int>(std::floor(std::max(col0, col1))));
    if (c_lo > c_hi) return true;
    const Eigen::Vector3d normal = sweep_->Normal(s.facet).cast<double>();
    if (normal.isZero()) return true;
    const double inv = 1.0 / (col1 - col0);
    if (affine_) {
      const bool turned_away = normal.dot(-l_) <= kMaskEdgeOnCos;
      const uint8_t lit_code = kLitBit | (normal.dot(n_up_) < 0.0 ? kMaskLayover : kMaskNone);
      const double up_from = sweep_->Elevation(s.from), up_to = sweep_->Elevation(s.to);
      for (int c = c_lo; c <= c_hi; ++c) {
        const double up = up_from + (c - col0) * inv * (up_to - up_from);
        // Hidden when the horizon before the point is above it (ties within
        // rounding: lit, as the tracer's ray ignores its own surface).
        const bool shadow = turned_away || s.horizon > up + kProfileShadowToleranceM;
        row[c] |= kCoveredBit | (shadow ? kMaskShadow : lit_code);
      }
      return true;
    }
    for (int c = c_lo; c <= c_hi; ++c) {
      const double f = (c - col0) * inv;
      const double x = range0_ + s.from.xl + f * (s.to.xl - s.from.xl);  // along l from the sensor
      const double e = s.from.e + f * (s.to.e - s.from.e);
      const Eigen::Vector3d dir = (x * l_ + e * n_) / std::sqrt(x * x + e * e);  // sensor -> point
      Eigen::Vector3d up_normal = dir.cross(h_);  // SarGeometry::UpwardRangePlaneNormal at the point
      if (up_normal.z() < 0.0) up_normal = -up_normal;
      const bool turned_away = normal.dot(-dir) <= kMaskEdgeOnCos;
      // The rounding tolerance in metres along n at the point's range.
      const bool shadow = turned_away || s.horizon > up_sign_ * e / x + kProfileShadowToleranceM / x;
      row[c] |= kCoveredBit |
                (shadow ? kMaskShadow : uint8_t(kLitBit | (normal.dot(up_normal) < 0.0 ? kMaskLayover : kMaskNone)));
    }
    return true;
  }

  // The image column of a profile point.
  double Column(const GridProfileSweep::ProfilePoint& p) const {
    const double x = range0_ + p.xl;
    return affine_ ? p.xl * inv_dr_ + u0_ : (std::sqrt(x * x + p.e * p.e) - range0_) * inv_dr_ + u0_;
  }

 private:

  const GridProfileSweep* sweep_;
  bool affine_;
  int width_;
  Eigen::Vector3d l_, n_, h_, n_up_;
  double inv_dr_, u0_, range0_, sensor_g_, up_sign_;
};

// One image row painted by ProfileMaskRule from its line's segments, in
// walk order. `rule` and `row` must outlive it.
class MaskRowPainter {
 public:
  MaskRowPainter(const ProfileMaskRule& rule, uint8_t* row) : rule_(&rule), row_(row) {}
  // The next segment of the walk: it starts where the last one ended (its
  // column is carried over).
  void Segment(const GridProfileSweep::ProfileSegment& segment) {
    const double col0 = started_ ? last_column_ : rule_->Column(segment.from);
    last_column_ = rule_->Column(segment.to);
    started_ = true;
    if (!rule_->Paint(segment, col0, last_column_, row_)) behind_sensor_ = true;
  }
  // Some segment lay behind the sensor (exact mode): the row does not count.
  bool behind_sensor() const { return behind_sensor_; }

 private:
  const ProfileMaskRule* rule_;
  uint8_t* row_;
  bool behind_sensor_ = false;
  bool started_ = false;
  double last_column_ = 0.0;
};

}  // namespace gissar::render
