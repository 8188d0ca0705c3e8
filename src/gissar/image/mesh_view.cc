#include "gissar/image/mesh_view.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "gissar/util/check.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Unit vector towards compass azimuth `az` at elevation `el` (ENU).
Eigen::Vector3d Direction(double az_deg, double el_deg) {
  return {std::sin(az_deg * kDeg) * std::cos(el_deg * kDeg), std::cos(az_deg * kDeg) * std::cos(el_deg * kDeg),
          std::sin(el_deg * kDeg)};
}

}  // namespace

void MeshViewOptions::Check() const {
  if (!std::isfinite(view_azimuth_deg)) throw ConfigError("must be finite", "view_azimuth_deg");
  if (!(view_elevation_deg > 0 && view_elevation_deg <= 90)) {
    throw ConfigError("must be in (0, 90] degrees", "view_elevation_deg");
  }
  if (!(vertical_exaggeration > 0) || !std::isfinite(vertical_exaggeration)) {
    throw ConfigError("must be positive", "vertical_exaggeration");
  }
  if (!(field_of_view_deg > 1 && field_of_view_deg < 120)) {
    throw ConfigError("must be in (1, 120) degrees", "field_of_view_deg");
  }
  if (!std::isfinite(sun_azimuth_deg) || !(sun_elevation_deg > 0 && sun_elevation_deg <= 90)) {
    throw ConfigError("sun elevation must be in (0, 90] degrees", "sun_elevation_deg");
  }
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    throw ConfigError("image size must be in [16, 8192] pixels", "width/height");
  }
}

std::vector<std::array<uint8_t, 3>> ClassColourList() {
  return {ClassColours().begin(), ClassColours().end()};
}

