// The height-field path of EmbreeScene (render/heightfield.h) against
// Embree's own triangles: the same hits on the same terrain, watertight
// edges, hits independent of the grid's extent (a DEM window and the whole
// DEM), other triangles in the same scene, curved (geographic) grids and
// posts without a height.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <vector>

#include <tbb/parallel_for.h>

#include "gissar/render/embree_scene.h"
#include "gissar/render/heightfield.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {
namespace {

using Eigen::Vector3f;

constexpr float kInf = std::numeric_limits<float>::infinity();

// Rough terrain (every triangle's normal differs from its neighbours').
std::vector<float> RoughHeights(int posts, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> jitter(-15.0f, 15.0f);
  std::vector<float> h(size_t(posts) * posts);
  for (int r = 0; r < posts; ++r) {
    for (int c = 0; c < posts; ++c) {
      h[size_t(r) * posts + c] = 300.0f + 40.0f * std::sin(0.21f * float(c)) * std::cos(0.17f * float(r)) + jitter(rng);
    }
  }
  return h;
}

std::array<float, 9> Corners(const scene::TriangleMesh& mesh, uint32_t triangle) {
  std::array<float, 9> out{};
  for (int c = 0; c < 3; ++c) {
    for (int a = 0; a < 3; ++a) out[3 * c + a] = mesh.vertices[mesh.triangles[triangle][c]][a];
  }
  return out;
}

struct TestRay {
  Vector3f origin, direction;
};

// Rays at random points of the terrain's plan from a sensor at `depression`
// (radians) and random azimuths 5 km away, and from random surface-height
// points in random directions (secondary rays).
std::vector<TestRay> RandomRays(const scene::TriangleMesh& mesh, int count, uint32_t seed) {
  std::mt19937 rng(seed);
  const Eigen::AlignedBox3d box = mesh.Bounds();
  std::uniform_real_distribution<double> ux(box.min().x(), box.max().x()), uy(box.min().y(), box.max().y()),
      uz(box.min().z(), box.max().z()), angle(0.0, 2.0 * M_PI), depression(0.2, 1.4), unit(-1.0, 1.0);
  std::vector<TestRay> rays;
  for (int k = 0; k < count; ++k) {
    const Vector3f target(float(ux(rng)), float(uy(rng)), float(uz(rng)));
    if (k % 2 == 0) {
      const double az = angle(rng), dep = depression(rng);
      const Vector3f look = Vector3f(float(std::cos(dep) * std::cos(az)), float(std::cos(dep) * std::sin(az)),
                                     float(-std::sin(dep)))
                                .normalized();
      rays.push_back({target - 5000.0f * look, look});
    } else {
      Vector3f dir(float(unit(rng)), float(unit(rng)), float(unit(rng)));
      if (dir.norm() < 1e-3f) dir = Vector3f(0, 0, -1);
      rays.push_back({target, dir.normalized()});
    }
  }
  return rays;
}

// Rays aimed at posts, grid-edge midpoints and diagonal midpoints (exact in
// float) from above, obliquely or vertically.
std::vector<TestRay> RaysAtEdges(const scene::TriangleMesh& mesh, int posts, bool oblique) {
  const Vector3f look = oblique ? Vector3f(0.6f, 0.45f, -0.66f).normalized() : Vector3f(0.0f, 0.0f, -1.0f);
  auto at = [&](int c, int r) { return mesh.vertices[size_t(r) * posts + c]; };
  std::vector<TestRay> rays;
  for (int r = 4; r + 5 < posts; ++r) {
    for (int c = 4; c + 5 < posts; ++c) {
      for (const Vector3f& target : {at(c, r), Vector3f(0.5f * (at(c, r) + at(c + 1, r))),
                                     Vector3f(0.5f * (at(c, r) + at(c, r + 1))),
                                     Vector3f(0.5f * (at(c + 1, r) + at(c, r + 1)))}) {
        rays.push_back({target - 3000.0f * look, look});
      }
    }
  }
  return rays;
}

// Agreement of two scenes over the same mesh: hit or miss, distance (rays
// whose distances differ by more than 2 mm) and triangle.
struct Agreement {
  int rays = 0, hits = 0, hit_mismatch = 0, distance_mismatch = 0, triangle_mismatch = 0, occlusion_mismatch = 0;
};
Agreement Compare(const EmbreeScene& a, const EmbreeScene& b, const std::vector<TestRay>& rays) {
  Agreement out;
  for (const TestRay& ray : rays) {
    ++out.rays;
    const auto ha = a.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    const auto hb = b.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    out.occlusion_mismatch += a.Occluded(ray.origin, ray.direction, 0.0f, kInf) !=
                              b.Occluded(ray.origin, ray.direction, 0.0f, kInf);
    if (ha.has_value() != hb.has_value()) {
      ++out.hit_mismatch;
      continue;
    }
    if (!ha) continue;
    ++out.hits;
    out.distance_mismatch += std::abs(ha->t - hb->t) > 2e-3f;
    out.triangle_mismatch += ha->triangle != hb->triangle;
  }
  return out;
}

// The first hit in exact terms (double precision, every triangle): the
// reference both ray tracers are measured against.
std::optional<float> BruteForceFirstHit(const scene::TriangleMesh& mesh, const TestRay& ray) {
  const Eigen::Vector3d o = ray.origin.cast<double>(), d = ray.direction.cast<double>();
  double best = std::numeric_limits<double>::infinity();
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3d a = mesh.vertices[mesh.triangles[t][0]].cast<double>();
    const Eigen::Vector3d e1 = mesh.vertices[mesh.triangles[t][1]].cast<double>() - a;
    const Eigen::Vector3d e2 = mesh.vertices[mesh.triangles[t][2]].cast<double>() - a;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (!(std::abs(det) > 0.0) || !std::isfinite(det)) continue;
    const Eigen::Vector3d tv = o - a, q = tv.cross(e1);
    const double u = tv.dot(p) / det, v = d.dot(q) / det, s = e2.dot(q) / det;
    if (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && s >= 0.0) best = std::min(best, s);
  }
  if (!std::isfinite(best)) return std::nullopt;
  return float(best);
}

