#include "gissar/image/quicklook.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gissar/util/check.h"

namespace gissar::image {
namespace {

double Percentile(std::vector<float>& values, double p) {
  const size_t k = static_cast<size_t>(std::llround(p / 100.0 * double(values.size() - 1)));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

}  // namespace

std::vector<uint8_t> DbQuicklook(const std::vector<float>& intensity, double low_percentile,
                                 double high_percentile, DbStretch* stretch) {
  GISSAR_CHECK(0.0 <= low_percentile && low_percentile < high_percentile && high_percentile <= 100.0);
  // Percentiles of the linear values, then in dB: 10 log10 is increasing,
  // so the k-th smallest dB value is the dB of the k-th smallest value (one
  // logarithm per percentile instead of one per pixel).
  std::vector<float> positive;
  positive.reserve(intensity.size());
  for (float v : intensity) {
    if (std::isfinite(v) && v > 0.0f) positive.push_back(v);
  }
  DbStretch s;
  if (!positive.empty()) {
    // In float, as the dB values were computed pixel by pixel.
    s.low_db = 10.0f * std::log10(static_cast<float>(Percentile(positive, low_percentile)));
    s.high_db = 10.0f * std::log10(static_cast<float>(Percentile(positive, high_percentile)));
  }
  if (stretch != nullptr) *stretch = s;
  if (positive.empty()) return std::vector<uint8_t>(intensity.size(), 0);
  return DbQuicklookWithStretch(intensity, s);
}

std::vector<uint8_t> DbQuicklookWithStretch(const std::vector<float>& intensity, const DbStretch& s) {
  std::vector<uint8_t> grey(intensity.size(), 0);
  const double span = std::max(s.high_db - s.low_db, 1e-6);
  for (size_t i = 0; i < intensity.size(); ++i) {
    const float v = intensity[i];
    if (!(std::isfinite(v) && v > 0.0f)) continue;
    const double t = (10.0 * std::log10(v) - s.low_db) / span;
    grey[i] = static_cast<uint8_t>(1 + std::lround(254.0 * std::clamp(t, 0.0, 1.0)));
  }
  return grey;
}

std::vector<float> Multilook(const std::vector<float>& image, int rows, int cols, int la, int lr) {
  GISSAR_CHECK(la >= 1 && lr >= 1 && rows >= 0 && cols >= 0 && image.size() == size_t(rows) * cols);
  const int out_rows = rows / la, out_cols = cols / lr;
  std::vector<float> out(size_t(out_rows) * out_cols, std::numeric_limits<float>::quiet_NaN());
  for (int r = 0; r < out_rows; ++r) {
    for (int c = 0; c < out_cols; ++c) {
      double sum = 0.0;
      int n = 0;
      for (int i = 0; i < la; ++i) {
        const float* row = image.data() + size_t(r * la + i) * cols + size_t(c) * lr;
        for (int j = 0; j < lr; ++j) {
          if (std::isfinite(row[j])) sum += row[j], ++n;
        }
      }
      if (n > 0) out[size_t(r) * out_cols + c] = static_cast<float>(sum / n);
    }
  }
  return out;
}

}  // namespace gissar::image
