#include "gissar/render/profile_sweep.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "gissar/render/profile_mask.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/check.h"

namespace gissar::render {
GridProfileSweep::GridProfileSweep(const Eigen::Vector3f* posts, int width, int height,
                                   const sensor::SarGeometry& geometry)
    : posts_(posts), width_(width), height_(height) {
  GISSAR_CHECK(posts != nullptr && width >= 2 && height >= 2);
  affine_ = geometry.mode() == sensor::ProjectionMode::kAffine;
  xc_ = geometry.scene_centre();
  h_ = geometry.flight_direction();
  l_ = geometry.look_direction();
  n_ = geometry.range_plane_normal();
  ground_ = Eigen::Vector3d(l_.x(), l_.y(), 0.0).normalized();
  range0_ = geometry.slant_range_m();
  up_sign_ = n_.z() >= 0.0 ? 1.0 : -1.0;
  column_cross_row_up_ = scene::GridColumnCrossRowUp(posts, width);

  for (int c = 0; c + 1 < width; ++c) {
    edges_.push_back({c, 0, 0, 0});
    edges_.push_back({c, height - 2, 1, 1});
  }
  for (int r = 0; r + 1 < height; ++r) {
    edges_.push_back({0, r, 0, 2});
    edges_.push_back({width - 2, r, 1, 0});
  }
  // Along-track span of each boundary edge, and buckets about one edge wide.
  std::vector<std::array<double, 2>> span(edges_.size());
  double a_lo = std::numeric_limits<double>::infinity(), a_hi = -a_lo;
  for (size_t k = 0; k < edges_.size(); ++k) {
    const BoundaryEdge& b = edges_[k];
    const std::array<int64_t, 3> corners = Corners(b.c, b.r, b.half);
    const double ap = AlongTrack(corners[size_t(b.edge)]), aq = AlongTrack(corners[size_t((b.edge + 1) % 3)]);
    span[k] = {std::min(ap, aq), std::max(ap, aq)};
    a_lo = std::min(a_lo, span[k][0]);
    a_hi = std::max(a_hi, span[k][1]);
  }
  GISSAR_CHECK(std::isfinite(a_lo) && std::isfinite(a_hi));
  const size_t buckets = edges_.size();
  a_lo_ = a_lo;
  bucket_width_ = std::max((a_hi - a_lo) / double(buckets), 1e-9);
  auto bucket = [&](double a) {
    return size_t(std::clamp((a - a_lo_) / bucket_width_, 0.0, double(buckets - 1)));
  };
  std::vector<uint32_t> count(buckets + 1, 0);
  for (const auto& s : span) {
    for (size_t k = bucket(s[0]); k <= bucket(s[1]); ++k) ++count[k + 1];
  }
  for (size_t k = 0; k < buckets; ++k) count[k + 1] += count[k];
  bucket_start_ = count;
  bucket_edges_.resize(count.back());
  for (size_t e = 0; e < span.size(); ++e) {
    for (size_t k = bucket(span[e][0]); k <= bucket(span[e][1]); ++k) bucket_edges_[count[k]++] = uint32_t(e);
  }
}


GridProfileSweep::LineWalk::LineWalk(const GridProfileSweep& sweep, double a_m) : sweep_(&sweep), a_m_(a_m) {
  const GridProfileSweep& s = sweep;
  // Entry: the boundary edge the line crosses nearest the radar.
  const double fb = (a_m - s.a_lo_) / s.bucket_width_;
  if (!(fb >= 0.0) || fb >= double(s.bucket_start_.size() - 1)) return;  // beside the grid
  const size_t bucket = size_t(fb);
  int crossings = 0;
  ProfilePoint entry{0.0, 0.0, std::numeric_limits<double>::infinity()};
  BoundaryEdge entry_edge{};
  for (uint32_t k = s.bucket_start_[bucket]; k < s.bucket_start_[bucket + 1]; ++k) {
    const BoundaryEdge& b = s.edges_[s.bucket_edges_[k]];
    const auto corners = s.Corners(b.c, b.r, b.half);
    const int64_t p = corners[size_t(b.edge)], q = corners[size_t((b.edge + 1) % 3)];
    const PostValues vp = s.Values(p), vq = s.Values(q);
    if (!Crosses(vp.a, vq.a, a_m)) continue;
    ++crossings;
    const ProfilePoint v = Crossing(vp, vq);
    if (v.g < entry.g) {
      entry = v;
      entry_edge = b;
    }
  }
  if (crossings == 0) return;
  if (crossings != 2) {
    state_ = State::kRefused;
    return;
  }
  state_ = State::kWalking;
  c_ = entry_edge.c;
  r_ = entry_edge.r;
  half_ = entry_edge.half;
  in_edge_ = entry_edge.edge;
  const auto corners = s.Corners(c_, r_, half_);
  in_post_ = {corners[size_t(in_edge_)], corners[size_t((in_edge_ + 1) % 3)]};
  in_value_ = {s.Values(in_post_[0]), s.Values(in_post_[1])};
  from_ = entry;
  steps_left_ = 2 * int64_t(s.width_) * s.height_ + 8;
}

namespace {

// Depth (as GridProfileSweep::Trace's depth_m) of the crossing of the ray of
// coordinate `v` (affine: offset e; exact: tangent) with the profile
// segment from (u_xl, u_e) to (w_xl, w_e).
double DepthOnSegment(bool affine, double range0, double v, double u_xl, double u_e, double w_xl, double w_e) {
  if (affine) {
    const double lambda = (v - u_e) / (w_e - u_e);
    return u_xl + lambda * (w_xl - u_xl);
  }
  // Sensor frame: x along l from the sensor, y along n.
  const double ux = range0 + u_xl, uy = u_e, dx = w_xl - u_xl, dy = w_e - u_e;
  const double denom = dy - v * dx;
  const double lambda = denom != 0.0 ? std::clamp((v * ux - uy) / denom, 0.0, 1.0) : 1.0;
  // (sqrt of the sum, not std::hypot: no overflow at these magnitudes, and a
  // third of the cost.)
  const double x = ux + lambda * dx, y = uy + lambda * dy;
  return std::sqrt(x * x + y * y);
}

// The rays of one line being assigned their hits as its walk goes
// (GridProfileSweep::Trace): the covered interval [lo_v, hi_v] of ray
// coordinates (Coordinate); hi, the lowest ray above it (count: none), lo,
// the highest ray below it (-1: none). Rays are compared by angle in exact
// mode (atan of the coordinate), by e in affine mode.
class RayAssigner {
 public:
  RayAssigner(const GridProfileSweep& sweep, bool affine, double range0, const GridProfileSweep::LineRays& rays)
      : sweep_(sweep), affine_(affine), range0_(range0), rays_(rays), hi_(rays.count) {
    std::fill(rays.triangle, rays.triangle + rays.count, GridProfileSweep::kNoHit);
    if (rays.frontier != nullptr) {
      rays.frontier->upper.clear();
      rays.frontier->lower.clear();
    }
  }

