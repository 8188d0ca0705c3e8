// Ray-traced SAR image formation: rays leave the sensor (parallel rays in
// affine mode, fans from the flight line in exact mode), hit the scene, and
// each hit returns a Lambertian share of its power to the radar at the hit's
// (azimuth, slant range). See docs/geometry.md for the ray layout and the
// radiometric normalisation.
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "gissar/material/material.h"
#include "gissar/material/reflector.h"
#include "gissar/render/embree_scene.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/sensor/sar_geometry.h"
#include "gissar/util/reporter.h"

namespace gissar::render {

// Layover/shadow mask codes in radar geometry (SNAP's convention).
inline constexpr uint8_t kMaskNone = 0;
inline constexpr uint8_t kMaskLayover = 1;
inline constexpr uint8_t kMaskShadow = 2;  // kMaskLayover | kMaskShadow = 3: both
// Written masks: no surface covers the pixel centre and no return landed
// there (outside the imaged footprint; the images are NaN there). The
// no-data value of the mask GeoTIFFs.
inline constexpr uint8_t kMaskOutside = 255;
// The masks of both engines count a surface seen at cos(local incidence)
// at or below this (within 0.06 deg of edge-on) as turned away: shadow.
// Exactly grazing surfaces return no power, and whether they are lit is
// decided by rounding otherwise.
inline constexpr double kMaskEdgeOnCos = 1e-3;

// A canonical reflector in the scene (material/reflector.h), ENU metres.
struct SceneReflector {
  material::ReflectorType type = material::ReflectorType::kTrihedral;
  double size_m = 1.0;
  Eigen::Vector3d apex_enu = Eigen::Vector3d::Zero();  // phase centre
  Eigen::Vector3d boresight_enu = Eigen::Vector3d::UnitZ();  // towards the sensor
  // Turned about the boresight (radians; material::ReflectorSpec::roll_deg,
  // the sense of material/scattering.h): a polarimetric pass's matrix
  // material::UnitReflectorMatrix(type, roll_rad). The RCS pattern and
  // single-channel renders ignore it.
  double roll_rad = 0.0;
  int row = 0;  // CSV row, for messages
};

// A point scatterer's return, added analytically by the sensor stage
// (image::ApplySensorEffects) after the impulse response: its integrated
// response sums to beta0_sum = RCS / (range_spacing_m azimuth_spacing_m).
struct PointReturn {
  double col = 0.0, row = 0.0;  // continuous pixel of the phase centre
  double beta0_sum = 0.0;
  double range_m = 0.0;          // slant range of the phase centre (coherent phase -4 pi r / lambda)
  int layer = 0;                 // bounce band: 0 single (plate), 1 double (dihedral), 2 triple (trihedral)
  // Added to the coherent phase -4 pi r / lambda (radians): arg S_c of the
  // reflector's unit matrix in a polarimetric pass (0 for a trihedral, pi
  // for a plate and for a roll-0 dihedral's VV); 0 otherwise.
  double phase_offset_rad = 0.0;
};

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
  // cell, each with phase -4 pi r / lambda plus a random phase per
  // scatterer (seeded) instead of a sum of intensities.
  bool coherent = false;
  // Radar wavelength (X band by default) and polarisation: they select the
  // materials' sigma0 laws, and the wavelength sets the coherent phase.
  double wavelength_m = 0.031;
  material::Polarization polarization = material::Polarization::kVV;
  uint64_t seed = 1;
  // This pass is one channel of a polarimetric set: passes with the same
  // seed (and everything else) and different `polarization` together give
  // the channels of one scattering matrix per return (RenderSar, "Polarimetric
  // passes"; docs/radiometry.md, "Polarimetry in the renderer"). False: the
  // single-channel model, bit for bit as before the option existed.
  bool polarimetric = false;
  // Canonical reflectors: their returns (RCS towards the sensor, zero when
  // the way back is occluded) go to SarImage::points.
  std::vector<SceneReflector> reflectors;
  // Where tracing progress goes, and who may cancel it (nullptr: nowhere,
  // never). Not owned; must outlive the render.
  Reporter* reporter = nullptr;
  // The box (ENU) the primary rays are laid out over and start in, and
  // whose size sets the rays' offsets and the mask's far limit; default the
  // mesh's bounds. A box that does not depend on how much terrain was loaded
  // (pipeline::SimulateImage: the image's footprint and halo) makes the image
  // of a DEM window equal to that of the whole DEM: the same rays, starting
  // at the same points. It must hold every surface that can reach the image.
  std::optional<Eigen::AlignedBox3d> ray_box;
  // Over a scene that is only a height field (EmbreeScene::HeightfieldOnly),
  // each packet of primary rays starts where the highest ray of the packet
  // below it met the terrain (the hits move monotonically away from the
  // radar up an azimuth line): the same hits, fewer tiles visited. False
  // traces every primary ray from its origin (for comparison).
  bool skip_to_previous_hit = true;
  // Over a scene that is a whole terrain grid's height field and nothing
  // else, the primary rays' first hits come from one walk per azimuth line
  // along the terrain's profile (GridProfileSweep) instead of a traversal
  // per ray: the same hits to float rounding. False traces every primary ray.
  // The mask does the same (RenderLayoverShadowMask's profile_sweep).
  bool profile_sweep = true;
  // A first hit whose footprint is wider than twice the flat-ground
  // footprint of a ray (near grazing) is split into sub-rays across the
  // ray's interval, each with its own hit (stats.sub_rays); false keeps the
  // one hit and spreads its return over the footprint (fixed sampling: the
  // rays traced are exactly the ray grid's).
  bool adaptive_sampling = true;
  // Incoherent, one channel, no recorded contributions: a swept line's rays
  // are shaded one by one instead of in the 16-lane packets built for
  // Embree, in the same order with the same arithmetic (the same image, bit
  // for bit). False keeps the packets (for comparison).
  bool one_pass_swept_lines = true;
  // Affine mode: only the primary rays whose returns can reach the image
  // are traced (those whose beam, between the ray box's lowest and highest
  // heights, passes within a footprint's reach of the image's slant-range
  // columns; with several bounces every ray nearer than that): the same
  // image bit for bit, and for an image of part of a large scene a fraction
  // of the rays. Recorded contributions then hold only the traced rays'
  // returns; false traces the whole ray box (contributions from anywhere,
  // e.g. to re-project them onto another grid). Exact mode traces the whole
  // box either way.
  bool image_rays_only = true;

