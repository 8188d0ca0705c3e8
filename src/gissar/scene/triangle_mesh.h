// The scene geometry every renderer consumes: a triangle mesh in the scene's
// local ENU frame (metres) with a radar class per triangle.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gissar::scene {

// Radar class of a triangle; indexes the material table. 0 is "default"
// (bare terrain).
using ClassId = uint8_t;
inline constexpr ClassId kDefaultClass = 0;

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;   // ENU metres
  // Vertex indices, counter-clockwise seen from the side the normal points
  // to: every triangle, or with an implicit grid (below) the triangles after
  // the grid's (triangle t is triangles[t - GridTriangleCount()]). Read a
  // triangle with Triangle(t), count them with triangle_count().
  std::vector<Eigen::Vector3i> triangles;
  std::vector<ClassId> classes;            // one per triangle (triangle_count())
  // An implicit grid (GridMesh): vertices [0, grid_width * grid_height) are
  // a grid's posts, row-major, and triangles [0, GridTriangleCount()) are
  // MeshFromGrid's two triangles of each of its cells, computed on demand
  // instead of stored (a 8192^2 DEM's index array is 1.6 GB). grid_width 0:
  // none, every triangle is in `triangles`.
  int grid_width = 0;
  int grid_height = 0;
  bool grid_column_cross_row_up = true;  // GridColumnCrossRowUp of the grid
  // Optional per-vertex unit shading normals (smooth terrain): empty = flat
  // shading everywhere; a zero vector at any vertex of a triangle = flat
  // shading for that triangle (buildings). Geometry (hits, shadows, back
  // faces, mirror directions) always uses the facet normal.
  std::vector<Eigen::Vector3f> shading_normals;

  size_t GridTriangleCount() const {
    return grid_width > 1 ? size_t(grid_width - 1) * size_t(grid_height - 1) * 2 : 0;
  }
  size_t triangle_count() const { return GridTriangleCount() + triangles.size(); }
  // Vertex indices of triangle t (t < triangle_count()).
  Eigen::Vector3i Triangle(size_t t) const;
  // Stores the implicit grid's triangles in `triangles` (no implicit grid
  // afterwards): for code that hands the index array to another library.
  void MakeExplicit();

  // Shading normal of triangle `t` at barycentric (u, v) (the point
  // (1-u-v) v0 + u v1 + v v2): the normalised interpolation of its vertices'
  // shading normals, or Normal(t) when it has none.
  Eigen::Vector3f ShadingNormal(size_t t, float u, float v) const;

  // Sets shading_normals to the area-weighted mean of the facet normals of
  // the triangles around each vertex, over triangles whose class is not
  // `excluded` (e.g. buildings: their vertices get zero normals when no
  // other triangle uses them).
  void SmoothShadingNormals(ClassId excluded);

  // Unit normal of triangle `t` (right-hand rule on its vertex order); zero
  // for a degenerate triangle.
  Eigen::Vector3f Normal(size_t t) const;

  // Axis-aligned bounds of all vertices (empty box for an empty mesh).
  Eigen::AlignedBox3d Bounds() const;

  // Appends `other`, re-indexing its triangles.
  void Append(const TriangleMesh& other);

  // Adds a triangle (a, b, c) of class `cls`, the vertices appended.
  void AddTriangle(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
                   ClassId cls = kDefaultClass);
  // Adds the quad a-b-c-d (in order around its boundary) as two triangles.
  void AddQuad(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
               const Eigen::Vector3f& d, ClassId cls = kDefaultClass);

  // Bytes held by the mesh arrays.
  size_t MemoryBytes() const;
};

// Whether (next column) x (next row) points up at the first post of a grid
// `width` posts wide (row-major `posts`, at least 2 x 2): the orientation
// MeshFromGrid's triangles follow.
inline bool GridColumnCrossRowUp(const Eigen::Vector3f* posts, int width) {
  return (posts[1] - posts[0]).cross(posts[size_t(width)] - posts[0]).z() > 0.0f;
}

// Unit normal of the triangle (v0, v1, v2), counter-clockwise seen from
// where it points; zero for a degenerate triangle (TriangleMesh::Normal).
inline Eigen::Vector3f TriangleNormal(const Eigen::Vector3f& v0, const Eigen::Vector3f& v1, const Eigen::Vector3f& v2) {
  const Eigen::Vector3f n = (v1 - v0).cross(v2 - v0);
  const float norm = n.norm();
  return norm > 0.0f ? Eigen::Vector3f(n / norm) : Eigen::Vector3f::Zero();
}

// MeshFromGrid's two triangles of cell (c, r) of a grid `width` posts wide
// (vertex r * width + c is post (c, r)): split from post (c + 1, r) to
// (c, r + 1), counter-clockwise seen from above (`column_cross_row_up`:
// GridColumnCrossRowUp). The first holds post (c, r), the second (c + 1, r + 1).
inline std::array<Eigen::Vector3i, 2> GridCellTriangles(int width, int c, int r, bool column_cross_row_up) {
  const int a = r * width + c, b = a + 1, d = a + width, e = d + 1;
  if (column_cross_row_up) return {Eigen::Vector3i(a, b, d), Eigen::Vector3i(b, e, d)};
  return {Eigen::Vector3i(a, d, b), Eigen::Vector3i(b, d, e)};
}

// Terrain mesh of a grid of posts (row-major, `width` x `height`, e.g. the
// DEM posts in ENU): two triangles per cell (GridCellTriangles), normals
// pointing up (+z), class kDefaultClass. CHECKs that the grid has at least
// 2x2 posts.
TriangleMesh MeshFromGrid(const std::vector<Eigen::Vector3f>& posts, int width, int height);
// The same, taking the posts over (no copy of the vertex array).
TriangleMesh MeshFromGrid(std::vector<Eigen::Vector3f>&& posts, int width, int height);
// The same triangles kept implicit (TriangleMesh::grid_width): no index
// array, Triangle(t) computes them. Same CHECKs.
TriangleMesh GridMesh(std::vector<Eigen::Vector3f>&& posts, int width, int height);

// A terrain grid at the start of a mesh that is not all grid (a GIS scene):
// vertices [0, width * height) are the DEM posts, row-major, and triangles
// [0, 2 * cells) are MeshFromGrid's two triangles of each of `cells` grid
// cells, in row-major cell order; the other cells' surface is elsewhere in
// the mesh. cells == 0: none.
struct GridPrefix {
  int width = 0;
  int height = 0;
  int64_t cells = 0;
};

// The cells of `prefix` ((width - 1) x (height - 1) row-major, 1 = one of
// its grid cells), read from the mesh's first triangles; nullopt when the
// mesh does not start that way (too few vertices or triangles, a pair that
// is not a cell's MeshFromGrid triangles, cells out of order).
std::optional<std::vector<uint8_t>> GridPrefixCells(const TriangleMesh& mesh, const GridPrefix& prefix);

// Terrain mesh of a regular height grid in the ENU frame: post (c, r) at
// x = x0 + c * spacing_m, y = y0 + r * spacing_m, z = heights[r * width + c].
// Convenience for synthetic scenes and tests.
TriangleMesh MeshFromHeights(const std::vector<float>& heights, int width, int height,
                             double spacing_m, double x0 = 0.0, double y0 = 0.0);

}  // namespace gissar::scene