// Rays whose hit (or miss) by `scene` differs from the exact first hit by
// more than 2 mm.
int ExactMismatches(const EmbreeScene& scene, const scene::TriangleMesh& mesh, const std::vector<TestRay>& rays) {
  int mismatches = 0;
  for (const TestRay& ray : rays) {
    const auto exact = BruteForceFirstHit(mesh, ray);
    const auto hit = scene.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    mismatches += exact.has_value() != hit.has_value() || (hit && std::abs(hit->t - *exact) > 2e-3f);
  }
  return mismatches;
}

TEST(HeightfieldTest, HitsAreTheExactFirstHitsAndEmbreesTriangles) {
  constexpr int kPosts = 37;  // 3 x 3 tiles, the last ones partial
  const scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 3), kPosts, kPosts, 25.0);
  const EmbreeScene triangles(mesh), heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  EXPECT_FALSE(triangles.heightfield());
  ASSERT_TRUE(heightfield.heightfield());
  const std::vector<TestRay> rays = RandomRays(mesh, 6000, 11);
  EXPECT_EQ(ExactMismatches(heightfield, mesh, rays), 0);
  // Embree's float arithmetic loses a ray grazing a ridge now and then
  // (measured: 5 of 6000); otherwise the same hits on the same triangles.
  const Agreement random = Compare(triangles, heightfield, rays);
  EXPECT_GT(random.hits, 3500);
  EXPECT_LE(random.hit_mismatch + random.distance_mismatch, 10);
  EXPECT_LE(random.triangle_mismatch, 10);
  EXPECT_EQ(random.occlusion_mismatch, random.hit_mismatch);
  // Rays aimed exactly at posts, edges and diagonals: ties, where the two
  // tie rules may name either neighbour (at the same distance), and ridges
  // the ray grazes, where float arithmetic (Embree: 2.8 % of the oblique
  // rays) or double arithmetic (the height field) may go either way.
  for (const bool oblique : {true, false}) {
    const std::vector<TestRay> edge_rays = RaysAtEdges(mesh, kPosts, oblique);
    EXPECT_LE(ExactMismatches(heightfield, mesh, edge_rays), int(edge_rays.size()) / 200);
    const Agreement edges = Compare(triangles, heightfield, edge_rays);
    EXPECT_LE(edges.hit_mismatch + edges.distance_mismatch, edges.rays / 20);
  }
}

