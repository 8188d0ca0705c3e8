#include "gissar/render/embree_scene.h"

#include "gissar/util/check.h"

#include <embree3/rtcore.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/collaborative_call_once.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <new>
#include <string>
#include <utility>

#include "gissar/render/heightfield.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"

namespace gissar::render {
namespace {

void OnEmbreeError(void* /*user*/, RTCError code, const char* message) {
  // Errors are checked through rtcGetDeviceError after each call; nothing to
  // print here.
  (void)code;
  (void)message;
}

void ThrowIfError(RTCDevice device, const char* what) {
  const RTCError code = rtcGetDeviceError(device);
  if (code != RTC_ERROR_NONE) {
    throw Error(std::string("Embree failed: ") + what + " (code " + std::to_string(code) + ")",
                "ray tracer");
  }
}

// Whether every pair of triangles 2q, 2q + 1 is a quad split along its
// diagonal the way Embree splits quads: (x, y, z) followed by (y, w, z) or
// (z, y, w), both then the quad (x, y, w, z). scene::MeshFromGrid's meshes
// are (either orientation of the grid); building them as quads halves the
// primitives, the build time and the memory of the BVH.
bool PairsIntoQuads(const scene::TriangleMesh& mesh) {
  if (mesh.triangles.size() % 2 != 0) return false;
  for (size_t q = 0; q < mesh.triangles.size() / 2; ++q) {
    const Eigen::Vector3i& t0 = mesh.triangles[2 * q];
    const Eigen::Vector3i& t1 = mesh.triangles[2 * q + 1];
    const bool first = t1[0] == t0[1] && t1[2] == t0[2];   // (y, w, z)
    const bool second = t1[0] == t0[2] && t1[1] == t0[1];  // (z, y, w)
    if (!first && !second) return false;
    const int w = first ? t1[1] : t1[2];
    if (w == t0[0] || w == t0[1] || w == t0[2]) return false;
  }
  return true;
}

// The number of grid cells (two triangles each) the mesh starts with when
// they are scene::MeshFromGrid's triangles of the cells of `grid` (every
// cell, or those in grid.cells) over its first vertices (either
// orientation); 0 when it does not.
size_t TerrainGridCells(const scene::TriangleMesh& mesh, const TerrainGrid& grid) {
  if (grid.width < 2 || grid.height < 2) return 0;
  const size_t w = size_t(grid.width), h = size_t(grid.height);
  const bool masked = !grid.cells.empty();
  if (masked && grid.cells.size() != (w - 1) * (h - 1)) return 0;
  // First triangle pair of each row of cells.
  std::vector<size_t> row_first(h, 0);
  for (size_t r = 0; r + 1 < h; ++r) {
    size_t in_row = w - 1;
    if (masked) in_row = size_t(std::count_if(grid.cells.begin() + r * (w - 1), grid.cells.begin() + (r + 1) * (w - 1),
                                              [](uint8_t f) { return f != 0; }));
    row_first[r + 1] = row_first[r] + in_row;
  }
  const size_t cells = row_first[h - 1];
  if (cells == 0 || mesh.vertices.size() < w * h || mesh.triangle_count() < cells * 2) return 0;
  // An implicit grid (scene::GridMesh) is MeshFromGrid's by construction.
  if (!masked && mesh.grid_width == grid.width && mesh.grid_height == grid.height) return cells;
  const bool up = scene::GridColumnCrossRowUp(mesh.vertices.data(), grid.width);
  std::atomic<bool> same{true};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, h - 1, 64), [&](const tbb::blocked_range<size_t>& rows) {
    for (size_t r = rows.begin(); r < rows.end() && same.load(std::memory_order_relaxed); ++r) {
      size_t pair = row_first[r];
      for (size_t c = 0; c + 1 < w; ++c) {
        if (masked && grid.cells[r * (w - 1) + c] == 0) continue;
        const size_t cell = pair++;
        const auto expected = scene::GridCellTriangles(grid.width, int(c), int(r), up);
        if (mesh.Triangle(2 * cell) != expected[0] || mesh.Triangle(2 * cell + 1) != expected[1]) {
          same = false;
          return;
        }
      }
    }
  });
  return same ? cells : 0;
}

