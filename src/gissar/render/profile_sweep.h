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

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::render {

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
  // The part of the profile inside one triangle, and the horizon before it:
  // the highest Elevation of the profile from its near end to `from`. A
  // point of the segment with an Elevation below the horizon is hidden from
  // the radar.
  struct ProfileSegment {
    ProfilePoint from, to;
    double horizon;
    Facet facet;
  };
  // The profile of the line at `a_m` (as Trace), segments in order away
  // from the radar; empty when the line misses the grid. False as Trace.
  bool Profile(double a_m, std::vector<ProfileSegment>* segments) const;
  // The coordinate the rays of a line are ordered by: affine e (metres along
  // n), exact tan of the angle from l seen from the sensor.
  double Coordinate(const ProfilePoint& p) const { return affine_ ? p.e : p.e / (range0_ + p.xl); }
  // The same, increasing upwards (n may point down: a left-looking radar).
  double Elevation(const ProfilePoint& p) const { return up_sign_ * Coordinate(p); }

 private:
  // Walks the line's profile from its near end, calling
  // segment(from, to, triangle) for each triangle crossed, until it returns
  // false. False when the line does not cross the grid in one piece.
  template <class Segment>
  bool Walk(double a_m, Segment&& segment) const;
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

}  // namespace gissar::render
