// First hits of the primary rays of one azimuth line over a terrain grid,
// all at once, by a sweep along the terrain's profile in the line's plane
// (docs/performance.md, "Primary hits by profile sweep").
//
// The primary rays of an azimuth line (RenderSar's RayGrid) lie in one
// plane normal to the flight direction: parallel rays offset along the
// range-plane normal n (affine mode), or a fan from the sensor (exact mode).
// That plane cuts a height field in a polyline, the profile, running away
// from the radar with ground range g. At a fixed ray coordinate (offset or
// angle) the distance along the ray grows with g, so a ray's first hit is
// the first point of the profile, in g order, at which the profile reaches
// the ray's coordinate. Walking the profile from its near end, the profile
// has covered every coordinate between its running minimum and maximum;
// each segment that extends that interval is the first hit of exactly the
// rays in the extension. One walk over the triangles the line crosses gives
// every ray's hit: no traversal per ray, no acceleration structure.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/check.h"

namespace gissar::render {

class MaskRowPainter;  // profile_mask.h

class GridProfileSweep {
 public:
  static constexpr uint32_t kNoHit = 0xFFFFFFFFu;

  // `posts`: width x height posts (ENU metres, row-major, all finite, at
  // least 2 x 2), triangulated as scene::MeshFromGrid does (two triangles
  // per cell, scene::GridCellTriangles): a hit names triangle
  // 2 * (r * (width - 1) + c) + k of cell (c, r), k = 0 for the triangle
  // holding post (c, r). `posts` must outlive the sweep. CHECKs the sizes.
  GridProfileSweep(const Eigen::Vector3f* posts, int width, int height, const sensor::SarGeometry& geometry);

  // The rays of the azimuth line at along-track coordinate `a_m` (metres
  // from the scene centre along the flight direction h): ray j in [0, count)
  // has coordinate e_j = e0 + j * de, de > 0, and runs
  //   affine: along the look direction l at offset e_j (metres) along the
  //           range-plane normal n from the scene centre's line;
  //   exact:  from the sensor at a_m along cos(e_j) l + sin(e_j) n (e_j in
  //           radians, |e_j| < pi / 2).
  // Fills, for each ray, depth_m[j]: the hit's coordinate along l from the
  // scene centre (affine) or its distance from the sensor (exact),
  // triangle[j] (kNoHit when the ray misses; depth_m and normal are then
  // left alone) and, when `normal` is not null, normal[j]: the triangle's
  // TriangleMesh::Normal (Normal below).
  // The hit is the first crossing of the ray with the grid's triangles,
  // front or back face. Returns false, leaving the outputs undefined, when
  // the line does not cross the grid in one piece (its boundary crosses the
  // line more than twice): trace such a line otherwise.
  bool Trace(double a_m, double e0, double de, int count, double* depth_m, uint32_t* triangle,
             Eigen::Vector3f* normal = nullptr) const;

  // One triangle of the grid: cell (c, r) and its half (0: the triangle
  // holding post (c, r)).
  struct Facet {
    int c, r, half;
  };
  // The mesh's index of a facet's triangle.
  uint32_t Triangle(const Facet& f) const { return uint32_t(2 * (int64_t(f.r) * (width_ - 1) + f.c) + f.half); }
  // TriangleMesh::Normal of the grid mesh's triangle (the same floats),
  // computed from the posts.
  Eigen::Vector3f Normal(const Facet& facet) const {
    const Eigen::Vector3i t = scene::GridCellTriangles(width_, facet.c, facet.r, column_cross_row_up_)[facet.half];
    return scene::TriangleNormal(posts_[t[0]], posts_[t[1]], posts_[t[2]]);
  }

