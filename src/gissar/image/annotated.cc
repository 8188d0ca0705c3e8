#include "gissar/image/annotated.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "gissar/util/check.h"

namespace gissar::image {
namespace {

double NiceStep(double span, int target_ticks) {
  const double raw = span / std::max(1, target_ticks);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (raw <= m * mag) return m * mag;
  }
  return 10 * mag;
}

std::string Fmt(double v, int decimals = 0) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

RgbImage ToRgb(const cv::Mat& m) {
  RgbImage out{m.cols, m.rows, {}};
  out.rgb.assign(m.data, m.data + size_t(m.cols) * m.rows * 3);
  return out;
}

}  // namespace

std::vector<AxisTick> AxisTicks(double origin_m, double spacing_m, int pixels, int target_ticks,
                                std::string* unit) {
  GISSAR_CHECK(spacing_m > 0 && pixels > 0 && std::isfinite(origin_m));
  const double first_m = origin_m, last_m = origin_m + (pixels - 1) * spacing_m;
  const bool km = std::max(std::abs(first_m), std::abs(last_m)) >= 1000.0;
  if (unit != nullptr) *unit = km ? "km" : "m";
  const double scale = km ? 1e-3 : 1.0;
  const double step_m = NiceStep(std::max(last_m - first_m, spacing_m), target_ticks);
  const double step_unit = step_m * scale;
  const int decimals = step_unit < 1.0 ? static_cast<int>(std::ceil(-std::log10(step_unit) - 1e-9)) : 0;
  std::vector<AxisTick> ticks;
  // Multiples of the step, counted as integers to avoid accumulating error.
  const long long k0 = static_cast<long long>(std::ceil(first_m / step_m - 1e-9));
  const long long k1 = static_cast<long long>(std::floor(last_m / step_m + 1e-9));
  for (long long k = k0; k <= k1; ++k) {
    const double v = static_cast<double>(k) * step_m;
    const double label_value = v * scale;
    ticks.push_back({(v - origin_m) / spacing_m, v, Fmt(label_value == 0.0 ? 0.0 : label_value, decimals)});
  }
  return ticks;
}

RgbImage AnnotatedQuicklook(std::span<const float> intensity, int width, int height,
                            const QuicklookAxes& axes, const std::string& title) {
  GISSAR_CHECK(intensity.size() == size_t(width) * height);
  DbStretch stretch;
  const std::vector<uint8_t> levels = DbQuicklook(intensity, 2.0, 98.0, &stretch);
  const GreyImage grey = AnnotatedGreyQuicklook(levels, stretch, width, height, axes, title);
  RgbImage out{grey.width, grey.height, std::vector<uint8_t>(grey.grey.size() * 3)};
  for (size_t i = 0; i < grey.grey.size(); ++i) out.rgb[3 * i] = out.rgb[3 * i + 1] = out.rgb[3 * i + 2] = grey.grey[i];
  return out;
}

GreyImage AnnotatedGreyQuicklook(std::span<const uint8_t> levels, const DbStretch& stretch, int width, int height,
                                 const QuicklookAxes& axes, const std::string& title) {
  GISSAR_CHECK(levels.size() == size_t(width) * height && axes.range_spacing_m > 0 &&
               axes.azimuth_spacing_m > 0);
  const int left = 70, top = 44, bottom = 50, bar = 90;
  cv::Mat canvas(height + top + bottom, width + left + bar + 20, CV_8UC1, cv::Scalar(255));
  cv::Mat(height, width, CV_8UC1, const_cast<uint8_t*>(levels.data())).copyTo(canvas(cv::Rect(left, top, width, height)));
  const cv::Scalar black(0);
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  // Title on its own line, shrunk to fit the picture's width.
  double title_scale = 0.55;
  const int title_room = canvas.cols - 8;
  while (title_scale > 0.3 && cv::getTextSize(title, font, title_scale, 1, nullptr).width > title_room) title_scale -= 0.05;
  cv::putText(canvas, title, cv::Point(4, 18), font, title_scale, black, 1, cv::LINE_AA);
  cv::rectangle(canvas, cv::Rect(left - 1, top - 1, width + 2, height + 2), black, 1);
  // Slant-range axis (bottom): true slant range (or, affine, relative to the
  // scene centre), near range on the left.
  std::string range_unit;
  for (const AxisTick& t : AxisTicks(axes.range_origin_m, axes.range_spacing_m, width, 6, &range_unit)) {
    const int x = left + static_cast<int>(std::lround(t.pixel));
    const int text_width = cv::getTextSize(t.label, font, 0.4, 1, nullptr).width;
    cv::line(canvas, cv::Point(x, top + height + 1), cv::Point(x, top + height + 6), black, 1);
    cv::putText(canvas, t.label, cv::Point(x - text_width / 2, top + height + 20), font, 0.4, black, 1, cv::LINE_AA);
  }
  // The longest label that fits the picture's width.
  std::string range_label = "slant range (" + range_unit + ") ->";
  if (axes.range_relative) {
    for (const char* words : {"slant range from scene centre (", "range from scene centre (", "range from centre ("}) {
      range_label = words + range_unit + ") ->";
      if (cv::getTextSize(range_label, font, 0.45, 1, nullptr).width <= canvas.cols - 4) break;
    }
  }
  const int range_label_width = cv::getTextSize(range_label, font, 0.45, 1, nullptr).width;
  cv::putText(canvas, range_label, cv::Point(std::max(2, left + width / 2 - range_label_width / 2), top + height + 40),
              font, 0.45, black, 1, cv::LINE_AA);
  // Along-track axis (left), relative to the scene centre, increasing down.
  std::string azimuth_unit;
  for (const AxisTick& t : AxisTicks(axes.azimuth_origin_m, axes.azimuth_spacing_m, height, 6, &azimuth_unit)) {
    const int y = top + static_cast<int>(std::lround(t.pixel));
    cv::line(canvas, cv::Point(left - 6, y), cv::Point(left - 2, y), black, 1);
    cv::putText(canvas, t.label, cv::Point(2, y + 4), font, 0.4, black, 1, cv::LINE_AA);
  }
  // The long label when it ends before the colour bar's "dB".
  std::string azimuth_label = "along track from scene centre (" + azimuth_unit + ")";
  if (cv::getTextSize(azimuth_label, font, 0.4, 1, nullptr).width > left + width + 10) {
    azimuth_label = "along track (" + azimuth_unit + ")";
  }
  cv::putText(canvas, azimuth_label, cv::Point(2, top - 8), font, 0.4, black, 1, cv::LINE_AA);
  // Colour bar in dB.
  const int bx = left + width + 20, bw = 18;
  for (int y = 0; y < height; ++y) {
    const int v = 255 - static_cast<int>(std::lround(254.0 * y / std::max(1, height - 1)));
    cv::line(canvas, cv::Point(bx, top + y), cv::Point(bx + bw, top + y), cv::Scalar(v), 1);
  }
  cv::rectangle(canvas, cv::Rect(bx, top, bw, height), black, 1);
  for (int k = 0; k <= 4; ++k) {
    const double db = stretch.high_db - k * (stretch.high_db - stretch.low_db) / 4;
    const int y = top + static_cast<int>(std::lround(k * (height - 1) / 4.0));
    cv::putText(canvas, Fmt(db, 1), cv::Point(bx + bw + 4, y + 4), font, 0.4, black, 1, cv::LINE_AA);
  }
  cv::putText(canvas, "dB", cv::Point(bx, top - 8), font, 0.45, black, 1, cv::LINE_AA);
  GreyImage out{canvas.cols, canvas.rows, {}};
  out.grey.assign(canvas.data, canvas.data + size_t(canvas.cols) * canvas.rows);
  return out;
}

