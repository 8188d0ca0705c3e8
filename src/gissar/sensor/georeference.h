// Georeferencing of a slant-range image for GIS tools: WGS84 ground control
// points on the imaged terrain and rational polynomial coefficients (RPCs)
// fitted to the image's own projection (docs/georeferencing.md).
#pragma once

#include <functional>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::sensor {

// Height (ENU z, metres) of the terrain's top surface at ENU (x, y) metres,
// or NaN where there is no terrain.
using SurfaceHeight = std::function<double(double x_m, double y_m)>;

// What is known of a SurfaceHeight beyond its values, to march faster.
struct SurfaceLimits {
  // Bound on the surface's slope (rise per horizontal metre: the tangent of
  // its steepest facet) where it is defined; +inf: unknown. Lets the march
  // leap while it is high above the terrain.
  double max_gradient = std::numeric_limits<double>::infinity();
  // ENU plan box (x, y metres) outside which the surface is NaN; empty:
  // unknown. The march skips the part of a locus outside it.
  Eigen::AlignedBox2d plan;
};

struct GeoreferenceReport {
  int gcp_count = 0;
  double rpc_max_error_px = 0.0;  // largest fit residual over the lattice
  double rpc_rms_error_px = 0.0;
};

// Pixel centre (column, row) of node (i, j) of SlantRangeGeoreference's
// `grid` x `grid` lattice: ((width - 1) i / (grid - 1), (height - 1) j /
// (grid - 1)); the node's index is j * grid + i.
Eigen::Vector2d LatticePixel(const SarGeometry& geometry, int grid, int i, int j);

// A lattice node's terrain point as a caller found it directly (e.g. by a
// walk along the terrain's profile under the node's image row): `known`
// false leaves the node to the march; `enu` nullopt: the node's locus misses
// the terrain.
struct KnownLatticePoint {
  bool known = false;
  std::optional<Eigen::Vector3d> enu;
};

// GCPs on a `grid` x `grid` lattice of pixels spanning the image (corners
// included): each is the first terrain point, seen from above, whose
// projection is that pixel (the affine model's line along n, or exact mode's
// iso-range circle in the zero-Doppler plane), found by marching in steps of
// a quarter pixel and bisecting. Nodes whose locus misses the terrain are
// left out. `z_min_m`/`z_max_m` bound the terrain's ENU heights.
// `limits` (optional) lets the march leap over what cannot hold the first
// crossing; the GCPs are the same (to 2^-26 of a quarter-pixel step).
// RPCs: cubic polynomials in normalised (lon, lat, height) with denominator
// 1, fitted by least squares to geometry.Project() on a 15 x 15 x 7 lattice
// spanning the GCPs' longitude/latitude box (grown by 10 %) and their
// heights +-100 m; pixel coordinates follow GDAL's RPC convention (centre
// of the first pixel = 0). The affine model is an affine map of ENU, and
// ENU is smooth in lon/lat/h, so the fit is exact to rounding (3e-10 px
// measured); exact mode's square-root range fits to a few hundredths of a
// pixel. The residuals are reported.
// `known` (optional, one per lattice node in index order): nodes whose
// point the caller found are not marched (that point is the node's GCP).
// Throws ConfigError when fewer than 3 GCPs hit the terrain or grid < 2;
// CHECKs that `known`, when given, has grid * grid entries.
geo::Georeference SlantRangeGeoreference(const SarGeometry& geometry, const geo::LocalFrame& frame,
                                         const SurfaceHeight& surface, double z_min_m,
                                         double z_max_m, int grid = 12,
                                         GeoreferenceReport* report = nullptr,
                                         const SurfaceLimits& limits = {},
                                         const std::vector<KnownLatticePoint>* known = nullptr);

}  // namespace gissar::sensor