  // Throws ConfigError when rays_per_cell is below 1, above 1024 or NaN.
  void Check() const;
};

// One return to the radar (RaySAR's Contributions.txt, one row each).
struct Contribution {
  double azimuth_m = 0.0;    // along-track coordinate (rule: see docs/geometry.md)
  double range_m = 0.0;      // slant range: half the total path length
  double elevation_m = 0.0;  // last hit's offset along the slant-range plane normal n
  float intensity = 0.0f;    // beta0 it adds to the image: RCS (m^2) / pixel area (m^2)
  uint8_t bounces = 1;       // 1 single, 2 double, ...
  bool specular = false;     // the specular term dominated this return
  Eigen::Vector3f hit_enu = Eigen::Vector3f::Zero();  // last hit position
  uint8_t class_id = 0;      // class of the last hit
  // Polarimetric passes only (RenderOptions::polarimetric; zero otherwise):
  // what a coherent re-projection (RenderProduct) needs to form the pass's
  // channel with the joint statistics of RenderSar's own phasors.
  //  - A later bounce: channel_amplitude = sqrt(P) (S_c + S^T_c), the path
  //    and its reversed path (RenderSar, "Polarimetric passes"), without the
  //    path phase: |channel_amplitude|^2 is the coherent power of the two
  //    paths (intensity = P (|S_c|^2 + |S^T_c|^2) their incoherent power).
  //  - A first bounce: channel_amplitude = rho_hh_vv, the class's HH-VV
  //    correlation at the hit (material::PolarimetricLaw; 0 unless the
  //    pass is VV), and (ray_id, phase_key) the keys of its seeded micro-
  //    phases, the same in every pass of the set (the return's index in
  //    `contributions` is not: a channel whose sigma0 is 0 records none).
  std::complex<float> channel_amplitude{0.0f, 0.0f};
  uint64_t ray_id = 0;
  uint16_t phase_key = 0;
};