  // A point of a line's profile: its coordinates from the scene centre
  // along l (xl) and n (e), and along the horizontal look direction (g).
  struct ProfilePoint {
    double xl, e, g;
  };
  // The frontiers of a line's profile, for rays at any coordinate
  // (sub-rays between the grid's): the profile segments that raised the
  // running maximum of the Coordinate (upper) or lowered its running minimum
  // (lower), in walk order, each with the extreme reached at its end. A ray
  // of coordinate v above the entry point's first meets the profile on the
  // first upper segment that reaches v, one below it on the first lower
  // segment that reaches v (FrontierHit), as Trace assigns its rays.
  struct FrontierSegment {
    double reached;
    double from_xl, from_e, to_xl, to_e;
    uint32_t triangle;
  };
  struct Frontier {
    double entry = 0.0;  // the entry point's Coordinate
    std::vector<FrontierSegment> upper, lower;
  };
  // The part of the profile inside one triangle, and the horizon before it:
  // the highest Elevation of the profile from its near end to `from`. A
  // point of the segment with an Elevation below the horizon is hidden from
  // the radar.
  struct ProfileSegment {
    ProfilePoint from, to;
    double horizon;
    Facet facet;
  };
  // The rays of one azimuth line and where their hits go (Trace's arguments).
  struct LineRays {
    double a_m, e0, de;
    // Ray j in [0, count) has coordinate e0 + (first + j) * de (Trace's
    // rays with first = 0).
    int first, count;
    double* depth_m;
    uint32_t* triangle;
    Eigen::Vector3f* normal;  // may be null
    // Exact mode: tan of ray j's coordinate for j < count, or null (computed
    // per ray).
    const double* tan_e = nullptr;
    // When not null: the line's frontiers, recorded until the running
    // maximum reaches `frontier_above` and the running minimum
    // `frontier_below` (Coordinates), or the profile ends.
    Frontier* frontier = nullptr;
    double frontier_below = 0.0, frontier_above = 0.0;
    // When not null: given every segment of the line's profile in order
    // away from the radar, with its horizon, as ProfileLines gives them
    // (profile_mask.h; the walk then goes on to the profile's end whatever
    // the rays need; none when the line misses the grid or is refused).
    MaskRowPainter* mask_row = nullptr;
  };
  // Trace for several lines, walked in lockstep (a stretch of each in turn:
  // neighbouring lines cross the same posts, which the next line then finds
  // in cache); ok[k]: Trace's result for lines[k].
  void TraceLines(const std::vector<LineRays>& lines, uint8_t* ok) const;

  // The profiles of `lines` lines at a_m[k] (as Trace), walked in lockstep:
  // calls segment(k, ProfileSegment) for line k's segments in order away
  // from the radar (none when the line misses the grid); ok[k]: false when
  // the line does not cross the grid in one piece (as Trace; line k's calls
  // so far are then void).
  template <class Segment>
  void ProfileLines(const double* a_m, size_t lines, uint8_t* ok, Segment&& segment) const;
  // The first hit of the ray of Coordinate `v` (affine: its offset e;
  // exact: the tangent of its angle) on the line whose `frontier` was
  // recorded: true with its depth (as Trace's depth_m) and triangle (front
  // or back face, as Trace) when a frontier segment reaches v; false when v
  // equals the entry point's Coordinate or no recorded segment reaches it
  // (the ray misses, or the recording stopped short of v).
  bool FrontierHit(const Frontier& frontier, double v, double* depth_m, uint32_t* triangle) const;

  // The coordinate the rays of a line are ordered by: affine e (metres along
  // n), exact tan of the angle from l seen from the sensor.
  double Coordinate(const ProfilePoint& p) const { return affine_ ? p.e : p.e / (range0_ + p.xl); }
  // The same, increasing upwards (n may point down: a left-looking radar).
  double Elevation(const ProfilePoint& p) const { return up_sign_ * Coordinate(p); }

