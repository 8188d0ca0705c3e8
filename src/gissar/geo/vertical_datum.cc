#include "gissar/geo/vertical_datum.h"

#include <cpl_error.h>
#include <ogr_spatialref.h>
#include <proj.h>

#include <algorithm>
#include <cctype>
#include <memory>

#include "gissar/geo/dem.h"
#include "gissar/geo/gdal_env.h"
#include "gissar/geo/geoid.h"
#include "gissar/geo/local_frame.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace {

constexpr int kEgm96Code = 5773;
constexpr int kEgm2008Code = 3855;

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

std::string DatumOfVerticalCode(int code) {
  if (code == kEgm96Code) return "egm96";
  if (code == kEgm2008Code) return "egm2008";
  return "EPSG:" + std::to_string(code);
}

// EPSG code of the vertical CRS of a datum name ("egm96" -> 5773, ...); 0
// for "ellipsoid".
int VerticalCode(const std::string& datum) {
  if (datum == "ellipsoid") return 0;
  if (datum == "egm96") return kEgm96Code;
  if (datum == "egm2008") return kEgm2008Code;
  if (datum.rfind("EPSG:", 0) == 0) return std::stoi(datum.substr(5));
  throw ConfigError("unknown vertical datum '" + datum + "'", "--vertical-datum");
}

// Grids the operations from `source` to EPSG:4979 need that PROJ cannot find
// (short names, at most three), for the error message.
std::vector<std::string> MissingGrids(const std::string& source) {
  std::vector<std::string> names;
  PJ_CONTEXT* ctx = proj_context_create();
  proj_log_level(ctx, PJ_LOG_NONE);  // the caller reports what is missing
  PJ* src = proj_create(ctx, source.c_str());
  PJ* dst = proj_create(ctx, "EPSG:4979");
  PJ_OPERATION_FACTORY_CONTEXT* factory = src && dst ? proj_create_operation_factory_context(ctx, nullptr) : nullptr;
  if (factory != nullptr) {
    proj_operation_factory_context_set_grid_availability_use(ctx, factory, PROJ_GRID_AVAILABILITY_IGNORED);
    proj_operation_factory_context_set_spatial_criterion(ctx, factory, PROJ_SPATIAL_CRITERION_PARTIAL_INTERSECTION);
    if (PJ_OBJ_LIST* ops = proj_create_operations(ctx, src, dst, factory)) {
      for (int i = 0; i < proj_list_get_count(ops) && names.size() < 3; ++i) {
        PJ* op = proj_list_get(ctx, ops, i);
        for (int g = 0; op != nullptr && g < proj_coordoperation_get_grid_used_count(ctx, op); ++g) {
          const char* short_name = nullptr;
          int available = 1;
          if (proj_coordoperation_get_grid_used(ctx, op, g, &short_name, nullptr, nullptr, nullptr, nullptr, nullptr,
                                                &available) &&
              !available && short_name != nullptr &&
              std::find(names.begin(), names.end(), short_name) == names.end() && names.size() < 3) {
            names.emplace_back(short_name);
          }
        }
        proj_destroy(op);
      }
      proj_list_destroy(ops);
    }
    proj_operation_factory_context_destroy(factory);
  }
  proj_destroy(src);
  proj_destroy(dst);
  proj_context_destroy(ctx);
  return names;
}

struct CtDeleter {
  void operator()(OGRCoordinateTransformation* ct) const { OGRCoordinateTransformation::DestroyCT(ct); }
};

}  // namespace

std::string CanonicalVerticalDatum(const std::string& value, const std::string& flag) {
  const std::string lower = Lower(value);
  if (lower.empty() || lower == "ellipsoid" || lower == "egm96" || lower == "egm2008") return lower;
  const std::string expected = "vertical datum must be ellipsoid, egm96, egm2008 or EPSG:<code of a vertical CRS>, got '" + value + "'";
  if (lower.rfind("epsg:", 0) != 0 || lower.size() == 5 || lower.size() > 11 ||
      !std::all_of(lower.begin() + 5, lower.end(), [](unsigned char c) { return std::isdigit(c); })) {
    throw ConfigError(expected, flag);
  }
  const int code = std::stoi(lower.substr(5));
  EnsureGdal();
  OGRSpatialReference srs;
  CPLPushErrorHandler(CPLQuietErrorHandler);
  const OGRErr err = srs.importFromEPSG(code);
  CPLPopErrorHandler();
  if (err != OGRERR_NONE) throw ConfigError("EPSG:" + std::to_string(code) + " is not a CRS PROJ knows; " + expected, flag);
  if (srs.IsVertical() && !srs.IsCompound()) return DatumOfVerticalCode(code);
  if (srs.IsGeographic() && srs.GetAxesCount() == 3) return "ellipsoid";
  throw ConfigError("EPSG:" + std::to_string(code) + " (" + (srs.GetName() ? srs.GetName() : "?") +
                        ") is not a vertical CRS; " + expected,
                    flag);
}

std::string VerticalDatumOfCrs(const std::string& crs_definition, const std::string& driver) {
  EnsureGdal();
  OGRSpatialReference srs;
  if (!crs_definition.empty() && srs.SetFromUserInput(crs_definition.c_str()) == OGRERR_NONE) {
    if (srs.IsCompound()) {
      const char* code = srs.GetAuthorityCode("VERT_CS");
      const char* authority = srs.GetAuthorityName("VERT_CS");
      if (code != nullptr && authority != nullptr && std::string(authority) == "EPSG") {
        return DatumOfVerticalCode(std::atoi(code));
      }
    } else if (srs.IsGeographic() && srs.GetAxesCount() == 3) {
      return "ellipsoid";
    }
  }
  if (driver == "SRTMHGT") return "egm96";
  return "";
}

