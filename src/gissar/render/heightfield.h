// Terrain as a height field: ray queries on the triangles of a grid of posts
// (scene::MeshFromGrid's mesh) without a per-triangle BVH. A min-max
// mip-map -- a quadtree of 3-D bounding boxes over the grid's cells -- is the
// whole index: its memory is about a third of a box per cell, against
// Embree's BVH over every quad. Boxes are bounds of the posts in the scene
// frame (ENU), not of heights over a plan grid, so posts of a geographic DEM
// (curved, unevenly spaced rows in ENU) are bounded exactly as well.
//
// The quadtree's nodes at level kTileLevel (tiles of 2^kTileLevel cells a
// side) are the primitives EmbreeScene hands to Embree as a user geometry;
// Embree's BVH over the tiles (262 k boxes for a 4096^2 DEM) finds the tiles
// a ray crosses and the traversal below descends each, for one ray or for
// the lanes of a packet together (IntersectPacket).
//
// Triangle tests are watertight (Woop, Benthin & Wald 2013, in double
// precision): edge functions of an edge shared by two triangles are computed
// from the same transformed posts, so a ray through a shared edge or post
// hits at least one of them. A hit is a function of the ray and the
// triangle's three posts only, never of the traversal order.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <emmintrin.h>
#include <xmmintrin.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace gissar::render {

// A ray prepared for the height field: origin, direction and the shear of the
// watertight triangle test. Directions need not be unit length (t is in units
// of the direction's length).
struct HeightfieldRay {
  HeightfieldRay(const float org[3], const float dir[3]);
  // Moves the ray to another origin (the direction and shear unchanged).
  void SetOrigin(float x, float y, float z) {
    org[0] = org_f[0] = x;
    org[1] = org_f[1] = y;
    org[2] = org_f[2] = z;
  }
  double org[3];
  float org_f[3];
  float dir_f[3];
  float inv_dir[3];  // 1 / dir (0 where dir is 0)
  bool parallel[3];  // dir has no component along the axis
  int kx = 0, ky = 1, kz = 2;
  double sx = 0.0, sy = 0.0, sz = 1.0;
};

// A candidate hit: ray parameter, mesh triangle (scene::MeshFromGrid's
// numbering: triangles 2k and 2k + 1 of the k-th cell of the height field,
// row-major; without holes cell k = row * (width - 1) + column), its
// barycentrics (point = (1 - u - v) v0 + u v1 + v v2 in the mesh's vertex
// order of that triangle), and its cell and half (0: the triangle holding
// post (c, r), 1: the one holding (c + 1, r + 1)).
struct HeightfieldHit {
  float t = 0.0f;
  uint32_t triangle = 0;
  float u = 0.0f, v = 0.0f;
  uint32_t cell = 0;
  int half = 0;
};

class HeightfieldTree {
 public:
  // Tiles are nodes of 2^kTileLevel x 2^kTileLevel cells (measured on a
  // 4096^2 fractal DEM, docs/performance.md).
  static constexpr int kTileLevel = 3;

  // Builds the quadtree over the `width` x `height` posts (row-major, ENU
  // metres), which must outlive the tree. Non-finite posts bound nothing
  // (their triangles are never hit). `cells` (optional, (width - 1) x
  // (height - 1) row-major, nonzero = in): the cells of the height field;
  // the others are holes, never hit (a GIS scene's cells that its
  // constraints triangulate otherwise), and the mesh numbers only the cells
  // in. CHECKs at least 2 x 2 posts and the size of `cells`.
  HeightfieldTree(const Eigen::Vector3f* posts, int width, int height, const std::vector<uint8_t>* cells = nullptr);

  int width() const { return width_; }
  int height() const { return height_; }
  // Tiles that hold at least one finite post, in row-major tile order.
  size_t tile_count() const { return tiles_.size(); }
  // Bounds of tile `tile` (an index below tile_count()).
  void TileBounds(size_t tile, float lower[3], float upper[3]) const;
  // Bytes held by the quadtree.
  size_t MemoryBytes() const;
  // Corner posts of `triangle` in the mesh's vertex order.
  void TriangleCorners(uint32_t triangle, const Eigen::Vector3f* corners[3]) const;
  // The same for half `half` of grid cell `cell` (row-major over all cells).
  void CellCorners(uint32_t cell, int half, const Eigen::Vector3f* corners[3]) const;
  // Cells in the height field (all of them without holes).
  size_t cell_count() const { return masked_ ? size_t(rank_before_.back()) : size_t(width_ - 1) * (height_ - 1); }

