#include "gissar/render/image_agreement.h"

#include <cmath>
#include <limits>

#include "gissar/util/check.h"

namespace gissar::render {

IntensityAgreement CompareIntensities(const std::vector<float>& a, const std::vector<float>& b) {
  GISSAR_CHECK(a.size() == b.size());
  IntensityAgreement result;
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const bool pa = a[i] > 0.0f, pb = b[i] > 0.0f;
    if (pa != pb) ++result.one_sided_zero;
    if (!pa || !pb) continue;
    const double x = 10.0 * std::log10(double(a[i])), y = 10.0 * std::log10(double(b[i]));
    sx += x;
    sy += y;
    sxx += x * x;
    syy += y * y;
    sxy += x * y;
    ++result.compared_pixels;
  }
  const double n = double(result.compared_pixels);
  const double cov = sxy - sx * sy / n, vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
  result.db_pearson = n >= 2 && vx > 0 && vy > 0 ? cov / std::sqrt(vx * vy)
                                                 : std::numeric_limits<double>::quiet_NaN();
  result.mean_db_difference = n >= 1 ? (sy - sx) / n : std::numeric_limits<double>::quiet_NaN();
  return result;
}

MaskAgreement CompareMasks(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b, int width,
                           int height) {
  GISSAR_CHECK(a.size() == b.size() && a.size() == size_t(width) * height);
  MaskAgreement result;
  // Whether `mask` has `bit` within one pixel of (c, r).
  auto near = [&](const std::vector<uint8_t>& mask, int c, int r, uint8_t bit) {
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int cc = c + dc, rr = r + dr;
        if (cc < 0 || rr < 0 || cc >= width || rr >= height) continue;
        if (mask[size_t(rr) * width + cc] & bit) return true;
      }
    }
    return false;
  };
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const size_t i = size_t(r) * width + c;
      if (a[i] != 0 || b[i] != 0) ++result.flagged;
      if (a[i] == b[i]) continue;
      ++result.differing;
      bool explained = true;
      for (uint8_t bit : {uint8_t{1}, uint8_t{2}}) {
        if ((a[i] & bit) && !(b[i] & bit) && !near(b, c, r, bit)) explained = false;
        if ((b[i] & bit) && !(a[i] & bit) && !near(a, c, r, bit)) explained = false;
      }
      if (!explained) {
        ++result.away_from_edges;
        if (result.unexplained.size() < MaskAgreement::kMaxListed) {
          result.unexplained.push_back({c, r, a[i], b[i]});
        }
      }
    }
  }
  return result;
}

}  // namespace gissar::render