// A hit this close (in barycentric or quad parameter units) to a border of
// its primitive may be a tie: a ray through an edge or vertex shared by
// several primitives meets each of them at (nearly) the same distance, and
// which one Embree reports depends on the order its BVH visits them, which
// differs between two BVHs of the same terrain (a DEM window and the whole
// DEM). Such hits are resolved again by ResolveTie. Rounding puts a true tie
// within about 1e-6 of the border; 2^-14 leaves a wide margin and re-traces
// a few rays in ten thousand.
constexpr float kBorderParameter = 1.0f / 16384.0f;

// Candidates are collected within this distance (metres; relative, per km,
// beyond 1 km) of the first hit: the float distances of a tie differ by a
// few units in the last place (2 mm at 20 km).
constexpr float kTieSlab = 0.05f;

// One ray query over [t_near, t_far], no hit yet (its .ray alone for
// occlusion queries).
RTCRayHit Query(const float org[3], const float dir[3], float t_near, float t_far) {
  RTCRayHit query;
  query.ray.org_x = org[0];
  query.ray.org_y = org[1];
  query.ray.org_z = org[2];
  query.ray.dir_x = dir[0];
  query.ray.dir_y = dir[1];
  query.ray.dir_z = dir[2];
  query.ray.tnear = t_near;
  query.ray.tfar = t_far;
  query.ray.time = 0.0f;
  query.ray.mask = std::numeric_limits<unsigned>::max();
  query.ray.id = 0;
  query.ray.flags = 0;
  query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  query.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return query;
}

// The context of a 16-ray query and the lanes' fields Embree reads besides
// the rays (time, mask, id, flags). `valid` and `packet` must be 64-byte
// aligned, as Embree requires.
RTCIntersectContext PacketContext(const int valid[16], RayPacket16& packet, bool coherent) {
  GISSAR_CHECK((reinterpret_cast<uintptr_t>(valid) & 63u) == 0 &&
               (reinterpret_cast<uintptr_t>(&packet) & 63u) == 0);
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  for (int k = 0; k < 16; ++k) {
    packet.time[k] = 0.0f;
    packet.mask[k] = std::numeric_limits<unsigned>::max();
    packet.id[k] = static_cast<uint32_t>(k);
    packet.flags[k] = 0;
  }
  return context;
}

}  // namespace