// A grid with holes (a GIS scene: cells its constraints triangulate): the
// height field traces the cells in, the BVH the rest of the mesh (here a fan
// of four triangles round a raised centre in each hole, so that a hole's
// surface is not the grid's). Against the BVH of the whole mesh and the
// exact first hit: the same hits on the same triangles, the holes' among
// them; packets as single rays.
TEST(HeightfieldTest, HolesAreTracedThroughTheRestOfTheMesh) {
  constexpr int kPosts = 37;
  const scene::TriangleMesh grid = scene::MeshFromHeights(RoughHeights(kPosts, 21), kPosts, kPosts, 25.0);
  constexpr int kCells = kPosts - 1;
  std::vector<uint8_t> cells(size_t(kCells) * kCells, 1);
  std::mt19937 rng(4);
  for (auto& f : cells) f = std::uniform_real_distribution<double>(0.0, 1.0)(rng) < 0.25 ? 0 : 1;
  for (int r = 10; r < 18; ++r)
    for (int c = 5; c < 20; ++c) cells[size_t(r) * kCells + c] = 0;  // a block of holes
  scene::TriangleMesh mesh;
  mesh.vertices = grid.vertices;
  for (size_t k = 0; k < cells.size(); ++k) {
    if (!cells[k]) continue;
    for (int half = 0; half < 2; ++half) {
      mesh.triangles.push_back(grid.triangles[2 * k + size_t(half)]);
      mesh.classes.push_back(1);
    }
  }
  const size_t grid_triangles = mesh.triangles.size();
  for (int r = 0; r < kCells; ++r) {
    for (int c = 0; c < kCells; ++c) {
      if (cells[size_t(r) * kCells + c]) continue;
      const int a = r * kPosts + c, b = a + 1, d = a + kPosts, e = d + 1;
      const Vector3f centre = (mesh.vertices[a] + mesh.vertices[b] + mesh.vertices[d] + mesh.vertices[e]) / 4.0f +
                              Vector3f(0.0f, 0.0f, 3.0f);
      const int m = int(mesh.vertices.size());
      mesh.vertices.push_back(centre);
      for (const auto& [p, q] : {std::pair{a, b}, {b, e}, {e, d}, {d, a}}) {
        Eigen::Vector3i t(p, q, m);
        const Vector3f n = (mesh.vertices[q] - mesh.vertices[p]).cross(centre - mesh.vertices[p]);
        if (n.z() < 0.0f) std::swap(t[1], t[2]);
        mesh.triangles.push_back(t);
        mesh.classes.push_back(2);
      }
    }
  }
  const EmbreeScene triangles(mesh), heightfield(mesh, TerrainGrid{kPosts, kPosts, cells});
  ASSERT_TRUE(heightfield.heightfield());
  EXPECT_FALSE(heightfield.HeightfieldOnly());
  // A mask that does not match the mesh's first triangles: no height field.
  std::vector<uint8_t> wrong = cells;
  wrong[0] = !wrong[0];
  EXPECT_FALSE(EmbreeScene(mesh, TerrainGrid{kPosts, kPosts, wrong}).heightfield());

  // The exact first hit, to 2 mm: always on the height field's cells; on the
  // holes' triangles (Embree's float arithmetic: a few mm at 5 km) the BVH
  // alone gives the same hit.
  const std::vector<TestRay> rays = RandomRays(mesh, 6000, 12);
  int grid_off = 0, hole_off = 0;
  for (const TestRay& ray : rays) {
    const auto exact = BruteForceFirstHit(mesh, ray);
    const auto hit = heightfield.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    if (exact.has_value() == hit.has_value() && (!hit || std::abs(hit->t - *exact) <= 2e-3f)) continue;
    const auto bvh = triangles.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    if (hit && bvh && hit->triangle >= grid_triangles && bvh->triangle == hit->triangle && bvh->t == hit->t) {
      ++hole_off;
    } else {
      ++grid_off;
    }
  }
  EXPECT_EQ(grid_off, 0);
  EXPECT_LE(hole_off, 10);
  const Agreement random = Compare(triangles, heightfield, rays);
  EXPECT_GT(random.hits, 3500);
  EXPECT_LE(random.hit_mismatch + random.distance_mismatch, 10);
  EXPECT_LE(random.triangle_mismatch, 10);
  int grid_hits = 0, hole_hits = 0;
  for (const TestRay& ray : rays) {
    const auto hit = heightfield.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    if (!hit) continue;
    (hit->triangle < grid_triangles ? grid_hits : hole_hits) += 1;
    EXPECT_EQ(mesh.classes[hit->triangle], hit->triangle < grid_triangles ? 1 : 2);
  }
  EXPECT_GT(grid_hits, 1000);
  EXPECT_GT(hole_hits, 300);
  // Rays at posts and edges (ties, resolved by the triangles' corners).
  for (const bool oblique : {true, false}) {
    const std::vector<TestRay> edge_rays = RaysAtEdges(mesh, kPosts, oblique);
    const Agreement edges = Compare(triangles, heightfield, edge_rays);
    EXPECT_LE(edges.hit_mismatch + edges.distance_mismatch, edges.rays / 20);
  }
  // The tree names every grid triangle's corners as the mesh does.
  const HeightfieldTree tree(mesh.vertices.data(), kPosts, kPosts, &cells);
  ASSERT_EQ(tree.cell_count() * 2, grid_triangles);
  for (uint32_t t = 0; t < grid_triangles; ++t) {
    const Eigen::Vector3f* corners[3];
    tree.TriangleCorners(t, corners);
    for (int k = 0; k < 3; ++k) ASSERT_EQ(corners[k], &mesh.vertices[size_t(mesh.triangles[t][k])]) << t;
  }
  // Packets.
  int compared = 0;
  for (size_t first = 0; first + 16 <= rays.size(); first += 16) {
    RayPacket16 packet;
    alignas(64) int valid[16];
    for (int k = 0; k < 16; ++k) {
      valid[k] = -1;
      packet.SetRay(k, rays[first + k].origin, rays[first + k].direction);
    }
    heightfield.Intersect16(valid, packet, false);
    for (int k = 0; k < 16; ++k) {
      const auto single = heightfield.Intersect(rays[first + k].origin, rays[first + k].direction, 0.0f, kInf);
      ++compared;
      ASSERT_EQ(single.has_value(), packet.triangle[k] != RayPacket16::kNoHit) << "ray " << first + k;
      if (single) {
        EXPECT_EQ(single->triangle, packet.triangle[k]) << "ray " << first + k;
      }
    }
  }
  EXPECT_GT(compared, 5000);
}

