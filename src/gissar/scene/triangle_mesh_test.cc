#include "gissar/scene/triangle_mesh.h"

#include <gtest/gtest.h>

namespace gissar::scene {
namespace {

TEST(TriangleMeshTest, GridHasTwoUpFacingTrianglesPerCell) {
  const TriangleMesh mesh = MeshFromHeights(std::vector<float>(4 * 3, 5.0f), 4, 3, 10.0);
  EXPECT_EQ(mesh.triangle_count(), 3u * 2u * 2u);
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    EXPECT_NEAR(mesh.Normal(t).z(), 1.0f, 1e-6f);
  }
  const auto box = mesh.Bounds();
  EXPECT_DOUBLE_EQ(box.max().x(), 30.0);
  EXPECT_DOUBLE_EQ(box.max().y(), 20.0);
}

TEST(TriangleMeshTest, NorthUpGridIsOrientedUpToo) {
  // Rows running south (like a north-up raster) flip the grid's handedness.
  std::vector<Eigen::Vector3f> posts;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) posts.emplace_back(c * 10.0f, -r * 10.0f, 0.0f);
  const TriangleMesh mesh = MeshFromGrid(posts, 3, 3);
  for (size_t t = 0; t < mesh.triangle_count(); ++t) EXPECT_GT(mesh.Normal(t).z(), 0.99f);
}

TEST(TriangleMeshTest, SlopeNormalMatchesGradient) {
  // z = 0.5 x: normal (-0.5, 0, 1) / |.|.
  std::vector<float> h;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) h.push_back(0.5f * c * 10.0f);
  const TriangleMesh mesh = MeshFromHeights(h, 2, 2, 10.0);
  const Eigen::Vector3f expected = Eigen::Vector3f(-0.5f, 0.0f, 1.0f).normalized();
  EXPECT_NEAR((mesh.Normal(0) - expected).norm(), 0.0f, 1e-6f);
  EXPECT_NEAR((mesh.Normal(1) - expected).norm(), 0.0f, 1e-6f);
}

TEST(TriangleMeshTest, AppendReindexes) {
  TriangleMesh a, b;
  a.AddTriangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  b.AddQuad({0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}, 3);
  a.Append(b);
  EXPECT_EQ(a.triangle_count(), 3u);
  EXPECT_EQ(a.triangles[1], Eigen::Vector3i(3, 4, 5));
  EXPECT_EQ(a.classes[2], 3);
}

// A grid mesh with implicit triangles is MeshFromGrid's, triangle by
// triangle (both grid orientations), until it is made explicit; triangles
// appended to it come after the grid's, and appending it to another mesh
// stores its triangles.
TEST(TriangleMeshTest, ImplicitGridIsMeshFromGrids) {
  for (const float row_step : {10.0f, -10.0f}) {
    std::vector<Eigen::Vector3f> posts;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 5; ++c) posts.emplace_back(c * 10.0f, r * row_step, float((c * 7 + r * 3) % 5));
    const TriangleMesh stored = MeshFromGrid(posts, 5, 4);
    TriangleMesh implicit = GridMesh(std::vector<Eigen::Vector3f>(posts), 5, 4);
    EXPECT_TRUE(implicit.triangles.empty());
    ASSERT_EQ(implicit.triangle_count(), 4u * 3u * 2u);
    ASSERT_EQ(implicit.classes.size(), implicit.triangle_count());
    EXPECT_EQ(implicit.MemoryBytes(), posts.size() * sizeof(Eigen::Vector3f) + implicit.classes.capacity());
    for (size_t t = 0; t < stored.triangle_count(); ++t) {
      EXPECT_EQ(implicit.Triangle(t), stored.triangles[t]) << t;
      EXPECT_EQ(implicit.Normal(t), stored.Normal(t)) << t;
      EXPECT_GT(implicit.Normal(t).z(), 0.0f) << t;
    }
    TriangleMesh extended = implicit;
    extended.AddTriangle({0, 0, 50}, {1, 0, 50}, {0, 1, 50}, 4);
    ASSERT_EQ(extended.triangle_count(), 25u);
    EXPECT_EQ(extended.Triangle(24), Eigen::Vector3i(20, 21, 22));
    EXPECT_EQ(extended.classes[24], 4);
    extended.MakeExplicit();
    EXPECT_EQ(extended.grid_width, 0);
    ASSERT_EQ(extended.triangles.size(), 25u);
    for (size_t t = 0; t < 24; ++t) EXPECT_EQ(extended.triangles[t], stored.triangles[t]) << t;
    EXPECT_EQ(extended.triangles[24], Eigen::Vector3i(20, 21, 22));
    TriangleMesh host;
    host.AddTriangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    host.Append(implicit);
    ASSERT_EQ(host.triangles.size(), 25u);
    EXPECT_EQ(host.triangles[1], stored.triangles[0] + Eigen::Vector3i::Constant(3));
  }
}

}  // namespace
}  // namespace gissar::scene

namespace gissar::scene {
namespace {

// The grid cells a mesh opens with: every cell of MeshFromGrid's mesh;
// cells kept in order with the others dropped; nothing for a prefix the
// mesh does not have (too many cells, a triangle changed, cells out of
// order, a grid wider than the vertices allow).
TEST(GridPrefixTest, CellsAreReadFromTheMeshsFirstTriangles) {
  std::vector<float> heights(5 * 4);
  for (size_t i = 0; i < heights.size(); ++i) heights[i] = float(i % 3);
  const TriangleMesh grid = MeshFromHeights(heights, 5, 4, 10.0);
  const auto all = GridPrefixCells(grid, {5, 4, 12});
  ASSERT_TRUE(all.has_value());
  EXPECT_EQ(*all, std::vector<uint8_t>(12, 1));
  EXPECT_FALSE(GridPrefixCells(grid, {5, 4, 13}).has_value());
  EXPECT_FALSE(GridPrefixCells(grid, {6, 4, 12}).has_value());
  EXPECT_FALSE(GridPrefixCells(grid, {5, 4, 0}).has_value());
  // Cells 1, 2 and 7 only, in order.
  TriangleMesh holed;
  holed.vertices = grid.vertices;
  for (const int cell : {1, 2, 7}) {
    holed.triangles.push_back(grid.triangles[2 * cell]);
    holed.triangles.push_back(grid.triangles[2 * cell + 1]);
  }
  const auto some = GridPrefixCells(holed, {5, 4, 3});
  ASSERT_TRUE(some.has_value());
  std::vector<uint8_t> want(12, 0);
  want[1] = want[2] = want[7] = 1;
  EXPECT_EQ(*some, want);
  TriangleMesh swapped = holed;
  std::swap(swapped.triangles[0], swapped.triangles[2]);
  std::swap(swapped.triangles[1], swapped.triangles[3]);
  EXPECT_FALSE(GridPrefixCells(swapped, {5, 4, 3}).has_value());
  TriangleMesh changed = holed;
  std::swap(changed.triangles[4][1], changed.triangles[4][2]);
  EXPECT_FALSE(GridPrefixCells(changed, {5, 4, 3}).has_value());
}

}  // namespace
}  // namespace gissar::scene
