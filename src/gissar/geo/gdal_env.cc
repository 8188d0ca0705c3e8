#include "gissar/geo/gdal_env.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>

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

}  // namespace gissar::geo
