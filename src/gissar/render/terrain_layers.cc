#include "gissar/render/terrain_layers.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gissar/util/check.h"

namespace gissar::render {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// Area of triangle `t` inside the box [x0, x1] x [y0, y1]
// (Sutherland-Hodgman clipping against the four sides, then the shoelace
// formula).
double ClippedArea(const Vector2d t[3], double x0, double x1, double y0, double y1) {
  Vector2d buffer_a[8], buffer_b[8];
  int n = 3;
  for (int i = 0; i < 3; ++i) buffer_a[i] = t[i];
  Vector2d* in = buffer_a;
  Vector2d* out = buffer_b;
  // Each side keeps the points where value(q) >= 0.
  auto clip = [&](auto value) {
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const Vector2d& a = in[i];
      const Vector2d& b = in[(i + 1) % n];
      const double va = value(a), vb = value(b);
      if (va >= 0.0) out[m++] = a;
      if ((va >= 0.0) != (vb >= 0.0)) out[m++] = a + (b - a) * (va / (va - vb));
    }
    n = m;
    std::swap(in, out);
  };
  clip([&](const Vector2d& q) { return q.x() - x0; });
  if (n < 3) return 0.0;
  clip([&](const Vector2d& q) { return x1 - q.x(); });
  if (n < 3) return 0.0;
  clip([&](const Vector2d& q) { return q.y() - y0; });
  if (n < 3) return 0.0;
  clip([&](const Vector2d& q) { return y1 - q.y(); });
  if (n < 3) return 0.0;
  double twice = 0.0;
  for (int i = 0; i < n; ++i) {
    const Vector2d& a = in[i];
    const Vector2d& b = in[(i + 1) % n];
    twice += a.x() * b.y() - a.y() * b.x();
  }
  return 0.5 * std::abs(twice);
}

}  // namespace

TerrainLayers ComputeTerrainLayers(const scene::TriangleMesh& mesh, const sensor::SarGeometry& geometry) {
  const int width = geometry.width(), height = geometry.height();
  const size_t n = size_t(width) * height;
  // One pass in triangle order (a few samples per triangle; serial, so the
  // sums do not depend on threads).
  std::vector<double> area(n, 0.0), weighted(n, 0.0);
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Eigen::Vector3i tri = mesh.Triangle(t);
    const Vector3d v[3] = {mesh.vertices[tri[0]].cast<double>(), mesh.vertices[tri[1]].cast<double>(),
                           mesh.vertices[tri[2]].cast<double>()};
    if (!v[0].allFinite() || !v[1].allFinite() || !v[2].allFinite()) continue;
    const Vector3d cross = (v[1] - v[0]).cross(v[2] - v[0]);
    const double facet_area = 0.5 * cross.norm();
    if (!(facet_area > 0.0)) continue;
    const Vector3d normal = cross / (2.0 * facet_area);
    const Vector3d centre = (v[0] + v[1] + v[2]) / 3.0;
    const double cos_l = normal.dot(-geometry.RayDirectionTo(centre));
    if (!(cos_l > 0.0)) continue;  // turned away from the radar
    const double incidence = std::acos(std::min(1.0, cos_l)) * 180.0 / M_PI;
    const Vector2d p[3] = {geometry.Project(v[0]), geometry.Project(v[1]), geometry.Project(v[2])};
    const double image_area = 0.5 * std::abs((p[1] - p[0]).x() * (p[2] - p[0]).y() -
                                             (p[1] - p[0]).y() * (p[2] - p[0]).x());
    if (!(image_area > 1e-12)) continue;  // seen edge-on: no image area
    // The projection is affine over a facet (exactly in affine mode), so a
    // pixel receives the facet's area in the proportion of the projected
    // triangle it holds: clip the triangle to each pixel square.
    const double scale = facet_area / image_area;
    const int c_lo = std::max(0, int(std::floor(std::min({p[0].x(), p[1].x(), p[2].x()}) + 0.5)));
    const int c_hi = std::min(width - 1, int(std::floor(std::max({p[0].x(), p[1].x(), p[2].x()}) + 0.5)));
    const int r_lo = std::max(0, int(std::floor(std::min({p[0].y(), p[1].y(), p[2].y()}) + 0.5)));
    const int r_hi = std::min(height - 1, int(std::floor(std::max({p[0].y(), p[1].y(), p[2].y()}) + 0.5)));
    for (int r = r_lo; r <= r_hi; ++r) {
      for (int c = c_lo; c <= c_hi; ++c) {
        const double a = ClippedArea(p, c - 0.5, c + 0.5, r - 0.5, r + 0.5) * scale;
        if (!(a > 0.0)) continue;
        const size_t at = size_t(r) * width + c;
        area[at] += a;
        weighted[at] += a * incidence;
      }
    }
  }
  TerrainLayers out;
  out.width = width;
  out.height = height;
  out.projected_area_m2.resize(n);
  out.local_incidence_deg.resize(n);
  for (size_t i = 0; i < n; ++i) {
    out.projected_area_m2[i] = float(area[i]);
    out.local_incidence_deg[i] =
        area[i] > 0.0 ? float(weighted[i] / area[i]) : std::numeric_limits<float>::quiet_NaN();
  }
  return out;
}

}  // namespace gissar::render
