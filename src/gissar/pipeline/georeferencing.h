// Georeferencing of simulated slant-range images: the terrain's top surface
// as a height function for sensor::SlantRangeGeoreference.
#pragma once

#include <limits>
#include <mutex>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "gissar/geo/raster_io.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/render/profile_sweep.h"
#include "gissar/render/raster_renderer.h"
#include "gissar/sensor/georeference.h"

namespace gissar::pipeline {

// Height of the highest triangle of a mesh above ENU (x, y). A DEM's grid of
// posts (grid_width x grid_height finite vertices, row-major, with no
// triangles or exactly MeshFromGrid's) is searched as a grid
// (render::GridHeightfield: no index, O(1) memory); any other mesh by
// binning its triangles on a regular grid of about 4 triangles per cell.
// NaN outside every triangle.
class TerrainSurface {
 public:
  explicit TerrainSurface(const Terrain& terrain);
  double operator()(double x_m, double y_m) const;
  double z_min_m() const { return z_min_; }
  double z_max_m() const { return z_max_; }
  // For sensor::SlantRangeGeoreference: the plan box of the finite
  // vertices, and the steepest triangle's slope of a plain DEM grid (+inf
  // for any other mesh; computed at the first call, a pass over the grid).
  const sensor::SurfaceLimits& limits() const;
  // Whether the terrain is a plain DEM grid (searched as a grid).
  bool plain_grid() const { return grid_.has_value(); }

 private:
  Eigen::Vector3i Triangle(size_t t) const;
  const std::vector<Eigen::Vector3f>& vertices_;
  std::optional<render::GridHeightfield> grid_;  // a plain DEM grid
  const scene::TriangleMesh* mesh_ = nullptr;  // its triangles, when it has any
  int grid_width_ = 0, grid_height_ = 0;
  bool grid_cross_up_ = true;  // scene::GridColumnCrossRowUp of the posts-only grid
  size_t triangle_count_ = 0;
  double x0_ = 0, y0_ = 0, cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> start_;    // CSR offsets, nx*ny + 1
  std::vector<uint32_t> members_;  // triangle indices
  double z_min_ = 0, z_max_ = 0;
  int plain_width_ = 0, plain_height_ = 0;
  mutable std::once_flag gradient_once_;
  mutable sensor::SurfaceLimits limits_;
};

// The terrain's top point at every node of sensor::SlantRangeGeoreference's
// `grid` x `grid` lattice over a plain DEM grid in affine mode, from one walk
// along the terrain's profile under each lattice row (`sweep`: the grid's
// render::GridProfileSweep for `geometry`): node (i, j)'s locus is the line
// along n at the range of column i in row j's zero-Doppler plane, so its
// points on the terrain are where the row's profile crosses that range, and
// the first one seen from above is the highest of them (the march's point,
// exactly). The nodes of a row whose line the grid's boundary crosses other
// than twice stay unknown (left to the march).
std::vector<sensor::KnownLatticePoint> ProfileLatticePoints(const render::GridProfileSweep& sweep,
                                                            const sensor::SarGeometry& geometry, int grid);

// Limits of the GCP refinement for thin-plate-spline users (gdalwarp -tps).
inline constexpr int kMaxGcps = 1024;
inline constexpr int kTpsCandidateLattice = 150;  // candidates: at most 150 x 150, about one per 3 px
inline constexpr int kTpsMaxRounds = 8;
inline constexpr int kTpsMaxAddedPerRound = 160;
inline constexpr double kTpsMinSeparationPx = 3.0;
inline constexpr double kTpsToleranceSpacings = 0.4;  // of the finer pixel spacing, on the ground

// What the refinement did, for the sidecar. Errors are horizontal ground
// distances (metres) between the spline through the final GCPs and the
// simulation's own terrain point of each candidate pixel.
struct TpsRefinement {
  bool enabled = false;  // refine_for_tps
  int candidates = 0;   // lattice pixels clear of layover/shadow/no-data
  int added_gcps = 0;   // GCPs added to the base lattice
  int rounds = 0;
  double tolerance_m = 0.0;
  double max_error_m = 0.0;
  double p95_error_m = 0.0;
};

// GCPs and RPCs of a simulated image on its terrain; the RPC fit's residuals
// and the GCP count go to `report`. GCPs: a 12 x 12 lattice (or a denser one,
// up to 40 x 40, until at least 100 of them see the terrain), then refined
// for gdalwarp -tps: wherever GDAL's thin-plate spline through the GCPs
// (geo::ThinPlateSpline, GDAL's interpolant) puts
// a candidate pixel (a lattice about one node per 3 pixels, at most 150 x 150,
// away from layover/shadow/no-data in `mask` when given) more than
// kTpsToleranceSpacings x the finer pixel spacing from its terrain point,
// the worst candidates (at least kTpsMinSeparationPx from every GCP) are added,
// in rounds, up to kMaxGcps GCPs; `refine_for_tps` false keeps the lattice
// (no candidates, no spline). `refinement` (optional) tells what it did.
// Throws ConfigError when the image does not see the terrain.
geo::Georeference SimulationGeoreference(const Terrain& terrain, const sensor::SarGeometry& geometry,
                                         bool refine_for_tps, sensor::GeoreferenceReport* report = nullptr,
                                         const std::vector<uint8_t>* mask = nullptr,
                                         TpsRefinement* refinement = nullptr);

}  // namespace gissar::pipeline
