#include "gissar/render/triangle_tiles.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gissar/util/check.h"

namespace gissar::render {

TriangleTiles::TriangleTiles(const scene::TriangleMesh& mesh, size_t first) : first_triangle_(first) {
  const size_t all = mesh.triangle_count();
  GISSAR_CHECK(first < all && all <= std::numeric_limits<uint32_t>::max());
  const size_t count = all - first;
  const Eigen::AlignedBox3d box = mesh.Bounds();
  const double span_x = std::max(box.sizes().x(), 1e-3), span_y = std::max(box.sizes().y(), 1e-3);
  // Square-ish tiles, about kTrianglesPerTile triangles each.
  const double tiles = std::max(1.0, double(count) / double(kTrianglesPerTile));
  const int nx = std::clamp(static_cast<int>(std::ceil(std::sqrt(tiles * span_x / span_y))), 1, 4096);
  const int ny = std::clamp(static_cast<int>(std::ceil(tiles / nx)), 1, 4096);
  const double to_x = nx / span_x, to_y = ny / span_y;
  std::vector<uint32_t> tile_of(count);
  first_.assign(size_t(nx) * ny + 1, 0);
  bounds_.assign(size_t(nx) * ny, Eigen::AlignedBox3d());
  for (size_t t = 0; t < count; ++t) {
    const Eigen::Vector3i tri = mesh.Triangle(first + t);
    Eigen::AlignedBox3d b;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d v = mesh.vertices[size_t(tri[k])].cast<double>();
      b.extend(v);
      centroid += v / 3.0;
    }
    const int cx = std::clamp(static_cast<int>((centroid.x() - box.min().x()) * to_x), 0, nx - 1);
    const int cy = std::clamp(static_cast<int>((centroid.y() - box.min().y()) * to_y), 0, ny - 1);
    const uint32_t tile = uint32_t(cy) * uint32_t(nx) + uint32_t(cx);
    tile_of[t] = tile;
    ++first_[tile + 1];
    bounds_[tile].extend(b);
  }
  for (size_t k = 1; k < first_.size(); ++k) first_[k] += first_[k - 1];
  triangles_.resize(count);
  std::vector<uint32_t> next(first_.begin(), first_.end() - 1);
  for (size_t t = 0; t < count; ++t) triangles_[next[tile_of[t]]++] = uint32_t(first + t);
}

}  // namespace gissar::render
