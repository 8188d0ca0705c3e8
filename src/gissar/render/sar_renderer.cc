#include "gissar/render/sar_renderer.h"

#include "gissar/render/profile_mask.h"
#include "gissar/render/profile_sweep.h"
#include "gissar/render/raster_renderer.h"
#include "gissar/render/splat.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <limits>
#include <mutex>
#include <optional>
#include <utility>

#include "gissar/material/scattering.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/reporter.h"

namespace gissar::render {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

// Where the primary rays start and how they are spaced. Ray (i, j) lies in
// the zero-Doppler plane of along-track coordinate a_i = a0 + i * da; j steps
// across that plane: an offset along n (affine mode, metres) or an angle from
// l towards n (exact mode, radians).
struct RayGrid {
  int n_az = 0;
  double a0 = 0.0, da = 0.0;
  // The rays traced across each line: n_el of the n_el_all the box needs,
  // from index j_first on (a multiple of 16, so that packets hold the same
  // rays; CullToImage). Ray j of a line has coordinate E(j) (the same
  // double whatever j_first is) and id line * n_el_all + j_first + j.
  int n_el = 0, n_el_all = 0, j_first = 0;
  double e0 = 0.0, de = 0.0;
  double back_off_m = 0.0;  // affine: origin plane distance behind Xc along -l
  double ray_weight = 0.0;  // 1 / rays per cell
  double de_m = 0.0;        // across-range ray spacing, metres (exact: at the scene-centre range)
  double k_el = 1.0;        // rays per slant-range pixel on flat ground
  // Exact mode: cos, sin and tan of e_j = e0 + j * de for every j (the same
  // values std::cos/sin/tan give at each ray, computed once per image
  // instead of once per ray: every azimuth line shares them).
  std::vector<double> cos_e, sin_e, tan_e;
  double E(int j) const { return e0 + (j_first + j) * de; }
  uint64_t RayId(int line, int j) const { return uint64_t(line) * uint64_t(n_el_all) + uint64_t(j_first + j); }
};

RayGrid MakeRayGrid(const sensor::SarGeometry& g, const Eigen::AlignedBox3d& box,
                    double rays_per_cell) {
  RayGrid grid;
  const int k_az = std::max(1, static_cast<int>(std::lround(std::sqrt(rays_per_cell))));
  const double k_el = rays_per_cell / k_az;
  grid.ray_weight = 1.0 / rays_per_cell;
  grid.da = g.azimuth_spacing_m() / k_az;
  grid.n_az = g.height() * k_az;
  grid.a0 = (-0.5 - g.v0()) * g.azimuth_spacing_m() + 0.5 * grid.da;
  // Across-range spacing: flat ground at depression d gets k_el rays per
  // slant-range pixel when rays are de = dr * tan(d) / k_el apart.
  const double dep = g.options().depression_deg * M_PI / 180.0;
  const double de_m = g.range_spacing_m() * std::tan(dep) / k_el;
  const Vector3d& l = g.look_direction();
  const Vector3d& n = g.range_plane_normal();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo, back = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Vector3d corner = box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
    double e;
    if (g.mode() == sensor::ProjectionMode::kAffine) {
      e = (corner - g.scene_centre()).dot(n);
      back = std::max(back, -(corner - g.scene_centre()).dot(l));
    } else {
      const Vector3d v = corner - g.SensorPosition(g.AlongTrack(corner));
      e = std::atan2(v.dot(n), v.dot(l));
    }
    lo = std::min(lo, e);
    hi = std::max(hi, e);
  }
  grid.de_m = de_m;
  grid.k_el = k_el;
  grid.de = g.mode() == sensor::ProjectionMode::kAffine ? de_m : de_m / g.slant_range_m();
  grid.e0 = lo - grid.de;
  grid.n_el = static_cast<int>(std::ceil((hi - lo) / grid.de)) + 3;
  grid.n_el_all = grid.n_el;
  grid.back_off_m = back + 1.0;
  if (g.mode() != sensor::ProjectionMode::kAffine) {
    grid.cos_e.resize(size_t(grid.n_el));
    grid.sin_e.resize(size_t(grid.n_el));
    grid.tan_e.resize(size_t(grid.n_el));
    for (int j = 0; j < grid.n_el; ++j) {
      const double e = grid.E(j);
      grid.cos_e[size_t(j)] = std::cos(e);
      grid.sin_e[size_t(j)] = std::sin(e);
      grid.tan_e[size_t(j)] = std::tan(e);
    }
  }
  return grid;
}

// How far (pixels) a return spreads from its column: half the widest
// footprint box (kMaxBoxWidthPx) and the bilinear tent's pixel, and one
// more for rounding.
constexpr double kReturnReachPx = 0.5 * kMaxBoxWidthPx + 2.0;

// The tiles whose bounds project (affine, by `g`) onto `pixels` (column,
// row). The projection is affine, so every point of a tile's bounds
// projects within the bounds of its corners' projections: a triangle of any
// other tile projects outside `pixels`.
std::vector<size_t> TilesOnPixels(const TriangleTiles& tiles, const sensor::SarGeometry& g,
                                  const Eigen::AlignedBox2d& pixels) {
  GISSAR_CHECK(g.mode() == sensor::ProjectionMode::kAffine);
  std::vector<size_t> near;
  for (size_t k = 0; k < tiles.tile_count(); ++k) {
    const Eigen::AlignedBox3d& b = tiles.bounds(k);
    if (b.isEmpty()) continue;
    Eigen::AlignedBox2d projected;
    for (int c = 0; c < 8; ++c) {
      projected.extend(g.Project(b.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c))));
    }
    if (projected.intersects(pixels)) near.push_back(k);
  }
  return near;
}

// The image's pixel centres [0, width - 1] x [0, height - 1] widened by
// `cols` columns (each side; near_cols on the near side) and `rows` rows.
Eigen::AlignedBox2d PixelWindow(const sensor::SarGeometry& g, double cols, double rows, double near_cols) {
  return Eigen::AlignedBox2d(Eigen::Vector2d(-near_cols, -rows),
                             Eigen::Vector2d(g.width() - 1 + cols, g.height() - 1 + rows));
}

// The triangles a walk over a mesh (the mask's ray pass) visits one by one
// start here: after a whole terrain grid's, walked by rows (a height field
// without holes), else at 0.
size_t FirstTriangleWalkedAlone(const EmbreeScene& embree) {
  const int grid_w = embree.heightfield_grid_width(), grid_h = embree.heightfield_grid_height();
  const bool whole_grid = grid_w >= 2 && embree.heightfield_cells() == int64_t(grid_w - 1) * (grid_h - 1);
  return whole_grid ? size_t(2 * embree.heightfield_cells()) : 0;
}

// Affine mode: `grid` narrowed to the rays whose returns can reach the
// image (RenderOptions::image_rays_only). A ray of coordinate e, or one of
// its sub-rays (within half a spacing of it), meets a surface of height z
// at the slant-range offset t from the scene centre's (along l) with
//   e n_z = z - Xc_z - t l_z - a h_z   (a: its along-track offset),
// so when every surface within reach of the image has z in [z_lo, z_hi],
// the rays that can meet one at columns from -0.5 - M to width - 0.5 + M
// (M = kReturnReachPx) lie between the extremes of e over those bounds of
// z, t and the image's rows. A single bounce returns at its hit's range, a
// later bounce no nearer than the first hit (the way there and back is at
// least twice the first hit's offset along l): with several bounces the
// near bound of t is dropped (every nearer hit may return into the image).
// The rays kept are the same rays (RayGrid::E, RayId) in the same packets
// of 16: the image is the same, bit for bit. Unchanged when the
// range-plane normal or the look direction is (nearly) horizontal.
void CullToImage(const sensor::SarGeometry& g, double z_lo, double z_hi, int max_bounces, RayGrid* grid) {
  GISSAR_CHECK(g.mode() == sensor::ProjectionMode::kAffine);
  const Vector3d& l = g.look_direction();
  const Vector3d& n = g.range_plane_normal();
  const Vector3d& h = g.flight_direction();
  const Vector3d& xc = g.scene_centre();
  if (!(std::abs(n.z()) > 0.05) || !(std::abs(l.z()) > 1e-9)) return;
  const double t_near = max_bounces > 1 ? -std::numeric_limits<double>::infinity()
                                        : (-0.5 - kReturnReachPx - g.u0()) * g.range_spacing_m();
  const double t_far = (g.width() - 0.5 + kReturnReachPx - g.u0()) * g.range_spacing_m();
  const double a_bounds[2] = {grid->a0 - grid->da, grid->a0 + grid->n_az * grid->da};
  double e_lo = std::numeric_limits<double>::infinity(), e_hi = -e_lo;
  for (const double z : {z_lo, z_hi}) {
    for (const double t : {t_near, t_far}) {
      for (const double a : a_bounds) {
        const double e = (z - xc.z() - t * l.z() - a * h.z()) / n.z();
        e_lo = std::min(e_lo, e);
        e_hi = std::max(e_hi, e);
      }
    }
  }
  // Ray j's sub-rays reach E(j) +- de / 2: one more ray each side, and one
  // for rounding.
  const double all = grid->n_el_all;
  const double j_lo = std::clamp(std::floor((e_lo - grid->e0) / grid->de) - 2.0, 0.0, all);
  const double j_end = std::clamp(std::ceil((e_hi - grid->e0) / grid->de) + 3.0, j_lo, all);
  grid->j_first = static_cast<int>(j_lo) / 16 * 16;
  grid->n_el = static_cast<int>(j_end) - grid->j_first;
}

// Affine mode: the lowest and highest heights of the surfaces whose returns
// can reach the image (with one bounce, those within kReturnReachPx of its
// columns; with more, also every nearer one): those of the tiles there
// (EmbreeScene::Tiles) when the tiles hold every triangle (the mask's ray
// pass walks them anyway), else `box`'s.
std::pair<double, double> HeightsWithinReach(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                             const sensor::SarGeometry& g, const Eigen::AlignedBox3d& box,
                                             int max_bounces) {
  if (FirstTriangleWalkedAlone(embree) != 0) return {box.min().z(), box.max().z()};
  const TriangleTiles& tiles = embree.Tiles(mesh, 0);
  const double near_cols = max_bounces > 1 ? std::numeric_limits<double>::infinity() : kReturnReachPx + 0.5;
  Eigen::AlignedBox3d near;
  for (const size_t k : TilesOnPixels(tiles, g, PixelWindow(g, kReturnReachPx + 0.5, 1.0, near_cols))) {
    near.extend(tiles.bounds(k));
  }
  if (near.isEmpty()) return {box.min().z(), box.max().z()};
  return {near.min().z(), near.max().z()};
}

