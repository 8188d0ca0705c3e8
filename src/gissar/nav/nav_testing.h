// Test scenes shared by the nav tests (not part of the library).
#pragma once

#include <cmath>

#include "gissar/scene/triangle_mesh.h"

namespace gissar::nav::testing {

// 8 km x 8 km of hills on a 50 m grid (relief ~300 m), ENU metres: enough
// structure for matching and non-coplanar control points.
inline scene::TriangleMesh Hills() {
  scene::TriangleMesh mesh;
  const int n = 161;
  const double step = 50.0, half = 4000.0;
  auto z = [](double x, double y) {
    return 150.0 * std::sin(x / 700.0) * std::cos(y / 530.0) + 80.0 * std::sin((x + 2 * y) / 310.0) +
           40.0 * std::cos((3 * x - y) / 170.0);
  };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = -half + i * step, y = -half + j * step;
      mesh.vertices.emplace_back(float(x), float(y), float(z(x, y)));
    }
  for (int j = 0; j + 1 < n; ++j)
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      mesh.triangles.emplace_back(a, b, d);
      mesh.triangles.emplace_back(a, d, c);
      mesh.classes.push_back(0);
      mesh.classes.push_back(0);
    }
  return mesh;
}

}  // namespace gissar::nav::testing