// Bands of the output: total, then per bounce count.
inline constexpr int kBounceLayers = 4;  // single, double, triple, >= 4

struct RenderStats {
  int64_t rays = 0;           // primary rays traced
  int64_t hits = 0;           // rays that hit the scene
  int64_t sub_rays = 0;       // extra first-bounce rays of footprint splitting (near-grazing hits)
  int64_t shadow_rays = 0;    // visibility rays of the mask
  int64_t cells = 0;          // DEM cells projected (raster engine)
  int64_t heightfield_cells = 0;  // terrain cells traced as a height field (EmbreeScene::heightfield_cells)
  // Azimuth lines whose primary hits came from a profile sweep, and image
  // rows whose mask did (RenderOptions::profile_sweep); 0: traced. With one
  // ray line per image row (rays per cell below 2.25) the tracer's walk of a
  // row's line also paints the row's mask: those rows (of the swept ones)
  // are traced_mask_rows.
  int64_t profile_swept_lines = 0;
  int64_t profile_swept_mask_rows = 0;
  int64_t traced_mask_rows = 0;
  double trace_seconds = 0.0;  // tracer: rays, shading, splatting, merging; raster: all
  double mask_seconds = 0.0;
  // Illuminated footprint: pixels whose centre a lit surface covers (the
  // mask pass), and those of them that received no single-bounce return.
  int64_t footprint_pixels = 0;
  int64_t empty_footprint_pixels = 0;
};

struct SarImage {
  int width = 0;                // columns: slant range
  int height = 0;               // rows: azimuth
  // beta0 (radar brightness, linear m^2/m^2), row-major: the sum of the
  // radar cross sections returned into each pixel over its area
  // range_spacing_m * azimuth_spacing_m; all bounces (coherent sum in
  // coherent mode).
  std::vector<float> intensity;
  // Intensity per bounce count: [0] single, [1] double, [2] triple, [3] four
  // or more (incoherent sums; after image::ApplySensorEffects in coherent
  // mode, the detected power of bounce_real/bounce_imag). A layer the render
  // cannot reach (more bounces than RenderOptions::max_bounces; the raster
  // engine's multi-bounce layers) is empty rather than a full-size plane of
  // zeros: no return of that order (pipeline::NoReturnPlane gives its
  // pixels as written).
  std::array<std::vector<float>, kBounceLayers> bounce_layers;
  // Coherent mode: the complex image (amplitude sqrt(beta0)) before the
  // sensor stage; `intensity` is its detected power. Empty otherwise.
  std::vector<float> real, imag;
  // Coherent mode: the complex image of each bounce count (same layers as
  // bounce_layers, empty where bounce_layers is); they add up to real/imag
  // (before thermal noise). Empty otherwise.
  std::array<std::vector<float>, kBounceLayers> bounce_real, bounce_imag;
  // Canonical reflectors' returns (added by the sensor stage).
  std::vector<PointReturn> points;
  std::vector<Contribution> contributions;  // when record_contributions
  std::vector<uint8_t> mask;    // kMask* codes, row-major
  // 1 where a projected surface of the scene (lit, shadowed or turned away)
  // covers the pixel centre: the imaged footprint; 0 outside it (no terrain
  // maps there). Row-major, same size as mask.
  std::vector<uint8_t> footprint;
  RenderStats stats;
};