// Distance along the ray to the entry of `box` (0 when starting inside);
// +inf when the ray misses it.
double EntryDistance(const Vector3d& origin, const Vector3d& dir, const Eigen::AlignedBox3d& box) {
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    if (std::abs(dir[k]) < 1e-15) {
      if (origin[k] < box.min()[k] || origin[k] > box.max()[k]) return t1;
      continue;
    }
    double ta = (box.min()[k] - origin[k]) / dir[k];
    double tb = (box.max()[k] - origin[k]) / dir[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}

// Primary ray at along-track a and across-plane coordinate e of `grid`
// (RayGrid), from the sensor position `sensor` at a: its origin (ENU
// metres), unit direction, and path length from the sensor to the origin.
// Affine rays start on the origin plane behind the scene; exact rays where
// they enter `box`. False when an exact ray misses `box`.
// `cos_e`, `sin_e`: cos and sin of e (exact mode only).
bool PrimaryRay(const sensor::SarGeometry& g, const RayGrid& grid, const Eigen::AlignedBox3d& box, double a,
                double e, double cos_e, double sin_e, const Vector3d& sensor, Vector3d* origin, Vector3d* dir,
                double* travelled) {
  const Vector3d& l = g.look_direction();
  const Vector3d& n = g.range_plane_normal();
  if (g.mode() == sensor::ProjectionMode::kAffine) {
    *dir = l;
    *origin = g.scene_centre() + a * g.flight_direction() + e * n - grid.back_off_m * l;
    *travelled = g.slant_range_m() - grid.back_off_m;
    return true;
  }
  *dir = cos_e * l + sin_e * n;
  const double entry = EntryDistance(sensor, *dir, box);
  if (!std::isfinite(entry)) return false;
  *travelled = std::max(0.0, entry - 1.0);
  *origin = sensor + *travelled * *dir;
  return true;
}

// Primary ray j of the grid at along-track a.
bool PrimaryRayAt(const sensor::SarGeometry& g, const RayGrid& grid, const Eigen::AlignedBox3d& box, double a, int j,
                  const Vector3d& sensor, Vector3d* origin, Vector3d* dir, double* travelled) {
  if (g.mode() == sensor::ProjectionMode::kAffine) {
    return PrimaryRay(g, grid, box, a, grid.E(j), 1.0, 0.0, sensor, origin, dir, travelled);
  }
  return PrimaryRay(g, grid, box, a, grid.E(j), grid.cos_e[size_t(j)], grid.sin_e[size_t(j)], sensor, origin, dir,
                    travelled);
}

// Accumulation band of image rows [row0, row0 + rows), `planes` planes of
// width x rows each (a buffer of the thread rendering the band); returns
// landing outside the band (multi-bounce returns may move in azimuth) are
// kept in `overflow` and added afterwards.
struct Band {
  int row0 = 0;
  int rows = 0;
  int planes = 0;
  float* values = nullptr;
  struct Overflow {
    int plane;
    double col, row;
    float value;
    bool amplitude;
    double box_cols = -1.0, box_rows = -1.0;  // >= 0: a box footprint (SplatBox)
  };
  std::vector<Overflow>* overflow = nullptr;
};

// Bilinear splat of `value` at continuous (col, row) into `plane`. Complex
// amplitudes (`amplitude` true) use the square roots of the bilinear
// weights, so that the expected intensity |sum|^2 of random phasors equals
// the intensity splat.
void Splat(Band& band, int width, int plane, double col, double row, float value, bool amplitude = false) {
  const double c0f = std::floor(col), r0f = std::floor(row);
  const int c0 = static_cast<int>(c0f), r0 = static_cast<int>(r0f);
  if (r0 < band.row0 || r0 + 1 >= band.row0 + band.rows) {
    band.overflow->push_back({plane, col, row, value, amplitude});
    return;
  }
  const float fc = static_cast<float>(col - c0f), fr = static_cast<float>(row - r0f);
  float w[2][2] = {{(1 - fr) * (1 - fc), (1 - fr) * fc}, {fr * (1 - fc), fr * fc}};
  if (amplitude) {
    for (auto& line : w)
      for (float& x : line) x = std::sqrt(x);
  }
  float* base = band.values + size_t(plane) * band.rows * width;
  for (int dr = 0; dr < 2; ++dr) {
    const int r = r0 + dr - band.row0;
    for (int dc = 0; dc < 2; ++dc) {
      const int c = c0 + dc;
      if (c < 0 || c >= width) continue;
      base[size_t(r) * width + c] += value * w[dr][dc];
    }
  }
}

// Area-integrated splat of the box footprint wc x wr (pixels) at (col, row).
void SplatFootprint(Band& band, int width, int plane, double col, double row, double wc, double wr,
                    float value) {
  float* base = band.values + size_t(plane) * band.rows * width;
  if (!SplatBox(base, width, band.row0, band.rows, col, row, wc, wr, value, /*clip=*/false)) {
    band.overflow->push_back({plane, col, row, value, false, wc, wr});
  }
}

// SplatFootprint of the same value into planes `first` and `second` (their
// shares computed once).
void SplatFootprint2(Band& band, int width, int first, int second, double col, double row, double wc, double wr,
                     float value) {
  float* const planes[2] = {band.values + size_t(first) * band.rows * width,
                            band.values + size_t(second) * band.rows * width};
  if (!SplatBoxPlanes(planes, 2, width, band.row0, band.rows, col, row, wc, wr, value, /*clip=*/false)) {
    band.overflow->push_back({first, col, row, value, false, wc, wr});
    band.overflow->push_back({second, col, row, value, false, wc, wr});
  }
}

// First-bounce (incoherent) returns of a block's azimuth lines, summed
// along range into one profile per line. A first hit lies in its line's
// zero-Doppler plane, so every first-bounce return of a line has the line's
// along-track coordinate and the same footprint height (the ray spacing
// across azimuth): its row shares are the line's. The profile keeps the
// column shares; Flush spreads it over the rows once per line, instead of
// every return splatting its box into two planes.
struct LineProfiles {
  int width = 0;
  std::vector<double> values;  // lines x width, zero outside [lo, hi]
  std::vector<int> lo, hi;     // columns touched per line (lo > hi: none)

  void Reset(int lines, int image_width) {
    if (image_width != width || values.size() < size_t(lines) * image_width) {
      width = image_width;
      values.assign(size_t(lines) * width, 0.0);
    }
    lo.assign(size_t(lines), width);
    hi.assign(size_t(lines), -1);
  }

  // A return of `value` with footprint width `box_cols` (pixels) centred on
  // column `col`.
  void Add(int line, double col, double box_cols, double value) {
    double share[kMaxShares];
    int first = 0;
    const int count = FootprintShares(col, box_cols, &first, share);
    double* row = values.data() + size_t(line) * width;
    int& line_lo = lo[size_t(line)];
    int& line_hi = hi[size_t(line)];
    for (int k = 0; k < count; ++k) {
      const int c = first + k;
      if (c < 0 || c >= width || share[k] == 0.0) continue;
      row[c] += value * share[k];
      line_lo = std::min(line_lo, c);
      line_hi = std::max(line_hi, c);
    }
  }

  // Line `line`'s profile at image row `row` with footprint height
  // `box_rows` into planes `first_plane` and `second_plane` of `band` (rows
  // outside the band: its overflow), then cleared.
  void Flush(int line, double row, double box_rows, Band& band, int first_plane, int second_plane) {
    const size_t l = size_t(line);
    if (hi[l] < lo[l]) return;
    double row_share[kMaxShares];
    int r_first = 0;
    const int count = FootprintShares(row, box_rows, &r_first, row_share);
    double* profile = values.data() + l * width;
    float* const planes[2] = {band.values + size_t(first_plane) * band.rows * width,
                              band.values + size_t(second_plane) * band.rows * width};
    for (int k = 0; k < count; ++k) {
      if (row_share[k] == 0.0) continue;
      const int r = r_first + k;
      const bool inside = r >= band.row0 && r < band.row0 + band.rows;
      for (int c = lo[l]; c <= hi[l]; ++c) {
        if (profile[c] == 0.0) continue;
        const float v = static_cast<float>(profile[c] * row_share[k]);
        if (inside) {
          const size_t at = size_t(r - band.row0) * width + c;
          planes[0][at] += v;
          planes[1][at] += v;
        } else {
          // A point at the pixel itself (box 0: all of it in (r, c)).
          for (const int plane : {first_plane, second_plane}) {
            band.overflow->push_back({plane, double(c), double(r), v, false, 0.0, 0.0});
          }
        }
      }
    }
    std::fill(profile + lo[l], profile + hi[l] + 1, 0.0);
    lo[l] = width;
    hi[l] = -1;
  }
};

// SplitMix64: a per-scatterer random phase from (seed, ray, bounce).
double RandomPhase(uint64_t seed, uint64_t ray, uint64_t bounce) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (ray * 17 + bounce + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return 2.0 * M_PI * (double(z >> 11) * 0x1.0p-53);
}

// Odd multipliers of a pixel's index in the seed of its micro-phases: phi1
// (the single-channel micro-phase), and the two further phases phi2, phi3 of
// polarimetric passes (MicroPhasorMix).
constexpr uint64_t kPixelPhaseKey1 = 0x632be59bd9b4e019ULL;
constexpr uint64_t kPixelPhaseKey2 = 0x9e6c63d0676a9a99ULL;
constexpr uint64_t kPixelPhaseKey3 = 0xd6e8feb86659fd93ULL;

// The seeded micro-phase (radians, [0, 2 pi)) of ray `ray_id` in pixel
// `pixel` (row-major index), `pixel_key` one of kPixelPhaseKey*.
double PixelPhase(uint64_t seed, uint64_t pixel_key, int64_t pixel, uint64_t ray_id, uint64_t key) {
  return RandomPhase(seed ^ (pixel_key * uint64_t(pixel + 1)), ray_id, key);
}

// The unit micro-phasor of a rough-surface return in one channel of a
// polarimetric set, from the pixel's three independent seeded phases:
// first exp(j phi1) + second exp(j phi2), or exp(j phi3) alone (`cross`).
// |first|^2 + second^2 = 1: unit mean power. The default (first 1, second
// 0) is the single-channel micro-phasor exp(j phi1), computed as before.
struct MicroPhasorMix {
  std::complex<double> first{1.0, 0.0};
  double second = 0.0;
  bool cross = false;
  bool Plain() const { return !cross && second == 0.0 && first == std::complex<double>(1.0, 0.0); }
};

// The mix of channel `pol` for HH-VV correlation rho (RenderSar,
// "Polarimetric passes"): HH exp(j phi1), VV conj(rho) exp(j phi1) +
// sqrt(1 - |rho|^2) exp(j phi2), HV and VH exp(j phi3).
MicroPhasorMix MixOfChannel(material::Polarization pol, std::complex<double> rho) {
  MicroPhasorMix mix;
  switch (pol) {
    case material::Polarization::kHH: break;
    case material::Polarization::kVV:
      mix.first = std::conj(rho);
      mix.second = std::sqrt(std::max(0.0, 1.0 - std::norm(rho)));
      break;
    default: mix.cross = true; break;
  }
  return mix;
}

// Coherent rough-surface return: amplitude `amplitude` spread over the
// footprint (see SplatFootprint) into the real and imaginary planes 0 and 1,
// each pixel receiving sqrt(share) of it with its own seeded micro-phasor
// (`mix` of the pixel's seeded phases; the parts of a footprint are
// independent scatterers), so that the expected intensity of every pixel is
// the incoherent share, before and after any linear filtering. Pixels
// outside the band go to the overflow.
void SplatFootprintPhasors(Band& band, int width, int plane, double col, double row, double wc, double wr,
                           double amplitude, double phase, uint64_t seed, uint64_t ray_id, uint64_t key,
                           const MicroPhasorMix& mix = {}) {
  double cs[kMaxShares], rs[kMaxShares];
  int c0 = 0, r0 = 0;
  const int nc = FootprintShares(col, wc, &c0, cs), nr = FootprintShares(row, wr, &r0, rs);
  float* plane_re = band.values + size_t(plane) * band.rows * width;
  float* plane_im = plane_re + size_t(band.rows) * width;
  for (int j = 0; j < nr; ++j) {
    if (rs[j] == 0.0) continue;
    const int r = r0 + j;
    for (int i = 0; i < nc; ++i) {
      const int c = c0 + i;
      if (c < 0 || c >= width || cs[i] == 0.0) continue;
      const int64_t pixel = int64_t(r) * width + c;
      const double a = amplitude * std::sqrt(rs[j] * cs[i]);
      float re, im;
      if (mix.Plain() || mix.cross) {
        const double micro = PixelPhase(seed, mix.cross ? kPixelPhaseKey3 : kPixelPhaseKey1, pixel, ray_id, key);
        re = static_cast<float>(a * std::cos(phase + micro));
        im = static_cast<float>(a * std::sin(phase + micro));
      } else {
        const double phi1 = PixelPhase(seed, kPixelPhaseKey1, pixel, ray_id, key);
        const double phi2 = PixelPhase(seed, kPixelPhaseKey2, pixel, ray_id, key);
        const std::complex<double> z =
            a * (mix.first * std::polar(1.0, phase + phi1) + mix.second * std::polar(1.0, phase + phi2));
        re = static_cast<float>(z.real());
        im = static_cast<float>(z.imag());
      }
      if (r < band.row0 || r >= band.row0 + band.rows) {
        band.overflow->push_back({plane, double(c), double(r), re, true});
        band.overflow->push_back({plane + 1, double(c), double(r), im, true});
        continue;
      }
      const size_t k = size_t(r - band.row0) * width + c;
      plane_re[k] += re;
      plane_im[k] += im;
    }
  }
}

// ------------------------------------------------ polarimetric passes

// Per class, the HH-VV correlation rho of material::PolarimetricLaw as a
// function of cos(local incidence), sampled uniformly in sqrt(1 - cos)
// (kSamples steps, at most 0.9 deg apart in angle) and interpolated
// linearly: one law evaluation per sample and class per render instead of
// several sigma0 laws per hit (constant for oh, table and Lambert; Bragg's
// phase and the water cloud's coherence vary with incidence).
class HhVvCorrelationTables {
 public:
  static constexpr int kSamples = 128;

  HhVvCorrelationTables() = default;
  HhVvCorrelationTables(const material::MaterialTable& materials, double wavelength_m) {
    tables_.resize(materials.size());
    for (size_t id = 0; id < materials.size(); ++id) {
      const material::Material& m = materials.Get(static_cast<scene::ClassId>(id));
      std::vector<std::complex<double>>& t = tables_[id];
      t.resize(kSamples + 1);
      for (int i = 0; i < kSamples; ++i) {
        const double s = double(i) / kSamples;
        t[size_t(i)] = material::PolarimetricLaw(m, 1.0 - s * s, wavelength_m).rho_hh_vv;
      }
      t[kSamples] = t[kSamples - 1];  // grazing: the law is 0 at cos 0; keep the last value
    }
  }

  // rho of class `id` (unknown classes: class 0) at cos(local incidence).
  std::complex<double> operator()(scene::ClassId id, double cos_incidence) const {
    const std::vector<std::complex<double>>& t = tables_[id < tables_.size() ? id : 0];
    const double x = std::sqrt(std::clamp(1.0 - cos_incidence, 0.0, 1.0)) * kSamples;
    const int i = std::min(kSamples - 1, static_cast<int>(x));
    const double f = x - i;
    return t[size_t(i)] + f * (t[size_t(i) + 1] - t[size_t(i)]);
  }

 private:
  std::vector<std::vector<std::complex<double>>> tables_;
};

// The field a mirror chain carries, world (ENU) components, one column per
// transmit polarisation (0: H, 1: V of the primary ray's HvBasis), per unit
// transmitted field.
using ChainField = Eigen::Matrix<std::complex<double>, 3, 2>;

// The field of a primary ray of unit direction `dir` before any vertex.
ChainField TransmitField(const Vector3d& dir) {
  const material::PolarizationBasis b = material::HvBasis(dir);
  ChainField f;
  f.col(0) = b.h.cast<std::complex<double>>();
  f.col(1) = b.v.cast<std::complex<double>>();
  return f;
}

// The complex Fresnel amplitudes of permittivity `eps` at cos(incidence)
// `cos_incidence` (clamped to [0, 1]).
material::FresnelAmplitudes FresnelAt(std::complex<double> eps, double cos_incidence) {
  return material::FresnelCoefficients(eps, std::acos(std::clamp(cos_incidence, 0.0, 1.0)));
}

// A mirror vertex: the ray of unit direction `dir` meets a face of unit
// normal `normal` (cos(incidence) `cos_in` > 0) of permittivity `eps` and
// leaves along its mirror direction; `field` takes the vertex's Fresnel
// amplitudes in the face's own plane of incidence.
void ReflectChainField(ChainField& field, const Vector3d& dir, const Vector3d& normal, double cos_in,
                       std::complex<double> eps) {
  field = material::SpecularReflectionOperator(dir, normal, FresnelAt(eps, cos_in)) * field;
}

// `field` (one column per transmit polarisation) read in the receive basis
// HvBasis(-to_radar): the BSA matrix, row transmit, column receive.
material::ScatteringMatrix ReadInReceiveBasis(const ChainField& field, const Vector3d& to_radar) {
  material::ScatteringMatrix s;
  const material::PolarizationBasis rx = material::HvBasis(-to_radar);
  for (int t = 0; t < 2; ++t) {
    s(t, 0) = rx.h.cast<std::complex<double>>().dot(field.col(t));  // real basis: no conjugate matters
    s(t, 1) = rx.v.cast<std::complex<double>>().dot(field.col(t));
  }
  return s;
}

// The field operator of the diffuse (Lambertian) part of a last vertex's
// bistatic law: the wave arriving along `dir` on a face of unit normal
// `normal` scatters towards `to_radar` in the face's own frame, its TE
// component (s_i = dir x n) into the TE of the scattering plane (s_o =
// to_radar x n) with r_h, its TM component (p_i = s_i x dir) into the TM
// (p_o = s_o x to_radar) with r_v, r_h and r_v the face's Fresnel amplitudes
// at the incidence of cosine sqrt(cos_in cos_out) (symmetric in the two
// directions: the reversed path's operator is the transpose). For the
// mirror direction it is SpecularReflectionOperator. Unit directions;
// cos_in = -dir . n > 0 and cos_out = to_radar . n > 0.
Eigen::Matrix3cd DiffuseScatterOperator(const Vector3d& dir, const Vector3d& normal, const Vector3d& to_radar,
                                        double cos_in, double cos_out, std::complex<double> eps) {
  const material::FresnelAmplitudes r = FresnelAt(eps, std::sqrt(cos_in * cos_out));
  Vector3d s_in = dir.cross(normal), s_out = to_radar.cross(normal);
  // Along the normal (no plane of incidence): the h of the wave's own basis,
  // as SpecularReflectionOperator (the limit of the mirror case).
  s_in = s_in.norm() < 1e-12 ? material::HvBasis(dir).h : Vector3d(s_in.normalized());
  s_out = s_out.norm() < 1e-12 ? material::HvBasis(-to_radar).h : Vector3d(s_out.normalized());
  const Vector3d p_in = s_in.cross(dir), p_out = s_out.cross(to_radar);
  return r.r_h * (s_out * s_in.transpose()).cast<std::complex<double>>() +
         r.r_v * (p_out * p_in.transpose()).cast<std::complex<double>>();
}

// The BSA matrix (row transmit, column receive) of a chain whose last
// vertex, a face of unit normal `normal` and permittivity `eps`, scatters
// the ray arriving along `dir` back towards the radar along `to_radar`
// (unit vectors), its bistatic law split into `diffuse` and `specular`
// powers (Material::BistaticSigma0): the amplitude-weighted sum
//   (sqrt(diffuse) D / |D|_rms + sqrt(specular) F / |F|_rms) / sqrt(diffuse + specular)
// of the diffuse operator D (DiffuseScatterOperator: the face's own frame)
// and the specular one F (the Fresnel matrix of the bistatic reflection off
// the facet bisecting -dir and to_radar, Kirchhoff's stationary-phase
// facet), each divided by its rms amplitude sqrt((|r_h|^2 + |r_v|^2) / 2)
// (the bistatic law already holds the power), read in the receive basis
// HvBasis(-to_radar). In the mirror direction D = F (facet = face).
material::ScatteringMatrix ClosedChainMatrix(const ChainField& field, const Vector3d& dir, const Vector3d& to_radar,
                                             const Vector3d& normal, double diffuse, double specular,
                                             std::complex<double> eps) {
  ChainField out = ChainField::Zero();
  const double total = diffuse + specular;
  if (!(total > 0.0)) return material::ScatteringMatrix::Zero();
  const double cos_in = -dir.dot(normal), cos_out = to_radar.dot(normal);
  if (diffuse > 0.0 && cos_in > 0.0 && cos_out > 0.0) {
    const material::FresnelAmplitudes r = FresnelAt(eps, std::sqrt(cos_in * cos_out));
    const double rms = std::sqrt(0.5 * (std::norm(r.r_h) + std::norm(r.r_v)));
    if (rms > 0.0) {
      out += std::sqrt(diffuse / total) / rms *
             (DiffuseScatterOperator(dir, normal, to_radar, cos_in, cos_out, eps) * field);
    }
  }
  const Vector3d bisector = to_radar - dir;
  if (specular > 0.0 && bisector.norm() > 1e-9) {
    const Vector3d facet = bisector.normalized();
    const material::FresnelAmplitudes r = FresnelAt(eps, -dir.dot(facet));
    const double rms = std::sqrt(0.5 * (std::norm(r.r_h) + std::norm(r.r_v)));
    if (rms > 0.0) {
      out += std::sqrt(specular / total) / rms * (material::SpecularReflectionOperator(dir, facet, r) * field);
    }
  }
  return ReadInReceiveBasis(out, to_radar);
}

// The polarimetric terms of one return (TracePlan, "Polarimetric passes").
struct PolarimetricTerms {
  // First bounce, coherent: the micro-phasor of the channel, and the
  // class's HH-VV correlation it was mixed with (recorded contributions).
  MicroPhasorMix mix;
  std::complex<double> rho{0.0, 0.0};
  // Later bounces: |S_c|^2 + |S^T_c|^2 (the path and its reversed path;
  // replaces the single-channel reciprocal factor 2) and S_c + S^T_c (their
  // coherent sum; replaces the amplitude factor 2).
  double mirror_power = 0.0;
  std::complex<double> mirror_amplitude{0.0, 0.0};
};

// The later-bounce terms of channel `pol` of a path of BSA matrix `s`.
PolarimetricTerms MirrorTerms(const material::ScatteringMatrix& s, material::Polarization pol) {
  PolarimetricTerms terms;
  const std::complex<double> forward = material::Channel(s, pol);
  const std::complex<double> reverse = material::Channel(s.transpose(), pol);
  terms.mirror_power = std::norm(forward) + std::norm(reverse);
  terms.mirror_amplitude = forward + reverse;
  return terms;
}

// Below this cosine of the local incidence angle, a visibility ray of the
// mask that finds its own triangle is continued past it.
constexpr double kSelfHitCos = 0.05;

// First-bounce footprints wider than twice the flat-ground footprint of a
// ray (1 / rays per slant-range pixel), and at least this wide (pixels),
// are split into sub-rays (at most kMaxSubRays).
constexpr double kMinSplitFootprintPx = 0.25;
// A primary ray starts this far (metres of ground) before the hit of the
// ray below it (TracePlan::skip_to_previous_hit): far beyond rounding.
constexpr double kSkipMarginM = 1.0;
constexpr int kMaxSubRays = 64;

// Image rows whose profiles the mask walks in lockstep.
constexpr int kMaskRowsInLockstep = 16;

// Small offset along a ray that clears float rounding of scene coordinates.
float RayEpsilon(const Eigen::AlignedBox3d& box) {
  const double extent = std::max(box.max().cwiseAbs().maxCoeff(), box.min().cwiseAbs().maxCoeff());
  return static_cast<float>(std::max(0.01, 4e-7 * extent));
}

// The profile sweep over `embree`'s terrain grid when it applies: a whole
// grid's height field and nothing else (GridProfileSweep's conditions).
std::optional<GridProfileSweep> ProfileSweepOf(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                               const sensor::SarGeometry& geometry) {
  if (!embree.HeightfieldOnly()) return std::nullopt;
  const int gw = embree.heightfield_grid_width(), gh = embree.heightfield_grid_height();
  if (gw < 2 || embree.heightfield_cells() != int64_t(gw - 1) * (gh - 1) || mesh.vertices.size() < size_t(gw) * gh) {
    return std::nullopt;
  }
  return GridProfileSweep(mesh.vertices.data(), gw, gh, geometry);
}

// Mask flags painted while the tracer walks the profiles (TracePlan::
// mask_rule): per image row its flags (ProfileMaskRule) and its state.
struct PaintedMaskRows {
  enum : uint8_t { kNotPainted = 0, kPainted = 1, kRefused = 2 };
  std::vector<uint8_t> flags;  // width x height, row-major
  std::vector<uint8_t> state;  // per row
  // Some segment lay behind the sensor (exact mode): none of it counts.
  std::atomic<bool> behind_sensor{false};
};

// RenderLayoverShadowMask's flags of a whole terrain grid from one profile
// per image row (ProfileMaskRule) through `sweep`, walked in groups of
// kMaskRowsInLockstep rows. `painted` (or null): rows whose flags the
// tracer painted already (their flags moved out, not walked again).
// `refused_rows` (one
// per image row): 1 where the row's line does not cross the grid in one
// piece (its flags are left 0: the ray pass finds them). False (nothing
// written) when the sweep does not apply: (exact) a profile point not beyond
// the sensor in ground range.
bool MaskByProfileSweep(const GridProfileSweep& sweep, const sensor::SarGeometry& geometry,
                        PaintedMaskRows* painted, std::vector<uint8_t>* flags,
                        std::vector<uint8_t>* refused_rows) {
  const int width = geometry.width(), height = geometry.height();
  if (painted != nullptr && painted->behind_sensor.load()) return false;
  const ProfileMaskRule rule(sweep, geometry);
  if (painted != nullptr) {
    *flags = std::move(painted->flags);
  } else {
    flags->assign(size_t(width) * height, 0);
  }
  refused_rows->assign(size_t(height), 0);
  std::atomic<bool> failed{false};
  // Rows in groups walked in lockstep (neighbouring rows cross the same
  // posts); each writes only its own row.
  tbb::parallel_for(tbb::blocked_range<int>(0, height, kMaskRowsInLockstep), [&](const tbb::blocked_range<int>& rows) {
    std::vector<double> a_m;
    std::vector<int> row_of;
    std::vector<uint8_t> ok;
    for (int r0 = rows.begin(); r0 < rows.end() && !failed.load(std::memory_order_relaxed);
         r0 += kMaskRowsInLockstep) {
      const int r1 = std::min(rows.end(), r0 + kMaskRowsInLockstep);
      a_m.clear();
      row_of.clear();
      for (int r = r0; r < r1; ++r) {
        const uint8_t state = painted != nullptr ? painted->state[size_t(r)] : uint8_t{PaintedMaskRows::kNotPainted};
        if (state == PaintedMaskRows::kRefused) (*refused_rows)[size_t(r)] = 1;
        if (state != PaintedMaskRows::kNotPainted) continue;
        a_m.push_back(RowLineAlongTrack(geometry, r));
        row_of.push_back(r);
      }
      if (a_m.empty()) continue;
      ok.assign(a_m.size(), 0);
      bool behind_sensor = false;
      sweep.ProfileLines(a_m.data(), a_m.size(), ok.data(), [&](size_t k, const GridProfileSweep::ProfileSegment& s) {
        if (!rule.Paint(s, flags->data() + size_t(row_of[k]) * width)) behind_sensor = true;
      });
      if (behind_sensor) failed = true;
      for (size_t k = 0; k < ok.size(); ++k) {
        if (ok[k]) continue;
        const int r = row_of[k];
        (*refused_rows)[size_t(r)] = 1;
        std::fill_n(flags->data() + size_t(r) * width, width, uint8_t{0});
      }
    }
  });
  return !failed.load();
}

}  // namespace

