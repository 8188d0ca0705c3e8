#include "gissar/mvg/point_match.h"

#include "gissar/util/error.h"

namespace gissar::mvg {

void CheckFinite(const std::vector<PointMatch>& matches, const std::string& what) {
  for (size_t i = 0; i < matches.size(); ++i) {
    if (!matches[i].p1.allFinite() || !matches[i].p2.allFinite()) {
      throw InputError("match has a non-finite coordinate (NaN or infinity)",
                       what + ", match " + std::to_string(i));
    }
  }
}

void CheckFinite(const std::vector<ControlPoint>& points, const std::string& what) {
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].world.allFinite() || !points[i].pixel.allFinite()) {
      throw InputError("control point has a non-finite coordinate (NaN or infinity)",
                       what + ", point " + std::to_string(i));
    }
  }
}

}  // namespace gissar::mvg
