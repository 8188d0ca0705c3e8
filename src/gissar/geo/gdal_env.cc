#include "gissar/geo/gdal_env.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>

#include <limits>
#include <mutex>

namespace gissar::geo {

void EnsureGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetErrorHandler(CPLQuietErrorHandler);
    CPLSetConfigOption("GDAL_PAM_ENABLED", "NO");
    CPLSetConfigOption("CPL_LOG_ERRORS", "OFF");
  });
}

std::string LastGdalMessage() {
  const char* message = CPLGetLastErrorMsg();
  return message != nullptr ? std::string(message) : std::string();
}

GdalGcpList::GdalGcpList(const std::vector<GroundControlPoint>& gcps) : ids(gcps.size()), list(gcps.size()) {
  for (size_t i = 0; i < gcps.size(); ++i) {
    ids[i] = std::to_string(i + 1);
    list[i].pszId = ids[i].data();
    list[i].pszInfo = const_cast<char*>("");
    list[i].dfGCPPixel = gcps[i].pixel;
    list[i].dfGCPLine = gcps[i].line;
    list[i].dfGCPX = gcps[i].lon_deg;
    list[i].dfGCPY = gcps[i].lat_deg;
    list[i].dfGCPZ = gcps[i].height_m;
  }
}

std::vector<Eigen::Vector2d> TransformPixels(GDALTransformerFunc transform, void* transformer,
                                             const std::vector<Eigen::Vector2d>& pixels) {
  const int n = static_cast<int>(pixels.size());
  std::vector<double> x(n), y(n), z(n, 0.0);
  std::vector<int> ok(n, 0);
  for (int i = 0; i < n; ++i) {
    x[i] = pixels[i].x();
    y[i] = pixels[i].y();
  }
  transform(transformer, FALSE, n, x.data(), y.data(), z.data(), ok.data());
  std::vector<Eigen::Vector2d> out(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < n; ++i) out[i] = ok[i] ? Eigen::Vector2d(x[i], y[i]) : Eigen::Vector2d(nan, nan);
  return out;
}

}  // namespace gissar::geo