// Packets (one walk of a tile for all lanes, HeightfieldTree::
// IntersectPacket) give each lane the hit a single ray gets, on coherent
// packets (neighbouring primary rays) and incoherent ones (random rays).
TEST(HeightfieldTest, PacketHitsEqualSingleRayHits) {
  constexpr int kPosts = 65;
  const scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 13), kPosts, kPosts, 20.0);
  const EmbreeScene scene(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(scene.heightfield());
  std::vector<TestRay> rays = RandomRays(mesh, 4000, 5);
  // Coherent packets: rows of 16 parallel rays over neighbouring posts.
  const Vector3f look = Vector3f(0.5f, 0.5f, -0.7f).normalized();
  for (int r = 2; r + 2 < kPosts; ++r) {
    for (int c = 0; c < 64; ++c) {
      const Vector3f target = mesh.vertices[size_t(r) * kPosts + (c % kPosts)] + Vector3f(3.1f, 7.3f, 0.0f);
      rays.push_back({target - 8000.0f * look, look});
    }
  }
  int compared = 0, hits = 0;
  for (size_t first = 0; first < rays.size(); first += 16) {
    RayPacket16 packet;
    alignas(64) int valid[16];
    for (int k = 0; k < 16; ++k) {
      // Every fifth lane is off, as at the ends of a row.
      valid[k] = first + k < rays.size() && k % 5 != 4 ? -1 : 0;
      if (valid[k] != 0) packet.SetRay(k, rays[first + k].origin, rays[first + k].direction);
    }
    scene.Intersect16(valid, packet, true);
    for (int k = 0; k < 16; ++k) {
      if (valid[k] == 0) continue;
      const auto single = scene.Intersect(rays[first + k].origin, rays[first + k].direction, 0.0f, kInf);
      ++compared;
      ASSERT_EQ(single.has_value(), packet.triangle[k] != RayPacket16::kNoHit) << "ray " << first + k;
      if (!single) continue;
      ++hits;
      EXPECT_EQ(single->triangle, packet.triangle[k]) << "ray " << first + k;
      EXPECT_EQ(std::memcmp(&single->t, &packet.tfar[k], sizeof(float)), 0) << single->t << " vs " << packet.tfar[k];
    }
  }
  EXPECT_GT(compared, 5000);
  EXPECT_GT(hits, compared / 2);
}