  // Offers every triangle of tile `tile` that the ray meets at t in
  // [t_near, *t_far] to `accept(const HeightfieldHit&)`, boxes nearest
  // first; accept returns the new far end of the search (the hit's t when it
  // keeps it, *t_far unchanged when it rejects it, or -infinity to stop).
  template <class Accept>
  void Intersect(size_t tile, const HeightfieldRay& ray, float t_near, float* t_far, Accept&& accept) const;

  // The same for the lanes k of a packet with bit k of `lanes` set (up to
  // 16; rays[k], t_near[k], t_far[k]): one walk of the tile for all of
  // them, each node and leaf's cell boxes loaded once, each lane tested
  // against its own boxes. accept(k, hit) returns lane k's new far end
  // (-infinity ends that lane). Offers each lane exactly the hits
  // Intersect would.
  template <class Accept>
  void IntersectPacket(size_t tile, const HeightfieldRay* rays, uint32_t lanes, const float* t_near, float* t_far,
                       Accept&& accept) const;

 private:
  struct Box {
    float lower[3], upper[3];
  };
  // The four children of a node (children (2i + di, 2j + dj) at index
  // 2 dj + di), structure of arrays for a 4-wide slab test; a missing child
  // (beyond the grid's border, or without a finite post) has lower > upper.
  struct alignas(16) Group {
    // Left uninitialised (every field is written when a level is built, in
    // parallel): a level's groups are then first touched by the threads
    // that fill them, not zeroed on one thread by the vector's resize.
    Group() {}  // NOLINT(modernize-use-equals-default): = default would value-initialise
    float lower[3][4];
    float upper[3][4];
  };
  struct Level {
    int nx = 0, ny = 0;         // nodes of this level
    std::vector<Group> groups;  // their children (levels >= 2)
  };
  // Slab test of the four boxes of `group`: bit q of the result is set when
  // child q's padded box meets the ray within [t_near, t_far]; t0[q] its
  // entry distance. Padding: each distance carries a few roundings of
  // relative size 2^-24, so a point on a box's boundary stays inside.
  static int SlabGroup(const Group& group, const HeightfieldRay& ray, float t_near, float t_far, float t0[4]);
  // Tests the cells of the level-1 node (i, j) (up to 2 x 2 cells):
  // their boxes (from the posts), then the triangles of the cells the ray
  // meets. False when accept stopped the search.
  template <class Accept>
  bool IntersectLeaf(int i, int j, const HeightfieldRay& ray, float t_near, float* t_far, Accept& accept) const;
  void CellBoxes(int i, int j, Group* cells) const;
  template <class Accept>
  bool LeafTriangles(int i, int j, const Group& cells, const HeightfieldRay& ray, float t_near, float* t_far,
                     Accept& accept) const;

  // Holes: bit k of cell_bits_ (row-major cell k) set for a cell in;
  // rank_before_[w] counts the cells in before word w (one more entry at
  // the end: the total).
  bool Included(size_t cell) const { return !masked_ || (cell_bits_[cell >> 6] >> (cell & 63)) & 1u; }
  uint32_t TriangleOf(size_t cell, int half) const {
    if (!masked_) return uint32_t(2 * cell + size_t(half));
    const uint64_t below = cell_bits_[cell >> 6] & ((uint64_t{1} << (cell & 63)) - 1);
    return 2 * (rank_before_[cell >> 6] + uint32_t(__builtin_popcountll(below))) + uint32_t(half);
  }
  const Eigen::Vector3f* posts_;
  int width_, height_;
  bool masked_ = false;
  std::vector<uint64_t> cell_bits_;
  std::vector<uint32_t> rank_before_;
  bool column_cross_row_up_ = true;  // MeshFromGrid's triangle orientation
  bool all_finite_ = true;           // every post has finite coordinates
  std::vector<Level> levels_;        // levels 1 .. kTileLevel (level 1 holds no groups)
  std::vector<Box> tile_boxes_;      // bounds of the non-empty tiles
  std::vector<uint32_t> tiles_;      // their node index (j * nx + i) at level kTileLevel
};

