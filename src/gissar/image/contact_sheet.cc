#include "gissar/image/contact_sheet.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "gissar/util/check.h"

namespace gissar::image {
namespace {

constexpr int kCaption = 24;

RgbImage FromMat(const cv::Mat& m) {
  RgbImage out;
  out.width = m.cols;
  out.height = m.rows;
  out.rgb.assign(m.data, m.data + size_t(m.cols) * m.rows * 3);
  return out;
}

}  // namespace

RgbImage GreyToRgb(const std::vector<uint8_t>& grey, int width, int height) {
  GISSAR_CHECK(grey.size() == size_t(width) * height);
  RgbImage out{width, height, std::vector<uint8_t>(grey.size() * 3)};
  for (size_t i = 0; i < grey.size(); ++i) out.rgb[3 * i] = out.rgb[3 * i + 1] = out.rgb[3 * i + 2] = grey[i];
  return out;
}

RgbImage ContactSheet(const std::vector<std::vector<uint8_t>>& frames, int width, int height,
                      const std::vector<std::string>& captions) {
  GISSAR_CHECK(!frames.empty() && captions.size() == frames.size());
  const int n = static_cast<int>(frames.size());
  const int cols = static_cast<int>(std::ceil(std::sqrt(double(n))));
  const int rows = (n + cols - 1) / cols;
  const int gap = 4;
  cv::Mat sheet(rows * (height + kCaption + gap) + gap, cols * (width + gap) + gap, CV_8UC3,
                cv::Scalar(255, 255, 255));
  for (int i = 0; i < n; ++i) {
    GISSAR_CHECK(frames[i].size() == size_t(width) * height);
    const int x = gap + (i % cols) * (width + gap), y = gap + (i / cols) * (height + kCaption + gap);
    cv::Mat grey(height, width, CV_8UC1, const_cast<uint8_t*>(frames[i].data()));
    cv::Mat rgb;
    cv::cvtColor(grey, rgb, cv::COLOR_GRAY2RGB);
    rgb.copyTo(sheet(cv::Rect(x, y, width, height)));
    cv::putText(sheet, captions[i], cv::Point(x + 4, y + height + 17), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return FromMat(sheet);
}

RgbImage SideBySide(const std::vector<RgbImage>& panels, const std::vector<std::string>& titles) {
  GISSAR_CHECK(!panels.empty() && titles.size() == panels.size());
  int width = 8, height = 0;
  for (const RgbImage& p : panels) {
    width += p.width + 8;
    height = std::max(height, p.height);
  }
  cv::Mat sheet(height + kCaption + 8, width, CV_8UC3, cv::Scalar(255, 255, 255));
  int x = 8;
  for (size_t i = 0; i < panels.size(); ++i) {
    const RgbImage& p = panels[i];
    cv::Mat(p.height, p.width, CV_8UC3, const_cast<uint8_t*>(p.rgb.data()))
        .copyTo(sheet(cv::Rect(x, kCaption, p.width, p.height)));
    cv::putText(sheet, titles[i], cv::Point(x + 2, 17), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
    x += p.width + 8;
  }
  return FromMat(sheet);
}

}  // namespace gissar::image
