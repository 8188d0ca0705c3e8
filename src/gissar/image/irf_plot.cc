#include "gissar/image/irf_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "gissar/image/annotated.h"
#include "gissar/util/check.h"

namespace gissar::image {
namespace {

constexpr int kPanelWidth = 420;   // plot area, pixels
constexpr int kPanelHeight = 220;
constexpr int kLeft = 56;          // room for the dB labels
constexpr int kTop = 58;           // caption and panel title
constexpr int kBottom = 46;        // offset labels
constexpr int kGap = 24;           // between the two panels

std::string Fmt(double v, int decimals) {
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, v);
  return buffer;
}

RgbImage ToRgb(const cv::Mat& m) {
  RgbImage out{m.cols, m.rows, {}};
  out.rgb.assign(m.data, m.data + size_t(m.cols) * m.rows * 3);
  return out;
}

// One panel: the cut against the offset from `peak_px` (metres), in
// [-span_m, span_m] x [floor_db, 3 dB], plot area at (x0, y0).
void DrawCut(cv::Mat& canvas, int x0, int y0, const PointTargetCut& cut, double peak_px, double spacing_m,
             double floor_db, const std::string& title) {
  const cv::Scalar black(0, 0, 0), grey(200, 200, 200), blue(30, 90, 220), lobe(225, 235, 250), red(200, 40, 40);
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  const double top_db = 3.0;
  const double first_m = (cut.first_px - peak_px) * spacing_m;
  const double last_m = (cut.first_px + (double(cut.power_db.size()) - 1.0) * cut.step_px - peak_px) * spacing_m;
  const double span_m = std::max({std::abs(first_m), std::abs(last_m), spacing_m});
  auto x_of = [&](double offset_m) { return x0 + (offset_m + span_m) / (2.0 * span_m) * (kPanelWidth - 1); };
  auto y_of = [&](double db) {
    return y0 + (top_db - std::clamp(db, floor_db, top_db)) / (top_db - floor_db) * (kPanelHeight - 1);
  };
  // Main lobe shaded, grid lines every 10 dB, the -3 dB level dashed.
  const int lobe_a = int(std::lround(x_of((cut.null_first_px - peak_px) * spacing_m)));
  const int lobe_b = int(std::lround(x_of((cut.null_last_px - peak_px) * spacing_m)));
  const cv::Point lobe_top_left(std::max(x0, lobe_a), y0);
  const cv::Point lobe_bottom_right(std::min(x0 + kPanelWidth - 1, lobe_b), y0 + kPanelHeight - 1);
  cv::rectangle(canvas, cv::Rect(lobe_top_left, lobe_bottom_right), lobe, cv::FILLED);
  for (double db = 0.0; db >= floor_db; db -= 10.0) {
    const int y = int(std::lround(y_of(db)));
    cv::line(canvas, cv::Point(x0, y), cv::Point(x0 + kPanelWidth - 1, y), grey, 1);
    const std::string label = Fmt(db, 0);
    const int w = cv::getTextSize(label, font, 0.38, 1, nullptr).width;
    cv::putText(canvas, label, cv::Point(x0 - w - 6, y + 4), font, 0.38, black, 1, cv::LINE_AA);
  }
  {
    const int y = int(std::lround(y_of(-3.0)));
    for (int x = x0; x < x0 + kPanelWidth; x += 8) {
      cv::line(canvas, cv::Point(x, y), cv::Point(std::min(x + 4, x0 + kPanelWidth - 1), y), red, 1);
    }
  }
  // The curve.
  std::vector<cv::Point> points;
  points.reserve(cut.power_db.size());
  for (size_t i = 0; i < cut.power_db.size(); ++i) {
    const double offset_m = (cut.first_px + double(i) * cut.step_px - peak_px) * spacing_m;
    points.emplace_back(int(std::lround(x_of(offset_m))), int(std::lround(y_of(cut.power_db[i]))));
  }
  if (points.size() > 1) cv::polylines(canvas, points, false, blue, 1, cv::LINE_AA);
  cv::rectangle(canvas, cv::Rect(x0 - 1, y0 - 1, kPanelWidth + 2, kPanelHeight + 2), black, 1);
  // Offset axis: ticks from AxisTicks, the original samples as short marks.
  std::string unit;
  const int n_ticks_px = kPanelWidth;
  const double metres_per_px = 2.0 * span_m / (n_ticks_px - 1);
  for (const AxisTick& t : AxisTicks(-span_m, metres_per_px, n_ticks_px, 6, &unit)) {
    const int x = x0 + int(std::lround(t.pixel));
    const int w = cv::getTextSize(t.label, font, 0.38, 1, nullptr).width;
    cv::line(canvas, cv::Point(x, y0 + kPanelHeight), cv::Point(x, y0 + kPanelHeight + 5), black, 1);
    cv::putText(canvas, t.label, cv::Point(x - w / 2, y0 + kPanelHeight + 18), font, 0.38, black, 1, cv::LINE_AA);
  }
  const double last_px = cut.first_px + (double(cut.power_db.size()) - 1.0) * cut.step_px;
  for (double s = std::ceil(cut.first_px - 1e-9); s <= last_px + 1e-9; s += 1.0) {
    const int x = int(std::lround(x_of((s - peak_px) * spacing_m)));
    cv::line(canvas, cv::Point(x, y0 + kPanelHeight - 4), cv::Point(x, y0 + kPanelHeight - 1), black, 1);
  }
  const std::string axis = "offset from the peak (" + unit + "); marks: samples";
  const int aw = cv::getTextSize(axis, font, 0.4, 1, nullptr).width;
  cv::putText(canvas, axis, cv::Point(x0 + kPanelWidth / 2 - aw / 2, y0 + kPanelHeight + 36), font, 0.4, black, 1,
              cv::LINE_AA);
  cv::putText(canvas, title, cv::Point(x0, y0 - 8), font, 0.42, black, 1, cv::LINE_AA);
}

}  // namespace