  // One segment of the profile; false once every ray has its hit and the
  // frontiers, when recorded, reach their bounds.
  bool operator()(const GridProfileSweep::ProfilePoint& from, const GridProfileSweep::ProfilePoint& to,
                  const GridProfileSweep::Facet& facet) {
    const int count = rays_.count;
    if (rays_.mask_row != nullptr) {
      horizon_ = std::max(horizon_, sweep_.Elevation(from));
      rays_.mask_row->Segment(GridProfileSweep::ProfileSegment{from, to, horizon_, facet});
    }
    if (!started_) {
      started_ = true;
      hi_v_ = lo_v_ = sweep_.Coordinate(from);
      const double angle = AngleOf(hi_v_);
      hi_ = std::clamp(static_cast<int>(std::floor((angle - rays_.e0) / rays_.de)) + 1 - rays_.first, 0, count);
      while (hi_ > 0 && RayE(hi_ - 1) > angle) --hi_;
      while (hi_ < count && !(RayE(hi_) > angle)) ++hi_;
      lo_ = std::clamp(static_cast<int>(std::ceil((angle - rays_.e0) / rays_.de)) - 1 - rays_.first, -1, count - 1);
      while (lo_ + 1 < count && RayE(lo_ + 1) < angle) ++lo_;
      while (lo_ >= 0 && !(RayE(lo_) < angle)) --lo_;
      if (rays_.frontier != nullptr) rays_.frontier->entry = hi_v_;
    }
    const double v = sweep_.Coordinate(to);
    if (v > hi_v_) {
      if (rays_.frontier != nullptr) {
        rays_.frontier->upper.push_back({v, from.xl, from.e, to.xl, to.e, sweep_.Triangle(facet)});
      }
      const double limit = Limit(v);
      if (hi_ < count && RayV(hi_) <= limit) {
        const uint32_t tri = sweep_.Triangle(facet);
        const Eigen::Vector3f n = rays_.normal != nullptr ? sweep_.Normal(facet) : Eigen::Vector3f::Zero();
        for (; hi_ < count && RayV(hi_) <= limit; ++hi_) Record(hi_, from, to, tri, n);
      }
      hi_v_ = v;
    } else if (v < lo_v_) {
      if (rays_.frontier != nullptr) {
        rays_.frontier->lower.push_back({v, from.xl, from.e, to.xl, to.e, sweep_.Triangle(facet)});
      }
      const double limit = Limit(v);
      if (lo_ >= 0 && RayV(lo_) >= limit) {
        const uint32_t tri = sweep_.Triangle(facet);
        const Eigen::Vector3f n = rays_.normal != nullptr ? sweep_.Normal(facet) : Eigen::Vector3f::Zero();
        for (; lo_ >= 0 && RayV(lo_) >= limit; --lo_) Record(lo_, from, to, tri, n);
      }
      lo_v_ = v;
    }
    return hi_ < count || lo_ >= 0 || rays_.mask_row != nullptr ||
           (rays_.frontier != nullptr && (hi_v_ < rays_.frontier_above || lo_v_ > rays_.frontier_below));
  }

