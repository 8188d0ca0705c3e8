#include "gissar/geo/warp.h"

#include <gdal_priv.h>
#include <gdal_alg.h>
#include <gdal_utils.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;

void Warp(const fs::path& src, const fs::path& dst, const std::vector<std::string>& args) {
  EnsureGdal();
  GDALDatasetH in = GDALOpen(src.c_str(), GA_ReadOnly);
  if (in == nullptr) throw InputError("not a raster GDAL can read", src.string());
  std::vector<char*> argv;
  std::vector<std::string> all = args;
  all.push_back("-overwrite");
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  GDALWarpAppOptions* options = GDALWarpAppOptionsNew(argv.data(), nullptr);
  if (options == nullptr) {
    GDALClose(in);
    throw IoError("bad warp options: " + LastGdalMessage(), dst.string());
  }
  int usage_error = 0;
  GDALDatasetH out = GDALWarp(dst.c_str(), nullptr, 1, &in, options, &usage_error);
  GDALWarpAppOptionsFree(options);
  GDALClose(in);
  if (out == nullptr || usage_error) {
    throw IoError("warp failed: " + LastGdalMessage(), dst.string());
  }
  GDALClose(out);
}

std::vector<double> ReadGeoTransform(const fs::path& path) {
  EnsureGdal();
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  if (ds == nullptr) throw InputError("not a raster GDAL can read", path.string());
  std::vector<double> gt(6);
  const CPLErr err = GDALGetGeoTransform(ds, gt.data());
  GDALClose(ds);
  if (err != CE_None) throw InputError("raster has no geotransform", path.string());
  return gt;
}

std::vector<Eigen::Vector2d> PixelsToLonLat(const fs::path& path,
                                            const std::vector<std::string>& transformer_options,
                                            const std::vector<Eigen::Vector2d>& pixels) {
  EnsureGdal();
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  if (ds == nullptr) throw InputError("not a raster GDAL can read", path.string());
  std::vector<std::string> all = transformer_options;
  all.push_back("DST_SRS=EPSG:4326");
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  void* transformer = GDALCreateGenImgProjTransformer2(ds, nullptr, argv.data());
  if (transformer == nullptr) {
    const std::string message = LastGdalMessage();
    GDALClose(ds);
    throw InputError("cannot build a transformer: " + message, path.string());
  }
  std::vector<Eigen::Vector2d> out = TransformPixels(GDALGenImgProjTransform, transformer, pixels);
  GDALDestroyGenImgProjTransformer(transformer);
  GDALClose(ds);
  return out;
}

std::vector<Eigen::Vector2d> TpsLonLat(const std::vector<GroundControlPoint>& gcps,
                                       const std::vector<Eigen::Vector2d>& pixels) {
  EnsureGdal();
  GdalGcpList list(gcps);
  void* tps = GDALCreateTPSTransformer(static_cast<int>(list.list.size()), list.list.data(), FALSE);
  if (tps == nullptr) throw InputError("cannot build a thin-plate spline: " + LastGdalMessage(), "GCPs");
  // Evaluated in parallel blocks: the solved spline is only read
  // (GDALTPSTransform calls VizGeorefSpline2D::get_point, which keeps no
  // state), and each block transforms its own points.
  const size_t n = pixels.size();
  std::vector<double> x(n), y(n), z(n, 0.0);
  std::vector<int> ok(n, 0);
  for (size_t i = 0; i < n; ++i) {
    x[i] = pixels[i].x();
    y[i] = pixels[i].y();
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& block) {
    GDALTPSTransform(tps, FALSE, static_cast<int>(block.size()), x.data() + block.begin(), y.data() + block.begin(),
                     z.data() + block.begin(), ok.data() + block.begin());
  });
  GDALDestroyTPSTransformer(tps);
  std::vector<Eigen::Vector2d> out(n);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (size_t i = 0; i < n; ++i) out[i] = ok[i] ? Eigen::Vector2d(x[i], y[i]) : Eigen::Vector2d(nan, nan);
  return out;
}

}  // namespace gissar::geo
