#include "gissar/scene/triangle_mesh.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "gissar/util/check.h"

namespace gissar::scene {

Eigen::Vector3i TriangleMesh::Triangle(size_t t) const {
  const size_t grid = GridTriangleCount();
  if (t >= grid) return triangles[t - grid];
  const size_t cell = t / 2, cells_per_row = size_t(grid_width - 1);
  const int r = int(cell / cells_per_row), c = int(cell % cells_per_row);
  return GridCellTriangles(grid_width, c, r, grid_column_cross_row_up)[t % 2];
}

void TriangleMesh::MakeExplicit() {
  if (grid_width == 0) return;
  const size_t grid = GridTriangleCount();
  std::vector<Eigen::Vector3i> all(grid + triangles.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, grid, size_t(1) << 16), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t t = range.begin(); t != range.end(); ++t) all[t] = Triangle(t);
  });
  std::copy(triangles.begin(), triangles.end(), all.begin() + std::ptrdiff_t(grid));
  triangles = std::move(all);
  grid_width = grid_height = 0;
}

Eigen::Vector3f TriangleMesh::Normal(size_t t) const {
  const Eigen::Vector3i tri = Triangle(t);
  return TriangleNormal(vertices[tri[0]], vertices[tri[1]], vertices[tri[2]]);
}

Eigen::Vector3f TriangleMesh::ShadingNormal(size_t t, float u, float v) const {
  if (shading_normals.empty()) return Normal(t);
  const Eigen::Vector3i tri = Triangle(t);
  const Eigen::Vector3f& n0 = shading_normals[tri[0]];
  const Eigen::Vector3f& n1 = shading_normals[tri[1]];
  const Eigen::Vector3f& n2 = shading_normals[tri[2]];
  if (n0.isZero() || n1.isZero() || n2.isZero()) return Normal(t);
  const Eigen::Vector3f n = (1.0f - u - v) * n0 + u * n1 + v * n2;
  const float norm = n.norm();
  return norm > 0.0f ? Eigen::Vector3f(n / norm) : Normal(t);
}

void TriangleMesh::SmoothShadingNormals(ClassId excluded) {
  std::vector<Eigen::Vector3d> sum(vertices.size(), Eigen::Vector3d::Zero());
  for (size_t t = 0; t < triangle_count(); ++t) {
    if (classes[t] == excluded) continue;
    const Eigen::Vector3i tri = Triangle(t);
    const Eigen::Vector3d a = vertices[tri[0]].cast<double>();
    // Cross product = normal * twice the area: area weighting.
    const Eigen::Vector3d n =
        (vertices[tri[1]].cast<double>() - a).cross(vertices[tri[2]].cast<double>() - a);
    for (int k = 0; k < 3; ++k) sum[tri[k]] += n;
  }
  shading_normals.assign(vertices.size(), Eigen::Vector3f::Zero());
  for (size_t i = 0; i < vertices.size(); ++i) {
    const double norm = sum[i].norm();
    if (norm > 0.0) shading_normals[i] = (sum[i] / norm).cast<float>();
  }
}

Eigen::AlignedBox3d TriangleMesh::Bounds() const {
  // In parallel blocks, in float (the bounds of float coordinates are float
  // coordinates; casting afterwards gives the same box). A non-finite
  // coordinate never wins a comparison, as in AlignedBox::extend.
  using Box = Eigen::AlignedBox3f;
  const Box box = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, vertices.size(), size_t{1} << 16), Box(),
      [&](const tbb::blocked_range<size_t>& range, Box b) {
        for (size_t i = range.begin(); i != range.end(); ++i) b.extend(vertices[i]);
        return b;
      },
      [](Box a, const Box& b) {
        if (!b.isEmpty()) a.extend(b);
        return a;
      });
  if (box.isEmpty()) return Eigen::AlignedBox3d();
  return Eigen::AlignedBox3d(box.min().cast<double>(), box.max().cast<double>());
}

void TriangleMesh::Append(const TriangleMesh& other) {
  // An implicit grid can only start a mesh: one appended is stored.
  if (other.grid_width > 0) {
    TriangleMesh copy = other;
    copy.MakeExplicit();
    Append(copy);
    return;
  }
  const int offset = static_cast<int>(vertices.size());
  if (!shading_normals.empty() || !other.shading_normals.empty()) {
    shading_normals.resize(vertices.size(), Eigen::Vector3f::Zero());
    if (other.shading_normals.empty()) {
      shading_normals.resize(vertices.size() + other.vertices.size(), Eigen::Vector3f::Zero());
    } else {
      shading_normals.insert(shading_normals.end(), other.shading_normals.begin(), other.shading_normals.end());
    }
  }
  vertices.insert(vertices.end(), other.vertices.begin(), other.vertices.end());
  for (const Eigen::Vector3i& t : other.triangles) {
    triangles.push_back(t + Eigen::Vector3i::Constant(offset));
  }
  classes.insert(classes.end(), other.classes.begin(), other.classes.end());
}