 private:
  double RayE(int j) const { return rays_.e0 + (rays_.first + j) * rays_.de; }
  double AngleOf(double v) const { return affine_ ? v : std::atan(v); }
  // Rays are compared with a profile coordinate v by RayV(j) against
  // Limit(v): in exact mode with the rays' tangents given, tangent against v
  // (tan is increasing on the rays' angles: no atan per segment), else
  // coordinate against AngleOf(v).
  bool by_tan() const { return !affine_ && rays_.tan_e != nullptr; }
  double RayV(int j) const { return by_tan() ? rays_.tan_e[j] : RayE(j); }
  double Limit(double v) const { return by_tan() ? v : AngleOf(v); }
  // Ray j's hit on the segment from u to v: the crossing of the ray with it.
  void Record(int j, const GridProfileSweep::ProfilePoint& u, const GridProfileSweep::ProfilePoint& v, uint32_t tri,
              const Eigen::Vector3f& n) {
    rays_.triangle[j] = tri;
    if (rays_.normal != nullptr) rays_.normal[j] = n;
    const double coordinate =
        affine_ ? RayE(j) : rays_.tan_e != nullptr ? rays_.tan_e[j] : std::tan(RayE(j));
    rays_.depth_m[j] = DepthOnSegment(affine_, range0_, coordinate, u.xl, u.e, v.xl, v.e);
  }

  const GridProfileSweep& sweep_;
  bool affine_;
  double range0_;
  GridProfileSweep::LineRays rays_;
  bool started_ = false;
  double horizon_ = -std::numeric_limits<double>::infinity();  // with rays_.mask_row
  double hi_v_ = 0.0, lo_v_ = 0.0;
  int hi_, lo_ = -1;
};

}  // namespace

bool GridProfileSweep::Trace(double a_m, double e0, double de, int count, double* depth_m, uint32_t* triangle,
                             Eigen::Vector3f* normal) const {
  uint8_t ok = 0;
  TraceLines({LineRays{a_m, e0, de, 0, count, depth_m, triangle, normal}}, &ok);
  return ok != 0;
}

bool GridProfileSweep::FrontierHit(const Frontier& frontier, double v, double* depth_m, uint32_t* triangle) const {
  // As RayAssigner: a ray above the entry's coordinate is an upper ray, one
  // below it a lower ray; its hit is on the first segment whose end reaches
  // it (`reached` increases along the upper frontier, decreases along the
  // lower one).
  std::vector<FrontierSegment>::const_iterator it;
  if (v > frontier.entry) {
    it = std::lower_bound(frontier.upper.begin(), frontier.upper.end(), v,
                          [](const FrontierSegment& s, double x) { return s.reached < x; });
    if (it == frontier.upper.end()) return false;
  } else if (v < frontier.entry) {
    it = std::lower_bound(frontier.lower.begin(), frontier.lower.end(), v,
                          [](const FrontierSegment& s, double x) { return s.reached > x; });
    if (it == frontier.lower.end()) return false;
  } else {
    return false;
  }
  *depth_m = DepthOnSegment(affine_, range0_, v, it->from_xl, it->from_e, it->to_xl, it->to_e);
  *triangle = it->triangle;
  return true;
}

void GridProfileSweep::TraceLines(const std::vector<LineRays>& lines, uint8_t* ok) const {
  std::vector<LineWalk> walks;
  std::vector<RayAssigner> assigners;
  walks.reserve(lines.size());
  assigners.reserve(lines.size());
  for (const LineRays& line : lines) {
    GISSAR_CHECK(line.de > 0.0 && line.count >= 0);
    walks.emplace_back(*this, line.a_m);
    assigners.emplace_back(*this, affine_, range0_, line);
  }
  Lockstep(walks, [&](size_t k, const ProfilePoint& from, const ProfilePoint& to, const Facet& facet) {
    return assigners[k](from, to, facet);
  });
  for (size_t k = 0; k < lines.size(); ++k) ok[k] = walks[k].state() != LineWalk::State::kRefused;
}

}  // namespace gissar::render