struct EmbreeScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  // The terrain grid as a height field (a user geometry whose primitives are
  // its tiles; a hit's primitive is the mesh triangle), or none.
  std::unique_ptr<HeightfieldTree> heightfield;
  unsigned heightfield_geometry = RTC_INVALID_GEOMETRY_ID;
  // The mesh's other triangles (all of them without a height field), from
  // mesh triangle `mesh_first_triangle` on.
  unsigned mesh_geometry = RTC_INVALID_GEOMETRY_ID;
  uint32_t mesh_first_triangle = 0;
  // The mesh geometry went in as quads (PairsIntoQuads): Embree's primitive
  // q is triangles 2q (hit barycentrics u + v <= 1) and 2q + 1.
  bool quads = false;
  // Embree's copies of the vertices (x, y, z floats) and the primitives'
  // corner indices (4 for quads, 3 for triangles); owned by the scene.
  const float* vertices = nullptr;
  const unsigned* indices = nullptr;
  // The terrain grid's shape, known before anything is built.
  int grid_width = 0, grid_height = 0;
  size_t grid_cells = 0;
  bool heightfield_only = false;
  // A height field alone is built on the first query (Build): a run whose
  // rays all come from the profile sweep never builds it. Until then the
  // inputs of the build are kept here (the mesh must outlive the scene).
  const scene::TriangleMesh* pending_mesh = nullptr;
  TerrainGrid pending_grid;
  tbb::collaborative_once_flag once;
  std::atomic<bool> built{false};
  double build_seconds = 0.0;
  // Tiles(): built on first use.
  size_t triangle_count = 0;
  std::unique_ptr<TriangleTiles> tiles;
  tbb::collaborative_once_flag tiles_once;
  bool IsHeightfield(unsigned geometry) const { return geometry == heightfield_geometry; }
  uint32_t Triangle(unsigned geometry, uint32_t primitive, float u, float v) const {
    if (IsHeightfield(geometry)) return primitive;
    return mesh_first_triangle + (quads ? 2 * primitive + (u + v > 1.0f ? 1u : 0u) : primitive);
  }
  bool NearBorder(unsigned geometry, float u, float v) const {
    const float m = quads && !IsHeightfield(geometry) ? std::min(std::min(u, v), std::min(1.0f - u, 1.0f - v))
                                                       : std::min(std::min(u, v), 1.0f - u - v);
    return m < kBorderParameter;
  }
  // Corner coordinates of a primitive (3 or 4 corners); returns the count.
  int Corners(unsigned geometry, uint32_t primitive, const float* out[4]) const {
    if (IsHeightfield(geometry)) {
      const Eigen::Vector3f* corners[3];
      heightfield->TriangleCorners(primitive, corners);
      for (int c = 0; c < 3; ++c) out[c] = corners[c]->data();
      return 3;
    }
    const int corners = quads ? 4 : 3;
    for (int c = 0; c < corners; ++c) out[c] = vertices + 3 * size_t(indices[size_t(corners) * primitive + c]);
    return corners;
  }
  // Strict order of two primitives by their corners' coordinates, which do
  // not depend on the primitives' indices (a window's mesh numbers the same
  // terrain differently).
  bool CornersBefore(unsigned geometry_a, uint32_t a, unsigned geometry_b, uint32_t b) const {
    const float* pa[4];
    const float* pb[4];
    const int na = Corners(geometry_a, a, pa), nb = Corners(geometry_b, b, pb);
    for (int c = 0; c < std::min(na, nb); ++c) {
      for (int axis = 0; axis < 3; ++axis) {
        if (pa[c][axis] != pb[c][axis]) return pa[c][axis] < pb[c][axis];
      }
    }
    return na < nb;
  }
  // The first hit of a ray whose first hit found by the BVH (at `t`) lies on
  // a primitive's border, chosen independently of the BVH: every primitive
  // the ray meets within kTieSlab of t is collected and the nearest wins,
  // exact ties going to the primitive (then the triangle of a quad) first in
  // CornersBefore order. Each primitive's intersection is a function of the
  // ray and its corners only, so the choice is the same for any BVH holding
  // the primitives. Outputs untouched when nothing is collected.
  void ResolveTie(const float org[3], const float dir[3], float t_near, float t, float* t_out,
                  uint32_t* triangle_out) const;
  struct TieCollector;
  static void CollectTie(const RTCFilterFunctionNArguments* args);
  // Embree callbacks of the height field's user geometry.
  static void HeightfieldBounds(const RTCBoundsFunctionArguments* args);
  static void HeightfieldIntersect(const RTCIntersectFunctionNArguments* args);
  static void HeightfieldOccluded(const RTCOccludedFunctionNArguments* args);
  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

// The intersect context of ResolveTie's query: Embree hands the context to
// the filter, which records the best candidate and rejects every hit, so the
// traversal goes on to the next. The height field offers its candidates
// directly.
struct EmbreeScene::Impl::TieCollector {
  RTCIntersectContext context;  // first member: the filter casts back
  const EmbreeScene::Impl* impl = nullptr;
  bool found = false;
  float t = 0.0f;
  unsigned geometry = RTC_INVALID_GEOMETRY_ID;
  uint32_t primitive = 0, triangle = 0;
  void Offer(float t_hit, unsigned geometry_hit, uint32_t primitive_hit, uint32_t triangle_hit) {
    bool better = !found || t_hit < t;
    if (found && t_hit == t) {
      better = geometry_hit == geometry && primitive_hit == primitive
                   ? triangle_hit < triangle
                   : impl->CornersBefore(geometry_hit, primitive_hit, geometry, primitive);
    }
    if (better) {
      found = true;
      t = t_hit;
      geometry = geometry_hit;
      primitive = primitive_hit;
      triangle = triangle_hit;
    }
  }
};

void EmbreeScene::Impl::CollectTie(const RTCFilterFunctionNArguments* args) {
  auto* collector = reinterpret_cast<TieCollector*>(const_cast<RTCIntersectContext*>(args->context));
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    args->valid[i] = 0;
    const unsigned geometry = RTCHitN_geomID(args->hit, args->N, i);
    const uint32_t primitive = RTCHitN_primID(args->hit, args->N, i);
    collector->Offer(RTCRayN_tfar(args->ray, args->N, i), geometry, primitive,
                     collector->impl->Triangle(geometry, primitive, RTCHitN_u(args->hit, args->N, i),
                                               RTCHitN_v(args->hit, args->N, i)));
  }
}