// Renders the single-bounce Lambertian image and the layover/shadow mask of
// `mesh` (already in `embree`) seen with `geometry`.
//
// Calibration (docs/radiometry.md): every primary ray stands for the beam
// cross-section A (m^2, perpendicular to the ray) between it and its
// neighbours: da_ray x de metres in affine mode, da_ray x (range x de rad)
// in exact mode. Its first hit, on a surface at local incidence theta_l,
// covers the surface area A / cos(theta_l) and returns the radar cross
// section sigma0(theta_l) A / cos(theta_l) (the material's law for the
// wavelength and polarisation). The image is beta0: RCS per pixel area
// dr x da. Values do not depend on the ray count, the image size or the
// pixel spacing: flat ground of constant sigma0 reads sigma0 / sin(theta_i).
// A first-bounce return is spread over its footprint in the image (the
// ray's cross-section projected through the hit surface's plane into range
// and azimuth, at most kMaxBoxWidthPx wide) by area integration, so that the
// footprints of neighbouring rays tile a surface's image without gaps
// whatever the incidence, slope and pixel/ray ratio; later bounces are
// splatted bilinearly at their (column, row).
//
// Coherent mode: each return adds phasors of total power `value`: the
// single-bounce (rough-surface) return sqrt(share x value) in each pixel of
// its footprint with phase -4 pi r / lambda plus a seeded random micro-phase
// per ray and pixel (so the mean intensity equals the incoherent image
// whatever the ray count, also after the complex PSF); mirror paths (later
// bounces) with the deterministic phase -4 pi r / lambda of their path (r:
// half the path), split with the square roots of the bilinear weights.
//
// Multi-bounce (up to max_bounces): at later hits, if the way back to the
// radar is free, the ray returns RCS 4 A f, with f = diffuse * cos(angle
// to the radar) plus the specular cone around the mirror direction, times
// the mirror shares of the earlier hits. Each hit continues as a mirror ray
// with the material's `mirror` share of the power.
// A return's slant range is half the total path (sensor -> hits -> sensor);
// its azimuth is the mean of the first and last hit's along-track
// coordinates (docs/geometry.md). Results do not depend on the thread count.
//
// Polarimetric passes (options.polarimetric; one channel c per pass, the
// scattering matrix S of a return in the radar's BSA H/V basis,
// material/scattering.h). Where they differ from the single-channel model:
//  - Rough-surface (first-bounce) returns: the power is unchanged (the
//    class's sigma0 law of channel c). In coherent mode the micro-phasor of
//    each ray and pixel is drawn jointly across the passes from three seeded
//    phases phi1 (the single-channel micro-phase), phi2, phi3: HH exp(j phi1)
//    (an HH pass equals the single-channel HH pass bit for bit), VV
//    conj(rho) exp(j phi1) + sqrt(1 - |rho|^2) exp(j phi2), HV and VH
//    exp(j phi3); rho = material::PolarimetricLaw(...).rho_hh_vv of the
//    class at the hit's (shading) incidence, tabulated per class. Hence
//    E[HH VV*] = rho sqrt(sigma0_hh sigma0_vv), E|HV|^2 = sigma0_hv, HV
//    uncorrelated: the multilooked covariance of a uniform class is the law.
//  - Mirror paths (bounce >= 2): the ray carries the field of each transmit
//    polarisation (transmit basis material::HvBasis of the primary ray)
//    through its mirror vertices, each applying the complex Fresnel
//    amplitudes of the class's EffectivePermittivity at its incidence in its
//    own plane of incidence (material::SpecularReflectionOperator), instead
//    of the Fresnel power MirrorReflectivity; the scalar share keeps only the
//    product of the `mirror` coefficients. The last vertex scatters back with
//    the bistatic law, whose two parts carry the polarisation differently and
//    add in amplitude with weights sqrt(part / (diffuse + specular)):
//    the diffuse (Lambertian, small-scale roughness) part in the face's own
//    frame: the incoming TE component (s_i = d x n) goes into the TE of the
//    scattering plane (s_o = to_radar x n) with r_h, the TM component
//    (p_i = s_i x d) into p_o = s_o x to_radar with r_v, at the incidence of
//    cosine sqrt(cos_in cos_out); the specular cone as the Fresnel reflection
//    off the facet bisecting the incoming and the radar direction (Kirchhoff
//    facets). Each is divided by its sqrt((|r_h|^2 + |r_v|^2) / 2) (the
//    bistatic law already holds the power); read in the receive basis
//    HvBasis(-to_radar) their sum is S. In the mirror direction the two are
//    the same. Elsewhere the bisecting facet is perpendicular to the mirror
//    before it: with a wall turned by phi in azimuth it forms a dihedral
//    turned about the line of sight (tan psi = tan phi / sin depression),
//    whose unequal dielectric faces bring HH and VV in phase beyond
//    psi ~ 28 deg; the diffuse part of rough ground, in the ground's frame,
//    keeps a wall-ground double bounce's HH and VV opposite whatever the
//    wall's azimuth (docs/radiometry.md, "Polarimetry in the renderer",
//    also for the limits: a last vertex tilted in azimuth turns the
//    polarisation in its own frame). With P the
//    single-channel path power without the Fresnel powers (bistatic sigma0 x
//    area / cos x mirror shares / pixel area), the path and its reversed
//    path (matrix S^T, material::TraceReversedSpecularChain) give channel c
//    the power P (|S_c|^2 + |S^T_c|^2) (the single-channel model: 2 P R) and
//    the coherent amplitude sqrt(P) (S_c + S^T_c) times the path phase: so
//    HV = VH, and the image's inter-channel phases are those of S
//    (arg z_HH z_VV* = arg S_HH S_VV*). A chain stops when the scalar share
//    times the mean over transmit polarisations of |field|^2 falls below
//    1e-9 (the single-channel cut on the share).
//  - Reflectors: ReflectorReturns with options.polarization (roll and
//    channel); single-channel passes keep the scalar RCS and no offset.
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