void RenderOptions::Check() const {
  if (!std::isfinite(rays_per_cell) || rays_per_cell < 1.0 || rays_per_cell > 1024.0) {
    throw ConfigError("rays per cell must be in [1, 1024]", "--rays-per-cell");
  }
  if (max_bounces < 1 || max_bounces > 16) throw ConfigError("bounces must be in [1, 16]", "--bounces");
  if (coherent && !(wavelength_m > 0.0 && std::isfinite(wavelength_m))) {
    throw ConfigError("wavelength must be positive", "--wavelength");
  }
}

namespace {

// The mask's per-pixel flags (kMaskLayover, kMaskShadow, kLitBit,
// kCoveredBit; `flag_at(i)` those of pixel i of `size`) unpacked: the mask
// codes (returned), and `lit` and `covered` (each when not nullptr) 1 where
// the flag is set, else 0.
template <typename FlagAt>
std::vector<uint8_t> UnpackMaskFlags(FlagAt&& flag_at, size_t size, std::vector<uint8_t>* lit,
                                     std::vector<uint8_t>* covered) {
  std::vector<uint8_t> mask(size);
  if (lit != nullptr) lit->assign(size, 0);
  if (covered != nullptr) covered->assign(size, 0);
  for (size_t i = 0; i < size; ++i) {
    const uint8_t f = flag_at(i);
    mask[i] = f & (kMaskLayover | kMaskShadow);
    if (lit != nullptr) (*lit)[i] = (f & kLitBit) != 0;
    if (covered != nullptr) (*covered)[i] = (f & kCoveredBit) != 0;
  }
  return mask;
}

// RenderLayoverShadowMask's ray pass: every triangle of the mesh projected
// into the image, each pixel centre it covers flagged turned away (shadow),
// or by a visibility ray towards the radar shadowed or lit (and layover when
// the surface faces away from the range plane's upward normal). Rays go 16
// at a time (neighbouring pixel centres, one direction in affine mode: a
// coherent packet). Flags are or-ed atomically: the result does not depend
// on the order. `box` (ENU metres) sizes the rays' epsilon and affine
// reach; `only_rows` (one per image row, or null: all): the rows whose
// centres it settles (the others stay 0). The inputs must outlive the pass.
class MaskRayPass {
 public:
  MaskRayPass(const EmbreeScene& embree, const scene::TriangleMesh& mesh, const sensor::SarGeometry& geometry,
              const Eigen::AlignedBox3d& box, bool want_lit, const std::vector<uint8_t>* only_rows = nullptr);

  // Runs the pass over every triangle; returns the visibility rays cast.
  int64_t Run();
  // Pixel flags, row-major, width x height (after Run).
  const std::vector<std::atomic<uint8_t>>& flags() const { return flags_; }

 private:
  // A pixel centre waiting for its visibility ray.
  struct Pending {
    size_t pixel;
    Vector3d point, to_radar;
    float t_near, t_far;
    double cos_in;
    size_t triangle;
    bool flipped;  // the surface faces away from the range plane's upward normal
  };
  // One task's packet of up to 16 pending rays and its ray count.
  struct Task {
    Pending pending[16];
    int count = 0;
    alignas(64) RayPacket16 packet;
    alignas(64) int valid[16];
    bool blocked[16];
    int64_t local_rays = 0;
  };

  Eigen::Vector2d Project(const Vector3d& p) const;
  void Settle(Task& task, const Pending& q, bool occluded);
  void Flush(Task& task);
  void Triangle(Task& task, size_t t, const Vector3d v[3], const Eigen::Vector2d p[3]);
  void Finish(Task& task);
  size_t WalkGrid();
  void WalkTriangles(size_t first);
  void WalkTiles(size_t first);