void EmbreeScene::Impl::HeightfieldBounds(const RTCBoundsFunctionArguments* args) {
  const auto* impl = static_cast<const Impl*>(args->geometryUserPtr);
  float lower[3], upper[3];
  impl->heightfield->TileBounds(args->primID, lower, upper);
  // Padded: Embree's box test rounds in float and a hit on a tile's border
  // (computed in double) may lie a few ulps beyond it.
  for (int a = 0; a < 3; ++a) {
    const float pad = 1e-3f + 1e-6f * std::max(std::abs(lower[a]), std::abs(upper[a]));
    lower[a] -= pad;
    upper[a] += pad;
  }
  args->bounds_o->lower_x = lower[0];
  args->bounds_o->lower_y = lower[1];
  args->bounds_o->lower_z = lower[2];
  args->bounds_o->upper_x = upper[0];
  args->bounds_o->upper_y = upper[1];
  args->bounds_o->upper_z = upper[2];
}

namespace {
// Lane k of Embree's ray packet `rays` (N = n) as a height-field ray.
HeightfieldRay LaneRay(RTCRayN* rays, unsigned n, unsigned k) {
  const float org[3] = {RTCRayN_org_x(rays, n, k), RTCRayN_org_y(rays, n, k), RTCRayN_org_z(rays, n, k)};
  const float dir[3] = {RTCRayN_dir_x(rays, n, k), RTCRayN_dir_y(rays, n, k), RTCRayN_dir_z(rays, n, k)};
  return HeightfieldRay(org, dir);
}

// Uninitialised room for a HeightfieldRay (constructed in place per lane).
struct HeightfieldRayStorage {
  alignas(HeightfieldRay) unsigned char bytes[sizeof(HeightfieldRay)];
};

// One walk of height-field tile `tile` for the valid lanes of an Embree
// packet of n <= 16 rays (HeightfieldTree::IntersectPacket); accept(k, hit)
// as there.
template <class Accept>
void WalkPacket(const HeightfieldTree& tree, unsigned tile, const int* valid, RTCRayN* rays, unsigned n,
                Accept&& accept) {
  HeightfieldRayStorage storage[16];
  float t_near[16], t_far[16];
  uint32_t lanes = 0;
  const HeightfieldRay* last = nullptr;  // the last lane set up
  for (unsigned k = 0; k < n; ++k) {
    if (valid[k] != -1) continue;
    auto* ray = reinterpret_cast<HeightfieldRay*>(&storage[k]);
    if (last != nullptr && RTCRayN_dir_x(rays, n, k) == last->dir_f[0] && RTCRayN_dir_y(rays, n, k) == last->dir_f[1] &&
        RTCRayN_dir_z(rays, n, k) == last->dir_f[2]) {
      // Parallel to it (every lane of an affine packet): the same shear,
      // only the origin differs.
      new (ray) HeightfieldRay(*last);
      ray->SetOrigin(RTCRayN_org_x(rays, n, k), RTCRayN_org_y(rays, n, k), RTCRayN_org_z(rays, n, k));
    } else {
      new (ray) HeightfieldRay(LaneRay(rays, n, k));
    }
    last = ray;
    t_near[k] = RTCRayN_tnear(rays, n, k);
    t_far[k] = RTCRayN_tfar(rays, n, k);
    lanes |= 1u << k;
  }
  tree.IntersectPacket(tile, reinterpret_cast<const HeightfieldRay*>(storage), lanes, t_near, t_far, accept);
}

// Walks height-field tile `tile` for each valid lane of an Embree query of
// n rays alone (HeightfieldTree::Intersect); accept(k, hit) as there.
template <class Accept>
void WalkLanes(const HeightfieldTree& tree, unsigned tile, const int* valid, RTCRayN* rays, unsigned n,
               Accept&& accept) {
  for (unsigned k = 0; k < n; ++k) {
    if (valid[k] != -1) continue;
    const HeightfieldRay ray = LaneRay(rays, n, k);
    float t_far = RTCRayN_tfar(rays, n, k);
    tree.Intersect(tile, ray, RTCRayN_tnear(rays, n, k), &t_far,
                   [&](const HeightfieldHit& hit) -> float { return accept(k, hit); });
  }
}
}  // namespace