// Returns of `reflectors` seen with `geometry` at `wavelength_m`: RCS from
// material::ReflectorRcs towards the sensor, none where the way from the
// apex to the sensor is occluded or the RCS is zero. With `polarization`
// (a polarimetric pass) the RCS of channel c is that RCS times |S_c|^2 and
// PointReturn::phase_offset_rad = arg S_c (0 where S_c = 0), S =
// material::UnitReflectorMatrix(type, roll_rad) (taken in the radar's H/V
// basis: the boresight's small offset from the line of sight does not turn
// it): roll 0 co-pol keeps the scalar RCS, a channel with S_c = 0 keeps the
// point with beta0_sum 0 (every pass lists the same reflectors). Without it
// (default): the scalar RCS in every channel, no phase offset.
std::vector<PointReturn> ReflectorReturns(const EmbreeScene& embree, const std::vector<SceneReflector>& reflectors,
                                          const sensor::SarGeometry& geometry, double wavelength_m,
                                          std::optional<material::Polarization> polarization = std::nullopt);

// Whether the segment origin + t dir, t in [t_near, t_far] (dir a unit
// vector, metres), meets the scene.
using OcclusionTest = std::function<bool(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_near,
                                         double t_far)>;
// The same with any occlusion test (the raster engine's height field,
// raster_renderer.h): the visibility ray leaves the apex towards the sensor
// from t = 5 cm (clear of the reflector's own ground) to the sensor (affine
// mode: twice the slant range).
std::vector<PointReturn> ReflectorReturns(const OcclusionTest& occluded, const std::vector<SceneReflector>& reflectors,
                                          const sensor::SarGeometry& geometry, double wavelength_m,
                                          std::optional<material::Polarization> polarization = std::nullopt);


// Only the layover/shadow mask (see RenderSar). `lit` (optional): 1 where a
// lit surface (facing the radar, not occluded) covers the pixel centre.
// `covered` (optional): 1 where any surface not seen exactly edge-on covers
// the pixel centre (SarImage::footprint). `profile_sweep`: over a whole
// terrain grid's height field and nothing else, in affine or exact mode,
// each image row's centres are read off the terrain profile of their
// azimuth line (GridProfileSweep: the horizon before a point decides its
// shadow exactly; *swept_rows, when given, counts those rows), and the rows
// whose line does not cross the grid in one piece get visibility rays;
// otherwise (also when a profile point is not beyond the sensor in ground
// range), and when false, one visibility ray per covered centre (in affine
// mode only the triangles of the tiles near the image are visited:
// EmbreeScene::Tiles, built on the first such pass over the scene).
// *shadow_rays counts the visibility rays cast.
std::vector<uint8_t> RenderLayoverShadowMask(const EmbreeScene& embree,
                                             const scene::TriangleMesh& mesh,
                                             const sensor::SarGeometry& geometry,
                                             int64_t* shadow_rays = nullptr,
                                             std::vector<uint8_t>* lit = nullptr,
                                             std::vector<uint8_t>* covered = nullptr,
                                             const Eigen::AlignedBox3d* ray_box = nullptr,
                                             bool profile_sweep = true, int64_t* swept_rows = nullptr);

}  // namespace gissar::render
