// Georeferencing of simulated slant-range images: the terrain's top surface
// as a height function for sensor::SlantRangeGeoreference.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "gissar/geo/raster_io.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/sensor/georeference.h"

namespace gissar::pipeline {

// Height of the highest triangle of a mesh above ENU (x, y), by binning the
// triangles on a regular grid of about 4 triangles per cell. A DEM's grid of
// posts without triangles (grid_width x grid_height vertices, row-major) is
// triangulated on the fly. NaN outside every triangle.
class TerrainSurface {
 public:
  explicit TerrainSurface(const Terrain& terrain);
  double operator()(double x_m, double y_m) const;
  double z_min_m() const { return z_min_; }
  double z_max_m() const { return z_max_; }

 private:
  Eigen::Vector3i Triangle(size_t t) const;
  const std::vector<Eigen::Vector3f>& vertices_;
  const std::vector<Eigen::Vector3i>* triangles_ = nullptr;
  int grid_width_ = 0, grid_height_ = 0;
  size_t triangle_count_ = 0;
  double x0_ = 0, y0_ = 0, cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> start_;    // CSR offsets, nx*ny + 1
  std::vector<uint32_t> members_;  // triangle indices
  double z_min_ = 0, z_max_ = 0;
};

// GCPs (12 x 12, or a denser lattice up to 40 x 40 until at least 100 of
// them see the terrain) and RPCs of a simulated image on its terrain; the fit's
// residuals go to `report`. Throws ConfigError when the image does not see
// the terrain.
geo::Georeference SimulationGeoreference(const Terrain& terrain, const sensor::SarGeometry& geometry,
                                         sensor::GeoreferenceReport* report = nullptr);

}  // namespace gissar::pipeline
