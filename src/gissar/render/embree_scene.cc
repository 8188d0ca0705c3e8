#include "gissar/render/embree_scene.h"

#include "gissar/util/check.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <limits>
#include <string>

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

}  // namespace

struct EmbreeScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  // The mesh went in as quads (PairsIntoQuads): Embree's primitive q is
  // triangles 2q (hit barycentrics u + v <= 1) and 2q + 1.
  bool quads = false;
  // Embree's copies of the vertices (x, y, z floats) and the primitives'
  // corner indices (4 for quads, 3 for triangles); owned by the scene.
  const float* vertices = nullptr;
  const unsigned* indices = nullptr;
  uint32_t Triangle(uint32_t primitive, float u, float v) const {
    return quads ? 2 * primitive + (u + v > 1.0f ? 1u : 0u) : primitive;
  }
  bool NearBorder(float u, float v) const {
    const float m = quads ? std::min(std::min(u, v), std::min(1.0f - u, 1.0f - v))
                          : std::min(std::min(u, v), 1.0f - u - v);
    return m < kBorderParameter;
  }
  // Strict order of two primitives by their corners' coordinates, which do
  // not depend on the primitives' indices (a window's mesh numbers the same
  // terrain differently).
  bool CornersBefore(uint32_t a, uint32_t b) const {
    const int corners = quads ? 4 : 3;
    for (int c = 0; c < corners; ++c) {
      const float* pa = vertices + 3 * size_t(indices[size_t(corners) * a + c]);
      const float* pb = vertices + 3 * size_t(indices[size_t(corners) * b + c]);
      for (int axis = 0; axis < 3; ++axis) {
        if (pa[axis] != pb[axis]) return pa[axis] < pb[axis];
      }
    }
    return false;
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
  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

// The intersect context of ResolveTie's query: Embree hands the context to
// the filter, which records the best candidate and rejects every hit, so the
// traversal goes on to the next.
struct EmbreeScene::Impl::TieCollector {
  RTCIntersectContext context;  // first member: the filter casts back
  const EmbreeScene::Impl* impl = nullptr;
  bool found = false;
  float t = 0.0f;
  uint32_t primitive = 0, triangle = 0;
};

void EmbreeScene::Impl::CollectTie(const RTCFilterFunctionNArguments* args) {
  auto* collector = reinterpret_cast<TieCollector*>(const_cast<RTCIntersectContext*>(args->context));
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    args->valid[i] = 0;
    const float t = RTCRayN_tfar(args->ray, args->N, i);
    const uint32_t primitive = RTCHitN_primID(args->hit, args->N, i);
    const uint32_t triangle =
        collector->impl->Triangle(primitive, RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i));
    bool better = !collector->found || t < collector->t;
    if (collector->found && t == collector->t) {
      better = primitive == collector->primitive ? triangle < collector->triangle
                                                 : collector->impl->CornersBefore(primitive, collector->primitive);
    }
    if (better) {
      collector->found = true;
      collector->t = t;
      collector->primitive = primitive;
      collector->triangle = triangle;
    }
  }
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
    : impl_(std::make_unique<Impl>()) {
  if (mesh.triangles.empty()) throw InputError("scene has no triangles", "mesh");
  Stopwatch watch;
  const bool quads = PairsIntoQuads(mesh);
  if (quality == BvhQuality::kAuto) {
    quality = !quads && mesh.triangles.size() > kLargeSceneTriangles ? BvhQuality::kLow : BvhQuality::kMedium;
  }
  quality_ = quality;
  impl_->device = rtcNewDevice(nullptr);
  if (impl_->device == nullptr) throw Error("cannot create Embree device", "ray tracer");
  rtcSetDeviceErrorFunction(impl_->device, OnEmbreeError, nullptr);
  impl_->scene = rtcNewScene(impl_->device);
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
  impl_->quads = quads;
  RTCGeometry geometry =
      rtcNewGeometry(impl_->device, impl_->quads ? RTC_GEOMETRY_TYPE_QUAD : RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
      mesh.vertices.size()));
  const size_t primitives = impl_->quads ? mesh.triangles.size() / 2 : mesh.triangles.size();
  const int corners = impl_->quads ? 4 : 3;
  auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_INDEX, 0, impl_->quads ? RTC_FORMAT_UINT4 : RTC_FORMAT_UINT3,
      corners * sizeof(unsigned), primitives));
  if (vertices == nullptr || indices == nullptr) {
    rtcReleaseGeometry(geometry);
    ThrowIfError(impl_->device, "allocating geometry buffers");
    throw Error("Embree could not allocate geometry buffers", "ray tracer");
  }
  std::memcpy(vertices, mesh.vertices.data(), mesh.vertices.size() * 3 * sizeof(float));
  if (impl_->quads) {
    // Quad (v0, v1, v2, v3) is Embree's triangle pair (v0, v1, v3) and
    // (v2, v3, v1): triangles 2q and 2q + 1 of the mesh.
    for (size_t q = 0; q < primitives; ++q) {
      const Eigen::Vector3i& t0 = mesh.triangles[2 * q];
      const Eigen::Vector3i& t1 = mesh.triangles[2 * q + 1];
      const int fourth = t1[0] == t0[1] ? t1[1] : t1[2];
      unsigned* quad = indices + 4 * q;
      quad[0] = unsigned(t0[0]);
      quad[1] = unsigned(t0[1]);
      quad[2] = unsigned(fourth);
      quad[3] = unsigned(t0[2]);
    }
  } else {
    std::memcpy(indices, mesh.triangles.data(), mesh.triangles.size() * 3 * sizeof(unsigned));
  }
  impl_->vertices = vertices;
  impl_->indices = indices;
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(impl_->scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(impl_->scene);
  ThrowIfError(impl_->device, "building the scene");
  build_seconds_ = watch.ElapsedSeconds();
}

EmbreeScene::~EmbreeScene() = default;

std::optional<RayHit> EmbreeScene::Intersect(const Eigen::Vector3f& origin,
                                             const Eigen::Vector3f& direction, float t_near,
                                             float t_far) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const float org[3] = {origin.x(), origin.y(), origin.z()};
  const float dir[3] = {direction.x(), direction.y(), direction.z()};
  RTCRayHit query = Query(org, dir, t_near, t_far);
  rtcIntersect1(impl_->scene, &context, &query);
  if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  RayHit hit{query.ray.tfar, impl_->Triangle(query.hit.primID, query.hit.u, query.hit.v)};
  if (impl_->NearBorder(query.hit.u, query.hit.v)) impl_->ResolveTie(org, dir, t_near, hit.t, &hit.t, &hit.triangle);
  return hit;
}

void EmbreeScene::Intersect16(const int valid[16], RayPacket16& packet, bool coherent) const {
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
    packet.triangle[k] = impl_->Triangle(packet.triangle[k], packet.u[k], packet.v[k]);
    if (impl_->NearBorder(packet.u[k], packet.v[k])) {
      const float org[3] = {packet.org_x[k], packet.org_y[k], packet.org_z[k]};
      const float dir[3] = {packet.dir_x[k], packet.dir_y[k], packet.dir_z[k]};
      impl_->ResolveTie(org, dir, packet.tnear[k], packet.tfar[k], &packet.tfar[k], &packet.triangle[k]);
    }
  }
}

bool EmbreeScene::Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                           float t_near, float t_far) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  const float org[3] = {origin.x(), origin.y(), origin.z()};
  const float dir[3] = {direction.x(), direction.y(), direction.z()};
  RTCRay ray = Query(org, dir, t_near, t_far).ray;
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace gissar::render
