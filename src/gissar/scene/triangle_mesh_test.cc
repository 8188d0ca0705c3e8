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

}  // namespace
}  // namespace gissar::scene
