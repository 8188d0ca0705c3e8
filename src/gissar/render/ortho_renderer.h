// Orthographic (optical-style) views of a scene that explain the SAR image:
//  - kLineOfSight: an orthographic camera looking along the radar's line of
//    sight l from the sensor side (columns along the flight direction h,
//    rows down the image along -n, the up vector of the view);
//  - kSlantRangeNormal: the virtual orthographic camera G_perp looking along
//    -n, normal to the slant-range plane, with exactly the affine SAR
//    image's pixel grid: pixel (x, y) <-> Xc + (x - u0) dr l + (y - v0) da h.
//    A point projects to the same pixel in this view as in the affine SAR
//    image; only visibility differs (along n instead of along l).
// Surfaces are coloured by class (or by a draped orthophoto) and shaded by
// the cosine of their incidence from the radar.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "gissar/render/embree_scene.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::render {

enum class OrthoView { kLineOfSight, kSlantRangeNormal };

struct OrthoImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;       // interleaved, row-major; background white
  std::vector<int32_t> triangle;  // hit triangle per pixel, -1 for background
};

// Colour of a hit: class colours, or e.g. an orthophoto sampled at the hit's
// ENU position. Called for every hit pixel (after tracing, single thread).
using HitColour = std::function<std::array<uint8_t, 3>(const Eigen::Vector3d& enu, int32_t triangle)>;

// Renders the view. kSlantRangeNormal uses the geometry's image grid;
// kLineOfSight uses the azimuth spacing for both axes and just covers the
// scene. `geometry` must be in affine mode for kSlantRangeNormal to be the
// G_perp camera of the affine SAR model (exact mode uses the same axes at
// the scene centre).
OrthoImage RenderOrtho(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                       const sensor::SarGeometry& geometry, OrthoView view, const HitColour& colour);

}  // namespace gissar::render
