#include "gissar/render/triangle_tiles.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {
namespace {

// A random soup of small triangles over a 10 km x 4 km plan, heights 0-2 km.
scene::TriangleMesh RandomSoup(int triangles, unsigned seed) {
  scene::TriangleMesh mesh;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> x(0.0f, 10000.0f), y(-2000.0f, 2000.0f), z(0.0f, 2000.0f),
      d(-60.0f, 60.0f);
  for (int t = 0; t < triangles; ++t) {
    const Eigen::Vector3f a(x(rng), y(rng), z(rng));
    for (int k = 0; k < 3; ++k) mesh.vertices.push_back(a + Eigen::Vector3f(d(rng), d(rng), d(rng)));
    mesh.triangles.emplace_back(3 * t, 3 * t + 1, 3 * t + 2);
    mesh.classes.push_back(0);
  }
  return mesh;
}

TEST(TriangleTiles, EveryTriangleOnceInsideItsTilesBounds) {
  const scene::TriangleMesh mesh = RandomSoup(20000, 7);
  const TriangleTiles tiles(mesh);
  // 20000 / 512 = 39.1 tiles wanted over a 2.5 : 1 plan: 10 x 4 (each about
  // 1 km square).
  EXPECT_EQ(tiles.tile_count(), 40u);
  ASSERT_EQ(tiles.triangle_count(), 20000u);
  std::vector<int> seen(20000, 0);
  for (size_t k = 0; k < tiles.tile_count(); ++k) {
    EXPECT_TRUE(std::is_sorted(tiles.begin(k), tiles.end(k)));
    for (const uint32_t* t = tiles.begin(k); t != tiles.end(k); ++t) {
      ++seen[*t];
      for (int c = 0; c < 3; ++c) {
        EXPECT_TRUE(tiles.bounds(k).contains(mesh.vertices[size_t(mesh.Triangle(*t)[c])].cast<double>()));
      }
    }
  }
  EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](int n) { return n == 1; }));
}

TEST(TriangleTiles, TilesArePlanCellsOfTheCentroids) {
  // Two triangles far apart: different tiles, each tile's bounds those of
  // its own triangle only.
  scene::TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {10, 0, 5}, {0, 10, 0}, {990, 990, 100}, {1000, 990, 100}, {1000, 1000, 120}};
  mesh.triangles = {{0, 1, 2}, {3, 4, 5}};
  mesh.classes = {0, 0};
  const TriangleTiles tiles(mesh);
  ASSERT_EQ(tiles.tile_count(), 1u);  // 2 triangles: one tile
  EXPECT_EQ(tiles.end(0) - tiles.begin(0), 2);

  // With 1200 copies of each the grid splits; the two groups never share a
  // tile and each tile's bounds stay within its group's corner.
  scene::TriangleMesh many;
  for (int copy = 0; copy < 1200; ++copy) {
    for (int t = 0; t < 2; ++t) {
      const int base = int(many.vertices.size());
      for (int k = 0; k < 3; ++k) many.vertices.push_back(mesh.vertices[size_t(mesh.triangles[size_t(t)][k])]);
      many.triangles.emplace_back(base, base + 1, base + 2);
      many.classes.push_back(0);
    }
  }
  const TriangleTiles split(many);
  EXPECT_GT(split.tile_count(), 1u);
  for (size_t k = 0; k < split.tile_count(); ++k) {
    if (split.begin(k) == split.end(k)) {
      EXPECT_TRUE(split.bounds(k).isEmpty());
      continue;
    }
    const bool near = (*split.begin(k) % 2) == 0;
    for (const uint32_t* t = split.begin(k); t != split.end(k); ++t) EXPECT_EQ((*t % 2) == 0, near);
    EXPECT_LE(split.bounds(k).max().x(), near ? 10.0 : 1000.0);
    EXPECT_GE(split.bounds(k).min().x(), near ? 0.0 : 990.0);
  }
}

}  // namespace
}  // namespace gissar::render