void EmbreeScene::Impl::HeightfieldIntersect(const RTCIntersectFunctionNArguments* args) {
  const auto* impl = static_cast<const Impl*>(args->geometryUserPtr);
  const unsigned n = args->N;
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, n);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, n);
  // ResolveTie's query: every candidate goes to the collector, none is kept.
  TieCollector* collector = args->context->filter == &Impl::CollectTie
                                ? reinterpret_cast<TieCollector*>(args->context)
                                : nullptr;
  // Keeps `hit` for lane k when strictly nearer than its hit so far
  // (Embree's rule for its own primitives; ties are ResolveTie's); returns
  // the lane's far end.
  auto keep = [&](unsigned k, const HeightfieldHit& hit) -> float {
    if (!(hit.t < RTCRayN_tfar(rays, n, k))) return RTCRayN_tfar(rays, n, k);
    RTCRayN_tfar(rays, n, k) = hit.t;
    const Eigen::Vector3f* corners[3];
    impl->heightfield->CellCorners(hit.cell, hit.half, corners);
    const Eigen::Vector3f ng = (*corners[1] - *corners[0]).cross(*corners[2] - *corners[0]);
    RTCHitN_Ng_x(hits, n, k) = ng.x();
    RTCHitN_Ng_y(hits, n, k) = ng.y();
    RTCHitN_Ng_z(hits, n, k) = ng.z();
    RTCHitN_u(hits, n, k) = hit.u;
    RTCHitN_v(hits, n, k) = hit.v;
    RTCHitN_primID(hits, n, k) = hit.triangle;
    RTCHitN_geomID(hits, n, k) = args->geomID;
    RTCHitN_instID(hits, n, k, 0) = args->context->instID[0];
    return hit.t;
  };
  if (collector == nullptr && n > 1 && n <= 16) {
    // A packet: one walk of the tile for all its lanes.
    WalkPacket(*impl->heightfield, args->primID, args->valid, rays, n,
               [&](int k, const HeightfieldHit& hit) { return keep(unsigned(k), hit); });
    return;
  }
  WalkLanes(*impl->heightfield, args->primID, args->valid, rays, n, [&](unsigned k, const HeightfieldHit& hit) {
    if (collector != nullptr) {
      collector->Offer(hit.t, args->geomID, hit.triangle, hit.triangle);
      return RTCRayN_tfar(rays, n, k);
    }
    return keep(k, hit);
  });
}

void EmbreeScene::Impl::HeightfieldOccluded(const RTCOccludedFunctionNArguments* args) {
  const auto* impl = static_cast<const Impl*>(args->geometryUserPtr);
  const unsigned n = args->N;
  RTCRayN* rays = args->ray;
  if (n > 1 && n <= 16) {
    // A packet: one walk of the tile for all its lanes; a lane stops at its
    // first blocker.
    WalkPacket(*impl->heightfield, args->primID, args->valid, rays, n, [&](int k, const HeightfieldHit&) -> float {
      RTCRayN_tfar(rays, n, unsigned(k)) = -std::numeric_limits<float>::infinity();
      return -std::numeric_limits<float>::infinity();
    });
    return;
  }
  WalkLanes(*impl->heightfield, args->primID, args->valid, rays, n, [&](unsigned k, const HeightfieldHit&) {
    RTCRayN_tfar(rays, n, k) = -std::numeric_limits<float>::infinity();
    return -std::numeric_limits<float>::infinity();
  });
}

void EmbreeScene::Impl::ResolveTie(const float org[3], const float dir[3], float t_near, float t, float* t_out,
                                   uint32_t* triangle_out) const {
  TieCollector collector;
  rtcInitIntersectContext(&collector.context);
  collector.context.filter = CollectTie;
  collector.impl = this;
  const float slab = kTieSlab * std::max(1.0f, t / 1000.0f);
  RTCRayHit query = Query(org, dir, std::max(t_near, t - slab), t + slab);
  rtcIntersect1(scene, &collector.context, &query);
  if (!collector.found) return;
  *t_out = collector.t;
  *triangle_out = collector.triangle;
}

// RayPacket16 is Embree's RTCRayHit16, field by field.
static_assert(sizeof(RayPacket16) == sizeof(RTCRayHit16));
static_assert(offsetof(RTCRayHit16, ray) == 0);  // Occluded16 passes the packet as an RTCRay16
static_assert(alignof(RayPacket16) == alignof(RTCRayHit16));
static_assert(offsetof(RTCRayHit16, ray.tfar) == offsetof(RayPacket16, tfar));
static_assert(offsetof(RTCRayHit16, ray.flags) == offsetof(RayPacket16, flags));
static_assert(offsetof(RTCRayHit16, hit.Ng_x) == offsetof(RayPacket16, ng_x));
static_assert(offsetof(RTCRayHit16, hit.primID) == offsetof(RayPacket16, triangle));
static_assert(offsetof(RTCRayHit16, hit.geomID) == offsetof(RayPacket16, geometry));
static_assert(offsetof(RTCRayHit16, hit.instID) == offsetof(RayPacket16, instance));
static_assert(RTC_MAX_INSTANCE_LEVEL_COUNT == 1);
static_assert(RayPacket16::kNoHit == RTC_INVALID_GEOMETRY_ID);

