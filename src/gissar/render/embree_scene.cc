#include "gissar/render/embree_scene.h"

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

}  // namespace

struct EmbreeScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
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
  if (quality == BvhQuality::kAuto) {
    quality = mesh.triangles.size() > kLargeSceneTriangles ? BvhQuality::kLow : BvhQuality::kMedium;
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
  RTCGeometry geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
      mesh.vertices.size()));
  auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
      mesh.triangles.size()));
  if (vertices == nullptr || indices == nullptr) {
    rtcReleaseGeometry(geometry);
    ThrowIfError(impl_->device, "allocating geometry buffers");
    throw Error("Embree could not allocate geometry buffers", "ray tracer");
  }
  std::memcpy(vertices, mesh.vertices.data(), mesh.vertices.size() * 3 * sizeof(float));
  std::memcpy(indices, mesh.triangles.data(), mesh.triangles.size() * 3 * sizeof(unsigned));
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
  return RayHit{query.ray.tfar, query.hit.primID};
}

void EmbreeScene::Intersect16(const int valid[16], RayPacket16& packet, bool coherent) const {
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
    if (packet.geometry[k] == RTC_INVALID_GEOMETRY_ID) packet.triangle[k] = RayPacket16::kNoHit;
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
