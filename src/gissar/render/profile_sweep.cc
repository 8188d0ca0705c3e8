#include "gissar/render/profile_sweep.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/check.h"

namespace gissar::render {
namespace {

// The walk's triangles: cell (c, r), half 0 with corners (a, b, d) and half
// 1 with corners (b, e, d), where a = (c, r), b = (c + 1, r), d = (c, r + 1),
// e = (c + 1, r + 1) (scene::GridCellTriangles' triangles, corners in this
// fixed order whatever their winding). Edge k joins corners k and k + 1.
// Across edge k of half h lies the triangle (c + dc, r + dr, half), entered
// through its edge `edge`.
struct Across {
  int dc, dr, half, edge;
};
constexpr Across kAcross[2][3] = {
    {{0, -1, 1, 1}, {0, 0, 1, 2}, {-1, 0, 1, 0}},  // half 0: a-b (row r), b-d (diagonal), d-a (column c)
    {{1, 0, 0, 2}, {0, 1, 0, 0}, {0, 0, 0, 1}},    // half 1: b-e (column c + 1), e-d (row r + 1), d-b
};

// Where the line a = A crosses the edge from post p to post q: the rule
// (a_p < A) != (a_q < A) counts every crossing once, whichever triangle
// asks (exactly 0 or 2 edges of a triangle cross).
inline bool Crosses(double a_p, double a_q, double A) { return (a_p < A) != (a_q < A); }

}  // namespace

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
    const std::array<int64_t, 3> corners =
        b.half == 0 ? std::array<int64_t, 3>{int64_t(b.r) * width + b.c, int64_t(b.r) * width + b.c + 1,
                                             int64_t(b.r + 1) * width + b.c}
                    : std::array<int64_t, 3>{int64_t(b.r) * width + b.c + 1, int64_t(b.r + 1) * width + b.c + 1,
                                             int64_t(b.r + 1) * width + b.c};
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


template <class Segment>
bool GridProfileSweep::Walk(double a_m, Segment&& segment) const {
  const int64_t w = width_;
  auto corners_of = [&](int c, int r, int half) {
    const int64_t a = int64_t(r) * w + c;
    return half == 0 ? std::array<int64_t, 3>{a, a + 1, a + w} : std::array<int64_t, 3>{a + 1, a + w + 1, a + w};
  };
  // Where the line crosses the edge from p to q (Crosses): the coordinates
  // interpolated linearly, as the point itself is.
  auto crossing = [&](const PostValues& p, const PostValues& q) {
    const double lambda = (a_m - p.a) / (q.a - p.a);
    return ProfilePoint{p.xl + lambda * (q.xl - p.xl), p.e + lambda * (q.e - p.e), p.g + lambda * (q.g - p.g)};
  };

  // Entry: the boundary edge the line crosses nearest the radar.
  const double fb = (a_m - a_lo_) / bucket_width_;
  if (!(fb >= 0.0) || fb >= double(bucket_start_.size() - 1)) return true;  // beside the grid
  const size_t bucket = size_t(fb);
  int crossings = 0;
  ProfilePoint entry{0.0, 0.0, std::numeric_limits<double>::infinity()};
  BoundaryEdge entry_edge{};
  for (uint32_t k = bucket_start_[bucket]; k < bucket_start_[bucket + 1]; ++k) {
    const BoundaryEdge& b = edges_[bucket_edges_[k]];
    const auto corners = corners_of(b.c, b.r, b.half);
    const int64_t p = corners[size_t(b.edge)], q = corners[size_t((b.edge + 1) % 3)];
    const double a_p = AlongTrack(p), a_q = AlongTrack(q);
    if (!Crosses(a_p, a_q, a_m)) continue;
    ++crossings;
    const ProfilePoint v = crossing(Values(p), Values(q));
    if (v.g < entry.g) {
      entry = v;
      entry_edge = b;
    }
  }
  if (crossings == 0) return true;
  if (crossings != 2) return false;

  int c = entry_edge.c, r = entry_edge.r, half = entry_edge.half, in_edge = entry_edge.edge;
  // The entry edge's two posts and their values: carried from triangle to
  // triangle, so that each step computes only the new corner's.
  std::array<int64_t, 2> in_post;
  std::array<PostValues, 2> in_value;
  {
    const auto corners = corners_of(c, r, half);
    in_post = {corners[size_t(in_edge)], corners[size_t((in_edge + 1) % 3)]};
    in_value = {Values(in_post[0]), Values(in_post[1])};
  }
  ProfilePoint from = entry;
  const int64_t max_steps = 2 * int64_t(width_) * height_ + 8;
  for (int64_t step = 0; step < max_steps; ++step) {
    const auto corners = corners_of(c, r, half);
    // Entry edge: corners k (A) and k + 1 (B); the other edges B-C and C-A.
    const int64_t A = corners[size_t(in_edge)], B = corners[size_t((in_edge + 1) % 3)],
                  C = corners[size_t((in_edge + 2) % 3)];
    const bool same_order = in_post[0] == A;
    const PostValues& vA = same_order ? in_value[0] : in_value[1];
    const PostValues& vB = same_order ? in_value[1] : in_value[0];
    const PostValues vC = Values(C);
    int out_edge;
    if (Crosses(vB.a, vC.a, a_m)) {
      out_edge = (in_edge + 1) % 3;
      in_post = {B, C};
      in_value = {vB, vC};
    } else {
      GISSAR_CHECK(Crosses(vC.a, vA.a, a_m));
      out_edge = (in_edge + 2) % 3;
      in_post = {C, A};
      in_value = {vC, vA};
    }
    const ProfilePoint to = crossing(in_value[0], in_value[1]);
    if (!segment(from, to, Facet{c, r, half})) break;
    const Across& next = kAcross[half][out_edge];
    c += next.dc;
    r += next.dr;
    if (c < 0 || r < 0 || c > width_ - 2 || r > height_ - 2) break;  // left the grid
    half = next.half;
    in_edge = next.edge;
    from = to;
  }
  return true;
}

bool GridProfileSweep::Trace(double a_m, double e0, double de, int count, double* depth_m, uint32_t* triangle,
                             Eigen::Vector3f* normal) const {
  GISSAR_CHECK(de > 0.0 && count >= 0);
  std::fill(triangle, triangle + count, kNoHit);
  auto ray_e = [&](int j) { return e0 + j * de; };
  // Ray j's hit on the segment from u to v: the crossing of the ray with it.
  auto record = [&](int j, const ProfilePoint& u, const ProfilePoint& v, uint32_t tri, const Eigen::Vector3f& n) {
    triangle[j] = tri;
    if (normal != nullptr) normal[j] = n;
    if (affine_) {
      const double lambda = (ray_e(j) - u.e) / (v.e - u.e);
      depth_m[j] = u.xl + lambda * (v.xl - u.xl);
      return;
    }
    // Sensor frame: x along l from the sensor, y along n.
    const double tau = std::tan(ray_e(j));
    const double ux = range0_ + u.xl, uy = u.e, dx = v.xl - u.xl, dy = v.e - u.e;
    const double denom = dy - tau * dx;
    const double lambda = denom != 0.0 ? std::clamp((tau * ux - uy) / denom, 0.0, 1.0) : 1.0;
    depth_m[j] = std::hypot(ux + lambda * dx, uy + lambda * dy);
  };
  // The covered interval [lo_v, hi_v] of ray coordinates (Coordinate);
  // hi: the lowest ray above it (count: none), lo: the highest ray below it
  // (-1: none). Rays are compared by angle in exact mode (atan of the
  // coordinate), by e in affine mode.
  auto angle_of = [&](double v) { return affine_ ? v : std::atan(v); };
  bool started = false;
  double hi_v = 0.0, lo_v = 0.0;
  int hi = count, lo = -1;
  return Walk(a_m, [&](const ProfilePoint& from, const ProfilePoint& to, const Facet& facet) {
    if (!started) {
      started = true;
      hi_v = lo_v = Coordinate(from);
      const double angle = angle_of(hi_v);
      hi = std::clamp(static_cast<int>(std::floor((angle - e0) / de)) + 1, 0, count);
      while (hi > 0 && ray_e(hi - 1) > angle) --hi;
      while (hi < count && !(ray_e(hi) > angle)) ++hi;
      lo = std::clamp(static_cast<int>(std::ceil((angle - e0) / de)) - 1, -1, count - 1);
      while (lo + 1 < count && ray_e(lo + 1) < angle) ++lo;
      while (lo >= 0 && !(ray_e(lo) < angle)) --lo;
    }
    const double v = Coordinate(to);
    if (v > hi_v) {
      const double limit = angle_of(v);
      if (hi < count && ray_e(hi) <= limit) {
        const uint32_t tri = Triangle(facet);
        const Eigen::Vector3f n = normal != nullptr ? Normal(facet) : Eigen::Vector3f::Zero();
        for (; hi < count && ray_e(hi) <= limit; ++hi) record(hi, from, to, tri, n);
      }
      hi_v = v;
    } else if (v < lo_v) {
      const double limit = angle_of(v);
      if (lo >= 0 && ray_e(lo) >= limit) {
        const uint32_t tri = Triangle(facet);
        const Eigen::Vector3f n = normal != nullptr ? Normal(facet) : Eigen::Vector3f::Zero();
        for (; lo >= 0 && ray_e(lo) >= limit; --lo) record(lo, from, to, tri, n);
      }
      lo_v = v;
    }
    return hi < count || lo >= 0;  // every ray has its hit: stop
  });
}

bool GridProfileSweep::Profile(double a_m, std::vector<ProfileSegment>* segments) const {
  segments->clear();
  double horizon = -std::numeric_limits<double>::infinity();
  return Walk(a_m, [&](const ProfilePoint& from, const ProfilePoint& to, const Facet& facet) {
    horizon = std::max(horizon, Elevation(from));
    segments->push_back({from, to, horizon, facet});
    return true;
  });
}

}  // namespace gissar::render