// In line: it runs for every lane of every tile a packet reaches.
inline HeightfieldRay::HeightfieldRay(const float origin[3], const float direction[3]) {
  for (int a = 0; a < 3; ++a) {
    org[a] = origin[a];
    org_f[a] = origin[a];
    dir_f[a] = direction[a];
    parallel[a] = direction[a] == 0.0f;
    inv_dir[a] = parallel[a] ? 0.0f : 1.0f / direction[a];
  }
  // The watertight test's frame: z along the direction's largest component,
  // x and y swapped when it is negative (keeps the winding).
  kz = 0;
  for (int a = 1; a < 3; ++a) {
    if (std::abs(direction[a]) > std::abs(direction[kz])) kz = a;
  }
  kx = (kz + 1) % 3;
  ky = (kx + 1) % 3;
  if (direction[kz] < 0.0f) std::swap(kx, ky);
  sx = double(direction[kx]) / double(direction[kz]);
  sy = double(direction[ky]) / double(direction[kz]);
  sz = 1.0 / double(direction[kz]);
}

inline int HeightfieldTree::SlabGroup(const Group& group, const HeightfieldRay& ray, float t_near, float t_far,
                                      float t0[4]) {
  __m128 lo = _mm_set1_ps(-std::numeric_limits<float>::infinity());
  __m128 hi = _mm_set1_ps(std::numeric_limits<float>::infinity());
  __m128 valid = _mm_cmple_ps(_mm_load_ps(group.lower[0]), _mm_load_ps(group.upper[0]));
  for (int a = 0; a < 3; ++a) {
    const __m128 l = _mm_load_ps(group.lower[a]), u = _mm_load_ps(group.upper[a]);
    const __m128 o = _mm_set1_ps(ray.org_f[a]);
    if (ray.parallel[a]) {
      // Inside the slab for every t, or never.
      valid = _mm_and_ps(valid, _mm_and_ps(_mm_cmple_ps(l, o), _mm_cmple_ps(o, u)));
      continue;
    }
    const __m128 inv = _mm_set1_ps(ray.inv_dir[a]);
    const __m128 n = _mm_mul_ps(_mm_sub_ps(l, o), inv), f = _mm_mul_ps(_mm_sub_ps(u, o), inv);
    lo = _mm_max_ps(lo, _mm_min_ps(n, f));
    hi = _mm_min_ps(hi, _mm_max_ps(n, f));
  }
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 rel = _mm_set1_ps(1e-6f), abs_pad = _mm_set1_ps(1e-4f);
  lo = _mm_sub_ps(lo, _mm_add_ps(_mm_mul_ps(_mm_and_ps(lo, abs_mask), rel), abs_pad));
  hi = _mm_add_ps(hi, _mm_add_ps(_mm_mul_ps(_mm_and_ps(hi, abs_mask), rel), abs_pad));
  valid = _mm_and_ps(valid, _mm_cmple_ps(lo, hi));
  valid = _mm_and_ps(valid, _mm_cmpge_ps(hi, _mm_set1_ps(t_near)));
  valid = _mm_and_ps(valid, _mm_cmple_ps(lo, _mm_set1_ps(t_far)));
  _mm_storeu_ps(t0, lo);
  return _mm_movemask_ps(valid);
}

template <class Accept>
bool HeightfieldTree::IntersectLeaf(int i, int j, const HeightfieldRay& ray, float t_near, float* t_far,
                                    Accept& accept) const {
  alignas(16) Group cells;
  CellBoxes(i, j, &cells);
  return LeafTriangles(i, j, cells, ray, t_near, t_far, accept);
}

inline void HeightfieldTree::CellBoxes(int i, int j, Group* out) const {
  const int c0 = 2 * i, r0 = 2 * j;
  const int nc = std::min(2, width_ - 1 - c0), nr = std::min(2, height_ - 1 - r0);
  Group& cells = *out;
  for (int q = 0; q < 4; ++q) {
    for (int a = 0; a < 3; ++a) {
      cells.lower[a][q] = std::numeric_limits<float>::infinity();
      cells.upper[a][q] = -std::numeric_limits<float>::infinity();
    }
  }
  for (int dr = 0; dr < nr; ++dr) {
    for (int dc = 0; dc < nc; ++dc) {
      const int q = 2 * dr + dc;
      if (masked_ && !Included(size_t(r0 + dr) * (width_ - 1) + (c0 + dc))) continue;  // a hole: empty box
      const Eigen::Vector3f* p = posts_ + size_t(r0 + dr) * width_ + (c0 + dc);
      if (all_finite_) {
        for (int a = 0; a < 3; ++a) {
          cells.lower[a][q] = std::min(std::min(p[0][a], p[1][a]), std::min(p[width_][a], p[width_ + 1][a]));
          cells.upper[a][q] = std::max(std::max(p[0][a], p[1][a]), std::max(p[width_][a], p[width_ + 1][a]));
        }
        continue;
      }
      for (const Eigen::Vector3f* post : {p, p + 1, p + width_, p + width_ + 1}) {
        if (!post->allFinite()) continue;
        for (int a = 0; a < 3; ++a) {
          cells.lower[a][q] = std::min(cells.lower[a][q], (*post)[a]);
          cells.upper[a][q] = std::max(cells.upper[a][q], (*post)[a]);
        }
      }
    }
  }
}

