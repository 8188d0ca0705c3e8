// RAII wrapper of an Embree 3 device and scene built from a TriangleMesh.
// The render module is the only one that includes Embree headers.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/render/triangle_tiles.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {

struct RayHit {
  float t = 0.0f;          // distance along the (unit) ray direction
  uint32_t triangle = 0;   // index into the mesh's triangles
};

// 16 rays and their hits in structure-of-arrays layout (the layout of
// Embree's RTCRayHit16, checked at compile time), for Intersect16. The
// caller fills org, dir (unit), tnear and tfar of the valid lanes; on return
// a lane that hit has triangle[k] != kNoHit and tfar[k] its distance.
struct alignas(64) RayPacket16 {
  static constexpr uint32_t kNoHit = 0xFFFFFFFFu;
  float org_x[16], org_y[16], org_z[16], tnear[16];
  float dir_x[16], dir_y[16], dir_z[16], time[16];
  float tfar[16];
  uint32_t mask[16], id[16], flags[16];
  float ng_x[16], ng_y[16], ng_z[16], u[16], v[16];
  uint32_t triangle[16], geometry[16], instance[16];

  // Sets lane k to the ray from `origin` along the unit `direction` (ENU
  // metres), over [0, infinity).
  void SetRay(int k, const Eigen::Vector3f& origin, const Eigen::Vector3f& direction) {
    org_x[k] = origin.x();
    org_y[k] = origin.y();
    org_z[k] = origin.z();
    dir_x[k] = direction.x();
    dir_y[k] = direction.y();
    dir_z[k] = direction.z();
    tnear[k] = 0.0f;
    tfar[k] = std::numeric_limits<float>::infinity();
  }
};

// A grid of terrain posts at the start of a mesh: its first width * height
// vertices are the posts (row-major) and its first triangles are
// scene::MeshFromGrid's triangles of the grid's cells, two per cell,
// row-major: of every cell when `cells` is empty, else of the cells k with
// cells[k] != 0 ((width - 1) x (height - 1) row-major; the others are holes
// whose surface is in the rest of the mesh: a GIS scene's cells that its
// constraints triangulate, scene::GisScene). 0 x 0: no grid.
struct TerrainGrid {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> cells = {};
};

// BVH build quality: kAuto picks by scene size (EmbreeScene constructor).
enum class BvhQuality { kAuto, kLow, kMedium, kHigh };