  const EmbreeScene& embree_;
  const scene::TriangleMesh& mesh_;
  const sensor::SarGeometry& geometry_;
  const int width_, height_;
  const bool want_lit_;
  const std::vector<uint8_t>* only_rows_;
  std::vector<std::atomic<uint8_t>> flags_;
  const float eps_;
  const double far_affine_;
  std::atomic<int64_t> rays_{0};
  // SarGeometry::Project's affine arithmetic (Project).
  const bool affine_;
  const Vector3d xc_, l_, h_;
  const double range0_, dr_, da_, u0_, v0_;
};

MaskRayPass::MaskRayPass(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                         const sensor::SarGeometry& geometry, const Eigen::AlignedBox3d& box, bool want_lit,
                         const std::vector<uint8_t>* only_rows)
    : embree_(embree),
      mesh_(mesh),
      geometry_(geometry),
      width_(geometry.width()),
      height_(geometry.height()),
      want_lit_(want_lit),
      only_rows_(only_rows),
      flags_(size_t(width_) * height_),
      eps_(RayEpsilon(box)),
      far_affine_(geometry.slant_range_m() + box.diagonal().norm()),
      affine_(geometry.mode() == sensor::ProjectionMode::kAffine),
      xc_(geometry.scene_centre()),
      l_(geometry.look_direction()),
      h_(geometry.flight_direction()),
      range0_(geometry.slant_range_m()),
      dr_(geometry.range_spacing_m()),
      da_(geometry.azimuth_spacing_m()),
      u0_(geometry.u0()),
      v0_(geometry.v0()) {
  for (auto& f : flags_) f.store(0, std::memory_order_relaxed);
}

int64_t MaskRayPass::Run() {
  // A height field built on first use is built here, by this thread with
  // the whole pool, rather than by the first task that casts a ray.
  embree_.Build();
  WalkTriangles(WalkGrid());
  return rays_.load();
}

// SarGeometry::Project of `p` (ENU metres) to (column, row) pixels, with
// affine mode's arithmetic in line (the same operations in the same order:
// the same pixel coordinates): three calls per triangle were a third of
// the pass.
Eigen::Vector2d MaskRayPass::Project(const Vector3d& p) const {
  if (!affine_) return geometry_.Project(p);
  const double slant = range0_ + (p - xc_).dot(l_);
  return {(slant - range0_) / dr_ + u0_, (p - xc_).dot(h_) / da_ + v0_};
}

// Pending centre `q`'s flags from its ray's verdict `occluded`.
void MaskRayPass::Settle(Task& task, const Pending& q, bool occluded) {
  if (occluded && q.cos_in < kSelfHitCos) {
    // Seen almost edge-on the surface may still hit itself beyond t_near
    // by rounding: skip its own triangle once.
    const auto hit = embree_.Intersect(q.point.cast<float>(), q.to_radar.cast<float>(), q.t_near, q.t_far);
    if (hit && hit->triangle == q.triangle) {
      ++task.local_rays;
      occluded = embree_.Occluded(q.point.cast<float>(), q.to_radar.cast<float>(), hit->t + q.t_near, q.t_far);
    }
  }
  uint8_t code = kMaskNone;
  if (occluded) {
    code = kMaskShadow;
  } else {
    if (want_lit_) flags_[q.pixel].fetch_or(kLitBit, std::memory_order_relaxed);
    if (q.flipped) code = kMaskLayover;
  }
  flags_[q.pixel].fetch_or(code | kCoveredBit, std::memory_order_relaxed);
}

// The task's pending rays as one packet (rtcOccluded16), then settled.
void MaskRayPass::Flush(Task& task) {
  for (int k = 0; k < 16; ++k) {
    task.valid[k] = k < task.count ? -1 : 0;
    if (k >= task.count) continue;
    task.packet.SetRay(k, task.pending[k].point.cast<float>(), task.pending[k].to_radar.cast<float>());
    task.packet.tnear[k] = task.pending[k].t_near;
    task.packet.tfar[k] = task.pending[k].t_far;
  }
  embree_.Occluded16(task.valid, task.packet, /*coherent=*/true, task.blocked);
  for (int k = 0; k < task.count; ++k) Settle(task, task.pending[k], task.blocked[k]);
  task.count = 0;
}

// Triangle t with corners v (ENU metres) projected to p (pixels): the pixel
// centres it covers, turned away ones flagged at once, the others' rays
// queued (flushed 16 at a time). Edge-on and normal-less triangles cover
// nothing.
void MaskRayPass::Triangle(Task& task, size_t t, const Vector3d v[3], const Eigen::Vector2d p[3]) {
  const double area2 = (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
  if (std::abs(area2) < 1e-12) return;  // seen edge-on: covers no pixel centre
  const int c_lo = std::max(0, static_cast<int>(std::ceil(std::min({p[0].x(), p[1].x(), p[2].x()}))));
  const int c_hi = std::min(width_ - 1, static_cast<int>(std::floor(std::max({p[0].x(), p[1].x(), p[2].x()}))));
  const int r_lo = std::max(0, static_cast<int>(std::ceil(std::min({p[0].y(), p[1].y(), p[2].y()}))));
  const int r_hi = std::min(height_ - 1, static_cast<int>(std::floor(std::max({p[0].y(), p[1].y(), p[2].y()}))));
  if (c_lo > c_hi || r_lo > r_hi) return;  // no pixel centre inside its bounds
  if (only_rows_ != nullptr &&
      std::none_of(only_rows_->begin() + r_lo, only_rows_->begin() + r_hi + 1, [](uint8_t w) { return w != 0; })) {
    return;
  }
  const Vector3d normal = mesh_.Normal(t).cast<double>();
  if (normal.isZero()) return;
  for (int r = r_lo; r <= r_hi; ++r) {
    if (only_rows_ != nullptr && (*only_rows_)[size_t(r)] == 0) continue;
    for (int c = c_lo; c <= c_hi; ++c) {
      // Barycentric coordinates of the pixel centre in the projected triangle.
      const Eigen::Vector2d q(c, r);
      const double w1 = ((q - p[0]).x() * (p[2] - p[0]).y() - (q - p[0]).y() * (p[2] - p[0]).x()) / area2;
      const double w2 = ((p[1] - p[0]).x() * (q - p[0]).y() - (p[1] - p[0]).y() * (q - p[0]).x()) / area2;
      const double w0 = 1.0 - w1 - w2;
      constexpr double kTol = -1e-9;
      if (w0 < kTol || w1 < kTol || w2 < kTol) continue;
      const Vector3d point = w0 * v[0] + w1 * v[1] + w2 * v[2];
      const Vector3d dir = geometry_.RayDirectionTo(point);
      const size_t pixel = size_t(r) * width_ + c;
      if (normal.dot(-dir) <= kMaskEdgeOnCos) {
        // Turned away from the radar.
        flags_[pixel].fetch_or(kMaskShadow | kCoveredBit, std::memory_order_relaxed);
        continue;
      }
      const double t_far = geometry_.mode() == sensor::ProjectionMode::kAffine
                               ? far_affine_
                               : (geometry_.SensorPosition(geometry_.AlongTrack(point)) - point).norm();
      ++task.local_rays;
      // Leaving the surface at grazing incidence the ray climbs only
      // cos(theta) per metre: start it where it has cleared the rounding
      // of the surface itself (no self-shadowing).
      const double cos_in = normal.dot(-dir);
      const float t_near = eps_ / static_cast<float>(std::max(cos_in, 0.01));
      task.pending[task.count++] = Pending{pixel, point, -dir, t_near, static_cast<float>(t_far), cos_in, t,
                                           normal.dot(geometry_.UpwardRangePlaneNormal(point)) < 0.0};
      if (task.count == 16) Flush(task);
    }
  }
}

// The task's last rays, and its ray count into the total.
void MaskRayPass::Finish(Task& task) {
  if (task.count > 0) Flush(task);
  rays_.fetch_add(task.local_rays, std::memory_order_relaxed);
}

// A terrain grid without holes at the start of the mesh (a DEM's): its
// triangles row of cells by row of cells, every post projected once per
// row (a post is a corner of six triangles) instead of once per corner.
// Returns the number of triangles walked (0: no such grid).
size_t MaskRayPass::WalkGrid() {
  if (FirstTriangleWalkedAlone(embree_) == 0) return 0;
  const int grid_w = embree_.heightfield_grid_width(), grid_h = embree_.heightfield_grid_height();
  // With only_rows_: the wanted rows among [0, r) (wanted_before[r]), so
  // that a strip of cells whose posts' image rows (their along-track
  // coordinates alone, no projection) reach no wanted row is skipped.
  std::vector<int> wanted_before;
  if (only_rows_ != nullptr) {
    wanted_before.assign(size_t(height_) + 1, 0);
    for (int r = 0; r < height_; ++r) wanted_before[size_t(r) + 1] = wanted_before[size_t(r)] + ((*only_rows_)[size_t(r)] != 0);
  }
  auto strip_wanted = [&](int r) {
    if (only_rows_ == nullptr) return true;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t post = size_t(r) * grid_w; post < size_t(r + 2) * grid_w; ++post) {
      const double row = geometry_.RowOfAlongTrack(geometry_.AlongTrack(mesh_.vertices[post].cast<double>()));
      lo = std::min(lo, row);
      hi = std::max(hi, row);
    }
    // (A margin beyond Triangle's own bounds of the same values.)
    const int r_lo = std::max(0, static_cast<int>(std::ceil(lo - 1e-6)));
    const int r_hi = std::min(height_ - 1, static_cast<int>(std::floor(hi + 1e-6)));
    return r_lo <= r_hi && wanted_before[size_t(r_hi) + 1] > wanted_before[size_t(r_lo)];
  };
  tbb::parallel_for(tbb::blocked_range<int>(0, grid_h - 1, 8), [&](const tbb::blocked_range<int>& rows) {
    Task task;
    const size_t posts_across = size_t(grid_w);
    std::vector<Eigen::Vector2d> below(posts_across), above(posts_across);
    auto project_row = [&](int r, std::vector<Eigen::Vector2d>& out) {
      for (int c = 0; c < grid_w; ++c) out[size_t(c)] = Project(mesh_.vertices[size_t(r) * grid_w + c].cast<double>());
    };
    bool below_ready = false;  // `below` holds post row r's projections
    for (int r = rows.begin(); r < rows.end(); ++r) {
      if (!strip_wanted(r)) {
        below_ready = false;
        continue;
      }
      if (!below_ready) project_row(r, below);
      project_row(r + 1, above);
      for (size_t t = size_t(2) * size_t(r) * (grid_w - 1); t < size_t(2) * size_t(r + 1) * (grid_w - 1); ++t) {
        const Eigen::Vector3i tri = mesh_.Triangle(t);
        Vector3d v[3];
        Eigen::Vector2d p[3];
        for (int k = 0; k < 3; ++k) {
          const size_t post = size_t(tri[k]);
          v[k] = mesh_.vertices[post].cast<double>();
          p[k] = (post / size_t(grid_w) == size_t(r) ? below : above)[post % size_t(grid_w)];
        }
        Triangle(task, t, v, p);
      }
      std::swap(below, above);
      below_ready = true;
    }
    Finish(task);
  });
  return size_t(2 * embree_.heightfield_cells());
}

// The mesh's triangles from `first` on, each corner projected (affine
// mode: WalkTiles).
void MaskRayPass::WalkTriangles(size_t first) {
  if (first >= mesh_.triangle_count()) return;
  if (affine_) {
    WalkTiles(first);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(first, mesh_.triangle_count(), 4096),
                    [&](const tbb::blocked_range<size_t>& range) {
    Task task;
    for (size_t t = range.begin(); t != range.end(); ++t) {
      const Eigen::Vector3i tri = mesh_.Triangle(t);
      const Vector3d v[3] = {mesh_.vertices[tri[0]].cast<double>(),
                             mesh_.vertices[tri[1]].cast<double>(),
                             mesh_.vertices[tri[2]].cast<double>()};
      const Eigen::Vector2d p[3] = {Project(v[0]), Project(v[1]), Project(v[2])};
      Triangle(task, t, v, p);
    }
    Finish(task);
  });
}

// WalkTriangles in affine mode: only the triangles of the tiles
// (EmbreeScene::Tiles) whose bounds project onto the image. The projection
// is affine, so a triangle's projected corners lie within the bounds of its
// tile's projected corners: the other tiles' triangles cover no pixel
// centre (Triangle's own test; a pixel of slack for rounding). The same
// flags and rays as a walk over every triangle.
void MaskRayPass::WalkTiles(size_t first) {
  const TriangleTiles& tiles = embree_.Tiles(mesh_, first);
  const std::vector<size_t> near = TilesOnPixels(tiles, geometry_, PixelWindow(geometry_, 1.0, 1.0, 1.0));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, near.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
    Task task;
    for (size_t q = range.begin(); q != range.end(); ++q) {
      for (const uint32_t* t = tiles.begin(near[q]); t != tiles.end(near[q]); ++t) {
        const Eigen::Vector3i tri = mesh_.Triangle(*t);
        const Vector3d v[3] = {mesh_.vertices[tri[0]].cast<double>(), mesh_.vertices[tri[1]].cast<double>(),
                               mesh_.vertices[tri[2]].cast<double>()};
        const Eigen::Vector2d p[3] = {Project(v[0]), Project(v[1]), Project(v[2])};
        Triangle(task, *t, v, p);
      }
    }
    Finish(task);
  });
}

}  // namespace

namespace {

// RenderLayoverShadowMask with the profile sweep `sweep` (null: by rays
// alone) and the rows the tracer painted (`painted`, or null; their flags
// are moved out): `traced_rows` (or null), how many rows' flags were the
// tracer's.
std::vector<uint8_t> LayoverShadowMask(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                       const sensor::SarGeometry& geometry, int64_t* shadow_rays,
                                       std::vector<uint8_t>* lit, std::vector<uint8_t>* covered,
                                       const Eigen::AlignedBox3d* ray_box, const GridProfileSweep* sweep,
                                       PaintedMaskRows* painted, int64_t* swept_rows,
                                       int64_t* traced_rows = nullptr) {
  if (swept_rows != nullptr) *swept_rows = 0;
  if (traced_rows != nullptr) *traced_rows = 0;
  const Eigen::AlignedBox3d box = ray_box != nullptr ? *ray_box : mesh.Bounds();
  if (sweep != nullptr) {
    std::vector<uint8_t> flags, refused;
    if (MaskByProfileSweep(*sweep, geometry, painted, &flags, &refused)) {
      if (traced_rows != nullptr && painted != nullptr) {
        *traced_rows = std::count(painted->state.begin(), painted->state.end(), uint8_t{PaintedMaskRows::kPainted});
      }
      // Rows whose line the sweep refused: by rays.
      const int64_t refused_rows = std::count(refused.begin(), refused.end(), uint8_t{1});
      int64_t rays = 0;
      if (refused_rows > 0) {
        MaskRayPass pass(embree, mesh, geometry, box, lit != nullptr, &refused);
        rays = pass.Run();
        const size_t width = size_t(geometry.width());
        for (size_t r = 0; r < refused.size(); ++r) {
          if (!refused[r]) continue;
          for (size_t i = r * width; i < (r + 1) * width; ++i) flags[i] = pass.flags()[i].load(std::memory_order_relaxed);
        }
      }
      if (shadow_rays != nullptr) *shadow_rays = rays;
      if (swept_rows != nullptr) *swept_rows = geometry.height() - refused_rows;
      return UnpackMaskFlags([&](size_t i) { return flags[i]; }, flags.size(), lit, covered);
    }
  }
  MaskRayPass pass(embree, mesh, geometry, box, lit != nullptr);
  const int64_t rays = pass.Run();
  if (shadow_rays != nullptr) *shadow_rays = rays;
  const std::vector<std::atomic<uint8_t>>& flags = pass.flags();
  return UnpackMaskFlags([&](size_t i) { return flags[i].load(std::memory_order_relaxed); }, flags.size(), lit,
                         covered);
}

}  // namespace

std::vector<uint8_t> RenderLayoverShadowMask(const EmbreeScene& embree,
                                             const scene::TriangleMesh& mesh,
                                             const sensor::SarGeometry& geometry,
                                             int64_t* shadow_rays, std::vector<uint8_t>* lit,
                                             std::vector<uint8_t>* covered, const Eigen::AlignedBox3d* ray_box,
                                             bool profile_sweep, int64_t* swept_rows) {
  const std::optional<GridProfileSweep> sweep =
      profile_sweep ? ProfileSweepOf(embree, mesh, geometry) : std::nullopt;
  return LayoverShadowMask(embree, mesh, geometry, shadow_rays, lit, covered, ray_box,
                           sweep ? &*sweep : nullptr, nullptr, swept_rows);
}

namespace {

// ------------------------------------------------ RenderSar's phases
//
// RenderSar reads as its algorithm:
//   TracePlan       set up: the ray grid, geometry constants, material
//                   tables, the layout of the accumulation planes and of the
//                   blocks of azimuth lines;
//   TraceAccumulator the zeroed image planes the blocks add into;
//   TraceBlocks     trace and splat, block by block in parallel
//                   (BlockTracer: primary rays in 16-ray packets or from the
//                   profile sweep, each ray's bounces, each return splatted
//                   into the block's band, the band added into the planes);
//   SplatOverflows  the returns that landed outside their block's band;
//   ComposeImage    the output bands and statistics from the planes;
//   MaskImage       reflectors, layover/shadow mask and footprint counts.

// What tracing one image needs and keeps fixed: the inputs, the ray grid,
// geometry constants (ENU metres), the material tables and the layout of
// the accumulation planes and of the blocks. Building it is the set-up
// phase: nothing image-sized is allocated; it throws what
// MaterialTable::Tables throws and fails a GISSAR_CHECK when the blocks'
// bands would overlap more than their neighbours'. The referenced inputs
// must outlive it.
struct TracePlan {
  TracePlan(const EmbreeScene& embree_in, const scene::TriangleMesh& mesh_in,
            const material::MaterialTable& materials_in, const sensor::SarGeometry& geometry_in,
            const RenderOptions& options_in);
  // Not copied: mask_rule refers to the plan's own sweep.
  TracePlan(const TracePlan&) = delete;
  TracePlan& operator=(const TracePlan&) = delete;

  // sigma0 (linear m^2/m^2) of class `id` (unknown classes: class 0) at
  // cos(local incidence) `cos_in`: the float table uniform in sqrt(1 - cos)
  // (Sigma0Table::Fast: no arc cosine; within the angle table's own
  // interpolation error of the law).
  double Sigma0(scene::ClassId id, double cos_in) const {
    return double(sigma0_tables[id < sigma0_tables.size() ? id : 0].Fast(static_cast<float>(cos_in)));
  }

  // The polarimetric terms of a first-bounce return of class `id` at
  // cos(shading incidence) `cos_shade`.
  PolarimetricTerms FirstBounceTerms(scene::ClassId id, double cos_shade) const {
    PolarimetricTerms terms;
    terms.rho = uses_rho ? rho_tables(id, cos_shade) : std::complex<double>();
    terms.mix = MixOfChannel(options.polarization, terms.rho);
    return terms;
  }

  // The cosine of the local incidence of a ray of unit direction `ray` at
  // `point` (ENU metres) on `triangle` that the class's sigma0 law sees: from
  // the smooth-terrain shading normal when the mesh has one (barycentrics of
  // the point), else (or for a degenerate triangle) `cos_facet`, the facet's.
  double ShadingCos(uint32_t triangle, const Vector3d& point, const Vector3d& ray, double cos_facet) const {
    if (mesh.shading_normals.empty()) return cos_facet;
    const Eigen::Vector3i tri = mesh.Triangle(triangle);
    const Vector3d v0 = mesh.vertices[tri[0]].cast<double>();
    const Vector3d e1 = mesh.vertices[tri[1]].cast<double>() - v0;
    const Vector3d e2 = mesh.vertices[tri[2]].cast<double>() - v0;
    const Vector3d w = point - v0;
    const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2);
    const double det = d11 * d22 - d12 * d12;
    if (!(det > 0.0)) return cos_facet;
    const double u = (d22 * w.dot(e1) - d12 * w.dot(e2)) / det;
    const double v = (d11 * w.dot(e2) - d12 * w.dot(e1)) / det;
    const Vector3d ns = mesh.ShadingNormal(triangle, float(u), float(v)).cast<double>();
    return std::max(0.0, -ns.dot(ray));
  }

  // Along-track coordinate (metres) of azimuth line i of the ray grid.
  double AlongTrackOfLine(int i) const { return grid.a0 + i * grid.da; }
  // The real plane of bounce layer `layer`'s complex band (coherent mode;
  // the imaginary one follows it).
  int ComplexLayerPlane(int layer) const { return total_planes + used_layers + 2 * layer; }
  // First image row of block b's band, and its row count: the rows its
  // returns can reach (one further than its lines).
  int BandRow0(int b) const {
    return static_cast<int>(std::floor(geometry.RowOfAlongTrack(grid.a0 + b * rows_per_block * grid.da)));
  }
  int BandRows(int b) const {
    const int i1 = std::min(grid.n_az, (b + 1) * rows_per_block);
    return static_cast<int>(std::floor(geometry.RowOfAlongTrack(grid.a0 + (i1 - 1) * grid.da))) + 2 - BandRow0(b);
  }