// Occluded16 answers every lane as Occluded does, through the height field
// (its packet walk) and through Embree's triangles: segments from surface
// points towards a sensor (the mask's visibility rays), some blocked, some
// not, and random segments of random lengths.
TEST(HeightfieldTest, PacketOcclusionEqualsSingleRayOcclusion) {
  constexpr int kPosts = 65;
  const scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 17), kPosts, kPosts, 20.0);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}}), triangles(mesh);
  ASSERT_TRUE(heightfield.heightfield());
  std::vector<TestRay> rays = RandomRays(mesh, 3000, 9);
  std::vector<float> t_near(rays.size(), 0.0f), t_far(rays.size());
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> length(1.0f, 2000.0f);
  for (float& t : t_far) t = length(rng);
  // From just above the surface at every post towards a low sensor.
  const Vector3f to_sensor = Vector3f(-0.7f, -0.3f, 0.25f).normalized();
  for (size_t k = 0; k < mesh.vertices.size(); ++k) {
    rays.push_back({mesh.vertices[k] + Vector3f(0.0f, 0.0f, 0.05f), to_sensor});
    t_near.push_back(0.01f);
    t_far.push_back(kInf);
  }
  for (const EmbreeScene* scene : {&heightfield, &triangles}) {
    int compared = 0, blocked = 0;
    for (size_t first = 0; first < rays.size(); first += 16) {
      RayPacket16 packet;
      alignas(64) int valid[16];
      bool occluded[16];
      for (int k = 0; k < 16; ++k) {
        valid[k] = first + k < rays.size() && k % 7 != 6 ? -1 : 0;
        if (valid[k] == 0) continue;
        packet.SetRay(k, rays[first + k].origin, rays[first + k].direction);
        packet.tnear[k] = t_near[first + k];
        packet.tfar[k] = t_far[first + k];
      }
      scene->Occluded16(valid, packet, true, occluded);
      for (int k = 0; k < 16; ++k) {
        if (valid[k] == 0) {
          EXPECT_FALSE(occluded[k]);
          continue;
        }
        const size_t i = first + k;
        ++compared;
        const bool single = scene->Occluded(rays[i].origin, rays[i].direction, t_near[i], t_far[i]);
        ASSERT_EQ(occluded[k], single) << "ray " << i << (scene == &heightfield ? " (height field)" : " (BVH)");
        blocked += single;
      }
    }
    EXPECT_GT(compared, 5000);
    EXPECT_GT(blocked, compared / 10);
    EXPECT_LT(blocked, compared * 9 / 10);
  }
}

// Watertight: a ray aimed at a post, an edge or a diagonal from above meets
// the terrain (there or before); it never slips between the triangles
// sharing the point -- not even at posts, where Embree's robust triangles
// lose a few (embree_scene_test).
TEST(HeightfieldTest, RaysThroughEdgesAndPostsDoNotSlipThrough) {
  constexpr int kPosts = 48;
  const scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 5), kPosts, kPosts, 30.0);
  const EmbreeScene scene(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(scene.heightfield());
  for (const bool oblique : {true, false}) {
    const std::vector<TestRay> rays = RaysAtEdges(mesh, kPosts, oblique);
    int misses = 0, packet_misses = 0;
    for (size_t first = 0; first < rays.size(); first += 16) {
      RayPacket16 packet;
      alignas(64) int valid[16];
      for (int k = 0; k < 16; ++k) {
        valid[k] = first + k < rays.size() ? -1 : 0;
        if (valid[k] == 0) continue;
        packet.SetRay(k, rays[first + k].origin, rays[first + k].direction);
        misses += !scene.Intersect(rays[first + k].origin, rays[first + k].direction, 0.0f, kInf).has_value();
        misses += !scene.Occluded(rays[first + k].origin, rays[first + k].direction, 0.0f, kInf);
      }
      scene.Intersect16(valid, packet, true);
      for (int k = 0; k < 16; ++k) packet_misses += valid[k] != 0 && packet.triangle[k] == RayPacket16::kNoHit;
    }
    EXPECT_EQ(misses, 0) << (oblique ? "oblique" : "vertical");
    EXPECT_EQ(packet_misses, 0) << (oblique ? "oblique" : "vertical");
  }
}

