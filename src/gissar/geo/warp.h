// Reprojection through GDAL's warper (the library behind `gdalwarp`), for
// georeferencing checks and map-geometry outputs.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/raster_io.h"

namespace gissar::geo {

// Runs GDALWarp(src -> dst) with `gdalwarp`-style arguments (e.g. {"-rpc",
// "-t_srs", "EPSG:32631", "-tr", "5", "5"}). Overwrites dst. Throws
// InputError when src cannot be opened, IoError when warping fails.
void Warp(const std::filesystem::path& src, const std::filesystem::path& dst,
          const std::vector<std::string>& args);

// Geotransform (GDAL's six coefficients) of a raster; throws InputError when
// it has none.
std::vector<double> ReadGeoTransform(const std::filesystem::path& path);

// Maps pixels (GDAL's corner-based convention: the centre of column c is
// c + 0.5) of a raster to WGS84 (longitude, latitude) degrees through the
// raster's own georeferencing, with GDALCreateGenImgProjTransformer2
// options such as {"METHOD=GCP_TPS"} or {"METHOD=RPC", "RPC_DEM=dem.tif"}.
// A point that does not transform is NaN. Throws InputError when the raster
// cannot be opened or the transformer cannot be built.
std::vector<Eigen::Vector2d> PixelsToLonLat(const std::filesystem::path& path,
                                            const std::vector<std::string>& transformer_options,
                                            const std::vector<Eigen::Vector2d>& pixels);

// The thin-plate spline through `gcps` that `gdalwarp -tps` builds (GDAL's
// TPS transformer, pixel/line -> the GCPs' longitude/latitude), evaluated at
// `pixels` (GDAL's corner-based convention). A point that does not transform
// is NaN. Throws InputError when GDAL cannot build the spline (e.g. fewer than
// 3 GCPs, or all collinear).
std::vector<Eigen::Vector2d> TpsLonLat(const std::vector<GroundControlPoint>& gcps,
                                       const std::vector<Eigen::Vector2d>& pixels);

}  // namespace gissar::geo
