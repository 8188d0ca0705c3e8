#include "gissar/image/epipolar_plot.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "gissar/util/check.h"

namespace gissar::image {
namespace {

// Segment of the line a x + b y + c = 0 inside a w x h image.
bool ClipLine(const Eigen::Vector3d& line, int w, int h, cv::Point2d* p, cv::Point2d* q) {
  std::vector<cv::Point2d> pts;
  const double a = line.x(), b = line.y(), c = line.z();
  if (std::abs(b) > 1e-12) {
    for (double x : {0.0, double(w - 1)}) {
      const double y = -(a * x + c) / b;
      if (y >= 0 && y <= h - 1) pts.emplace_back(x, y);
    }
  }
  if (std::abs(a) > 1e-12) {
    for (double y : {0.0, double(h - 1)}) {
      const double x = -(b * y + c) / a;
      if (x >= 0 && x <= w - 1) pts.emplace_back(x, y);
    }
  }
  if (pts.size() < 2) return false;
  *p = pts[0];
  *q = pts[1];
  return true;
}

}  // namespace

RgbImage DrawEpipolarPair(const EpipolarPlotInput& in) {
  GISSAR_CHECK(in.image1.size() == size_t(in.width1) * in.height1);
  GISSAR_CHECK(in.image2.size() == size_t(in.width2) * in.height2);
  const int gap = 10, height = std::max(in.height1, in.height2);
  cv::Mat canvas(height, in.width1 + gap + in.width2, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::Mat g1(in.height1, in.width1, CV_8UC1, const_cast<uint8_t*>(in.image1.data()));
  cv::Mat g2(in.height2, in.width2, CV_8UC1, const_cast<uint8_t*>(in.image2.data()));
  cv::Mat c1, c2;
  cv::cvtColor(g1, c1, cv::COLOR_GRAY2RGB);
  cv::cvtColor(g2, c2, cv::COLOR_GRAY2RGB);
  c1.copyTo(canvas(cv::Rect(0, 0, in.width1, in.height1)));
  c2.copyTo(canvas(cv::Rect(in.width1 + gap, 0, in.width2, in.height2)));
  const cv::Point2d offset(in.width1 + gap, 0);
  const cv::Scalar yellow(255, 220, 0), green(0, 200, 0), red(230, 0, 0), blue(80, 140, 255);
  for (size_t i = 0; i < in.matches.size(); ++i) {
    const bool ok = i >= in.inlier.size() || in.inlier[i];
    const cv::Point2d p1(in.matches[i][0].x(), in.matches[i][0].y());
    const cv::Point2d p2 = cv::Point2d(in.matches[i][1].x(), in.matches[i][1].y()) + offset;
    if (ok) {
      cv::Point2d a, b;
      if (i < in.lines_in_2.size() && ClipLine(in.lines_in_2[i], in.width2, in.height2, &a, &b)) {
        cv::line(canvas, a + offset, b + offset, yellow, 1, cv::LINE_AA);
      }
      if (i < in.lines_in_1.size() && ClipLine(in.lines_in_1[i], in.width1, in.height1, &a, &b)) {
        cv::line(canvas, a, b, yellow, 1, cv::LINE_AA);
      }
      cv::line(canvas, p1, p2, blue, 1, cv::LINE_AA);
      cv::circle(canvas, p1, 3, green, 2, cv::LINE_AA);
      cv::circle(canvas, p2, 3, green, 2, cv::LINE_AA);
    } else {
      cv::drawMarker(canvas, p1, red, cv::MARKER_CROSS, 8, 2);
      cv::drawMarker(canvas, p2, red, cv::MARKER_CROSS, 8, 2);
    }
  }
  RgbImage out{canvas.cols, canvas.rows, {}};
  out.rgb.assign(canvas.data, canvas.data + size_t(canvas.cols) * canvas.rows * 3);
  return out;
}

}  // namespace gissar::image