  const EmbreeScene& embree;
  const scene::TriangleMesh& mesh;
  const material::MaterialTable& materials;
  const sensor::SarGeometry& geometry;
  const RenderOptions& options;
  int width = 0, height = 0;      // image, pixels
  size_t implicit_triangles = 0;  // the mesh's computed (not stored) grid triangles
  Eigen::AlignedBox3d box;        // where rays are traced
  RayGrid grid;
  bool affine = false;
  Vector3d l, n, xc;  // look direction, range-plane normal, scene centre
  double range0 = 0.0;             // slant range of the scene centre, metres
  float eps = 0.0f;                // RayEpsilon of the box
  double far_affine = 0.0;         // affine mode: far end of a visibility ray, metres
  double wavenumber2 = 0.0;        // phase per metre of slant range, 4 pi / lambda
  double inv_pixel_area = 0.0;     // 1 / m^2
  double split_footprint_px = 0.0; // adaptive sampling: first-bounce footprints wider are split
  std::vector<material::Sigma0Table> sigma0_tables;
  // Primary rays of one azimuth line lie in one plane, ray j + 1 above ray
  // j when the range-plane normal points up (they share the origin plane,
  // or exact mode's sensor, and rise with e). Over a height field the first
  // hit then moves monotonically away from the radar with j: a ray above
  // one that met the terrain from above passes over everything before that
  // hit, and starts there (Embree and the height field skip the tiles
  // before tnear). The hits, and the image, are the same bit for bit.
  Vector3d ground_look;  // the look direction's horizontal unit vector
  bool skip_to_previous_hit = false;
  // Over a whole terrain grid and nothing else, the primary hits of each
  // azimuth line come from one walk along its profile (GridProfileSweep)
  // instead of a ray traversal each.
  std::optional<GridProfileSweep> sweep;
  // With one ray line per image row (the sweep applying), each line's walk
  // also paints its row's layover/shadow flags (ProfileMaskRule; the mask
  // phase then walks no profile again): set, referring to `sweep`, when the
  // lines are the rows' lines (RowLineAlongTrack).
  std::optional<ProfileMaskRule> mask_rule;
  // Polarimetric passes (see the header): the HH-VV correlation tables are
  // needed only by a VV pass's micro-phasors (coherent, or recorded for a
  // coherent re-projection).
  bool polarimetric = false;
  bool uses_rho = false;
  HhVvCorrelationTables rho_tables;
  // Planes: total intensity (coherent: real and imaginary amplitude), then
  // one per bounce count that can occur (the others stay zero). Coherent
  // mode adds a real and an imaginary plane per bounce count.
  int total_planes = 0, used_layers = 0, planes = 0;
  // Blocks of 16 image rows' worth of azimuth ray lines (TraceBlocks).
  int rows_per_block = 0, n_blocks = 0;
};

TracePlan::TracePlan(const EmbreeScene& embree_in, const scene::TriangleMesh& mesh_in,
                     const material::MaterialTable& materials_in, const sensor::SarGeometry& geometry_in,
                     const RenderOptions& options_in)
    : embree(embree_in), mesh(mesh_in), materials(materials_in), geometry(geometry_in), options(options_in),
      sweep(options_in.profile_sweep ? ProfileSweepOf(embree_in, mesh_in, geometry_in) : std::nullopt) {
  width = geometry.width();
  height = geometry.height();
  implicit_triangles = mesh.GridTriangleCount();
  box = options.ray_box ? *options.ray_box : mesh.Bounds();
  grid = MakeRayGrid(geometry, box, options.rays_per_cell);
  affine = geometry.mode() == sensor::ProjectionMode::kAffine;
  if (affine && options.image_rays_only) {
    const auto [z_lo, z_hi] = HeightsWithinReach(embree, mesh, geometry, box, options.max_bounces);
    CullToImage(geometry, z_lo, z_hi, options.max_bounces, &grid);
  }
  if (sweep && grid.n_az == height && grid.da == geometry.azimuth_spacing_m() &&
      AlongTrackOfLine(height - 1) == RowLineAlongTrack(geometry, height - 1)) {
    mask_rule.emplace(*sweep, geometry);
  }
  l = geometry.look_direction();
  n = geometry.range_plane_normal();
  xc = geometry.scene_centre();
  range0 = geometry.slant_range_m();
  eps = RayEpsilon(box);
  far_affine = range0 + box.diagonal().norm();
  wavenumber2 = 4.0 * M_PI / options.wavelength_m;
  inv_pixel_area = 1.0 / (geometry.range_spacing_m() * geometry.azimuth_spacing_m());
  split_footprint_px = std::max(kMinSplitFootprintPx, 2.0 / grid.k_el);
  sigma0_tables = materials.Tables(options.wavelength_m, options.polarization);
  ground_look = Vector3d(l.x(), l.y(), 0.0).normalized();
  skip_to_previous_hit = options.skip_to_previous_hit && embree.HeightfieldOnly() && n.z() > 0.0;
  polarimetric = options.polarimetric;
  uses_rho = polarimetric && (options.coherent || options.record_contributions) &&
             options.polarization == material::Polarization::kVV;
  if (uses_rho) rho_tables = HhVvCorrelationTables(materials, options.wavelength_m);
  total_planes = options.coherent ? 2 : 1;
  used_layers = std::min(options.max_bounces, kBounceLayers);
  planes = total_planes + used_layers + (options.coherent ? 2 * used_layers : 0);
  const int k_az = std::max(1, static_cast<int>(std::lround(grid.n_az / std::max(1, height))));
  rows_per_block = 16 * k_az;
  n_blocks = (grid.n_az + rows_per_block - 1) / rows_per_block;
  // A band shares rows only with its two neighbours (TraceBlocks).
  for (int b = 0; b + 2 < n_blocks; ++b) GISSAR_CHECK(BandRow0(b) + BandRows(b) <= BandRow0(b + 2));
}

// The image planes being accumulated (TracePlan's layout, width x height
// floats each, zeroed on construction in parallel, one task per plane: for
// a large image the first touch of fresh pages is most of their cost) and
// what the blocks hand over: the returns outside their band and the
// recorded contributions, both per block (used in block order), and
// counts. Blocks add their bands row by row under row_locks (by image row
// modulo 64).
struct TraceAccumulator {
  explicit TraceAccumulator(const TracePlan& plan)
      : image_planes(size_t(plan.planes)),
        block_overflow(size_t(plan.n_blocks)),
        block_contributions(plan.options.record_contributions ? size_t(plan.n_blocks) : 0) {
    tbb::parallel_for(0, plan.planes,
                      [&](int p) { image_planes[p].assign(size_t(plan.width) * plan.height, 0.0f); });
    if (plan.mask_rule) {
      painted_mask.flags.assign(size_t(plan.width) * plan.height, 0);
      painted_mask.state.assign(size_t(plan.height), PaintedMaskRows::kNotPainted);
    }
  }

  std::vector<std::vector<float>> image_planes;
  std::vector<std::vector<Band::Overflow>> block_overflow;
  std::vector<std::vector<Contribution>> block_contributions;
  std::array<std::mutex, 64> row_locks;
  std::atomic<int64_t> hits{0}, sub_rays{0}, swept_lines{0};
  // The rows the tracer's walks painted (TracePlan::mask_rule).
  PaintedMaskRows painted_mask;
};

// A block's primary hits from the profile sweep, per line: whether the
// sweep found them (else the line is traced), and per ray its depth
// (GridProfileSweep::LineRays), triangle and facet normal.
struct SweptHits {
  std::vector<uint8_t> swept;
  std::vector<double> depth;
  std::vector<uint32_t> triangle;
  std::vector<Vector3f> normal;
  // Per line, with adaptive sampling: its profile's upper frontier, where
  // the sub-rays find their first hits (GridProfileSweep::FrontierHit).
  std::vector<GridProfileSweep::Frontier> frontier;
};

// A thread's buffers, kept from block to block (tens of MB: allocating
// them per block cost page faults): the band's planes, the swept hits, the
// range profiles of incoherent first-bounce returns, and per line its
// sensor position and the ground coordinate skip_to_previous_hit starts at.
struct BlockScratch {
  std::vector<float> band;
  SweptHits swept;
  LineProfiles profiles;
  std::vector<Vector3d> line_sensor;
  std::vector<double> line_previous_hit;
};

// One packet of primary rays: lanes k = 0..15 are rays j0 + k of one
// azimuth line. `valid` is Embree's mask (-1: traced; 64-byte aligned for
// rtcIntersect16); per lane the ray's origin (ENU metres), unit direction
// and path length from the sensor to the origin (metres), and, once hit,
// the triangle's facet normal and class.
struct Lanes {
  RayPacket16 packet;
  alignas(64) int valid[16];
  Vector3d origin[16], dir[16];
  double travelled[16];
  Vector3f normal[16];
  scene::ClassId class_id[16];
};

// A ray followed through its bounces: where it starts and where it goes
// (ENU metres, unit direction), its path length from the sensor to
// `origin` (metres), its beam cross-section at the first hit (m^2), the
// product of the mirror shares so far, its id (RayGrid::RayId: the seed
// of its micro-phases) and, in polarimetric passes, the field it carries.
struct RayState {
  Vector3d origin, dir;
  double travelled = 0.0;
  double area = 0.0;
  double share = 1.0;
  uint64_t id = 0;
  ChainField field;
};

// Where a ray met a surface that faces it, and the way back to the radar.
struct SurfaceHit {
  Vector3d p;                               // the hit, ENU metres
  Vector3d normal;                          // the facet's unit normal
  double cos_in = 0.0;                      // -normal . dir, > 0
  uint32_t triangle = 0;
  scene::ClassId class_id = 0;
  const material::Material* material = nullptr;
  double along = 0.0;                       // along-track coordinate of p, metres
  Vector3d to_radar;                        // unit
  double back = 0.0;                        // path length p -> sensor, metres
  Vector3d mirror;                          // dir + 2 cos_in normal (not normalised)
};

// What a hit returns to the radar: `value` is beta0 summed over the
// footprint (later bounces: the path power P without its reversed path;
// 0: nothing, or returned by sub-rays), the bistatic law's diffuse and
// specular parts (first bounce: only with recorded contributions), the
// first-bounce footprint in pixels (-1: a point) and the polarimetric terms.
struct Shading {
  double value = 0.0;
  double diffuse_part = 0.0, specular_part = 0.0;
  double box_cols = -1.0, box_rows = -1.0;
  PolarimetricTerms terms;
};

// One return into the image (and the contributions): `value` as in
// Shading, at slant range `range` and along-track `along` (metres, the
// mean of the way out and back), footprint box_cols x box_rows (pixels;
// box_cols < 0: a point), after `bounce` bounces at hit `p` (ENU metres) of
// class `class_id`. `phase_key` picks the random micro-phase of
// rough-surface returns; `specular`: the specular part dominates; `pol`
// (polarimetric passes, else nullptr): the return's polarimetric terms.
struct Return {
  double value;
  double range, along;
  double box_cols, box_rows;
  int bounce;
  int phase_key;
  Vector3d p;
  scene::ClassId class_id;
  bool specular;
  const PolarimetricTerms* pol;
};

// Traces one block of azimuth lines [i0, i1) of the ray grid (block b:
// lines b * rows_per_block on) into its band of image rows (TracePlan::
// BandRow0/BandRows) in a thread's buffer, then adds the band into the
// accumulator's planes. Primary rays go out 16 at a time along an azimuth
// line (neighbouring origins, parallel or fanned directions: a coherent
// packet); each lane's later bounces are then followed one ray at a time,
// lanes in order, so returns are splatted in the same order as ray by ray.
// The block's lines go out interleaved: packet row j0 of every line, then
// the next packet row. Neighbouring lines meet the same terrain cells, so
// each line finds the posts, the quadtree nodes and the mesh in cache where
// the line before it left them.
class BlockTracer {
 public:
  BlockTracer(const TracePlan& plan, TraceAccumulator& acc, BlockScratch& scratch, int block);

  // Traces, splats and adds the block; adds its counts to the accumulator.
  void Run();

 private:
  // Azimuth line i: its along-track coordinate a (metres), its sensor
  // position (ENU metres), and whether the sweep found its primary hits.
  struct Line {
    int i;
    double a;
    const Vector3d& sensor;
    bool swept;
  };

  void PrepareLines();
  void SweptRays(int i, int j_begin, int j_end);
  void TracePacket(int i, int j0);
  bool CastPrimaryRays(const Line& line, int j0, double previous_hit_ground);
  void FindFirstHits(const Line& line, int j0);
  double HighestLaneGround() const;
  void FollowRay(const Line& line, int j0, int k);
  void WayBack(SurfaceHit& s, bool with_direction = true) const;
  void ContinueRay(const Line& line, RayState& ray, SurfaceHit s, int bounce);
  Shading ShadeFirstBounce(const Line& line, int j, const RayState& ray, const SurfaceHit& s);
  void TraceSubRays(const Line& line, int j, uint64_t ray_id, double box_cols, double box_rows);
  double SubRayStartGround(const Line& line, int j) const;
  Shading ShadeLaterBounce(const RayState& ray, const SurfaceHit& s) const;
  bool Reflect(RayState& ray, const SurfaceHit& s) const;
  void Emit(const Return& r, int i, uint64_t ray_id);
  void RecordContribution(const Return& r, double value, double path_power, uint64_t ray_id);
  void FlushProfiles();
  void MergeBand();

  const TracePlan& plan_;
  TraceAccumulator& acc_;
  BlockScratch& scratch_;
  const int block_;
  const int i0_, i1_;      // the block's azimuth lines
  const bool by_profile_;  // incoherent: first-bounce returns go through LineProfiles
  // Incoherent, one channel, no contributions: a swept line's rays are
  // shaded one by one, without packets (SweptRays).
  const bool one_pass_lines_;
  Band band_;
  Lanes lanes_;
  int64_t hits_ = 0, sub_rays_ = 0, swept_lines_ = 0;
};

BlockTracer::BlockTracer(const TracePlan& plan, TraceAccumulator& acc, BlockScratch& scratch, int block)
    : plan_(plan),
      acc_(acc),
      scratch_(scratch),
      block_(block),
      i0_(block * plan.rows_per_block),
      i1_(std::min(plan.grid.n_az, i0_ + plan.rows_per_block)),
      by_profile_(!plan.options.coherent),
      one_pass_lines_(by_profile_ && plan.sweep && plan.options.one_pass_swept_lines && !plan.polarimetric &&
                      !plan.options.record_contributions) {
  band_.planes = plan.planes;
  band_.row0 = plan.BandRow0(block);
  band_.rows = plan.BandRows(block);
  scratch.band.assign(size_t(plan.planes) * band_.rows * plan.width, 0.0f);
  band_.values = scratch.band.data();
  band_.overflow = &acc.block_overflow[size_t(block)];
  if (by_profile_) scratch.profiles.Reset(i1_ - i0_, plan.width);
}