RgbImage IrfPlot(const std::vector<IrfPlotEntry>& entries, double floor_db, const std::string& empty_text) {
  GISSAR_CHECK(floor_db < 0.0 && std::isfinite(floor_db));
  const auto font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar black(0, 0, 0);
  if (entries.empty()) {
    cv::Mat canvas(80, 2 * (kLeft + kPanelWidth) + kGap + 16, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(canvas, empty_text, cv::Point(16, 46), font, 0.6, black, 1, cv::LINE_AA);
    return ToRgb(canvas);
  }
  const int row_height = kTop + kPanelHeight + kBottom;
  const int width = 2 * (kLeft + kPanelWidth) + kGap + 16;
  cv::Mat canvas(row_height * int(entries.size()) + 8, width, CV_8UC3, cv::Scalar(255, 255, 255));
  for (size_t k = 0; k < entries.size(); ++k) {
    const IrfPlotEntry& e = entries[k];
    GISSAR_CHECK(e.range_spacing_m > 0.0 && e.azimuth_spacing_m > 0.0);
    const PointTargetMeasurement& m = e.measurement;
    const int y0 = int(k) * row_height;
    cv::putText(canvas, e.caption + "  (power relative to the peak, dB; shaded: main lobe; dashed: -3 dB)",
                cv::Point(8, y0 + 20), font, 0.45, black, 1, cv::LINE_AA);
    auto title = [&](const char* axis, double res_m, double pslr, double islr) {
      return std::string(axis) + ": width " + Fmt(res_m, 2) + " m, PSLR " + Fmt(pslr, 1) + " dB, ISLR " +
             Fmt(islr, 1) + " dB";
    };
    DrawCut(canvas, kLeft, y0 + kTop, m.range_cut, m.peak_px.range, e.range_spacing_m, floor_db,
            title("range", m.resolution_m.range, m.pslr_db.range, m.islr_db.range));
    DrawCut(canvas, 2 * kLeft + kPanelWidth + kGap, y0 + kTop, m.azimuth_cut, m.peak_px.azimuth, e.azimuth_spacing_m,
            floor_db, title("azimuth", m.resolution_m.azimuth, m.pslr_db.azimuth, m.islr_db.azimuth));
  }
  return ToRgb(canvas);
}

}  // namespace gissar::image