void TriangleMesh::AddTriangle(const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                               const Eigen::Vector3f& c, ClassId cls) {
  const int i = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), {a, b, c});
  if (!shading_normals.empty()) shading_normals.resize(vertices.size(), Eigen::Vector3f::Zero());
  triangles.emplace_back(i, i + 1, i + 2);
  classes.push_back(cls);
}

void TriangleMesh::AddQuad(const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                           const Eigen::Vector3f& c, const Eigen::Vector3f& d, ClassId cls) {
  const int i = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), {a, b, c, d});
  if (!shading_normals.empty()) shading_normals.resize(vertices.size(), Eigen::Vector3f::Zero());
  triangles.emplace_back(i, i + 1, i + 2);
  triangles.emplace_back(i, i + 2, i + 3);
  classes.push_back(cls);
  classes.push_back(cls);
}

size_t TriangleMesh::MemoryBytes() const {
  return vertices.capacity() * sizeof(Eigen::Vector3f) + shading_normals.capacity() * sizeof(Eigen::Vector3f) +
         triangles.capacity() * sizeof(Eigen::Vector3i) + classes.capacity() * sizeof(ClassId);
}

std::optional<std::vector<uint8_t>> GridPrefixCells(const TriangleMesh& mesh, const GridPrefix& prefix) {
  if (prefix.width < 2 || prefix.height < 2 || prefix.cells <= 0) return std::nullopt;
  const int64_t w = prefix.width, h = prefix.height;
  if (int64_t(mesh.vertices.size()) < w * h || int64_t(mesh.triangle_count()) < 2 * prefix.cells ||
      prefix.cells > (w - 1) * (h - 1)) {
    return std::nullopt;
  }
  const bool up = GridColumnCrossRowUp(mesh.vertices.data(), prefix.width);
  std::vector<uint8_t> cells(size_t((w - 1) * (h - 1)), 0);
  int64_t previous = -1;
  for (int64_t k = 0; k < prefix.cells; ++k) {
    const Eigen::Vector3i t0 = mesh.Triangle(size_t(2 * k));
    const Eigen::Vector3i t1 = mesh.Triangle(size_t(2 * k + 1));
    const int64_t a = t0[0], c = a % w, r = a / w;
    if (a < 0 || c + 1 >= w || r + 1 >= h) return std::nullopt;
    const int64_t cell = r * (w - 1) + c;
    if (cell <= previous) return std::nullopt;
    const auto expected = GridCellTriangles(prefix.width, int(c), int(r), up);
    if (t0 != expected[0] || t1 != expected[1]) return std::nullopt;
    cells[size_t(cell)] = 1;
    previous = cell;
  }
  return cells;
}

TriangleMesh MeshFromGrid(const std::vector<Eigen::Vector3f>& posts, int width, int height) {
  return MeshFromGrid(std::vector<Eigen::Vector3f>(posts), width, height);
}

TriangleMesh MeshFromGrid(std::vector<Eigen::Vector3f>&& posts_taken, int width, int height) {
  TriangleMesh mesh = GridMesh(std::move(posts_taken), width, height);
  mesh.MakeExplicit();
  return mesh;
}

TriangleMesh GridMesh(std::vector<Eigen::Vector3f>&& posts_taken, int width, int height) {
  GISSAR_CHECK(width >= 2 && height >= 2);
  GISSAR_CHECK(posts_taken.size() == size_t(width) * height);
  TriangleMesh mesh;
  mesh.vertices = std::move(posts_taken);
  mesh.grid_width = width;
  mesh.grid_height = height;
  mesh.grid_column_cross_row_up = GridColumnCrossRowUp(mesh.vertices.data(), width);
  mesh.classes.assign(mesh.GridTriangleCount(), kDefaultClass);
  return mesh;
}

TriangleMesh MeshFromHeights(const std::vector<float>& heights, int width, int height,
                             double spacing_m, double x0, double y0) {
  GISSAR_CHECK(heights.size() == size_t(width) * height);
  std::vector<Eigen::Vector3f> posts(heights.size());
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      posts[size_t(r) * width + c] = Eigen::Vector3f(static_cast<float>(x0 + c * spacing_m),
                                                     static_cast<float>(y0 + r * spacing_m),
                                                     heights[size_t(r) * width + c]);
    }
  }
  return MeshFromGrid(posts, width, height);
}

}  // namespace gissar::scene
