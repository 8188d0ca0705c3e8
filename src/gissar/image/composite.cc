#include "gissar/image/composite.h"

#include "gissar/image/quicklook.h"
#include "gissar/util/check.h"

namespace gissar::image {

RgbImage GreenMagentaComposite(const std::vector<uint8_t>& green, const std::vector<uint8_t>& magenta,
                               int width, int height) {
  GISSAR_CHECK(width > 0 && height > 0);
  GISSAR_CHECK(green.size() == size_t(width) * height && magenta.size() == green.size());
  RgbImage out{width, height, std::vector<uint8_t>(green.size() * 3)};
  for (size_t i = 0; i < green.size(); ++i) {
    out.rgb[3 * i + 0] = magenta[i];
    out.rgb[3 * i + 1] = green[i];
    out.rgb[3 * i + 2] = magenta[i];
  }
  return out;
}

RgbImage IntensityComposite(const std::vector<float>& green, const std::vector<float>& magenta, int width,
                            int height) {
  GISSAR_CHECK(green.size() == size_t(width) * height && magenta.size() == green.size());
  return GreenMagentaComposite(DbQuicklook(green, 2.0, 98.0), DbQuicklook(magenta, 2.0, 98.0), width, height);
}

}  // namespace gissar::image