void BlockTracer::Run() {
  PrepareLines();
  // A swept line's rays go without packets when they can (SweptRays).
  const auto one_pass = [&](int i) { return one_pass_lines_ && scratch_.swept.swept[size_t(i - i0_)] != 0; };
  const int n_el = plan_.grid.n_el;
  if (one_pass_lines_ && plan_.options.max_bounces == 1) {
    // One bounce: every return goes into its own line's range profile, so
    // a swept line's rays go all at once (its data stays in cache), the
    // other lines' in packets: the same sums either way.
    for (int i = i0_; i < i1_; ++i) {
      if (one_pass(i)) SweptRays(i, 0, n_el);
    }
    for (int j0 = 0; j0 < n_el; j0 += 16) {
      for (int i = i0_; i < i1_; ++i) {
        if (!one_pass(i)) TracePacket(i, j0);
      }
    }
  } else {
    // Later bounces land in the band shared by the block's lines: in the
    // packets' order (packet row, then line), so that every pixel sums its
    // returns in the same order either way.
    for (int j0 = 0; j0 < n_el; j0 += 16) {
      for (int i = i0_; i < i1_; ++i) {
        if (one_pass(i)) {
          SweptRays(i, j0, std::min(j0 + 16, n_el));
        } else {
          TracePacket(i, j0);
        }
      }
    }
  }
  FlushProfiles();
  MergeBand();
  acc_.hits.fetch_add(hits_, std::memory_order_relaxed);
  acc_.sub_rays.fetch_add(sub_rays_, std::memory_order_relaxed);
  acc_.swept_lines.fetch_add(swept_lines_, std::memory_order_relaxed);
}

// Per line of the block: the sensor position, no previous hit (-inf), and,
// where the sweep applies, the primary hits of the whole line.
void BlockTracer::PrepareLines() {
  const RayGrid& grid = plan_.grid;
  const int lines = i1_ - i0_;
  scratch_.line_sensor.resize(size_t(lines));
  for (int i = i0_; i < i1_; ++i) {
    scratch_.line_sensor[size_t(i - i0_)] = plan_.geometry.SensorPosition(plan_.AlongTrackOfLine(i));
  }
  scratch_.line_previous_hit.assign(size_t(lines), -std::numeric_limits<double>::infinity());
  if (!plan_.sweep) return;
  SweptHits& s = scratch_.swept;
  s.swept.resize(size_t(lines));
  s.depth.resize(size_t(lines) * grid.n_el);
  s.triangle.resize(size_t(lines) * grid.n_el);
  s.normal.resize(size_t(lines) * grid.n_el);
  // Sub-rays reach half a ray spacing beyond the lowest and the highest
  // ray: the frontiers are recorded out to there.
  const bool sub_rays = plan_.options.adaptive_sampling;
  if (sub_rays) s.frontier.resize(size_t(lines));
  const double bottom = grid.e0 + (grid.j_first - 0.5) * grid.de;
  const double top = grid.e0 + (grid.j_first + grid.n_el - 0.5) * grid.de;
  constexpr double kNearRightAngle = 0.5 * M_PI - 1e-9;
  const double frontier_below = plan_.affine ? bottom : std::tan(std::max(bottom, -kNearRightAngle));
  const double frontier_above = plan_.affine ? top : std::tan(std::min(top, kNearRightAngle));
  // Each line's row of the mask, painted from the same walk.
  PaintedMaskRows& painted = acc_.painted_mask;
  std::vector<MaskRowPainter> painters;
  if (plan_.mask_rule) {
    painters.reserve(size_t(lines));
    for (int i = i0_; i < i1_; ++i) painters.emplace_back(*plan_.mask_rule, painted.flags.data() + size_t(i) * plan_.width);
  }
  std::vector<GridProfileSweep::LineRays> rays;
  for (int i = i0_; i < i1_; ++i) {
    const size_t at = size_t(i - i0_) * grid.n_el;
    rays.push_back({plan_.AlongTrackOfLine(i), grid.e0, grid.de, grid.j_first, grid.n_el, &s.depth[at],
                    &s.triangle[at], &s.normal[at], grid.tan_e.empty() ? nullptr : grid.tan_e.data(),
                    sub_rays ? &s.frontier[size_t(i - i0_)] : nullptr, frontier_below, frontier_above,
                    painters.empty() ? nullptr : &painters[size_t(i - i0_)]});
  }
  plan_.sweep->TraceLines(rays, s.swept.data());
  for (const uint8_t swept : s.swept) swept_lines_ += swept;
  for (size_t k = 0; k < painters.size(); ++k) {
    if (painters[k].behind_sensor()) painted.behind_sensor = true;
    painted.state[size_t(i0_) + k] = s.swept[k] ? PaintedMaskRows::kPainted : PaintedMaskRows::kRefused;
  }
}

// Rays [j_begin, j_end) of swept line i, one after the other, without a
// packet (one_pass_lines_): the arithmetic of CastPrimaryRays,
// FindFirstHits, FollowRay's first bounce, ShadeFirstBounce and Emit in the
// same order (the same returns, bit for bit), without the lanes, and
// without the direction of the first hit's way back, its mirror direction and
// return row when there is no later bounce (the line's range profile has
// its row); later bounces as FollowRay's (ContinueRay).
void BlockTracer::SweptRays(int i, int j_begin, int j_end) {
  const RayGrid& grid = plan_.grid;
  const sensor::SarGeometry& geometry = plan_.geometry;
  const size_t line_index = size_t(i - i0_);
  const Line line{i, plan_.AlongTrackOfLine(i), scratch_.line_sensor[line_index], true};
  const SweptHits& swept_hits = scratch_.swept;
  const size_t at = line_index * grid.n_el;
  const double box_rows = grid.da / geometry.azimuth_spacing_m();
  const bool later_bounces = plan_.options.max_bounces > 1;
  for (int j = j_begin; j < j_end; ++j) {
    const uint32_t triangle = swept_hits.triangle[at + size_t(j)];
    if (triangle == RayPacket16::kNoHit) continue;
    RayState ray;
    if (!PrimaryRayAt(geometry, grid, plan_.box, line.a, j, line.sensor, &ray.origin, &ray.dir, &ray.travelled)) {
      continue;
    }
    const double depth = swept_hits.depth[at + size_t(j)];
    // The packet's float distance from the origin (FindFirstHits).
    const float t = static_cast<float>(plan_.affine ? depth + grid.back_off_m : depth - ray.travelled);
    ++hits_;
    SurfaceHit s;
    s.p = ray.origin + double(t) * ray.dir;
    ray.travelled += t;
    s.normal = swept_hits.normal[at + size_t(j)].cast<double>();
    s.cos_in = -s.normal.dot(ray.dir);
    if (s.cos_in <= 0.0) continue;  // back face
    s.triangle = triangle;
    s.class_id = plan_.mesh.classes[triangle];
    ray.area = plan_.affine ? grid.da * grid.de_m : grid.da * grid.de * ray.travelled;
    ray.id = grid.RayId(i, j);
    WayBack(s, /*with_direction=*/later_bounces);
    if (later_bounces) {
      s.material = &plan_.materials.Get(s.class_id);
      s.mirror = ray.dir + 2.0 * s.cos_in * s.normal;
    }
    const double cos_shade = plan_.ShadingCos(triangle, s.p, ray.dir, s.cos_in);
    const double cos_eff = std::max(s.cos_in, kMaskEdgeOnCos);
    const double value = plan_.Sigma0(s.class_id, cos_shade) * ray.area / cos_eff * plan_.inv_pixel_area;
    const Vector3d v_e = plan_.affine
                             ? Vector3d(plan_.n)
                             : Vector3d(-grid.sin_e[size_t(j)] * plan_.l + grid.cos_e[size_t(j)] * plan_.n);
    const double s_e = plan_.affine ? grid.de_m : ray.travelled * grid.de;
    const double box_cols = s_e * std::abs(s.normal.dot(v_e)) / cos_eff / geometry.range_spacing_m();
    if (plan_.options.adaptive_sampling && box_cols > plan_.split_footprint_px) {
      TraceSubRays(line, j, ray.id, box_cols, box_rows);
    } else if (value > 0.0) {
      scratch_.profiles.Add(int(line_index), geometry.ColumnOfRange(0.5 * (ray.travelled + s.back)), box_cols,
                            value);
    }
    if (later_bounces) ContinueRay(line, ray, s, 1);
  }
}

// Packet row j0 of azimuth line i: its primary rays, their first hits, then
// each hit lane's bounces.
void BlockTracer::TracePacket(int i, int j0) {
  const size_t line_index = size_t(i - i0_);
  const Line line{i, plan_.AlongTrackOfLine(i), scratch_.line_sensor[line_index],
                  plan_.sweep && scratch_.swept.swept[line_index]};
  double& previous_hit_ground = scratch_.line_previous_hit[line_index];
  if (!CastPrimaryRays(line, j0, previous_hit_ground)) return;
  FindFirstHits(line, j0);
  if (plan_.skip_to_previous_hit) previous_hit_ground = HighestLaneGround();
  for (int k = 0; k < 16; ++k) {
    if (lanes_.valid[k] == 0 || lanes_.packet.triangle[k] == RayPacket16::kNoHit) continue;
    FollowRay(line, j0, k);
  }
}

// Sets up the packet's lanes (rays j0 + k of `line` that exist and, in
// exact mode, meet the box); with skip_to_previous_hit each starts at the
// ground coordinate `previous_hit_ground` (metres along ground_look, less
// kSkipMarginM; -inf: from its origin). False when no lane is valid.
bool BlockTracer::CastPrimaryRays(const Line& line, int j0, double previous_hit_ground) {
  const RayGrid& grid = plan_.grid;
  RayPacket16& packet = lanes_.packet;
  bool any = false;
  for (int k = 0; k < 16; ++k) {
    const int j = j0 + k;
    lanes_.valid[k] = 0;
    if (j >= grid.n_el) continue;
    Vector3d origin, dir;
    double travelled;  // path length from the sensor to `origin`
    if (!PrimaryRayAt(plan_.geometry, grid, plan_.box, line.a, j, line.sensor, &origin, &dir, &travelled)) continue;
    lanes_.origin[k] = origin;
    lanes_.dir[k] = dir;
    lanes_.travelled[k] = travelled;
    packet.SetRay(k, origin.cast<float>(), dir.cast<float>());
    if (plan_.skip_to_previous_hit && previous_hit_ground > -std::numeric_limits<double>::infinity()) {
      // This ray passes above the previous packet's highest ray, so over
      // all the terrain before that ray's hit: start it there (less
      // kSkipMarginM of ground).
      const double t_skip =
          (previous_hit_ground - kSkipMarginM - origin.dot(plan_.ground_look)) / dir.dot(plan_.ground_look);
      if (t_skip > 0.0) packet.tnear[k] = static_cast<float>(t_skip);
    }
    lanes_.valid[k] = -1;
    any = true;
  }
  return any;
}

// The valid lanes' first hits (packet tfar, metres from the origin, and
// triangle; kNoHit: a miss) from the sweep on a swept line, else from
// Embree's rtcIntersect16; then the hit triangles' normals and classes.
void BlockTracer::FindFirstHits(const Line& line, int j0) {
  const RayGrid& grid = plan_.grid;
  const scene::TriangleMesh& mesh = plan_.mesh;
  RayPacket16& packet = lanes_.packet;
  const SweptHits& swept_hits = scratch_.swept;
  if (line.swept) {
    const size_t at = size_t(line.i - i0_) * grid.n_el + size_t(j0);
    for (int k = 0; k < 16; ++k) {
      if (lanes_.valid[k] == 0) continue;
      packet.triangle[k] = swept_hits.triangle[at + size_t(k)];
      // Distance from the ray's origin: affine depths are along l from the
      // scene centre, exact ones from the sensor.
      const double depth = swept_hits.depth[at + size_t(k)];
      packet.tfar[k] = static_cast<float>(plan_.affine ? depth + grid.back_off_m : depth - lanes_.travelled[k]);
    }
  } else {
    plan_.embree.Intersect16(lanes_.valid, packet, /*coherent=*/true);
  }
  // The hit triangles' normals and classes for all lanes first, prefetched
  // in two waves (triangles, then their vertices): the mesh is large and
  // the lanes' triangles lie in different DEM rows, so their cache misses
  // overlap instead of queueing. (A swept line's triangles are grid cells:
  // their normals come from the posts the sweep has just read, not through
  // the mesh.)
  for (int k = 0; k < 16; ++k) {
    if (lanes_.valid[k] == 0 || packet.triangle[k] == RayPacket16::kNoHit) continue;
    // (An implicit grid's triangles are computed, not read.)
    const size_t t = packet.triangle[k];
    if (!line.swept && t >= plan_.implicit_triangles) {
      __builtin_prefetch(&mesh.triangles[t - plan_.implicit_triangles]);
    }
    __builtin_prefetch(&mesh.classes[t]);
  }
  for (int k = 0; k < 16 && !line.swept; ++k) {
    if (lanes_.valid[k] == 0 || packet.triangle[k] == RayPacket16::kNoHit) continue;
    const Eigen::Vector3i tri = mesh.Triangle(packet.triangle[k]);
    for (int corner = 0; corner < 3; ++corner) __builtin_prefetch(&mesh.vertices[tri[corner]]);
  }
  for (int k = 0; k < 16; ++k) {
    if (lanes_.valid[k] == 0 || packet.triangle[k] == RayPacket16::kNoHit) continue;
    lanes_.normal[k] = line.swept ? swept_hits.normal[size_t(line.i - i0_) * grid.n_el + size_t(j0 + k)]
                                  : mesh.Normal(packet.triangle[k]);
    lanes_.class_id[k] = mesh.classes[packet.triangle[k]];
  }
}

// skip_to_previous_hit: the ground coordinate (metres along ground_look) of
// the hit of the packet's highest ray (lane 15, rays rising with j) when it
// met the terrain from above (a height field's faces point up): the next
// packet's rays, all above it, can start there. -inf otherwise.
double BlockTracer::HighestLaneGround() const {
  const RayPacket16& packet = lanes_.packet;
  if (lanes_.valid[15] != 0 && packet.triangle[15] != RayPacket16::kNoHit &&
      lanes_.normal[15].cast<double>().dot(lanes_.dir[15]) < 0.0) {
    return (lanes_.origin[15] + double(packet.tfar[15]) * lanes_.dir[15]).dot(plan_.ground_look);
  }
  return -std::numeric_limits<double>::infinity();
}

// Lane k (ray j0 + k of `line`, which hit) through up to max_bounces
// bounces: at each hit facing the ray, its return (Emit), then on as the
// mirror ray while its share of the power stays at or above 1e-9. Stops at
// a miss or a back face (blocked).
void BlockTracer::FollowRay(const Line& line, int j0, int k) {
  const RayGrid& grid = plan_.grid;
  const int j = j0 + k;
  RayState ray;
  ray.origin = lanes_.origin[k];
  ray.dir = lanes_.dir[k];
  ray.travelled = lanes_.travelled[k];
  ray.id = grid.RayId(line.i, j);
  if (plan_.polarimetric) ray.field = TransmitField(ray.dir);
  // The first hit, from the packet.
  const float t = lanes_.packet.tfar[k];
  ++hits_;
  SurfaceHit s;
  s.p = ray.origin + double(t) * ray.dir;
  ray.travelled += t;
  s.normal = lanes_.normal[k].cast<double>();
  s.cos_in = -s.normal.dot(ray.dir);
  if (s.cos_in <= 0.0) return;  // back face: blocked
  s.triangle = lanes_.packet.triangle[k];
  s.class_id = lanes_.class_id[k];
  s.material = &plan_.materials.Get(s.class_id);
  // Beam cross-section: constant in affine mode, growing with range in
  // exact mode (constant angular spacing).
  ray.area = plan_.affine ? grid.da * grid.de_m : grid.da * grid.de * ray.travelled;
  WayBack(s);
  s.mirror = ray.dir + 2.0 * s.cos_in * s.normal;
  const Shading shading = ShadeFirstBounce(line, j, ray, s);
  if (shading.value > 0.0) {
    Emit(Return{shading.value, 0.5 * (ray.travelled + s.back), 0.5 * (line.a + s.along), shading.box_cols,
                shading.box_rows, 1, 1, s.p, s.class_id, shading.specular_part > shading.diffuse_part,
                plan_.polarimetric ? &shading.terms : nullptr},
         line.i, ray.id);
  }
  ContinueRay(line, ray, s, 1);
}

