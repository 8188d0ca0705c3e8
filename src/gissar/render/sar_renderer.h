// Ray-traced SAR image formation: rays leave the sensor (parallel rays in
// affine mode, fans from the flight line in exact mode), hit the scene, and
// each hit returns a Lambertian share of its power to the radar at the hit's
// (azimuth, slant range). See docs/geometry.md for the ray layout and the
// radiometric normalisation.
#pragma once

#include <cstdint>
#include <vector>

#include "gissar/material/material.h"
#include "gissar/render/embree_scene.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"

namespace gissar::render {

// Layover/shadow mask codes in radar geometry (SNAP's convention).
inline constexpr uint8_t kMaskNone = 0;
inline constexpr uint8_t kMaskLayover = 1;
inline constexpr uint8_t kMaskShadow = 2;  // kMaskLayover | kMaskShadow = 3: both

struct RenderOptions {
  // Rays per resolution cell on flat ground at the scene-centre depression:
  // round(sqrt(N)) along azimuth times N / that across range. >= 1.
  double rays_per_cell = 4.0;
  // Progress lines on stderr.
  bool show_progress = true;

  // Throws ConfigError when rays_per_cell is below 1, above 1024 or NaN.
  void Check() const;
};

struct RenderStats {
  int64_t rays = 0;           // primary rays traced
  int64_t hits = 0;           // rays that hit the scene
  int64_t shadow_rays = 0;    // visibility rays of the mask
  double trace_seconds = 0.0;
  double mask_seconds = 0.0;
};

struct SarImage {
  int width = 0;                // columns: slant range
  int height = 0;               // rows: azimuth
  std::vector<float> intensity; // linear, row-major
  std::vector<uint8_t> mask;    // kMask* codes, row-major
  RenderStats stats;
};

// Renders the single-bounce Lambertian image and the layover/shadow mask of
// `mesh` (already in `embree`) seen with `geometry`.
//
// Intensity: every ray carries an equal share of the power crossing the
// beam; a hit with local incidence theta returns its material's
// Backscatter(cos theta) of it (diffuse rho * cos(theta) plus the specular
// highlight, see material.h), splatted bilinearly onto
// the four pixel centres around its continuous (column, row). The image is
// normalised so that flat ground at the scene-centre depression d reads
// rho * cos(90 deg - d) = rho * sin(d); foreshortened slopes read more,
// slopes turned away less, occluded surfaces nothing. In exact mode a ray's
// share grows with its range (constant angular spacing), so flat ground reads
// rho * sin(d_p) * tan(d_p) / tan(d) at a point of depression d_p.
//
// Mask (value at each pixel centre): bit kMaskLayover when a lit surface that
// is imaged flipped (steeper towards the radar than the local slant-range
// plane) covers the centre; bit kMaskShadow when a surface covering the
// centre is not lit (turned away from the radar or occluded).
SarImage RenderSar(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                   const material::MaterialTable& materials, const sensor::SarGeometry& geometry,
                   const RenderOptions& options);

// Only the layover/shadow mask (see RenderSar).
std::vector<uint8_t> RenderLayoverShadowMask(const EmbreeScene& embree,
                                             const scene::TriangleMesh& mesh,
                                             const sensor::SarGeometry& geometry,
                                             int64_t* shadow_rays = nullptr);

}  // namespace gissar::render