RgbImage RenderMeshView(const scene::TriangleMesh& mesh, const std::vector<std::array<uint8_t, 3>>& class_colours,
                        const MeshViewOptions& options) {
  options.Check();
  GISSAR_CHECK(mesh.triangle_count() > 0);
  const int ss = 2;  // supersampling factor
  const int w = options.width * ss, h = options.height * ss;
  const Eigen::AlignedBox3d box = mesh.Bounds();
  const double z_mean = box.center().z();
  const double k = options.vertical_exaggeration;
  auto world = [&](const Eigen::Vector3f& v) {
    return Eigen::Vector3d(v.x(), v.y(), z_mean + k * (v.z() - z_mean));
  };
  Eigen::Vector3d half = 0.5 * box.sizes();
  half.z() *= k;
  const double radius = std::max(half.norm(), 1.0);
  const double half_fov = 0.5 * options.field_of_view_deg * kDeg;
  const double distance = 1.05 * radius / std::sin(half_fov);
  const Eigen::Vector3d target = box.center();
  const Eigen::Vector3d eye = target + distance * Direction(options.view_azimuth_deg, options.view_elevation_deg);
  const Eigen::Vector3d forward = (target - eye).normalized();
  Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ());
  if (right.norm() < 1e-9) right = Eigen::Vector3d::UnitX();  // looking straight down
  right.normalize();
  const Eigen::Vector3d up = right.cross(forward);
  // Zoom and centre on the projected corners of the (exaggerated) bounding
  // box so that the mesh fills 95 % of the picture's limiting side.
  double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d c(corner & 1 ? box.max().x() : box.min().x(), corner & 2 ? box.max().y() : box.min().y(),
                            z_mean + k * ((corner & 4 ? box.max().z() : box.min().z()) - z_mean));
    const Eigen::Vector3d d = c - eye;
    const double z = d.dot(forward);  // > 0: the camera is outside the bounding sphere
    amin = std::min(amin, d.dot(right) / z);
    amax = std::max(amax, d.dot(right) / z);
    bmin = std::min(bmin, d.dot(up) / z);
    bmax = std::max(bmax, d.dot(up) / z);
  }
  const double focal = 0.95 * std::min(w / std::max(amax - amin, 1e-12), h / std::max(bmax - bmin, 1e-12));
  const double cx = 0.5 * w - focal * 0.5 * (amin + amax);
  const double cy = 0.5 * h + focal * 0.5 * (bmin + bmax);
  const Eigen::Vector3d sun = Direction(options.sun_azimuth_deg, options.sun_elevation_deg);

  // Background: pale sky, lighter towards the horizon (bottom).
  cv::Mat canvas(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y) {
    const double t = double(y) / (h - 1);
    canvas.row(y).setTo(cv::Scalar(200 + 40 * t, 220 + 28 * t, 240 + 12 * t));
  }
  std::vector<float> inv_depth(size_t(w) * h, 0.0f);  // 1 / z, larger = nearer; 0 = empty

  // Smooth (Gouraud) shading of the ground: area-weighted vertex normals of
  // the non-building triangles (upward), shade per vertex interpolated over
  // each triangle; buildings keep flat shading (sharp walls and roofs).
  std::vector<Eigen::Vector3d> vertex_normal(mesh.vertices.size(), Eigen::Vector3d::Zero());
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] == scene::kClassBuilding) continue;
    const Eigen::Vector3i tri = mesh.Triangle(t);
    Eigen::Vector3d n = (world(mesh.vertices[tri[1]]) - world(mesh.vertices[tri[0]]))
                            .cross(world(mesh.vertices[tri[2]]) - world(mesh.vertices[tri[0]]));
    if (n.z() < 0) n = -n;
    for (int i = 0; i < 3; ++i) vertex_normal[tri[i]] += n;  // |n| = twice the area
  }
  auto shade_of = [&](const Eigen::Vector3d& n) { return 0.35 + 0.65 * std::max(0.0, n.dot(sun)); };

  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Eigen::Vector3i tri = mesh.Triangle(t);
    Eigen::Vector3d p[3];
    double sx[3], sy[3], iz[3];
    bool behind = false;
    for (int i = 0; i < 3; ++i) {
      p[i] = world(mesh.vertices[tri[i]]);
      const Eigen::Vector3d d = p[i] - eye;
      const double z = d.dot(forward);
      if (z <= 1e-6 * distance) behind = true;
      iz[i] = 1.0 / z;
      sx[i] = cx + focal * d.dot(right) * iz[i];
      sy[i] = cy - focal * d.dot(up) * iz[i];
    }
    if (behind) continue;
    const double area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
    if (std::abs(area) < 1e-12) continue;
    Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
    if (n.norm() == 0) continue;
    n.normalize();
    if (n.dot(eye - p[0]) < 0) n = -n;  // shade the side the camera sees
    const size_t cls = mesh.classes[t];
    double shade[3];
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d& vn = vertex_normal[tri[i]];
      shade[i] = cls == scene::kClassBuilding || vn.squaredNorm() == 0 ? shade_of(n) : shade_of(vn.normalized());
    }
    const std::array<uint8_t, 3> base =
        cls < class_colours.size() ? class_colours[cls] : std::array<uint8_t, 3>{200, 200, 200};
    const int x0 = std::max(0, int(std::floor(std::min({sx[0], sx[1], sx[2]}))));
    const int x1 = std::min(w - 1, int(std::ceil(std::max({sx[0], sx[1], sx[2]}))));
    const int y0 = std::max(0, int(std::floor(std::min({sy[0], sy[1], sy[2]}))));
    const int y1 = std::min(h - 1, int(std::ceil(std::max({sy[0], sy[1], sy[2]}))));
    for (int y = y0; y <= y1; ++y) {
      const double py = y + 0.5;
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5;
        // Barycentric weights (pixel centre), inside when all share the area's sign.
        const double b0 = ((sx[1] - px) * (sy[2] - py) - (sx[2] - px) * (sy[1] - py)) / area;
        const double b1 = ((sx[2] - px) * (sy[0] - py) - (sx[0] - px) * (sy[2] - py)) / area;
        const double b2 = 1.0 - b0 - b1;
        if (b0 < 0 || b1 < 0 || b2 < 0) continue;
        // 1/z is affine in screen space: exact perspective depth.
        const float d = static_cast<float>(b0 * iz[0] + b1 * iz[1] + b2 * iz[2]);
        float& stored = inv_depth[size_t(y) * w + x];
        if (d <= stored) continue;
        stored = d;
        const double sh = b0 * shade[0] + b1 * shade[1] + b2 * shade[2];
        canvas.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uint8_t>(base[0] * sh),
                                               cv::saturate_cast<uint8_t>(base[1] * sh),
                                               cv::saturate_cast<uint8_t>(base[2] * sh));
      }
    }
  }
  cv::Mat small;
  cv::resize(canvas, small, cv::Size(options.width, options.height), 0, 0, cv::INTER_AREA);
  RgbImage out{small.cols, small.rows, {}};
  out.rgb.assign(small.data, small.data + size_t(small.cols) * small.rows * 3);
  return out;
}

}  // namespace gissar::image