// A window of the DEM (another grid, other tiles, other indices) gives
// bitwise the same hits as the whole DEM for rays inside the window.
TEST(HeightfieldTest, HitsDoNotDependOnTheGridExtent) {
  constexpr int kPosts = 70, kOffset = 13, kWindow = 40;
  constexpr double kSpacing = 20.0;
  const std::vector<float> heights = RoughHeights(kPosts, 9);
  std::vector<float> window(size_t(kWindow) * kWindow);
  for (int r = 0; r < kWindow; ++r) {
    for (int c = 0; c < kWindow; ++c) window[size_t(r) * kWindow + c] = heights[size_t(r + kOffset) * kPosts + c + kOffset];
  }
  const scene::TriangleMesh whole = scene::MeshFromHeights(heights, kPosts, kPosts, kSpacing);
  const scene::TriangleMesh part =
      scene::MeshFromHeights(window, kWindow, kWindow, kSpacing, kOffset * kSpacing, kOffset * kSpacing);
  const EmbreeScene scene_whole(whole, TerrainGrid{kPosts, kPosts, {}});
  const EmbreeScene scene_part(part, TerrainGrid{kWindow, kWindow, {}});
  // Rays aimed at the window's inner posts and edges, steep enough to stay
  // inside it.
  std::vector<TestRay> rays;
  const Vector3f look = Vector3f(0.3f, -0.2f, -0.93f).normalized();
  for (int r = 6; r + 7 < kWindow; ++r) {
    for (int c = 6; c + 7 < kWindow; ++c) {
      const Vector3f p = part.vertices[size_t(r) * kWindow + c], q = part.vertices[size_t(r) * kWindow + c + 1],
                     s = part.vertices[size_t(r + 1) * kWindow + c];
      for (const Vector3f& target : {p, Vector3f(0.5f * (p + q)), Vector3f(0.5f * (q + s)), Vector3f(0.25f * (p + q + 2.0f * s))}) {
        rays.push_back({target - 200.0f * look, look});
      }
    }
  }
  int hits = 0;
  for (const TestRay& ray : rays) {
    const auto hw = scene_whole.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    const auto hp = scene_part.Intersect(ray.origin, ray.direction, 0.0f, kInf);
    ASSERT_EQ(hw.has_value(), hp.has_value());
    if (!hw) continue;
    ++hits;
    EXPECT_EQ(std::memcmp(&hw->t, &hp->t, sizeof(float)), 0) << hw->t << " vs " << hp->t;
    EXPECT_EQ(Corners(whole, hw->triangle), Corners(part, hp->triangle));
  }
  EXPECT_EQ(hits, int(rays.size()));
}

// A height field alone is built by its first query, not by its
// constructor (a run whose rays all come from the profile sweep never builds
// it): queried first from many threads at once, it is built once and
// answers as the scene built beforehand does. A scene with other triangles
// is built at once.
TEST(HeightfieldTest, AHeightFieldAloneIsBuiltByItsFirstQuery) {
  constexpr int kPosts = 37;
  const scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 5), kPosts, kPosts, 25.0);
  const EmbreeScene triangles(mesh);
  EXPECT_GT(triangles.build_seconds(), 0.0);
  const EmbreeScene built(mesh, TerrainGrid{kPosts, kPosts, {}});
  EXPECT_EQ(built.build_seconds(), 0.0);
  built.Build();
  EXPECT_GT(built.build_seconds(), 0.0);
  const EmbreeScene lazy(mesh, TerrainGrid{kPosts, kPosts, {}});
  EXPECT_EQ(lazy.build_seconds(), 0.0);
  EXPECT_TRUE(lazy.heightfield());
  EXPECT_TRUE(lazy.HeightfieldOnly());
  EXPECT_EQ(lazy.heightfield_cells(), int64_t(kPosts - 1) * (kPosts - 1));
  EXPECT_EQ(lazy.heightfield_grid_width(), kPosts);
  EXPECT_EQ(lazy.heightfield_grid_height(), kPosts);
  const std::vector<TestRay> rays = RandomRays(mesh, 4000, 17);
  std::vector<std::optional<RayHit>> hits(rays.size());
  std::vector<uint8_t> blocked(rays.size(), 0);
  tbb::parallel_for(size_t(0), rays.size(), [&](size_t i) {
    hits[i] = lazy.Intersect(rays[i].origin, rays[i].direction, 0.0f, kInf);
    blocked[i] = lazy.Occluded(rays[i].origin, rays[i].direction, 0.0f, kInf);
  });
  EXPECT_GT(lazy.build_seconds(), 0.0);
  int hit_count = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const auto expected = built.Intersect(rays[i].origin, rays[i].direction, 0.0f, kInf);
    ASSERT_EQ(hits[i].has_value(), expected.has_value()) << i;
    EXPECT_EQ(bool(blocked[i]), expected.has_value()) << i;
    if (!expected) continue;
    EXPECT_EQ(hits[i]->t, expected->t) << i;
    EXPECT_EQ(hits[i]->triangle, expected->triangle) << i;
    ++hit_count;
  }
  EXPECT_GT(hit_count, 2000);
}

