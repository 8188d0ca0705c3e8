// Ray-traced SAR image formation: rays leave the sensor (parallel rays in
// affine mode, fans from the flight line in exact mode), hit the scene, and
// each hit returns a Lambertian share of its power to the radar at the hit's
// (azimuth, slant range). See docs/geometry.md for the ray layout and the
// radiometric normalisation.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "gissar/material/material.h"
#include "gissar/render/embree_scene.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/reporter.h"

namespace gissar::render {

// Layover/shadow mask codes in radar geometry (SNAP's convention).
inline constexpr uint8_t kMaskNone = 0;
inline constexpr uint8_t kMaskLayover = 1;
inline constexpr uint8_t kMaskShadow = 2;  // kMaskLayover | kMaskShadow = 3: both
// The masks of both engines count a surface seen at cos(local incidence)
// at or below this (within 0.06 deg of edge-on) as turned away: shadow.
// Exactly grazing surfaces return no power, and whether they are lit is
// decided by rounding otherwise.
inline constexpr double kMaskEdgeOnCos = 1e-3;

struct RenderOptions {
  // Rays per resolution cell on flat ground at the scene-centre depression:
  // round(sqrt(N)) along azimuth times N / that across range. >= 1.
  double rays_per_cell = 4.0;
  // Reflections followed per ray (1 = single bounce), in [1, 16]: a hit
  // continues as a mirror ray carrying its material's `mirror` share.
  int max_bounces = 3;
  // Keep every contribution in SarImage::contributions (can be large).
  bool record_contributions = false;
  // Coherent mode: the total band is |sum of complex contributions|^2 per
  // cell, each with phase 4 pi r / lambda plus a random phase per
  // scatterer (seeded) instead of a sum of intensities.
  bool coherent = false;
  double wavelength_m = 0.031;  // X band
  uint64_t seed = 1;
  // Where tracing progress goes, and who may cancel it (nullptr: nowhere,
  // never). Not owned; must outlive the render.
  Reporter* reporter = nullptr;

  // Throws ConfigError when rays_per_cell is below 1, above 1024 or NaN.
  void Check() const;
};

// One return to the radar (RaySAR's Contributions.txt, one row each).
struct Contribution {
  double azimuth_m = 0.0;    // along-track coordinate (rule: see docs/geometry.md)
  double range_m = 0.0;      // slant range: half the total path length
  double elevation_m = 0.0;  // last hit's offset along the slant-range plane normal n
  float intensity = 0.0f;    // power returned (image units)
  uint8_t bounces = 1;       // 1 single, 2 double, ...
  bool specular = false;     // the specular term dominated this return
  Eigen::Vector3f hit_enu = Eigen::Vector3f::Zero();  // last hit position
  uint8_t class_id = 0;      // class of the last hit
};

// Bands of the output: total, then per bounce count.
inline constexpr int kBounceLayers = 4;  // single, double, triple, >= 4

struct RenderStats {
  int64_t rays = 0;           // primary rays traced
  int64_t hits = 0;           // rays that hit the scene
  int64_t shadow_rays = 0;    // visibility rays of the mask
  int64_t cells = 0;          // DEM cells projected (raster engine)
  double trace_seconds = 0.0;  // tracer: rays, shading, splatting, merging; raster: all
  double mask_seconds = 0.0;
};

struct SarImage {
  int width = 0;                // columns: slant range
  int height = 0;               // rows: azimuth
  std::vector<float> intensity; // linear, row-major: all bounces (coherent sum in coherent mode)
  // Intensity per bounce count (incoherent): [0] single, [1] double,
  // [2] triple, [3] four or more.
  std::array<std::vector<float>, kBounceLayers> bounce_layers;
  std::vector<Contribution> contributions;  // when record_contributions
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
// Multi-bounce (up to max_bounces): at every hit the power sent back to the
// radar is recorded: at the first hit the material's backscatter; at later
// hits, if the way back to the radar is free, diffuse * cos(angle to the
// radar) plus the specular cone around the mirror direction. Each hit
// continues as a mirror ray with the material's `mirror` share of the power.
// A return's slant range is half the total path (sensor -> hits -> sensor);
// its azimuth is the mean of the first and last hit's along-track
// coordinates (docs/geometry.md). Results do not depend on the thread count.
//
// Mask (value at each pixel centre): bit kMaskLayover when a lit surface that
// is imaged flipped (steeper towards the radar than the local slant-range
// plane) covers the centre; bit kMaskShadow when a surface covering the
// centre is not lit (turned away from the radar or occluded).
SarImage RenderSar(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                   const material::MaterialTable& materials, const sensor::SarGeometry& geometry,
                   const RenderOptions& options);

// The limit RenderSar's primary rays are measured against (`make bench`):
// intersects exactly the primary rays RenderSar traces for `geometry` and
// `rays_per_cell` over `mesh` (same ray grid, same float origins and
// directions, same blocks of azimuth rows in parallel), 16 at a time with
// rtcIntersect16 and the coherent flag, and does nothing else with them (no
// shading, splatting, later bounces or mask). Returns the rays intersected;
// *hits (optional) the rays that hit the scene.
int64_t IntersectPrimaryRaysOnly(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                 const sensor::SarGeometry& geometry, double rays_per_cell,
                                 int64_t* hits = nullptr);

// Only the layover/shadow mask (see RenderSar).
std::vector<uint8_t> RenderLayoverShadowMask(const EmbreeScene& embree,
                                             const scene::TriangleMesh& mesh,
                                             const sensor::SarGeometry& geometry,
                                             int64_t* shadow_rays = nullptr);

}  // namespace gissar::render
