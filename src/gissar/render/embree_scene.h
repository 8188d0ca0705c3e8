// RAII wrapper of an Embree 3 device and scene built from a TriangleMesh.
// The render module is the only one that includes Embree headers.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>

#include <Eigen/Core>

#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {

struct RayHit {
  float t = 0.0f;          // distance along the (unit) ray direction
  uint32_t triangle = 0;   // index into the mesh's triangles
};

class EmbreeScene {
 public:
  // Builds the BVH of `mesh` (copied into Embree buffers). Throws Error when
  // Embree fails (e.g. out of memory) or the mesh is empty.
  explicit EmbreeScene(const scene::TriangleMesh& mesh);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // First hit of the ray origin + t * direction, t in [t_near, t_far];
  // `direction` must be unit length. nullopt when the ray misses.
  // Thread-safe.
  std::optional<RayHit> Intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                  float t_near, float t_far) const;

  // True when anything blocks the segment. Thread-safe.
  bool Occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_near,
                float t_far) const;

  // Seconds spent building the BVH.
  double build_seconds() const { return build_seconds_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double build_seconds_ = 0.0;
};

}  // namespace gissar::render