// Buildings (ordinary triangles after the grid) in the same scene: hits on
// them name their mesh triangles, and they hide the terrain behind them.
TEST(HeightfieldTest, OtherTrianglesShareTheScene) {
  constexpr int kPosts = 40;
  scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 21), kPosts, kPosts, 25.0);
  const size_t grid_triangles = mesh.triangles.size();
  // A 60 m box on posts 10..14, 20 m above the highest post.
  const float top = 400.0f;
  const Vector3f a(250, 250, 0), b(350, 250, 0), c(350, 350, 0), d(250, 350, 0), up(0, 0, top);
  mesh.AddQuad(a + up, b + up, c + up, d + up, 3);              // roof
  mesh.AddQuad(a, b, b + up, a + up, 3);                        // south wall
  mesh.AddQuad(b, c, c + up, b + up, 3);                        // east wall
  const EmbreeScene triangles(mesh), heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(heightfield.heightfield());
  const std::vector<TestRay> rays = RandomRays(mesh, 5000, 4);
  EXPECT_EQ(ExactMismatches(heightfield, mesh, rays), 0);
  const Agreement agreement = Compare(triangles, heightfield, rays);
  EXPECT_LE(agreement.hit_mismatch + agreement.distance_mismatch, 5);
  EXPECT_LE(agreement.triangle_mismatch, 5);
  // Straight down onto the roof's middle.
  const auto hit = heightfield.Intersect(Vector3f(300.0f, 300.0f, 1000.0f), Vector3f(0, 0, -1), 0.0f, kInf);
  ASSERT_TRUE(hit.has_value());
  EXPECT_FLOAT_EQ(hit->t, 1000.0f - top);
  EXPECT_GE(hit->triangle, grid_triangles);
  EXPECT_LT(hit->triangle, grid_triangles + 2);
}

// A grid whose rows are curved and unevenly spaced in the scene frame (a
// geographic DEM's posts in ENU), with a post without height: the same hits
// as Embree's triangles; the triangles of the missing post are never hit.
TEST(HeightfieldTest, CurvedGridsAndMissingPostsMatchEmbree) {
  constexpr int kPosts = 60;
  const std::vector<float> heights = RoughHeights(kPosts, 17);
  std::vector<Vector3f> posts(heights.size());
  for (int r = 0; r < kPosts; ++r) {
    for (int c = 0; c < kPosts; ++c) {
      // Meridians converge and parallels bend, as lon/lat posts do in ENU.
      const float x = (float(c) - 30.0f) * (28.0f - 0.05f * float(r));
      const float y = float(r) * 31.0f + 0.004f * x * x / 31.0f;
      posts[size_t(r) * kPosts + c] = Vector3f(x, y, heights[size_t(r) * kPosts + c]);
    }
  }
  posts[size_t(20) * kPosts + 33].z() = std::numeric_limits<float>::quiet_NaN();
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, kPosts, kPosts);
  const EmbreeScene triangles(mesh), heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(heightfield.heightfield());
  const std::vector<TestRay> rays = RandomRays(mesh, 5000, 8);
  EXPECT_EQ(ExactMismatches(heightfield, mesh, rays), 0);
  const Agreement agreement = Compare(triangles, heightfield, rays);
  EXPECT_GT(agreement.hits, 2500);
  EXPECT_LE(agreement.hit_mismatch + agreement.distance_mismatch, 5);
  EXPECT_LE(agreement.triangle_mismatch, 5);
  // Straight down through the missing post's cells: no hit there.
  const Vector3f hole = posts[size_t(20) * kPosts + 32] * 0.5f + posts[size_t(21) * kPosts + 33] * 0.5f;
  const auto hit = heightfield.Intersect(Vector3f(hole.x(), hole.y(), 2000.0f), Vector3f(0, 0, -1), 0.0f, kInf);
  EXPECT_FALSE(hit.has_value());
}

