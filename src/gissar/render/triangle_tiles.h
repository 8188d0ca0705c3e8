// A plan-view tile index of a triangle mesh, for passes that visit only the
// triangles near one image (the layover/shadow mask's ray pass over a
// large scene: RenderLayoverShadowMask).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {

class TriangleTiles {
 public:
  // About this many triangles per tile on average.
  static constexpr size_t kTrianglesPerTile = 512;

  // Groups the triangles [first, triangle_count()) of `mesh` (at least
  // one) by the tile of a uniform grid over the mesh's plan (x, y) bounds
  // that holds its centroid; each tile keeps the 3-D bounds (ENU metres) of
  // its whole triangles, so a triangle lies inside its tile's bounds.
  explicit TriangleTiles(const scene::TriangleMesh& mesh, size_t first = 0);

  // The first triangle held (the constructor's `first`).
  size_t first() const { return first_triangle_; }
  size_t tile_count() const { return bounds_.size(); }
  size_t triangle_count() const { return triangles_.size(); }
  // Tile k's triangles, ascending, and their bounds (empty for a tile
  // without triangles).
  const uint32_t* begin(size_t k) const { return triangles_.data() + first_[k]; }
  const uint32_t* end(size_t k) const { return triangles_.data() + first_[k + 1]; }
  const Eigen::AlignedBox3d& bounds(size_t k) const { return bounds_[k]; }

 private:
  size_t first_triangle_ = 0;
  std::vector<uint32_t> first_;      // tile k: triangles_[first_[k], first_[k + 1])
  std::vector<uint32_t> triangles_;  // mesh triangle indices, tile by tile
  std::vector<Eigen::AlignedBox3d> bounds_;
};

}  // namespace gissar::render