 private:
  // A grid edge on the boundary: triangle (c, r, half) and its edge index.
  struct BoundaryEdge {
    int c, r, half, edge;
  };
  // A post's coordinates from the scene centre: along h (a), l (xl), n (e)
  // and the horizontal look direction (g).
  struct PostValues {
    double a, xl, e, g;
  };
  PostValues Values(int64_t post) const {
    const Eigen::Vector3f& p = posts_[post];
    const double x = double(p.x()) - xc_.x(), y = double(p.y()) - xc_.y(), z = double(p.z()) - xc_.z();
    return {x * h_.x() + y * h_.y() + z * h_.z(), x * l_.x() + y * l_.y() + z * l_.z(),
            x * n_.x() + y * n_.y() + z * n_.z(), x * ground_.x() + y * ground_.y()};
  }
  double AlongTrack(int64_t post) const { return Values(post).a; }
  // A walk along one line's profile from its near end, resumable.
  class LineWalk {
   public:
    enum class State { kMissed, kRefused, kWalking, kDone };
    // Finds the line's entry: kMissed when it misses the grid, kRefused when
    // the grid's boundary crosses it other than twice.
    LineWalk(const GridProfileSweep& sweep, double a_m);
    State state() const { return state_; }
    // Crosses at most `steps` more triangles, calling
    // segment(from, to, facet) for each, until that returns false or the
    // line leaves the grid (kDone).
    template <class Segment>
    void Advance(int steps, Segment&& segment);

   private:
    ProfilePoint Crossing(const PostValues& p, const PostValues& q) const {
      const double lambda = (a_m_ - p.a) / (q.a - p.a);
      return ProfilePoint{p.xl + lambda * (q.xl - p.xl), p.e + lambda * (q.e - p.e), p.g + lambda * (q.g - p.g)};
    }
    const GridProfileSweep* sweep_;
    double a_m_;
    State state_ = State::kMissed;
    int c_ = 0, r_ = 0, half_ = 0, in_edge_ = 0;
    // The entry edge's two posts and their values, carried from triangle to
    // triangle: each step computes only the new corner's.
    std::array<int64_t, 2> in_post_{};
    std::array<PostValues, 2> in_value_{};
    ProfilePoint from_{};
    int64_t steps_left_ = 0;  // a bound that no walk reaches
  };
  // Walks `walks` in lockstep, kLockstepSteps triangles of each in turn,
  // calling segment(k, from, to, facet) for walk k until all are done.
  template <class Segment>
  void Lockstep(std::vector<LineWalk>& walks, Segment&& segment) const;
  static constexpr int kLockstepSteps = 64;