EmbreeScene::EmbreeScene(const scene::TriangleMesh& mesh, BvhQuality quality)
    : EmbreeScene(mesh, TerrainGrid{}, quality) {}

EmbreeScene::EmbreeScene(const scene::TriangleMesh& mesh, const TerrainGrid& grid, BvhQuality quality)
    : impl_(std::make_unique<Impl>()) {
  if (mesh.triangle_count() == 0) throw InputError("scene has no triangles", "mesh");
  bounds_ = mesh.Bounds();
  impl_->triangle_count = mesh.triangle_count();
  const size_t cells = TerrainGridCells(mesh, grid);
  if (cells > 0) {
    impl_->grid_width = grid.width;
    impl_->grid_height = grid.height;
    impl_->grid_cells = cells;
  }
  // Every triangle is the grid's: a height field alone, built on the first
  // query with quality_ (the one the build would pick now: no other
  // triangles, medium).
  impl_->heightfield_only = cells > 0 && 2 * cells == mesh.triangle_count();
  if (impl_->heightfield_only) {
    quality_ = quality == BvhQuality::kAuto ? BvhQuality::kMedium : quality;
    impl_->pending_mesh = &mesh;
    impl_->pending_grid = grid;
    return;
  }
  BuildScene(mesh, grid, cells, quality);
  impl_->built.store(true, std::memory_order_release);
}

void EmbreeScene::Build() const {
  if (impl_->built.load(std::memory_order_acquire)) return;
  // The threads that query meanwhile wait by taking part in the build's
  // parallel loops (and in nothing else of their callers').
  tbb::collaborative_call_once(impl_->once, [&] {
    auto* scene = const_cast<EmbreeScene*>(this);
    scene->BuildScene(*impl_->pending_mesh, impl_->pending_grid, impl_->grid_cells, quality_);
    impl_->built.store(true, std::memory_order_release);
  });
}

const TriangleTiles& EmbreeScene::Tiles(const scene::TriangleMesh& mesh, size_t first) const {
  GISSAR_CHECK(mesh.triangle_count() == impl_->triangle_count);
  tbb::collaborative_call_once(impl_->tiles_once,
                               [&] { impl_->tiles = std::make_unique<TriangleTiles>(mesh, first); });
  GISSAR_CHECK(impl_->tiles->first() == first);
  return *impl_->tiles;
}

double EmbreeScene::build_seconds() const { return impl_->build_seconds; }