template <class Accept>
bool HeightfieldTree::LeafTriangles(int i, int j, const Group& cells, const HeightfieldRay& ray, float t_near,
                                    float* t_far, Accept& accept) const {
  const int c0 = 2 * i, r0 = 2 * j;
  const int nc = std::min(2, width_ - 1 - c0), nr = std::min(2, height_ - 1 - r0);
  alignas(16) float cell_t0[4];
  const int hit_cells = SlabGroup(cells, ray, t_near, *t_far, cell_t0);
  if (hit_cells == 0) return true;
  // The posts in the ray's sheared frame, each computed once (so an edge
  // shared by two triangles has exactly opposite edge functions).
  double px[3][3], py[3][3], pz[3][3];
  int done = 0;  // bit 3 * row + column: post transformed
  auto transform = [&](int dr, int dc) {
    const int bit = 1 << (3 * dr + dc);
    if (done & bit) return;
    done |= bit;
    const Eigen::Vector3f& p = posts_[size_t(r0 + dr) * width_ + (c0 + dc)];
    const double a[3] = {double(p.x()) - ray.org[0], double(p.y()) - ray.org[1], double(p.z()) - ray.org[2]};
    px[dr][dc] = a[ray.kx] - ray.sx * a[ray.kz];
    py[dr][dc] = a[ray.ky] - ray.sy * a[ray.kz];
    pz[dr][dc] = ray.sz * a[ray.kz];
  };
  for (int dr = 0; dr < nr; ++dr) {
    for (int dc = 0; dc < nc; ++dc) {
      if (!(hit_cells & (1 << (2 * dr + dc)))) continue;
      if (cell_t0[2 * dr + dc] > *t_far) continue;
      transform(dr, dc);
      transform(dr, dc + 1);
      transform(dr + 1, dc);
      transform(dr + 1, dc + 1);
      const uint32_t cell = uint32_t(size_t(r0 + dr) * (width_ - 1) + (c0 + dc));
      // Corners (row, column offsets) of the cell's two triangles in the
      // mesh's vertex order: (a, b, d), (b, e, d) or (a, d, b), (b, d, e)
      // with a = (0, 0), b = (0, 1), d = (1, 0), e = (1, 1).
      static constexpr int kUp[2][3][2] = {{{0, 0}, {0, 1}, {1, 0}}, {{0, 1}, {1, 1}, {1, 0}}};
      static constexpr int kDown[2][3][2] = {{{0, 0}, {1, 0}, {0, 1}}, {{0, 1}, {1, 0}, {1, 1}}};
      const auto& corners = column_cross_row_up_ ? kUp : kDown;
      for (int half = 0; half < 2; ++half) {
        const int* a = corners[half][0];
        const int* b = corners[half][1];
        const int* c = corners[half][2];
        const double ax = px[dr + a[0]][dc + a[1]], ay = py[dr + a[0]][dc + a[1]];
        const double bx = px[dr + b[0]][dc + b[1]], by = py[dr + b[0]][dc + b[1]];
        const double cx = px[dr + c[0]][dc + c[1]], cy = py[dr + c[0]][dc + c[1]];
        const double u_edge = cx * by - cy * bx;
        const double v_edge = ax * cy - ay * cx;
        const double w_edge = bx * ay - by * ax;
        if ((u_edge < 0.0 || v_edge < 0.0 || w_edge < 0.0) && (u_edge > 0.0 || v_edge > 0.0 || w_edge > 0.0)) {
          continue;
        }
        const double det = u_edge + v_edge + w_edge;
        if (!(det != 0.0)) continue;  // edge-on (or NaN)
        const double t_scaled = u_edge * pz[dr + a[0]][dc + a[1]] + v_edge * pz[dr + b[0]][dc + b[1]] +
                                w_edge * pz[dr + c[0]][dc + c[1]];
        const float t = float(t_scaled / det);
        if (!(t >= t_near && t <= *t_far)) continue;
        const double inv = 1.0 / det;
        HeightfieldHit hit{t, TriangleOf(cell, half), float(v_edge * inv), float(w_edge * inv), cell, half};
        *t_far = accept(hit);
        if (*t_far == -std::numeric_limits<float>::infinity()) return false;
      }
    }
  }
  return true;
}