  // The walk's triangles: cell (c, r), half 0 with corners (a, b, d) and
  // half 1 with corners (b, e, d), where a = (c, r), b = (c + 1, r),
  // d = (c, r + 1), e = (c + 1, r + 1) (scene::GridCellTriangles'
  // triangles, corners in this fixed order whatever their winding). Edge k
  // joins corners k and k + 1. Across edge k of half h lies the triangle
  // (c + dc, r + dr, half), entered through its edge `edge`.
  struct Across {
    int dc, dr, half, edge;
  };
  static constexpr Across kAcross[2][3] = {
      {{0, -1, 1, 1}, {0, 0, 1, 2}, {-1, 0, 1, 0}},  // half 0: a-b (row r), b-d (diagonal), d-a (column c)
      {{1, 0, 0, 2}, {0, 1, 0, 0}, {0, 0, 0, 1}},    // half 1: b-e (column c + 1), e-d (row r + 1), d-b
  };
  std::array<int64_t, 3> Corners(int c, int r, int half) const {
    const int64_t a = int64_t(r) * width_ + c;
    return half == 0 ? std::array<int64_t, 3>{a, a + 1, a + width_}
                     : std::array<int64_t, 3>{a + 1, a + width_ + 1, a + width_};
  }
  // Whether the line a = A crosses the edge between posts with along-track
  // coordinates a_p and a_q: the rule (a_p < A) != (a_q < A) counts every
  // crossing once, whichever triangle asks (exactly 0 or 2 edges of a
  // triangle cross).
  static bool Crosses(double a_p, double a_q, double A) { return (a_p < A) != (a_q < A); }
  const Eigen::Vector3f* posts_;
  int width_, height_;
  bool affine_;
  Eigen::Vector3d xc_, h_, l_, n_, ground_;
  double range0_;
  double up_sign_;  // +1 when n points up, else -1
  bool column_cross_row_up_;  // scene::GridColumnCrossRowUp of the grid
  // Boundary edges bucketed by along-track coordinate: bucket k holds the
  // edges whose along-track span meets [a_lo_ + k w, a_lo_ + (k + 1) w).
  double a_lo_ = 0.0, bucket_width_ = 1.0;
  std::vector<BoundaryEdge> edges_;
  std::vector<uint32_t> bucket_start_, bucket_edges_;
};

template <class Segment>
void GridProfileSweep::LineWalk::Advance(int steps, Segment&& segment) {
  if (state_ != State::kWalking) return;
  const GridProfileSweep& s = *sweep_;
  // The walk's state in locals for the loop (the segment callback writes
  // through pointers, which would otherwise force every member back to
  // memory at each step), stored back on the way out.
  int c = c_, r = r_, half = half_, in_edge = in_edge_;
  std::array<int64_t, 2> in_post = in_post_;
  std::array<PostValues, 2> in_value = in_value_;
  ProfilePoint from = from_;
  int64_t steps_left = steps_left_;
  const double a_m = a_m_;
  State state = State::kWalking;
  for (int k = 0; k < steps; ++k) {
    GISSAR_CHECK(--steps_left >= 0);
    const auto corners = s.Corners(c, r, half);
    // Entry edge: corners in_edge (A) and in_edge + 1 (B); the others B-C, C-A.
    const int64_t A = corners[size_t(in_edge)], B = corners[size_t((in_edge + 1) % 3)],
                  C = corners[size_t((in_edge + 2) % 3)];
    const bool same_order = in_post[0] == A;
    const PostValues vA = same_order ? in_value[0] : in_value[1];
    const PostValues vB = same_order ? in_value[1] : in_value[0];
    const PostValues vC = s.Values(C);
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
    const ProfilePoint to = Crossing(in_value[0], in_value[1]);
    if (!segment(from, to, Facet{c, r, half})) {
      state = State::kDone;
      break;
    }
    const Across& next = kAcross[half][out_edge];
    c += next.dc;
    r += next.dr;
    if (c < 0 || r < 0 || c > s.width_ - 2 || r > s.height_ - 2) {  // left the grid
      state = State::kDone;
      break;
    }
    half = next.half;
    in_edge = next.edge;
    from = to;
  }
  state_ = state;
  c_ = c;
  r_ = r;
  half_ = half;
  in_edge_ = in_edge;
  in_post_ = in_post;
  in_value_ = in_value;
  from_ = from;
  steps_left_ = steps_left;
}

template <class Segment>
void GridProfileSweep::Lockstep(std::vector<LineWalk>& walks, Segment&& segment) const {
  for (bool any = true; any;) {
    any = false;
    for (size_t k = 0; k < walks.size(); ++k) {
      if (walks[k].state() != LineWalk::State::kWalking) continue;
      walks[k].Advance(kLockstepSteps, [&](const ProfilePoint& from, const ProfilePoint& to, const Facet& facet) {
        return segment(k, from, to, facet);
      });
      any = any || walks[k].state() == LineWalk::State::kWalking;
    }
  }
}

template <class Segment>
void GridProfileSweep::ProfileLines(const double* a_m, size_t lines, uint8_t* ok, Segment&& segment) const {
  std::vector<LineWalk> walks;
  walks.reserve(lines);
  for (size_t k = 0; k < lines; ++k) walks.emplace_back(*this, a_m[k]);
  std::vector<double> horizon(lines, -std::numeric_limits<double>::infinity());
  Lockstep(walks, [&](size_t k, const ProfilePoint& from, const ProfilePoint& to, const Facet& facet) {
    horizon[k] = std::max(horizon[k], Elevation(from));
    segment(k, ProfileSegment{from, to, horizon[k], facet});
    return true;
  });
  for (size_t k = 0; k < lines; ++k) ok[k] = walks[k].state() != LineWalk::State::kRefused;
}

}  // namespace gissar::render
