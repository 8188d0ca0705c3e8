// Ray-traced simulation on the radar grid of a real product (zero-Doppler
// time x slant range, real orbit). Design (docs/geometry.md, "Simulating a
// real product"): the tracer (RenderSar: single and multi-bounce physics,
// materials, occlusion) runs unchanged with an exact-mode SarGeometry whose
// straight, level flight line is tangent to the real trajectory at the
// scene centre; every return it records is then re-projected with the real
// range-Doppler geometry (geo2rdr on the real orbit) onto the product grid.
// The straight line only decides where the rays start (metres from the true
// track over a chip, so illumination and occlusion are unchanged to within
// milliradians); where each return lands is exact. The layover/shadow mask
// is looked up through each product pixel's ground point (rdr2geo).
#pragma once

#include <vector>

#include "gissar/geo/local_frame.h"
#include "gissar/material/material.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/range_doppler.h"

namespace gissar::render {

struct ProductImage {
  // Intensity (total and per bounce count) and mask on the product grid:
  // width = grid.cols (slant range), height = grid.rows (azimuth).
  SarImage image;
  // Per-pixel ground point of the product grid on the scene surface
  // (rdr2geo): WGS84 degrees and ellipsoidal metres; NaN where none.
  std::vector<float> lon_deg, lat_deg, height_m;
  std::vector<double> lon_deg_exact, lat_deg_exact;  // the same in double precision
  // The straight tracing geometry used (for provenance).
  sensor::SarGeometryOptions tracing_geometry;
  int64_t contributions = 0;  // returns re-projected
  int64_t geolocated = 0;     // pixels with a ground point
};

// The surface height below WGS84 (lon, lat) found by a ray along the
// ellipsoid normal through the scene (metres above the ellipsoid);
// nullopt where the ray misses the scene.
sensor::HeightFunction SceneHeightFunction(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                           const geo::LocalFrame& frame);

// Renders `mesh` (in `embree`, ENU coordinates of `frame`) on `grid` seen
// from `orbit`. options.coherent is not supported (ConfigError): the
// re-projection moves returns by fractions of a pixel, which would break the
// phase model. Throws InputError when no pixel of the grid reaches the
// scene (the product lies outside the DEM). options.reflectors come back as
// image.points on the product grid (RCS and visibility as RenderSar gives
// them; the phase centre by geo2rdr on the real orbit), for the sensor stage
// (image::AddPointIntensities).
ProductImage RenderProduct(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                           const material::MaterialTable& materials, const geo::LocalFrame& frame,
                           const sensor::Orbit& orbit, const sensor::RadarGrid& grid,
                           const RenderOptions& options);

}  // namespace gissar::render