template <class Accept>
void HeightfieldTree::Intersect(size_t tile, const HeightfieldRay& ray, float t_near, float* t_far,
                                Accept&& accept) const {
  struct Entry {
    float t0;
    int level, i, j;
  };
  Entry stack[4 * kTileLevel + 4];
  int top = 0;
  const Level& tiles = levels_[kTileLevel - 1];
  const uint32_t root = tiles_[tile];
  stack[top++] = Entry{-std::numeric_limits<float>::infinity(), kTileLevel, int(root % uint32_t(tiles.nx)),
                       int(root / uint32_t(tiles.nx))};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.t0 > *t_far) continue;
    if (e.level == 1) {
      if (!IntersectLeaf(e.i, e.j, ray, t_near, t_far, accept)) return;
      continue;
    }
    const Level& level = levels_[e.level - 1];
    alignas(16) float t0[4];
    const int hits = SlabGroup(level.groups[size_t(e.j) * level.nx + e.i], ray, t_near, *t_far, t0);
    if (hits == 0) continue;
    // Children nearest first: pushed farthest first (insertion sort of at
    // most 4 by entry distance, descending, in place on the stack: a
    // separate array copied over cost a memcpy per node).
    const int base = top;
    for (int q = 0; q < 4; ++q) {
      if (!(hits & (1 << q))) continue;
      const Entry x{t0[q], e.level - 1, 2 * e.i + (q & 1), 2 * e.j + (q >> 1)};
      int m = top++;
      for (; m > base && stack[m - 1].t0 < x.t0; --m) stack[m] = stack[m - 1];
      stack[m] = x;
    }
  }
}

template <class Accept>
void HeightfieldTree::IntersectPacket(size_t tile, const HeightfieldRay* rays, uint32_t lanes, const float* t_near,
                                      float* t_far, Accept&& accept) const {
  struct Entry {
    float t0;  // the nearest entry of its lanes
    int level, i, j;
    uint32_t lanes;
  };
  Entry stack[4 * kTileLevel + 4];
  int top = 0;
  const Level& tiles = levels_[kTileLevel - 1];
  const uint32_t root = tiles_[tile];
  stack[top++] = Entry{-std::numeric_limits<float>::infinity(), kTileLevel, int(root % uint32_t(tiles.nx)),
                       int(root / uint32_t(tiles.nx)), lanes};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.level == 1) {
      alignas(16) Group cells;
      CellBoxes(e.i, e.j, &cells);
      for (uint32_t m = e.lanes; m != 0; m &= m - 1) {
        const int k = __builtin_ctz(m);
        if (t_far[k] == -std::numeric_limits<float>::infinity()) continue;
        auto lane_accept = [&](const HeightfieldHit& hit) { return accept(k, hit); };
        LeafTriangles(e.i, e.j, cells, rays[k], t_near[k], &t_far[k], lane_accept);
      }
      continue;
    }
    const Level& level = levels_[e.level - 1];
    const Group& group = level.groups[size_t(e.j) * level.nx + e.i];
    uint32_t child_lanes[4] = {0, 0, 0, 0};
    float child_t0[4] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                         std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity()};
    for (uint32_t m = e.lanes; m != 0; m &= m - 1) {
      const int k = __builtin_ctz(m);
      alignas(16) float t0[4];
      const int hits = SlabGroup(group, rays[k], t_near[k], t_far[k], t0);
      for (int q = 0; q < 4; ++q) {
        if (!(hits & (1 << q))) continue;
        child_lanes[q] |= 1u << k;
        child_t0[q] = std::min(child_t0[q], t0[q]);
      }
    }
    // In place on the stack, farthest first (as in Intersect).
    const int base = top;
    for (int q = 0; q < 4; ++q) {
      if (child_lanes[q] == 0) continue;
      const Entry x{child_t0[q], e.level - 1, 2 * e.i + (q & 1), 2 * e.j + (q >> 1), child_lanes[q]};
      int m = top++;
      for (; m > base && stack[m - 1].t0 < x.t0; --m) stack[m] = stack[m - 1];
      stack[m] = x;
    }
  }
}

}  // namespace gissar::render