// Hit `s` (its point set): its along-track coordinate and the length of
// the way back to the radar, with its unit direction when `with_direction`
// (a later bounce needs it; a first bounce with none after it does not).
void BlockTracer::WayBack(SurfaceHit& s, bool with_direction) const {
  const sensor::SarGeometry& geometry = plan_.geometry;
  s.along = geometry.AlongTrack(s.p);
  if (plan_.affine) {
    if (with_direction) s.to_radar = -plan_.l;
    s.back = plan_.range0 + (s.p - plan_.xc).dot(plan_.l);
  } else {
    // One square root for both (Eigen's normalized() divides by the same
    // norm: the same values).
    const Vector3d to_sensor = geometry.SensorPosition(s.along) - s.p;
    s.back = to_sensor.norm();
    if (with_direction) s.to_radar = s.back > 0.0 ? Vector3d(to_sensor / s.back) : to_sensor;
  }
}

// `ray`, whose bounce `bounce` met `s` (its return emitted, its mirror
// direction set), on as the mirror ray through the later bounces up to
// max_bounces: at each hit facing the ray, its return, while its share of
// the power stays at or above 1e-9. Stops at a miss or a back face.
void BlockTracer::ContinueRay(const Line& line, RayState& ray, SurfaceHit s, int bounce) {
  const scene::TriangleMesh& mesh = plan_.mesh;
  while (bounce < plan_.options.max_bounces) {
    if (!Reflect(ray, s)) return;
    ++bounce;
    const auto hit = plan_.embree.Intersect(ray.origin.cast<float>(), ray.dir.cast<float>(), plan_.eps,
                                            std::numeric_limits<float>::infinity());
    if (!hit) return;
    s.p = ray.origin + double(hit->t) * ray.dir;
    ray.travelled += hit->t;
    s.normal = mesh.Normal(hit->triangle).cast<double>();
    s.cos_in = -s.normal.dot(ray.dir);
    if (s.cos_in <= 0.0) return;  // back face: blocked
    s.triangle = hit->triangle;
    s.class_id = mesh.classes[hit->triangle];
    s.material = &plan_.materials.Get(s.class_id);
    WayBack(s);
    s.mirror = ray.dir + 2.0 * s.cos_in * s.normal;
    const Shading shading = ShadeLaterBounce(ray, s);
    if (shading.value > 0.0) {
      Emit(Return{shading.value, 0.5 * (ray.travelled + s.back), 0.5 * (line.a + s.along), shading.box_cols,
                  shading.box_rows, bounce, bounce, s.p, s.class_id, shading.specular_part > shading.diffuse_part,
                  plan_.polarimetric ? &shading.terms : nullptr},
           line.i, ray.id);
    }
  }
}

// The first-bounce return of primary ray j of `line` at hit `s`: sigma0 at
// the shading incidence times the surface area the ray covers, per pixel
// area, and its footprint (pixels). Adaptive sampling: a footprint wider
// than split_footprint_px is returned by sub-rays instead (TraceSubRays;
// value 0).
Shading BlockTracer::ShadeFirstBounce(const Line& line, int j, const RayState& ray, const SurfaceHit& s) {
  const RayGrid& grid = plan_.grid;
  const sensor::SarGeometry& geometry = plan_.geometry;
  Shading shading;
  // The local incidence of the class's sigma0 law comes from the
  // smooth-terrain shading normal when the mesh has one; the footprint's
  // geometry keeps the facet normal. (The sub-rays do the same at their
  // own hits.)
  const double cos_shade = plan_.ShadingCos(s.triangle, s.p, ray.dir, s.cos_in);
  if (plan_.polarimetric) shading.terms = plan_.FirstBounceTerms(s.class_id, cos_shade);
  const double cos_eff = std::max(s.cos_in, kMaskEdgeOnCos);
  shading.value = plan_.Sigma0(s.class_id, cos_shade) * ray.area / cos_eff * plan_.inv_pixel_area;
  if (plan_.options.record_contributions) {  // only for the `specular` flag of contributions
    shading.diffuse_part = s.material->diffuse * s.cos_in;
    shading.specular_part = s.material->Backscatter(s.cos_in) - shading.diffuse_part;
  }
  // Footprint: the neighbouring ray across range hits the same plane
  // s_e |N.v_e| / cos(theta_l) further in slant range.
  const Vector3d v_e = plan_.affine ? Vector3d(plan_.n)
                                    : Vector3d(-grid.sin_e[size_t(j)] * plan_.l + grid.cos_e[size_t(j)] * plan_.n);
  const double s_e = plan_.affine ? grid.de_m : ray.travelled * grid.de;
  shading.box_cols = s_e * std::abs(s.normal.dot(v_e)) / cos_eff / geometry.range_spacing_m();
  shading.box_rows = grid.da / geometry.azimuth_spacing_m();
  if (plan_.options.adaptive_sampling && shading.box_cols > plan_.split_footprint_px) {
    TraceSubRays(line, j, ray.id, shading.box_cols, shading.box_rows);
    shading.value = 0.0;  // returned by the sub-rays
  }
  return shading;
}

// Adaptive sampling: a first-bounce footprint box_cols (pixels) wider than
// split_footprint_px (a surface seen near grazing) is covered by sub-rays
// across primary ray j's interval (at most kMaxSubRays), each with its own
// hit, normal and share of the cross-section, so the surface's true relief,
// not the plane of one triangle, decides where the power lands; each
// returns its first bounce (Emit, phase key 1000 + q, footprint height
// box_rows). The primary ray itself continues (multi-bounce).
void BlockTracer::TraceSubRays(const Line& line, int j, uint64_t ray_id, double box_cols, double box_rows) {
  const RayGrid& grid = plan_.grid;
  const sensor::SarGeometry& geometry = plan_.geometry;
  const scene::TriangleMesh& mesh = plan_.mesh;
  const bool affine = plan_.affine;
  const int subs = std::min(kMaxSubRays, static_cast<int>(std::ceil(box_cols / plan_.split_footprint_px)));
  sub_rays_ += subs;
  // A swept line's sub-rays meet its profile's frontiers (no traversal);
  // otherwise they are traced from where the ray below them met the
  // terrain.
  const GridProfileSweep::Frontier* frontier =
      line.swept && !scratch_.swept.frontier.empty() ? &scratch_.swept.frontier[size_t(line.i - i0_)] : nullptr;
  const double sub_start_ground = frontier != nullptr ? 0.0 : SubRayStartGround(line, j);
  const double e = grid.E(j);
  for (int q = 0; q < subs; ++q) {
    const double e_q = e + grid.de * ((q + 0.5) / subs - 0.5);
    const double cos_q_e = affine ? 1.0 : std::cos(e_q), sin_q_e = affine ? 0.0 : std::sin(e_q);
    Vector3d o_q, d_q;
    double trav_q;
    if (!PrimaryRay(geometry, grid, plan_.box, line.a, e_q, cos_q_e, sin_q_e, line.sensor, &o_q, &d_q, &trav_q)) {
      continue;
    }
    std::optional<RayHit> h_q;
    if (frontier != nullptr) {
      double depth = 0.0;
      uint32_t triangle = 0;
      // The frontier's coordinate: affine e, exact tan e.
      if (!plan_.sweep->FrontierHit(*frontier, affine ? e_q : sin_q_e / cos_q_e, &depth, &triangle)) continue;
      // Distance from the ray's origin (as FindFirstHits).
      const double t = plan_.affine ? depth + grid.back_off_m : depth - trav_q;
      if (!(t >= 0.0)) continue;
      h_q = RayHit{static_cast<float>(t), triangle};
    } else {
      float t_near_q = 0.0f;
      if (sub_start_ground > -std::numeric_limits<double>::infinity()) {
        const double t_skip =
            (sub_start_ground - kSkipMarginM - o_q.dot(plan_.ground_look)) / d_q.dot(plan_.ground_look);
        if (t_skip > 0.0) t_near_q = static_cast<float>(t_skip);
      }
      h_q = plan_.embree.Intersect(o_q.cast<float>(), d_q.cast<float>(), t_near_q,
                                   std::numeric_limits<float>::infinity());
    }
    if (!h_q) continue;
    const Vector3d p_q = o_q + double(h_q->t) * d_q;
    trav_q += h_q->t;
    const Vector3d n_q = mesh.Normal(h_q->triangle).cast<double>();
    const double cos_q = -n_q.dot(d_q);
    if (cos_q <= 0.0) continue;
    const double cos_q_eff = std::max(cos_q, kMaskEdgeOnCos);
    const scene::ClassId class_q = mesh.classes[h_q->triangle];
    const double area_q = affine ? grid.da * grid.de_m / subs : grid.da * grid.de / subs * trav_q;
    const double cos_shade_q = plan_.ShadingCos(h_q->triangle, p_q, d_q, cos_q);
    const double value_q = plan_.Sigma0(class_q, cos_shade_q) * area_q / cos_q_eff * plan_.inv_pixel_area;
    if (!(value_q > 0.0)) continue;
    const Vector3d v_q = affine ? Vector3d(plan_.n) : Vector3d(-sin_q_e * plan_.l + cos_q_e * plan_.n);
    const double s_q = affine ? grid.de_m / subs : trav_q * grid.de / subs;
    const double cols_q = s_q * std::abs(n_q.dot(v_q)) / cos_q_eff / geometry.range_spacing_m();
    const double a_q = geometry.AlongTrack(p_q);
    const double back_q =
        affine ? plan_.range0 + (p_q - plan_.xc).dot(plan_.l) : (geometry.SensorPosition(a_q) - p_q).norm();
    const PolarimetricTerms terms_q =
        plan_.polarimetric ? plan_.FirstBounceTerms(class_q, cos_shade_q) : PolarimetricTerms();
    Emit(Return{value_q, 0.5 * (trav_q + back_q), 0.5 * (line.a + a_q), cols_q, box_rows, 1, 1000 + q, p_q, class_q,
                false, plan_.polarimetric ? &terms_q : nullptr},
         line.i, ray_id);
  }
}

// Where primary ray j's sub-rays may start (ground coordinate, metres
// along ground_look; -inf: at their origins). On a swept line, the ray
// below it (j - 1 when the range-plane normal points up, else j + 1) that
// met the terrain from above has passed over everything before its hit,
// and so does every sub-ray (all above it): they start there (less
// kSkipMarginM of ground), as packets do with skip_to_previous_hit.
double BlockTracer::SubRayStartGround(const Line& line, int j) const {
  const RayGrid& grid = plan_.grid;
  const SweptHits& swept_hits = scratch_.swept;
  const int j_below = plan_.n.z() > 0.0 ? j - 1 : j + 1;
  if (!line.swept || j_below < 0 || j_below >= grid.n_el) return -std::numeric_limits<double>::infinity();
  const size_t below = size_t(line.i - i0_) * grid.n_el + size_t(j_below);
  Vector3d o_b, d_b;
  double trav_b;
  if (swept_hits.triangle[below] != GridProfileSweep::kNoHit &&
      PrimaryRayAt(plan_.geometry, grid, plan_.box, line.a, j_below, line.sensor, &o_b, &d_b, &trav_b) &&
      swept_hits.normal[below].cast<double>().dot(d_b) < 0.0) {
    const double t_b = plan_.affine ? swept_hits.depth[below] + grid.back_off_m : swept_hits.depth[below] - trav_b;
    return (o_b + t_b * d_b).dot(plan_.ground_look);
  }
  return -std::numeric_limits<double>::infinity();
}

// A later bounce: the mirror chain so far ends at `s` and scatters back to
// the radar (reciprocal bistatic law) when the way back is clear. Its
// reversed path (radar -> this point -> the mirrors in reverse order ->
// radar) has the same length and, by reciprocity, the same power
// (material::PathRcsPerArea); the tracer does not follow it from the other
// end, so Emit adds it: twice the power (incoherent), twice the amplitude
// in phase (coherent). The value is the path's RCS: bistatic sigma0 times
// the surface the ray's cross-section covers here (area / cos_in), times
// the mirror reflectivities on the way (polarimetric passes: the mirror
// coefficients only, the Fresnel amplitudes are in the chain's matrix),
// per pixel area; a point (no footprint).
Shading BlockTracer::ShadeLaterBounce(const RayState& ray, const SurfaceHit& s) const {
  const material::Material& m = *s.material;
  Shading shading;
  const double cos_out = s.normal.dot(s.to_radar);
  if (cos_out > 0.0 &&
      !plan_.embree.Occluded(s.p.cast<float>(), s.to_radar.cast<float>(), plan_.eps,
                             static_cast<float>(plan_.affine ? plan_.far_affine : s.back))) {
    const double cos_spec = s.mirror.dot(s.to_radar);
    shading.diffuse_part = m.BistaticSigma0(s.cos_in, cos_out, -1.0);
    shading.specular_part = m.BistaticSigma0(s.cos_in, cos_out, cos_spec) - shading.diffuse_part;
  }
  shading.value = (shading.diffuse_part + shading.specular_part) * ray.area / std::max(s.cos_in, kMaskEdgeOnCos) *
                  ray.share * plan_.inv_pixel_area;
  if (plan_.polarimetric && shading.value > 0.0) {
    shading.terms = MirrorTerms(ClosedChainMatrix(ray.field, ray.dir, s.to_radar, s.normal, shading.diffuse_part,
                                                  shading.specular_part,
                                                  m.EffectivePermittivity(plan_.options.wavelength_m)),
                                plan_.options.polarization);
  }
  return shading;
}

// Continues `ray` from hit `s` as its mirror ray, with the class's Fresnel
// mirror reflectivity at this incidence in its share. The radar's H/V
// basis is projected on this surface's plane of incidence (walls seen
// obliquely reflect part of V as TE); polarimetric passes carry the field
// through it instead (the mirror coefficient in the share, the Fresnel
// amplitudes in the field). False (the ray stops) when the mean power left
// is below 1e-9.
bool BlockTracer::Reflect(RayState& ray, const SurfaceHit& s) const {
  const material::Material& m = *s.material;
  if (plan_.polarimetric) {
    ray.share *= m.mirror;
    if (ray.share < 1e-9) return false;
    ReflectChainField(ray.field, ray.dir, s.normal, s.cos_in, m.EffectivePermittivity(plan_.options.wavelength_m));
    if (ray.share * 0.5 * ray.field.squaredNorm() < 1e-9) return false;
  } else {
    ray.share *= m.MirrorReflectivity(s.cos_in, ray.dir, s.mirror.normalized(), s.normal,
                                      plan_.options.wavelength_m, plan_.options.polarization);
    if (ray.share < 1e-9) return false;
  }
  ray.origin = s.p;
  ray.dir = s.mirror.normalized();
  return true;
}

