#include "gissar/render/ortho_renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

namespace gissar::render {

OrthoImage RenderOrtho(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                       const sensor::SarGeometry& geometry, OrthoView view, const HitColour& colour) {
  const Eigen::Vector3d& l = geometry.look_direction();
  const Eigen::Vector3d& h = geometry.flight_direction();
  const Eigen::Vector3d& n = geometry.range_plane_normal();
  const Eigen::Vector3d& xc = geometry.scene_centre();
  const Eigen::AlignedBox3d box = mesh.Bounds();
  const double reach = box.diagonal().norm() + (box.center() - xc).norm() + 10.0;

  // Pixel -> ray origin and direction.
  OrthoImage image;
  Eigen::Vector3d axis_x, axis_y, direction;
  double u0 = 0, v0 = 0, sx = 0, sy = 0;
  if (view == OrthoView::kSlantRangeNormal) {
    image.width = geometry.width();
    image.height = geometry.height();
    axis_x = l;
    axis_y = h;
    direction = -n;
    u0 = geometry.u0();
    v0 = geometry.v0();
    sx = geometry.range_spacing_m();
    sy = geometry.azimuth_spacing_m();
  } else {
    // Columns along h, rows along -n (image up = view up).
    axis_x = h;
    axis_y = -n;
    direction = l;
    sx = sy = geometry.azimuth_spacing_m();
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d d = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)) - xc;
      xmin = std::min(xmin, d.dot(axis_x) / sx);
      xmax = std::max(xmax, d.dot(axis_x) / sx);
      ymin = std::min(ymin, d.dot(axis_y) / sy);
      ymax = std::max(ymax, d.dot(axis_y) / sy);
    }
    u0 = std::ceil(-xmin) + 2;
    v0 = std::ceil(-ymin) + 2;
    image.width = static_cast<int>(std::ceil(xmax + u0)) + 3;
    image.height = static_cast<int>(std::ceil(ymax + v0)) + 3;
  }
  const size_t pixels = size_t(image.width) * image.height;
  image.triangle.assign(pixels, -1);
  std::vector<float> cos_inc(pixels, 0.0f);
  std::vector<Eigen::Vector3d> hit_point(pixels);
  const Eigen::Vector3f dir_f = direction.cast<float>();

  tbb::parallel_for(tbb::blocked_range<int>(0, image.height), [&](const tbb::blocked_range<int>& rows) {
    for (int y = rows.begin(); y != rows.end(); ++y) {
      for (int x = 0; x < image.width; ++x) {
        const Eigen::Vector3d on_plane = xc + (x - u0) * sx * axis_x + (y - v0) * sy * axis_y;
        const Eigen::Vector3d origin = on_plane - reach * direction;
        const auto hit = embree.Intersect(origin.cast<float>(), dir_f, 0.0f,
                                          std::numeric_limits<float>::infinity());
        if (!hit) continue;
        const size_t i = size_t(y) * image.width + x;
        image.triangle[i] = static_cast<int32_t>(hit->triangle);
        hit_point[i] = origin + double(hit->t) * direction;
        cos_inc[i] = std::max(0.0f, -mesh.Normal(hit->triangle).dot(l.cast<float>()));
      }
    }
  });

  image.rgb.assign(pixels * 3, 255);
  for (size_t i = 0; i < pixels; ++i) {
    if (image.triangle[i] < 0) continue;
    const std::array<uint8_t, 3> c = colour(hit_point[i], image.triangle[i]);
    const float shade = 0.35f + 0.65f * cos_inc[i];  // lit from the radar
    for (int k = 0; k < 3; ++k) image.rgb[i * 3 + k] = static_cast<uint8_t>(std::lround(c[k] * shade));
  }
  return image;
}

}  // namespace gissar::render