class EmbreeScene {
 public:
  // Builds the BVH of `mesh` (copied into Embree buffers; a mesh whose
  // triangles 2q, 2q + 1 pair into quads, as scene::MeshFromGrid's do, goes
  // in as Embree quads: half the primitives, and hits still name the mesh's
  // triangles). Throws Error when
  // Embree fails (e.g. out of memory) or the mesh is empty. kAuto (measured,
  // docs/performance.md): the binned SAH build (medium quality) for grids
  // of any size and for triangle meshes up to kLargeSceneTriangles; above
  // that the Morton build (low quality) with compact leaves, a third less
  // memory for triangles. On DEM grids (quads) the Morton build is slower
  // than the SAH build and saves no memory, and high quality (spatial
  // splits) doubles the build time without tracing any faster.
  static constexpr size_t kLargeSceneTriangles = size_t{4} << 20;
  explicit EmbreeScene(const scene::TriangleMesh& mesh, BvhQuality quality = BvhQuality::kAuto);
  // The same, with the terrain `grid` at the start of `mesh` traced as a
  // height field (render/heightfield.h: a quadtree of bounds over the grid's
  // cells instead of a BVH over its triangles; hits name the same
  // triangles, equally watertight and BVH-independent). Only the other
  // triangles go into an Embree mesh, with `quality` chosen for them. The
  // height field reads the grid's posts in place: `mesh` must outlive the
  // scene and keep its vertices. When the mesh does not start with such a
  // grid (checked), every triangle goes into the Embree mesh, as above. A
  // grid and nothing else is built on the first query (Build).
  EmbreeScene(const scene::TriangleMesh& mesh, const TerrainGrid& grid, BvhQuality quality = BvhQuality::kAuto);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // First hit of the ray origin + t * direction, t in [t_near, t_far];
  // `direction` must be unit length. nullopt when the ray misses.
  // Thread-safe. Hits are watertight along shared edges (Embree's robust
  // mode) and do not depend on the BVH: a ray through an edge or post shared
  // by several primitives gets the nearest of them, exact ties going to the
  // primitive first by its corners' coordinates, so two meshes holding the
  // same primitives in any order (a DEM window and the whole DEM) give
  // bitwise the same hit (embree_scene_test).
  std::optional<RayHit> Intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                  float t_near, float t_far) const;

  // True when anything blocks the segment. Thread-safe.
  bool Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_near,
                float t_far) const;

  // First hits of the lanes k of `packet` with valid[k] == -1 (others are
  // left alone), one rtcIntersect16 call; `coherent` tells Embree the rays
  // are coherent (neighbouring origins, near-parallel directions).
  // Embree requires `valid` and `packet` to be 64-byte aligned
  // (alignas(64)); a misaligned argument fails a CHECK. Thread-safe. Ties
  // are resolved as in Intersect.
  void Intersect16(const int valid[16], RayPacket16& packet, bool coherent) const;

  // Occluded for the lanes k of `packet` with valid[k] == -1 (their org,
  // dir, tnear, tfar), one rtcOccluded16 call: occluded[k] tells whether
  // anything blocks lane k's segment (false for the other lanes). Alignment
  // as for Intersect16. Thread-safe.
  void Occluded16(const int valid[16], RayPacket16& packet, bool coherent, bool occluded[16]) const;

  // Whether a terrain grid is traced as a height field.
  bool heightfield() const;
  // Its cells (holes not counted); 0 without one.
  int64_t heightfield_cells() const;
  // Its grid's posts across and down; 0 without one.
  int heightfield_grid_width() const;
  int heightfield_grid_height() const;
  // Whether the scene is a terrain grid's height field and nothing else:
  // every surface is a single-valued function of the plan position (no
  // walls, no overhangs), so along a vertical plane a ray that meets it
  // from above has passed over everything before its hit.
  bool HeightfieldOnly() const;
  // The bounds of the mesh it was built from (its frame, metres), kept at
  // construction: no pass over the vertices per query.
  const Eigen::AlignedBox3d& bounds() const { return bounds_; }
  // The quality the BVH was built with (never kAuto).
  BvhQuality quality() const { return quality_; }
  // Seconds spent building the BVH (0 until it is built).
  double build_seconds() const;
  // Builds what is not built yet: a height field alone (every triangle the
  // grid's) is built on the first query instead of by the constructor, so a
  // run whose rays all come from the profile sweep (GridProfileSweep) never
  // builds it. Queries call it; thread-safe (the first caller builds, the
  // others wait). Throws what the constructor throws.
  void Build() const;
  // The mesh's triangles from `first` on by plan tile (TriangleTiles),
  // built on the first call (thread-safe: the first caller builds, the
  // others wait) and kept for the scene's life: passes repeated over many
  // images of one scene (pose fixes) build it once. `mesh` must be the mesh
  // the scene was built from and `first` the same at every call (CHECKed:
  // the triangle count and `first`).
  const TriangleTiles& Tiles(const scene::TriangleMesh& mesh, size_t first = 0) const;

 private:
  void BuildScene(const scene::TriangleMesh& mesh, const TerrainGrid& grid, size_t cells, BvhQuality quality);

  struct Impl;
  std::unique_ptr<Impl> impl_;
  BvhQuality quality_ = BvhQuality::kMedium;
  Eigen::AlignedBox3d bounds_;
};

}  // namespace gissar::render