// The splat: return `r` of ray `ray_id` of azimuth line i into the band
// (its bounce layer and the total; incoherent first bounces through the
// line's range profile), in coherent mode as phasors (rough-surface first
// bounces: the seeded micro-phase; mirror paths: the path phase
// exp(-j 4 pi R / lambda), material/scattering.h, docs/conventions.md),
// and into the block's contributions when they are recorded. A
// later-bounce return stands for its path and the reversed path (same
// length, same power): twice the power; in coherent mode the two add in
// phase. Returns outside the band go to its overflow.
void BlockTracer::Emit(const Return& r, int i, uint64_t ray_id) {
  const sensor::SarGeometry& geometry = plan_.geometry;
  const int width = plan_.width;
  Band& band = band_;
  const double col = geometry.ColumnOfRange(r.range), row = geometry.RowOfAlongTrack(r.along);
  const int layer = std::min(r.bounce, kBounceLayers) - 1;
  const double box_cols = r.box_cols, box_rows = r.box_rows;
  auto deposit = [&](int plane, double value) {
    if (box_cols >= 0.0) {
      SplatFootprint(band, width, plane, col, row, box_cols, box_rows, static_cast<float>(value));
    } else {
      Splat(band, width, plane, col, row, static_cast<float>(value));
    }
  };
  const double reciprocal = r.bounce > 1 ? 2.0 : 1.0;
  const bool mirror_matrix = r.pol != nullptr && r.bounce > 1;
  const double path_power = r.value;  // P, before the reversed path
  double value = r.value;
  if (mirror_matrix) {
    value *= r.pol->mirror_power;
  } else {
    value *= reciprocal;
  }
  if (by_profile_ && r.bounce == 1 && box_cols >= 0.0) {
    // Into the line's range profile (its bounce layer and the total when
    // the block is done).
    scratch_.profiles.Add(i - i0_, col, box_cols, value);
  } else if (!plan_.options.coherent && box_cols >= 0.0) {
    // Its bounce layer and the total, from the same shares.
    SplatFootprint2(band, width, plan_.total_planes + layer, 0, col, row, box_cols, box_rows,
                    static_cast<float>(value));
  } else {
    deposit(plan_.total_planes + layer, value);
  }
  if (plan_.options.coherent) {
    const double phase = -plan_.wavenumber2 * r.range;
    const double amplitude = r.bounce > 1 ? 2.0 * std::sqrt(value / reciprocal) : std::sqrt(value);
    // The same phasor into the total and into its bounce's complex band, so
    // the complex bands add up to the complex total.
    for (const int plane : {0, plan_.ComplexLayerPlane(layer)}) {
      if (r.bounce == 1) {
        SplatFootprintPhasors(band, width, plane, col, row, std::max(0.0, box_cols), box_rows, amplitude, phase,
                              plan_.options.seed, ray_id, uint64_t(r.phase_key),
                              r.pol != nullptr ? r.pol->mix : MicroPhasorMix());
      } else if (mirror_matrix) {
        // sqrt(P) (S_c + S^T_c) with the path phase.
        const std::complex<double> z = std::sqrt(path_power) * r.pol->mirror_amplitude * std::polar(1.0, phase);
        Splat(band, width, plane, col, row, static_cast<float>(z.real()), true);
        Splat(band, width, plane + 1, col, row, static_cast<float>(z.imag()), true);
      } else {
        Splat(band, width, plane, col, row, static_cast<float>(amplitude * std::cos(phase)), true);
        Splat(band, width, plane + 1, col, row, static_cast<float>(amplitude * std::sin(phase)), true);
      }
    }
  } else if (box_cols < 0.0) {
    deposit(0, value);
  }
  if (plan_.options.record_contributions) RecordContribution(r, value, path_power, ray_id);
}

// Return `r` as a contribution of the block: `value` its intensity (with
// the reversed path), `path_power` P without it (later polarimetric
// bounces' channel amplitude sqrt(P) (S_c + S^T_c)).
void BlockTracer::RecordContribution(const Return& r, double value, double path_power, uint64_t ray_id) {
  Contribution c;
  c.azimuth_m = r.along;
  c.range_m = r.range;
  c.elevation_m = (r.p - plan_.xc).dot(plan_.n);
  c.intensity = static_cast<float>(value);
  c.bounces = static_cast<uint8_t>(r.bounce);
  c.specular = r.specular;
  c.hit_enu = r.p.cast<float>();
  c.class_id = r.class_id;
  if (r.pol != nullptr) {  // what a coherent re-projection needs (Contribution)
    const std::complex<double> a = r.bounce > 1 ? std::sqrt(path_power) * r.pol->mirror_amplitude : r.pol->rho;
    c.channel_amplitude = std::complex<float>(a);
    c.ray_id = ray_id;
    c.phase_key = static_cast<uint16_t>(r.phase_key);
  }
  acc_.block_contributions[size_t(block_)].push_back(c);
}

// Incoherent mode: every line's range profile of first-bounce returns into
// its bounce layer and the total, at the line's row with the first-bounce
// footprint's height (the ray spacing across azimuth).
void BlockTracer::FlushProfiles() {
  if (!by_profile_) return;
  const double box_rows = plan_.grid.da / plan_.geometry.azimuth_spacing_m();
  for (int i = i0_; i < i1_; ++i) {
    scratch_.profiles.Flush(i - i0_, plan_.geometry.RowOfAlongTrack(plan_.AlongTrackOfLine(i)), box_rows, band_,
                            plan_.total_planes, 0);
  }
}

// The band into the image planes, one row at a time under its lock (rows
// outside the image are dropped: their returns are in the overflow).
void BlockTracer::MergeBand() {
  const int width = plan_.width;
  for (int r = 0; r < band_.rows; ++r) {
    const int row = band_.row0 + r;
    if (row < 0 || row >= plan_.height) continue;
    std::lock_guard<std::mutex> lock(acc_.row_locks[size_t(row) % acc_.row_locks.size()]);
    for (int plane = 0; plane < plan_.planes; ++plane) {
      float* dst = acc_.image_planes[size_t(plane)].data() + size_t(row) * width;
      const float* src = band_.values + (size_t(plane) * band_.rows + r) * width;
      for (int c = 0; c < width; ++c) dst[c] += src[c];
    }
  }
}

// Trace phase: the plan's blocks in parallel, each a BlockTracer in its
// thread's buffers, reporting progress on `reporter`. Each block
// accumulates into a band of image rows (plus an overflow list) added into
// the planes when the block is done. A band shares rows only with its two
// neighbours (blocks are 16 rows tall, bands reach one row further), so
// every pixel sums at most two bands, and IEEE addition of two terms is
// commutative: the planes do not depend on which finishes first, on the
// thread count or on scheduling. Throws when the reporter cancels.
void TraceBlocks(const TracePlan& plan, TraceAccumulator& acc, Reporter& reporter) {
  tbb::enumerable_thread_specific<BlockScratch> scratch;
  Progress progress("simulate: tracing", plan.n_blocks, reporter);
  tbb::parallel_for(tbb::blocked_range<int>(0, plan.n_blocks, 1), [&](const tbb::blocked_range<int>& blocks) {
    BlockScratch& local = scratch.local();
    for (int b = blocks.begin(); b != blocks.end(); ++b) {
      BlockTracer(plan, acc, local, b).Run();
      progress.Advance(1);
      ThrowIfCancelled(reporter, "simulate: tracing");
    }
  });
  progress.Done();
}

// The returns that landed outside their block's band, into the planes in
// block order (deterministic), clipped to the image.
void SplatOverflows(const TracePlan& plan, TraceAccumulator& acc) {
  for (const auto& overflow : acc.block_overflow) {
    for (const Band::Overflow& o : overflow) {
      std::vector<float>& plane = acc.image_planes[size_t(o.plane)];
      if (o.box_cols >= 0.0) {
        SplatBox(plane.data(), plan.width, 0, plan.height, o.col, o.row, o.box_cols, o.box_rows, o.value,
                 /*clip=*/true);
      } else {
        SplatBilinear(plane, plan.width, plan.height, o.col, o.row, o.value, o.amplitude);
      }
    }
  }
}

// Compose phase: `image`'s size, bands (intensity; coherent: intensity
// |z|^2 of the complex total, the complex total and the complex band per
// bounce count; the intensity per bounce count, layers beyond max_bounces
// empty), contributions (block order) and trace statistics, moved out of
// `acc`'s planes.
void ComposeImage(const TracePlan& plan, TraceAccumulator& acc, SarImage* image) {
  std::vector<std::vector<float>>& full = acc.image_planes;
  image->width = plan.width;
  image->height = plan.height;
  image->stats.heightfield_cells = plan.embree.heightfield_cells();
  if (plan.options.coherent) {
    image->intensity.resize(size_t(plan.width) * plan.height);
    for (size_t k = 0; k < image->intensity.size(); ++k) {
      image->intensity[k] = full[0][k] * full[0][k] + full[1][k] * full[1][k];
    }
    image->real = std::move(full[0]);
    image->imag = std::move(full[1]);
    for (int layer = 0; layer < plan.used_layers; ++layer) {
      image->bounce_real[layer] = std::move(full[size_t(plan.ComplexLayerPlane(layer))]);
      image->bounce_imag[layer] = std::move(full[size_t(plan.ComplexLayerPlane(layer)) + 1]);
    }
  } else {
    image->intensity = std::move(full[0]);
  }
  for (int layer = 0; layer < plan.used_layers; ++layer) {
    image->bounce_layers[layer] = std::move(full[size_t(plan.total_planes + layer)]);
  }
  for (auto& list : acc.block_contributions) {
    image->contributions.insert(image->contributions.end(), list.begin(), list.end());
  }
  image->stats.rays = int64_t{plan.grid.n_az} * plan.grid.n_el;
  image->stats.hits = acc.hits.load();
  image->stats.sub_rays = acc.sub_rays.load();
  image->stats.profile_swept_lines = acc.swept_lines.load();
}

// Mask phase: the reflectors' point returns, the layover/shadow mask and
// footprint (RenderLayoverShadowMask, by profile sweep where it applies,
// the rows the tracer painted taken as they are) and the count of lit
// pixels, and of those without a first-bounce return, into `image` (its
// bounce layers composed).
void MaskImage(const TracePlan& plan, TraceAccumulator& acc, SarImage* image) {
  const RenderOptions& options = plan.options;
  image->points = ReflectorReturns(plan.embree, options.reflectors, plan.geometry, options.wavelength_m,
                                   plan.polarimetric ? std::optional<material::Polarization>(options.polarization)
                                                     : std::nullopt);
  std::vector<uint8_t> lit;
  image->mask = LayoverShadowMask(plan.embree, plan.mesh, plan.geometry, &image->stats.shadow_rays, &lit,
                                  &image->footprint, options.ray_box ? &*options.ray_box : nullptr,
                                  plan.sweep ? &*plan.sweep : nullptr, plan.mask_rule ? &acc.painted_mask : nullptr,
                                  &image->stats.profile_swept_mask_rows, &image->stats.traced_mask_rows);
  for (size_t q = 0; q < lit.size(); ++q) {
    if (!lit[q]) continue;
    ++image->stats.footprint_pixels;
    if (!(image->bounce_layers[0][q] > 0.0f)) ++image->stats.empty_footprint_pixels;
  }
}

}  // namespace

SarImage RenderSar(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                   const material::MaterialTable& materials, const sensor::SarGeometry& geometry,
                   const RenderOptions& options) {
  options.Check();
  GISSAR_CHECK(mesh.classes.size() == mesh.triangle_count());
  const TracePlan plan(embree, mesh, materials, geometry, options);
  TraceAccumulator acc(plan);
  Reporter& reporter = options.reporter != nullptr ? *options.reporter : NullReporter();
  SarImage image;
  Stopwatch trace_watch;
  TraceBlocks(plan, acc, reporter);
  SplatOverflows(plan, acc);
  // Tracing phase: rays, shading, splatting and merging (not the assembly
  // of the output planes).
  image.stats.trace_seconds = trace_watch.ElapsedSeconds();
  ComposeImage(plan, acc, &image);
  Stopwatch mask_watch;
  MaskImage(plan, acc, &image);
  image.stats.mask_seconds = mask_watch.ElapsedSeconds();
  return image;
}

std::vector<PointReturn> ReflectorReturns(const EmbreeScene& embree, const std::vector<SceneReflector>& reflectors,
                                          const sensor::SarGeometry& geometry, double wavelength_m,
                                          std::optional<material::Polarization> polarization) {
  return ReflectorReturns(
      [&](const Vector3d& origin, const Vector3d& dir, double t_near, double t_far) {
        return embree.Occluded(origin.cast<float>(), dir.cast<float>(), static_cast<float>(t_near),
                               static_cast<float>(t_far));
      },
      reflectors, geometry, wavelength_m, polarization);
}

std::vector<PointReturn> ReflectorReturns(const OcclusionTest& occluded, const std::vector<SceneReflector>& reflectors,
                                          const sensor::SarGeometry& geometry, double wavelength_m,
                                          std::optional<material::Polarization> polarization) {
  std::vector<PointReturn> out;
  const double inv_pixel_area = 1.0 / (geometry.range_spacing_m() * geometry.azimuth_spacing_m());
  for (const SceneReflector& r : reflectors) {
    const Vector3d to_sensor = -geometry.RayDirectionTo(r.apex_enu);
    const double rcs = material::ReflectorRcs(r.type, r.size_m, wavelength_m, r.boresight_enu, to_sensor);
    if (!(rcs > 0.0)) continue;
    // Clear the reflector's own ground: start the visibility ray a few
    // centimetres out.
    const double far = geometry.mode() == sensor::ProjectionMode::kAffine
                           ? geometry.slant_range_m() * 2.0
                           : (geometry.SensorPosition(geometry.AlongTrack(r.apex_enu)) - r.apex_enu).norm();
    if (occluded(r.apex_enu, to_sensor, 0.05, far)) continue;
    PointReturn p;
    const Eigen::Vector2d px = geometry.Project(r.apex_enu);
    p.col = px.x();
    p.row = px.y();
    p.beta0_sum = rcs * inv_pixel_area;
    if (polarization) {
      // The channel's share of the RCS and its phase (unit matrix, roll).
      const std::complex<double> s_c =
          material::Channel(material::UnitReflectorMatrix(r.type, r.roll_rad), *polarization);
      p.beta0_sum *= std::norm(s_c);
      p.phase_offset_rad = std::norm(s_c) > 0.0 ? std::arg(s_c) : 0.0;
    }
    p.range_m = geometry.SlantRange(r.apex_enu);
    p.layer = r.type == material::ReflectorType::kPlate ? 0 : r.type == material::ReflectorType::kDihedral ? 1 : 2;
    out.push_back(p);
  }
  return out;
}

int64_t IntersectPrimaryRaysOnly(const EmbreeScene& embree, const scene::TriangleMesh& mesh,
                                 const sensor::SarGeometry& geometry, double rays_per_cell,
                                 int64_t* hits) {
  const Eigen::AlignedBox3d box = mesh.Bounds();
  const RayGrid grid = MakeRayGrid(geometry, box, rays_per_cell);
  const int height = geometry.height();
  const int k_az = std::max(1, static_cast<int>(std::lround(grid.n_az / std::max(1, height))));
  const int rows_per_block = 16 * k_az;
  const int n_blocks = (grid.n_az + rows_per_block - 1) / rows_per_block;
  std::atomic<int64_t> rays{0}, hit_count{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, n_blocks, 1), [&](const tbb::blocked_range<int>& blocks) {
    RayPacket16 packet;
    alignas(64) int valid[16];  // Embree: the valid mask of rtcIntersect16 is 64-byte aligned
    int64_t local_rays = 0, local_hits = 0;
    for (int b = blocks.begin(); b != blocks.end(); ++b) {
      const int i0 = b * rows_per_block, i1 = std::min(grid.n_az, i0 + rows_per_block);
      for (int i = i0; i < i1; ++i) {
        const double a = grid.a0 + i * grid.da;
        const Vector3d sensor = geometry.SensorPosition(a);
        for (int j0 = 0; j0 < grid.n_el; j0 += 16) {
          bool any = false;
          for (int k = 0; k < 16; ++k) {
            const int j = j0 + k;
            valid[k] = 0;
            if (j >= grid.n_el) continue;
            Vector3d origin, dir;
            double travelled;
            if (!PrimaryRayAt(geometry, grid, box, a, j, sensor, &origin, &dir, &travelled)) continue;
            packet.SetRay(k, origin.cast<float>(), dir.cast<float>());
            valid[k] = -1;
            any = true;
            ++local_rays;
          }
          if (!any) continue;
          embree.Intersect16(valid, packet, /*coherent=*/true);
          for (int k = 0; k < 16; ++k) local_hits += valid[k] != 0 && packet.triangle[k] != RayPacket16::kNoHit;
        }
      }
    }
    rays.fetch_add(local_rays, std::memory_order_relaxed);
    hit_count.fetch_add(local_hits, std::memory_order_relaxed);
  });
  if (hits != nullptr) *hits = hit_count.load();
  return rays.load();
}

}  // namespace gissar::render