// A DEM's grid with its triangles kept implicit (scene::GridMesh) plus a
// building: the same hits, distances and triangle ids as the same mesh with
// every index stored, as a height field and (its triangles written out for
// Embree) without one.
TEST(HeightfieldTest, AnImplicitGridIsTracedLikeItsStoredTriangles) {
  constexpr int kPosts = 40;
  scene::TriangleMesh stored = scene::MeshFromHeights(RoughHeights(kPosts, 5), kPosts, kPosts, 25.0);
  scene::TriangleMesh implicit = scene::GridMesh(std::vector<Vector3f>(stored.vertices), kPosts, kPosts);
  const Vector3f a(250, 250, 0), b(350, 250, 0), c(350, 350, 0), up(0, 0, 400);
  for (scene::TriangleMesh* mesh : {&stored, &implicit}) {
    mesh->AddQuad(a + up, b + up, c + up, a + up + (c - b), 3);
    mesh->AddQuad(a, b, b + up, a + up, 3);
  }
  ASSERT_TRUE(implicit.triangles.size() == 4 && implicit.triangle_count() == stored.triangle_count());
  const std::vector<TestRay> rays = RandomRays(stored, 4000, 12);
  for (const bool as_heightfield : {true, false}) {
    SCOPED_TRACE(as_heightfield ? "height field" : "Embree triangles");
    const TerrainGrid grid = as_heightfield ? TerrainGrid{kPosts, kPosts, {}} : TerrainGrid{};
    const EmbreeScene from_stored(stored, grid), from_implicit(implicit, grid);
    EXPECT_EQ(from_implicit.heightfield(), as_heightfield);
    int hits = 0;
    for (const TestRay& ray : rays) {
      const auto hs = from_stored.Intersect(ray.origin, ray.direction, 0.0f, kInf);
      const auto hi = from_implicit.Intersect(ray.origin, ray.direction, 0.0f, kInf);
      ASSERT_EQ(hs.has_value(), hi.has_value());
      if (!hs) continue;
      ++hits;
      EXPECT_EQ(hs->t, hi->t);
      EXPECT_EQ(hs->triangle, hi->triangle);
      EXPECT_EQ(implicit.Triangle(hi->triangle), stored.triangles[hs->triangle]);
    }
    EXPECT_GT(hits, 2000);
  }
}

// A mesh that does not start with the stated grid goes into Embree whole.
TEST(HeightfieldTest, AMeshThatIsNotTheStatedGridIsTracedAsTriangles) {
  scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(10, 1), 10, 10, 10.0);
  std::swap(mesh.triangles[4], mesh.triangles[5]);
  EXPECT_FALSE(EmbreeScene(mesh, TerrainGrid{10, 10, {}}).heightfield());
  EXPECT_FALSE(EmbreeScene(mesh, TerrainGrid{9, 11, {}}).heightfield());
}

// The index: the children of every node above the cells, 96 bytes per four
// (levels of 2, 4 and 8 cells a side: 1/16 + 1/64 + 1/256 groups per cell),
// and the tiles' boxes for Embree: 8 bytes per cell, far below a BVH.
TEST(HeightfieldTest, TheQuadtreeHoldsAboutEightBytesPerCell) {
  constexpr int kPosts = 257;
  const scene::TriangleMesh mesh = scene::MeshFromHeights(RoughHeights(kPosts, 2), kPosts, kPosts, 10.0);
  const HeightfieldTree tree(mesh.vertices.data(), kPosts, kPosts);
  const double cells = double(kPosts - 1) * (kPosts - 1);
  static_assert(HeightfieldTree::kTileLevel == 3);
  const double tiles = cells / 64.0;
  EXPECT_EQ(tree.tile_count(), size_t(tiles));
  EXPECT_NEAR(double(tree.MemoryBytes()), cells * 96.0 * (1.0 / 16 + 1.0 / 64) + tiles * (24.0 + 4.0), 64.0);
  float lower[3], upper[3];
  tree.TileBounds(0, lower, upper);
  EXPECT_FLOAT_EQ(lower[0], 0.0f);
  EXPECT_FLOAT_EQ(upper[0], 80.0f);  // 8 cells of 10 m
  EXPECT_FLOAT_EQ(upper[1], 80.0f);
}

}  // namespace
}  // namespace gissar::render
