#include "gissar/image/quicklook.h"

#include <algorithm>
#include <cstring>
#include <cmath>
#include <limits>

#include "gissar/util/check.h"

namespace gissar::image {
namespace {

// Positive finite floats order as their IEEE 754 bit patterns; the top 16
// bits put them in 32,640 bins (exponent and 7 mantissa bits), each about
// 0.034 dB wide.
constexpr int kBinShift = 16;
constexpr size_t kPositiveBins = 0x7F80;  // bins below +inf

inline uint32_t Bits(float v) {
  uint32_t b;
  std::memcpy(&b, &v, sizeof(b));
  return b;
}

inline bool Positive(float v) { return std::isfinite(v) && v > 0.0f; }

// The grey level of a positive value: 1 + 254 x the clipped stretch.
inline uint8_t Grey(float v, const DbStretch& s, double span) {
  const double t = (10.0 * std::log10(v) - s.low_db) / span;
  return static_cast<uint8_t>(1 + std::lround(254.0 * std::clamp(t, 0.0, 1.0)));
}

}  // namespace

std::vector<uint8_t> DbQuicklook(std::span<const float> intensity, double low_percentile,
                                 double high_percentile, DbStretch* stretch) {
  GISSAR_CHECK(0.0 <= low_percentile && low_percentile < high_percentile && high_percentile <= 100.0);
  // Percentiles of the linear values, then in dB: 10 log10 is increasing,
  // so the k-th smallest dB value is the dB of the k-th smallest value (one
  // logarithm per percentile instead of one per pixel). The k-th smallest
  // of the positive values exactly, without sorting them: a histogram of
  // their bins finds the bin that holds it, and only that bin's values are
  // partitioned.
  std::vector<uint64_t> histogram(kPositiveBins, 0);
  uint64_t count = 0;
  for (float v : intensity) {
    if (!Positive(v)) continue;
    ++histogram[Bits(v) >> kBinShift];
    ++count;
  }
  DbStretch s;
  if (count > 0) {
    auto kth = [&](double p) {
      uint64_t k = static_cast<uint64_t>(std::llround(p / 100.0 * double(count - 1)));
      size_t bin = 0;
      while (k >= histogram[bin]) k -= histogram[bin++];
      std::vector<float> members;
      members.reserve(histogram[bin]);
      for (float v : intensity) {
        if (Positive(v) && (Bits(v) >> kBinShift) == bin) members.push_back(v);
      }
      std::nth_element(members.begin(), members.begin() + std::ptrdiff_t(k), members.end());
      return members[k];
    };
    // In float, as the dB values were computed pixel by pixel.
    s.low_db = 10.0f * std::log10(kth(low_percentile));
    s.high_db = 10.0f * std::log10(kth(high_percentile));
  }
  if (stretch != nullptr) *stretch = s;
  if (count == 0) return std::vector<uint8_t>(intensity.size(), 0);
  return DbQuicklookWithStretch(intensity, s);
}

std::vector<uint8_t> DbQuicklookWithStretch(std::span<const float> intensity, const DbStretch& s) {
  const double span = std::max(s.high_db - s.low_db, 1e-6);
  // The mapping is increasing in the value, so a bin whose smallest and
  // largest floats get the same grey level gives it to all of its values:
  // one table lookup per pixel instead of a logarithm, except in the bins
  // that straddle a step between levels (0 in the table: computed).
  std::vector<uint8_t> level(kPositiveBins, 0);
  for (size_t bin = 0; bin < kPositiveBins; ++bin) {
    float lo, hi;
    const uint32_t lo_bits = uint32_t(bin) << kBinShift, hi_bits = lo_bits | ((1u << kBinShift) - 1);
    std::memcpy(&lo, &lo_bits, sizeof(lo));
    std::memcpy(&hi, &hi_bits, sizeof(hi));
    if (!Positive(lo) || !Positive(hi)) continue;
    const uint8_t a = Grey(lo, s, span), b = Grey(hi, s, span);
    if (a == b) level[bin] = a;
  }
  std::vector<uint8_t> grey(intensity.size(), 0);
  for (size_t i = 0; i < intensity.size(); ++i) {
    const float v = intensity[i];
    if (!Positive(v)) continue;
    const uint8_t g = level[Bits(v) >> kBinShift];
    grey[i] = g != 0 ? g : Grey(v, s, span);
  }
  return grey;
}

std::vector<float> Multilook(std::span<const float> image, int rows, int cols, int la, int lr, NanPixels nan) {
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
          if (std::isfinite(row[j])) {
            sum += row[j], ++n;
          } else if (nan == NanPixels::kAsZero && std::isnan(row[j])) {
            ++n;
          }
        }
      }
      if (n > 0) out[size_t(r) * out_cols + c] = static_cast<float>(sum / n);
    }
  }
  return out;
}

}  // namespace gissar::image
