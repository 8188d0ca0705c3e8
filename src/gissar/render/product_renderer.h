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
// Coherent mode forms the complex image on the product grid itself: each
// re-projected return is a phasor of phase exp(-j 4 pi R / lambda) with R
// its true range (geo2rdr on the real orbit, plus the path excess of a
// multi-bounce return), so the phase is that of the real geometry, not of
// the straight tracing line.
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
  // width = grid.cols (slant range), height = grid.rows (azimuth). In
  // coherent mode also the complex total and complex bounce layers
  // (image.real/imag, bounce_real/bounce_imag; intensity = |real, imag|^2,
  // bounce_layers the incoherent sums, as RenderSar gives them).
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
// from `orbit`. Throws InputError when no pixel of the grid reaches the
// scene (the product lies outside the DEM). options.reflectors come back as
// image.points on the product grid (RCS and visibility as RenderSar gives
// them; the phase centre's pixel and range_m by geo2rdr on the real orbit),
// for the sensor stage (image::AddPointIntensities, or phasors of phase
// exp(-j 4 pi range_m / lambda) in coherent mode).
//
// Coherent mode (options.coherent, phase at options.wavelength_m: the
// product's): every return RenderSar recorded becomes, where geo2rdr lands
// it, a phasor sqrt(power) exp(-j 4 pi R / lambda), R = the hit's true
// zero-Doppler range plus the tracer's path excess over it (0 for single
// bounce), split over the four neighbouring pixels with the square roots of
// the bilinear weights into image.real/imag and the return's bounce layer
// (bounce_real/bounce_imag; the layers add up to the total). A single-
// bounce (rough-surface) return also carries a micro-phase drawn from
// (options.seed, its index), uniform and independent per return, so the
// expected intensity of every pixel is the incoherent image's; a later
// bounce carries only its path phase, with twice the amplitude of one path
// (the path and its reverse add in phase, as in RenderSar). image.intensity
// is the detected complex total; bounce_layers stay the incoherent sums.
// Polarimetric passes (options.polarimetric, one channel per call, one seed
// for the set): the channel of each return's scattering matrix with
// RenderSar's joint statistics (Contribution::channel_amplitude): a first
// bounce's micro-phasor mixes three phases drawn from (seed, the return's
// ray and key, pixel), the same in every pass (HH exp(j phi1), VV
// conj(rho) exp(j phi1) + sqrt(1 - |rho|^2) exp(j phi2), HV exp(j phi3));
// a later bounce is sqrt(P) (S_c + S^T_c) with its path phase. So the passes'
// HH-VV correlation is the class's rho and a dihedral's HH and VV are
// opposite. (The phases differ from a single-channel pass's, which are
// keyed by the return's index: same statistics, other draws.)
ProductImage RenderProduct(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                           const material::MaterialTable& materials, const geo::LocalFrame& frame,
                           const sensor::Orbit& orbit, const sensor::RadarGrid& grid,
                           const RenderOptions& options);

}  // namespace gissar::render