void EmbreeScene::BuildScene(const scene::TriangleMesh& mesh, const TerrainGrid& grid, size_t cells,
                             BvhQuality quality) {
  Stopwatch watch;
  // What a failed earlier attempt (a deferred build is retried) left.
  if (impl_->scene != nullptr) rtcReleaseScene(std::exchange(impl_->scene, nullptr));
  if (impl_->device != nullptr) rtcReleaseDevice(std::exchange(impl_->device, nullptr));
  impl_->heightfield.reset();
  impl_->heightfield_geometry = impl_->mesh_geometry = RTC_INVALID_GEOMETRY_ID;
  impl_->device = rtcNewDevice(nullptr);
  if (impl_->device == nullptr) throw Error("cannot create Embree device", "ray tracer");
  rtcSetDeviceErrorFunction(impl_->device, OnEmbreeError, nullptr);
  impl_->scene = rtcNewScene(impl_->device);
  // The terrain grid as a height field: a user geometry over its tiles.
  size_t first_mesh_triangle = 0;
  if (cells > 0) {
    impl_->heightfield = std::make_unique<HeightfieldTree>(mesh.vertices.data(), grid.width, grid.height,
                                                           grid.cells.empty() ? nullptr : &grid.cells);
    first_mesh_triangle = cells * 2;
    if (impl_->heightfield->tile_count() > 0) {
      RTCGeometry geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryUserPrimitiveCount(geometry, unsigned(impl_->heightfield->tile_count()));
      rtcSetGeometryUserData(geometry, impl_.get());
      rtcSetGeometryBoundsFunction(geometry, &Impl::HeightfieldBounds, nullptr);
      rtcSetGeometryIntersectFunction(geometry, &Impl::HeightfieldIntersect);
      rtcSetGeometryOccludedFunction(geometry, &Impl::HeightfieldOccluded);
      rtcCommitGeometry(geometry);
      impl_->heightfield_geometry = rtcAttachGeometry(impl_->scene, geometry);
      rtcReleaseGeometry(geometry);
    }
  }
  // The other triangles (buildings, reflectors; all of them without a
  // height field) as an Embree triangle or quad mesh, with only the
  // vertices they use (and every index stored: an implicit grid the height
  // field does not take is written out here).
  scene::TriangleMesh rest_storage;
  const scene::TriangleMesh* rest = &mesh;
  if (first_mesh_triangle > 0 || mesh.grid_width > 0) {
    rest = &rest_storage;
    const size_t count = mesh.triangle_count();
    std::vector<int> new_index(first_mesh_triangle < count ? mesh.vertices.size() : 0, -1);
    rest_storage.triangles.reserve(count - first_mesh_triangle);
    for (size_t t = first_mesh_triangle; t < count; ++t) {
      const Eigen::Vector3i source = mesh.Triangle(t);
      Eigen::Vector3i tri;
      for (int c = 0; c < 3; ++c) {
        int& index = new_index[size_t(source[c])];
        if (index < 0) {
          index = int(rest_storage.vertices.size());
          rest_storage.vertices.push_back(mesh.vertices[size_t(source[c])]);
        }
        tri[c] = index;
      }
      rest_storage.triangles.push_back(tri);
    }
  }
  impl_->mesh_first_triangle = uint32_t(first_mesh_triangle);
  const bool quads = PairsIntoQuads(*rest);
  if (quality == BvhQuality::kAuto) {
    quality = !quads && rest->triangles.size() > kLargeSceneTriangles ? BvhQuality::kLow : BvhQuality::kMedium;
  }
  quality_ = quality;
  const RTCBuildQuality rtc_quality = quality == BvhQuality::kLow    ? RTC_BUILD_QUALITY_LOW
                                      : quality == BvhQuality::kHigh ? RTC_BUILD_QUALITY_HIGH
                                                                     : RTC_BUILD_QUALITY_MEDIUM;
  rtcSetSceneBuildQuality(impl_->scene, rtc_quality);
  // Robust: watertight edges (without it 15 % of rays aimed exactly at
  // shared edges and posts slipped through the terrain, embree_scene_test;
  // it costs about 10 % of the raw primary-ray time, docs/performance.md).
  // The context filter lets ResolveTie collect a ray's candidates; other
  // queries pass none.
  rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION | RTC_SCENE_FLAG_ROBUST |
                                     (quality == BvhQuality::kLow ? RTC_SCENE_FLAG_COMPACT : RTC_SCENE_FLAG_NONE));
  if (!rest->triangles.empty()) {
    impl_->quads = quads;
    RTCGeometry geometry =
        rtcNewGeometry(impl_->device, impl_->quads ? RTC_GEOMETRY_TYPE_QUAD : RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), rest->vertices.size()));
    const size_t primitives = impl_->quads ? rest->triangles.size() / 2 : rest->triangles.size();
    const int corners = impl_->quads ? 4 : 3;
    auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geometry, RTC_BUFFER_TYPE_INDEX, 0, impl_->quads ? RTC_FORMAT_UINT4 : RTC_FORMAT_UINT3,
        corners * sizeof(unsigned), primitives));
    if (vertices == nullptr || indices == nullptr) {
      rtcReleaseGeometry(geometry);
      ThrowIfError(impl_->device, "allocating geometry buffers");
      throw Error("Embree could not allocate geometry buffers", "ray tracer");
    }
    std::memcpy(vertices, rest->vertices.data(), rest->vertices.size() * 3 * sizeof(float));
    if (impl_->quads) {
      // Quad (v0, v1, v2, v3) is Embree's triangle pair (v0, v1, v3) and
      // (v2, v3, v1): triangles 2q and 2q + 1 of the mesh.
      for (size_t q = 0; q < primitives; ++q) {
        const Eigen::Vector3i& t0 = rest->triangles[2 * q];
        const Eigen::Vector3i& t1 = rest->triangles[2 * q + 1];
        const int fourth = t1[0] == t0[1] ? t1[1] : t1[2];
        unsigned* quad = indices + 4 * q;
        quad[0] = unsigned(t0[0]);
        quad[1] = unsigned(t0[1]);
        quad[2] = unsigned(fourth);
        quad[3] = unsigned(t0[2]);
      }
    } else {
      std::memcpy(indices, rest->triangles.data(), rest->triangles.size() * 3 * sizeof(unsigned));
    }
    impl_->vertices = vertices;
    impl_->indices = indices;
    rtcCommitGeometry(geometry);
    impl_->mesh_geometry = rtcAttachGeometry(impl_->scene, geometry);
    rtcReleaseGeometry(geometry);
  }
  rtcCommitScene(impl_->scene);
  ThrowIfError(impl_->device, "building the scene");
  impl_->build_seconds = watch.ElapsedSeconds();
}

