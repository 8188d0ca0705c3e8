// GDAL/OGR process set-up, owned by the geo module: the only module that
// includes GDAL headers.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <gdal.h>
#include <gdal_alg.h>
#include <gdal_priv.h>

#include "gissar/geo/raster_io.h"

namespace gissar::geo {

// Registers all GDAL drivers once, routes GDAL's own messages to a quiet
// handler (they are reported through exceptions instead) and disables .aux.xml
// side files. Thread-safe; cheap after the first call.
void EnsureGdal();

// The last message GDAL reported on this thread ("" when none).
std::string LastGdalMessage();

// An open GDAL dataset, closed (GDALClose) when the pointer goes.
struct GdalDatasetCloser {
  void operator()(GDALDataset* ds) const { GDALClose(ds); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, GdalDatasetCloser>;

// GCPs in GDAL's form (ids "1", "2", ...; pixel/line, X = longitude,
// Y = latitude, Z = height). `list` points into `ids`: keep the object alive
// while GDAL uses it, and do not copy it.
struct GdalGcpList {
  explicit GdalGcpList(const std::vector<GroundControlPoint>& gcps);
  GdalGcpList(const GdalGcpList&) = delete;
  GdalGcpList& operator=(const GdalGcpList&) = delete;
  std::vector<std::string> ids;
  std::vector<GDAL_GCP> list;
};

// Runs a GDAL transformer (pixel/line -> georeferenced, bDstToSrc = FALSE)
// over `pixels`; a point it cannot transform is NaN.
std::vector<Eigen::Vector2d> TransformPixels(GDALTransformerFunc transform, void* transformer,
                                             const std::vector<Eigen::Vector2d>& pixels);

}  // namespace gissar::geo
