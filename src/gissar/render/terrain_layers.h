// Per-pixel terrain layers of a slant-range image: the surface area that
// projects into each pixel and its local incidence angle (the geometry
// behind radiometric terrain correction, Small 2011).
#pragma once

#include <vector>

#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::render {

struct TerrainLayers {
  int width = 0, height = 0;
  // Area (m^2) of the surfaces facing the radar (cos local incidence > 0)
  // whose projection falls in the pixel, occlusion ignored (a facet in
  // shadow still counts: it is the area the pixel's slant-range cell cuts
  // from the terrain). Row-major; 0 where nothing projects.
  std::vector<float> projected_area_m2;
  // Area-weighted mean local incidence (degrees, angle between the facet
  // normal and the direction to the sensor) of those surfaces; NaN where
  // projected_area_m2 is 0.
  std::vector<float> local_incidence_deg;
};

// Distributes the area of every triangle of `mesh` that faces the radar over
// the pixels its projection covers, in proportion to the part of the
// projected triangle inside each pixel square (exact clipping; the
// projection is affine over a facet). Flat ground gives range_spacing x
// azimuth_spacing / sin(local incidence) per pixel; a plane tilted towards
// the radar by a, sin(incidence - a) instead. Serial and deterministic.
TerrainLayers ComputeTerrainLayers(const scene::TriangleMesh& mesh, const sensor::SarGeometry& geometry);

}  // namespace gissar::render