bool EmbreeScene::heightfield() const { return impl_->grid_cells > 0; }

int64_t EmbreeScene::heightfield_cells() const { return int64_t(impl_->grid_cells); }

int EmbreeScene::heightfield_grid_width() const { return impl_->grid_width; }

int EmbreeScene::heightfield_grid_height() const { return impl_->grid_height; }

bool EmbreeScene::HeightfieldOnly() const { return impl_->heightfield_only; }

EmbreeScene::~EmbreeScene() = default;

std::optional<RayHit> EmbreeScene::Intersect(const Eigen::Vector3f& origin,
                                             const Eigen::Vector3f& direction, float t_near,
                                             float t_far) const {
  Build();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const float org[3] = {origin.x(), origin.y(), origin.z()};
  const float dir[3] = {direction.x(), direction.y(), direction.z()};
  RTCRayHit query = Query(org, dir, t_near, t_far);
  rtcIntersect1(impl_->scene, &context, &query);
  if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  RayHit hit{query.ray.tfar, impl_->Triangle(query.hit.geomID, query.hit.primID, query.hit.u, query.hit.v)};
  if (impl_->NearBorder(query.hit.geomID, query.hit.u, query.hit.v)) impl_->ResolveTie(org, dir, t_near, hit.t, &hit.t, &hit.triangle);
  return hit;
}

void EmbreeScene::Intersect16(const int valid[16], RayPacket16& packet, bool coherent) const {
  Build();
  RTCIntersectContext context = PacketContext(valid, packet, coherent);
  for (int k = 0; k < 16; ++k) {
    packet.geometry[k] = RTC_INVALID_GEOMETRY_ID;
    packet.instance[k] = RTC_INVALID_GEOMETRY_ID;
    packet.triangle[k] = RayPacket16::kNoHit;
  }
  rtcIntersect16(valid, impl_->scene, &context, reinterpret_cast<RTCRayHit16*>(&packet));
  for (int k = 0; k < 16; ++k) {
    if (packet.geometry[k] == RTC_INVALID_GEOMETRY_ID) {
      packet.triangle[k] = RayPacket16::kNoHit;
      continue;
    }
    packet.triangle[k] = impl_->Triangle(packet.geometry[k], packet.triangle[k], packet.u[k], packet.v[k]);
    if (impl_->NearBorder(packet.geometry[k], packet.u[k], packet.v[k])) {
      const float org[3] = {packet.org_x[k], packet.org_y[k], packet.org_z[k]};
      const float dir[3] = {packet.dir_x[k], packet.dir_y[k], packet.dir_z[k]};
      impl_->ResolveTie(org, dir, packet.tnear[k], packet.tfar[k], &packet.tfar[k], &packet.triangle[k]);
    }
  }
}

void EmbreeScene::Occluded16(const int valid[16], RayPacket16& packet, bool coherent, bool occluded[16]) const {
  Build();
  RTCIntersectContext context = PacketContext(valid, packet, coherent);
  // RayPacket16 begins with Embree's RTCRay16 (the ray part of RTCRayHit16).
  rtcOccluded16(valid, impl_->scene, &context, reinterpret_cast<RTCRay16*>(&packet));
  for (int k = 0; k < 16; ++k) {
    occluded[k] = valid[k] == -1 && packet.tfar[k] == -std::numeric_limits<float>::infinity();
  }
}

bool EmbreeScene::Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                           float t_near, float t_far) const {
  Build();
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const float org[3] = {origin.x(), origin.y(), origin.z()};
  const float dir[3] = {direction.x(), direction.y(), direction.z()};
  RTCRay ray = Query(org, dir, t_near, t_far).ray;
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace gissar::render