RgbImage KvdDiagram(double s, double theta_deg, double phi_deg, double heading_change_deg, bool heading_known) {
  const int size = 420, cx = size / 2, cy = size / 2 + 20, radius = 140;
  cv::Mat canvas(size + 40, size, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar black(0, 0, 0), blue(30, 90, 220), red(210, 40, 40), grey(170, 170, 170);
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  cv::circle(canvas, cv::Point(cx, cy), radius, grey, 1, cv::LINE_AA);
  // Image axes: x = slant range (right), y = azimuth (down).
  cv::arrowedLine(canvas, cv::Point(cx, cy), cv::Point(cx + radius + 30, cy), grey, 1, cv::LINE_AA, 0, 0.05);
  cv::arrowedLine(canvas, cv::Point(cx, cy), cv::Point(cx, cy + radius + 30), grey, 1, cv::LINE_AA, 0, 0.05);
  cv::putText(canvas, "x (range)", cv::Point(cx + radius - 40, cy - 6), font, 0.4, grey, 1, cv::LINE_AA);
  cv::putText(canvas, "y (azimuth)", cv::Point(cx + 6, cy + radius + 28), font, 0.4, grey, 1, cv::LINE_AA);
  // The rho axis at phi (in the image plane, y down).
  const double p = phi_deg * M_PI / 180.0;
  const cv::Point a(cx - int(radius * std::cos(p)), cy - int(radius * std::sin(p)));
  const cv::Point b(cx + int(radius * std::cos(p)), cy + int(radius * std::sin(p)));
  cv::line(canvas, a, b, blue, 2, cv::LINE_AA);
  const std::string rho_label = "rho axis, phi = " + Fmt(phi_deg, 2) + " deg";
  const int label_width = cv::getTextSize(rho_label, font, 0.45, 1, nullptr).width;
  const int label_x = std::clamp(b.x - 60, 4, size - label_width - 4);
  const int label_y = std::clamp(b.y + 18, 60, size + 10);
  cv::putText(canvas, rho_label, cv::Point(label_x, label_y), font, 0.45, blue, 1, cv::LINE_AA);
  // Cyclorotation theta as an arc from the x axis.
  cv::ellipse(canvas, cv::Point(cx, cy), cv::Size(radius / 2, radius / 2), 0, 0, theta_deg, red, 2, cv::LINE_AA);
  const double t = theta_deg * M_PI / 180.0;
  cv::arrowedLine(canvas, cv::Point(cx, cy), cv::Point(cx + int(radius / 2 * std::cos(t)), cy + int(radius / 2 * std::sin(t))),
                  red, 2, cv::LINE_AA, 0, 0.15);
  cv::putText(canvas, "theta = " + Fmt(theta_deg, 2) + " deg", cv::Point(cx + 10, cy - radius / 2 - 8), font, 0.45,
              red, 1, cv::LINE_AA);
  cv::putText(canvas, "Koenderink-van Doorn: s = " + Fmt(s, 4), cv::Point(10, 20), font, 0.5, black, 1, cv::LINE_AA);
  cv::putText(canvas, "rho: not recoverable from two views", cv::Point(10, 40), font, 0.45, black, 1, cv::LINE_AA);
  if (heading_known) {
    cv::putText(canvas, "heading change = " + Fmt(heading_change_deg, 3) + " deg", cv::Point(10, size + 30), font,
                0.55, black, 1, cv::LINE_AA);
  }
  return ToRgb(canvas);
}

}  // namespace gissar::image
