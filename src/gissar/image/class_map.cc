#include "gissar/image/class_map.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "gissar/util/check.h"

namespace gissar::image {

const std::array<std::array<uint8_t, 3>, scene::kClassCount>& ClassColours() {
  static const std::array<std::array<uint8_t, 3>, scene::kClassCount> colours = {{
      {{210, 190, 150}},  // default
      {{40, 110, 220}},   // water
      {{40, 140, 60}},    // forest
      {{160, 160, 160}},  // urban
      {{20, 20, 20}},     // road
      {{210, 50, 40}},    // building
      {{15, 50, 130}},    // sea
  }};
  return colours;
}

RgbImage RenderClassMap(const scene::TriangleMesh& mesh, const std::vector<std::string>& class_names,
                        int max_side_px) {
  GISSAR_CHECK(mesh.triangle_count() > 0);
  const Eigen::AlignedBox3d box = mesh.Bounds();
  const double span = std::max(box.sizes().x(), box.sizes().y());
  const double px_per_m = (max_side_px - 1) / span;
  RgbImage image;
  image.width = std::max(1, static_cast<int>(std::ceil(box.sizes().x() * px_per_m)) + 1);
  image.height = std::max(1, static_cast<int>(std::ceil(box.sizes().y() * px_per_m)) + 1);
  cv::Mat canvas(image.height, image.width, CV_8UC3, cv::Scalar(255, 255, 255));
  auto to_px = [&](const Eigen::Vector3f& v) {
    // Fixed-point (4 fractional bits) for sub-pixel accurate filling.
    return cv::Point(static_cast<int>(std::lround((v.x() - box.min().x()) * px_per_m * 16)),
                     static_cast<int>(std::lround((box.max().y() - v.y()) * px_per_m * 16)));
  };
  const Eigen::Vector3f sun = Eigen::Vector3f(-1.0f, 1.0f, 1.5f).normalized();
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const bool building = mesh.classes[t] == scene::kClassBuilding;
      if (building != (pass == 1)) continue;
      const Eigen::Vector3f n = mesh.Normal(t);
      if (n.z() < 0.01f) continue;  // walls and overhangs are invisible from above
      const float shade = 0.75f + 0.25f * std::max(0.0f, n.dot(sun));
      const auto& colour = ClassColours()[std::min<int>(mesh.classes[t], scene::kClassCount - 1)];
      const Eigen::Vector3i tri = mesh.Triangle(t);
      const cv::Point pts[3] = {to_px(mesh.vertices[tri[0]]), to_px(mesh.vertices[tri[1]]),
                                to_px(mesh.vertices[tri[2]])};
      cv::fillConvexPoly(canvas, pts, 3,
                         cv::Scalar(colour[0] * shade, colour[1] * shade, colour[2] * shade),
                         cv::LINE_8, 4);
    }
  }
  // Legend.
  const int rows = static_cast<int>(std::min<size_t>(class_names.size(), scene::kClassCount));
  const int line = 22;
  cv::rectangle(canvas, cv::Rect(6, 6, 150, 10 + rows * line), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(canvas, cv::Rect(6, 6, 150, 10 + rows * line), cv::Scalar(0, 0, 0), 1);
  for (int i = 0; i < rows; ++i) {
    const auto& c = ClassColours()[i];
    const int y = 12 + i * line;
    cv::rectangle(canvas, cv::Rect(12, y, 16, 16), cv::Scalar(c[0], c[1], c[2]), cv::FILLED);
    cv::putText(canvas, class_names[i], cv::Point(36, y + 13), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  image.rgb.assign(canvas.data, canvas.data + size_t(image.width) * image.height * 3);
  return image;
}

std::optional<std::vector<uint8_t>> NeutralGrey(const RgbImage& image) {
  GISSAR_CHECK(image.rgb.size() == size_t(image.width) * image.height * 3);
  std::vector<uint8_t> grey(size_t(image.width) * image.height);
  const uint8_t* p = image.rgb.data();
  for (size_t i = 0; i < grey.size(); ++i, p += 3) {
    if (p[0] != p[1] || p[0] != p[2]) return std::nullopt;
    grey[i] = p[0];
  }
  return grey;
}

}  // namespace gissar::image
