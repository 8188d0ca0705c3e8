#include "gissar/render/embree_scene.h"

#include "gissar/util/check.h"

#include <embree3/rtcore.h>

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

}  // namespace

struct EmbreeScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  // The mesh went in as quads (PairsIntoQuads): Embree's primitive q is
  // triangles 2q (hit barycentrics u + v <= 1) and 2q + 1.
  bool quads = false;
  uint32_t Triangle(uint32_t primitive, float u, float v) const {
    return quads ? 2 * primitive + (u + v > 1.0f ? 1u : 0u) : primitive;
  }
  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

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
  if (quality == BvhQuality::kLow) rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_COMPACT);
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
  RTCRayHit query;
  query.ray.org_x = origin.x();
  query.ray.org_y = origin.y();
  query.ray.org_z = origin.z();
  query.ray.dir_x = direction.x();
  query.ray.dir_y = direction.y();
  query.ray.dir_z = direction.z();
  query.ray.tnear = t_near;
  query.ray.tfar = t_far;
  query.ray.time = 0.0f;
  query.ray.mask = std::numeric_limits<unsigned>::max();
  query.ray.id = 0;
  query.ray.flags = 0;
  query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  query.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &query);
  if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  return RayHit{query.ray.tfar, impl_->Triangle(query.hit.primID, query.hit.u, query.hit.v)};
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
    packet.triangle[k] = packet.geometry[k] == RTC_INVALID_GEOMETRY_ID
                             ? RayPacket16::kNoHit
                             : impl_->Triangle(packet.triangle[k], packet.u[k], packet.v[k]);
  }
}

bool EmbreeScene::Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                           float t_near, float t_far) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray;
  ray.org_x = origin.x();
  ray.org_y = origin.y();
  ray.org_z = origin.z();
  ray.dir_x = direction.x();
  ray.dir_y = direction.y();
  ray.dir_z = direction.z();
  ray.tnear = t_near;
  ray.tfar = t_far;
  ray.time = 0.0f;
  ray.mask = std::numeric_limits<unsigned>::max();
  ray.id = 0;
  ray.flags = 0;
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace gissar::render