VerticalDatumChoice ResolveVerticalDatum(const std::string& flag_value, const std::string& file_datum) {
  if (!flag_value.empty()) return {flag_value, "flag"};
  if (!file_datum.empty()) return {file_datum, "file"};
  return {"ellipsoid", "assumed"};
}

std::string AssumedDatumWarning(const std::string& file) {
  return file + ": the DEM names no vertical datum; its heights are taken as WGS84 ellipsoidal "
                "(give --vertical-datum ellipsoid|egm96|egm2008|EPSG:n)";
}

std::vector<double> GeoidUndulationsViaProjM(const std::string& datum, const std::vector<double>& lon_deg,
                                             const std::vector<double>& lat_deg, const std::string& where) {
  const int code = VerticalCode(datum);
  std::vector<double> n(lon_deg.size(), 0.0);
  if (code == 0 || lon_deg.empty()) return n;
  EnsureGdal();
  const std::string source_definition = "EPSG:4326+" + std::to_string(code);
  OGRSpatialReference source, target;
  if (source.SetFromUserInput(source_definition.c_str()) != OGRERR_NONE || target.importFromEPSG(4979) != OGRERR_NONE) {
    throw InputError("cannot build the CRS " + source_definition, where);
  }
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  // Heights of the vertical CRS in its own unit (1 unit at zero is 0 m anyway).
  OGRCoordinateTransformationOptions options;
  options.SetBallparkAllowed(false);
  CPLPushErrorHandler(CPLQuietErrorHandler);
  std::unique_ptr<OGRCoordinateTransformation, CtDeleter> ct(
      OGRCreateCoordinateTransformation(&source, &target, options));
  CPLPopErrorHandler();
  auto missing_grid_error = [&]() {
    const std::vector<std::string> grids = MissingGrids(source_definition);
    std::string names;
    for (const std::string& g : grids) names += (names.empty() ? "" : ", ") + g;
    return InputError("no transformation from " + datum + " heights to WGS84 ellipsoidal heights: PROJ lacks the geoid grid " +
                          (names.empty() ? std::string("of ") + source_definition : names) +
                          " (not in Debian's proj-data; put it in $PROJ_DATA or ~/.local/share/proj, e.g. `projsync "
                          "--file " + (grids.empty() ? std::string("NAME") : grids.front()) +
                          "`, or give the DEM's true --vertical-datum)",
                      where);
  };
  if (!ct) throw missing_grid_error();
  std::vector<double> x = lon_deg, y = lat_deg;
  std::vector<int> ok(x.size(), 0);
  CPLPushErrorHandler(CPLQuietErrorHandler);
  const bool all = ct->Transform(x.size(), x.data(), y.data(), n.data(), ok.data());
  CPLPopErrorHandler();
  for (size_t i = 0; i < n.size(); ++i) {
    if (!all || !ok[i] || !std::isfinite(n[i])) {
      if (i == 0 || !all) throw missing_grid_error();
      throw InputError("the geoid of " + datum + " does not cover lon " + std::to_string(lon_deg[i]) + ", lat " +
                           std::to_string(lat_deg[i]),
                       where);
    }
  }
  return n;
}

std::vector<double> GeoidUndulationsM(const std::string& datum, const std::vector<double>& lon_deg,
                                      const std::vector<double>& lat_deg, const std::string& where) {
  if (datum == "ellipsoid") return std::vector<double>(lon_deg.size(), 0.0);
  if (datum == "egm96") {
    static const Egm96Geoid geoid;  // 4 MB grid, read once
    std::vector<double> n(lon_deg.size());
    for (size_t i = 0; i < n.size(); ++i) n[i] = geoid.UndulationM(lon_deg[i], lat_deg[i]);
    return n;
  }
  return GeoidUndulationsViaProjM(datum, lon_deg, lat_deg, where);
}

void ToEllipsoidalHeights(Dem& dem, const std::string& datum) {
  if (datum == "ellipsoid") return;
  const CrsTransform transform(dem.crs_wkt);
  // Blocks of rows of about 2^20 posts: bounded memory, few PROJ set-ups.
  const int rows_per_block = std::max(1, (1 << 20) / std::max(1, dem.width));
  for (int r0 = 0; r0 < dem.height; r0 += rows_per_block) {
    const int r1 = std::min(dem.height, r0 + rows_per_block);
    std::vector<double> x, y;
    x.reserve(size_t(r1 - r0) * dem.width);
    y.reserve(x.capacity());
    for (int r = r0; r < r1; ++r) {
      for (int c = 0; c < dem.width; ++c) {
        const Eigen::Vector2d m = dem.MapFromPost(c, r);
        x.push_back(m.x());
        y.push_back(m.y());
      }
    }
    transform.ToLonLat(x, y);
    const std::vector<double> n = GeoidUndulationsM(datum, x, y, dem.source);
    float* h = dem.heights_m.data() + size_t(r0) * dem.width;
    for (size_t i = 0; i < n.size(); ++i) h[i] += static_cast<float>(n[i]);
  }
}

}  // namespace gissar::geo
