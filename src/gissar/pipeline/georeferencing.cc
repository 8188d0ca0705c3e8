#include "gissar/pipeline/georeferencing.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include "gissar/geo/thin_plate_spline.h"
#include "gissar/geo/warp.h"
#include "gissar/render/profile_sweep.h"
#include "gissar/util/error.h"

namespace gissar::pipeline {
namespace {

// Steepest rise per horizontal metre over MeshFromGrid's two triangles of
// every cell of a row-major grid of finite ENU posts (+inf with a vertical
// facet).
double GridMaxGradient(const std::vector<Eigen::Vector3f>& posts, int width, int height) {
  return tbb::parallel_reduce(
      tbb::blocked_range<int>(0, height - 1, 16), 0.0,
      [&](const tbb::blocked_range<int>& rows, double best) {
        // Squared, in float (a bound: SlantRangeGeoreference keeps a margin):
        // |grad z|^2 = (nx^2 + ny^2) / nz^2 of each triangle's normal n.
        float best2 = 0.0f;
        auto offer = [&best2](float ux, float uy, float uz, float vx, float vy, float vz) {
          const float nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
          const float h2 = nx * nx + ny * ny;
          // A vertical facet (nz = 0) makes the bound infinite. (The
          // division only when the ratio may beat the best so far.)
          if (h2 > best2 * (nz * nz)) {
            best2 = std::max(best2, nz != 0.0f ? h2 / (nz * nz) : std::numeric_limits<float>::infinity());
          }
        };
        for (int r = rows.begin(); r < rows.end(); ++r) {
          const Eigen::Vector3f* row = posts.data() + size_t(r) * width;
          for (int c = 0; c + 1 < width; ++c) {
            const Eigen::Vector3f &a = row[c], &b = row[c + 1], &d = row[c + width], &e = row[c + width + 1];
            // MeshFromGrid's triangles (a, b, d) and (b, e, d).
            offer(b.x() - a.x(), b.y() - a.y(), b.z() - a.z(), d.x() - a.x(), d.y() - a.y(), d.z() - a.z());
            offer(e.x() - b.x(), e.y() - b.y(), e.z() - b.z(), d.x() - b.x(), d.y() - b.y(), d.z() - b.z());
          }
        }
        return std::max(best, 1.001 * std::sqrt(double(best2)));
      },
      [](double a, double b) { return std::max(a, b); });
}

// Lattice rows whose profiles are walked together (render::GridProfileSweep::
// ProfileLines, lockstep).
constexpr int kLatticeRowsInLockstep = 8;

}  // namespace

std::vector<sensor::KnownLatticePoint> ProfileLatticePoints(const render::GridProfileSweep& sweep,
                                                            const sensor::SarGeometry& geometry, int grid) {
  std::vector<sensor::KnownLatticePoint> out(size_t(grid) * grid);
  // Range offsets of the lattice's columns, increasing.
  std::vector<double> xl(static_cast<size_t>(grid));
  for (int i = 0; i < grid; ++i) {
    xl[size_t(i)] = (sensor::LatticePixel(geometry, grid, i, 0).x() - geometry.u0()) * geometry.range_spacing_m();
  }
  const Eigen::Vector3d& xc = geometry.scene_centre();
  const Eigen::Vector3d &h = geometry.flight_direction(), &l = geometry.look_direction(),
                        &n = geometry.range_plane_normal();
  tbb::parallel_for(tbb::blocked_range<int>(0, grid, kLatticeRowsInLockstep), [&](const tbb::blocked_range<int>& rows) {
    const int count = rows.size();
    std::vector<double> a_m(static_cast<size_t>(count));
    for (int k = 0; k < count; ++k) {
      const int j = rows.begin() + k;
      a_m[size_t(k)] = (sensor::LatticePixel(geometry, grid, 0, j).y() - geometry.v0()) * geometry.azimuth_spacing_m();
    }
    std::vector<uint8_t> ok(size_t(count), 0);
    // Per row and column: the highest crossing so far (elevation, point).
    constexpr double kNone = -std::numeric_limits<double>::infinity();
    std::vector<double> best(size_t(count) * grid, kNone);
    std::vector<render::GridProfileSweep::ProfilePoint> best_point(size_t(count) * grid);
    sweep.ProfileLines(a_m.data(), a_m.size(), ok.data(), [&](size_t k, const render::GridProfileSweep::ProfileSegment& s) {
      const double lo = std::min(s.from.xl, s.to.xl), hi = std::max(s.from.xl, s.to.xl);
      for (auto it = std::lower_bound(xl.begin(), xl.end(), lo); it != xl.end() && *it <= hi; ++it) {
        const size_t i = size_t(it - xl.begin());
        auto offer = [&](const render::GridProfileSweep::ProfilePoint& p) {
          const double elevation = sweep.Elevation(p);
          if (elevation > best[k * grid + i]) {
            best[k * grid + i] = elevation;
            best_point[k * grid + i] = p;
          }
        };
        if (s.from.xl == s.to.xl) {  // seen edge-on: both ends lie on the locus
          offer(s.from);
          offer(s.to);
          continue;
        }
        const double t = (*it - s.from.xl) / (s.to.xl - s.from.xl);
        offer({*it, s.from.e + t * (s.to.e - s.from.e), s.from.g + t * (s.to.g - s.from.g)});
      }
    });
    for (int k = 0; k < count; ++k) {
      if (!ok[size_t(k)]) continue;  // left to the march
      const int j = rows.begin() + k;
      for (int i = 0; i < grid; ++i) {
        sensor::KnownLatticePoint& node = out[size_t(j) * grid + i];
        node.known = true;
        const size_t at = size_t(k) * grid + i;
        if (best[at] == kNone) continue;  // the locus misses the terrain
        const render::GridProfileSweep::ProfilePoint& p = best_point[at];
        node.enu = xc + a_m[size_t(k)] * h + p.xl * l + p.e * n;
      }
    }
  });
  return out;
}


TerrainSurface::TerrainSurface(const Terrain& terrain) : vertices_(terrain.mesh.vertices) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  // One parallel pass for the bounds of the finite vertices (both paths need
  // the height range) and whether every vertex is finite.
  struct Bounds {
    float x_min = kInf, x_max = -kInf, y_min = kInf, y_max = -kInf, z_min = kInf, z_max = -kInf;
    bool all_finite = true;
    void Join(const Bounds& o) {
      x_min = std::min(x_min, o.x_min);
      x_max = std::max(x_max, o.x_max);
      y_min = std::min(y_min, o.y_min);
      y_max = std::max(y_max, o.y_max);
      z_min = std::min(z_min, o.z_min);
      z_max = std::max(z_max, o.z_max);
      all_finite = all_finite && o.all_finite;
    }
  };
  const Bounds bounds = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, vertices_.size(), 1 << 16), Bounds{},
      [&](const tbb::blocked_range<size_t>& range, Bounds b) {
        for (size_t i = range.begin(); i < range.end(); ++i) {
          const float x = vertices_[i].x(), y = vertices_[i].y(), z = vertices_[i].z();
          if (!std::isfinite(x + y + z)) {
            b.all_finite = false;
            continue;
          }
          b.x_min = std::min(b.x_min, x);
          b.x_max = std::max(b.x_max, x);
          b.y_min = std::min(b.y_min, y);
          b.y_max = std::max(b.y_max, y);
          b.z_min = std::min(b.z_min, z);
          b.z_max = std::max(b.z_max, z);
        }
        return b;
      },
      [](Bounds a, const Bounds& b) {
        a.Join(b);
        return a;
      });
  const double x_min = bounds.x_min, x_max = bounds.x_max, y_min = bounds.y_min, y_max = bounds.y_max;
  z_min_ = bounds.x_min <= bounds.x_max ? bounds.z_min : 1e300;
  z_max_ = bounds.x_min <= bounds.x_max ? bounds.z_max : -1e300;
  const bool all_finite = bounds.all_finite;
  if (x_min <= x_max) limits_.plan = Eigen::AlignedBox2d(Eigen::Vector2d(x_min, y_min), Eigen::Vector2d(x_max, y_max));
  const size_t cells = terrain.grid_width > 1 && terrain.grid_height > 1
                           ? size_t(terrain.grid_width - 1) * (terrain.grid_height - 1)
                           : 0;
  const bool plain_grid = cells > 0 && all_finite && vertices_.size() == size_t(terrain.grid_width) * terrain.grid_height &&
                          (terrain.mesh.triangle_count() == 0 || terrain.mesh.triangle_count() == 2 * cells);
  if (plain_grid) {
    grid_.emplace(vertices_, terrain.grid_width, terrain.grid_height, bounds.z_max);
    plain_width_ = terrain.grid_width;
    plain_height_ = terrain.grid_height;
    return;
  }
  if (terrain.mesh.triangle_count() > 0) {
    mesh_ = &terrain.mesh;
    triangle_count_ = terrain.mesh.triangle_count();
  } else if (cells > 0) {
    grid_width_ = terrain.grid_width;
    grid_height_ = terrain.grid_height;
    grid_cross_up_ = scene::GridColumnCrossRowUp(vertices_.data(), grid_width_);  // x and y only: finite
    triangle_count_ = 2 * cells;
  }
  if (triangle_count_ == 0 || x_min > x_max) {
    nx_ = ny_ = 0;
    return;
  }
  const double area = std::max((x_max - x_min) * (y_max - y_min), 1.0);
  cell_ = std::max(std::sqrt(4.0 * area / double(triangle_count_)), 1e-3);
  x0_ = x_min;
  y0_ = y_min;
  nx_ = std::max(1, int(std::ceil((x_max - x_min) / cell_)) + 1);
  ny_ = std::max(1, int(std::ceil((y_max - y_min) / cell_)) + 1);
  std::vector<uint32_t> counts(size_t(nx_) * ny_ + 1, 0);
  auto for_cells = [&](size_t t, auto&& fn) {
    const Eigen::Vector3i tri = Triangle(t);
    const auto &a = vertices_[tri[0]], &b = vertices_[tri[1]], &c = vertices_[tri[2]];
    if (!a.allFinite() || !b.allFinite() || !c.allFinite()) return;
    const int i0 = int((std::min({a.x(), b.x(), c.x()}) - x0_) / cell_);
    const int i1 = int((std::max({a.x(), b.x(), c.x()}) - x0_) / cell_);
    const int j0 = int((std::min({a.y(), b.y(), c.y()}) - y0_) / cell_);
    const int j1 = int((std::max({a.y(), b.y(), c.y()}) - y0_) / cell_);
    for (int j = std::max(j0, 0); j <= std::min(j1, ny_ - 1); ++j)
      for (int i = std::max(i0, 0); i <= std::min(i1, nx_ - 1); ++i) fn(size_t(j) * nx_ + i);
  };
  for (size_t t = 0; t < triangle_count_; ++t) for_cells(t, [&](size_t cell) { ++counts[cell + 1]; });
  for (size_t k = 1; k < counts.size(); ++k) counts[k] += counts[k - 1];
  start_ = counts;
  members_.resize(start_.back());
  std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
  for (size_t t = 0; t < triangle_count_; ++t) {
    for_cells(t, [&](size_t cell) { members_[fill[cell]++] = uint32_t(t); });
  }
}

const sensor::SurfaceLimits& TerrainSurface::limits() const {
  if (grid_) {
    std::call_once(gradient_once_,
                   [&] { limits_.max_gradient = GridMaxGradient(vertices_, plain_width_, plain_height_); });
  }
  return limits_;
}

Eigen::Vector3i TerrainSurface::Triangle(size_t t) const {
  if (mesh_ != nullptr) return mesh_->Triangle(t);
  // MeshFromGrid's triangles of the posts-only grid (the raster engine's).
  const size_t quad = t / 2;
  const int i = int(quad % (grid_width_ - 1)), j = int(quad / (grid_width_ - 1));
  return scene::GridCellTriangles(grid_width_, i, j, grid_cross_up_)[t % 2];
}

double TerrainSurface::operator()(double x, double y) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (grid_) return grid_->SurfaceHeight(x, y).value_or(nan);
  if (nx_ == 0) return nan;
  const int i = int(std::floor((x - x0_) / cell_)), j = int(std::floor((y - y0_) / cell_));
  if (i < 0 || j < 0 || i >= nx_ || j >= ny_) return nan;
  const size_t cell = size_t(j) * nx_ + i;
  double best = nan;
  for (uint32_t k = start_[cell]; k < start_[cell + 1]; ++k) {
    const Eigen::Vector3i tri = Triangle(members_[k]);
    const Eigen::Vector3d a = vertices_[tri[0]].cast<double>(), b = vertices_[tri[1]].cast<double>(),
                          c = vertices_[tri[2]].cast<double>();
    const double det = (b.y() - c.y()) * (a.x() - c.x()) + (c.x() - b.x()) * (a.y() - c.y());
    if (std::abs(det) < 1e-12) continue;  // vertical wall
    const double w0 = ((b.y() - c.y()) * (x - c.x()) + (c.x() - b.x()) * (y - c.y())) / det;
    const double w1 = ((c.y() - a.y()) * (x - c.x()) + (a.x() - c.x()) * (y - c.y())) / det;
    const double w2 = 1.0 - w0 - w1;
    const double tol = -1e-9;
    if (w0 < tol || w1 < tol || w2 < tol) continue;
    const double z = w0 * a.z() + w1 * b.z() + w2 * c.z();
    if (!(z <= best)) best = z;
  }
  return best;
}

namespace {

// The GCPs and RPCs of a grid x grid lattice of image nodes on the terrain
// (sensor::SlantRangeGeoreference). A plain DEM grid in affine mode: the
// lattices' terrain points from the terrain's profiles
// (ProfileLatticePoints), the march only for rows the profile walk refuses.
class LatticeGeoreference {
 public:
  LatticeGeoreference(const Terrain& terrain, const sensor::SarGeometry& geometry, const TerrainSurface& surface)
      : terrain_(terrain), geometry_(geometry), surface_(surface) {
    if (surface.plain_grid() && geometry.mode() == sensor::ProjectionMode::kAffine) {
      sweep_.emplace(terrain.mesh.vertices.data(), terrain.grid_width, terrain.grid_height, geometry);
    }
  }

  geo::Georeference operator()(int grid, sensor::GeoreferenceReport* lattice_report) {
    const auto height_at = [&](double x, double y) { return surface_(x, y); };
    std::vector<sensor::KnownLatticePoint> known;
    if (sweep_) known = ProfileLatticePoints(*sweep_, geometry_, grid);
    const bool all_known = !known.empty() && std::all_of(known.begin(), known.end(),
                                                          [](const sensor::KnownLatticePoint& k) { return k.known; });
    // The slope bound (a pass over the grid) only when something is marched.
    return sensor::SlantRangeGeoreference(geometry_, terrain_.frame, height_at, surface_.z_min_m(), surface_.z_max_m(),
                                          grid, lattice_report, all_known ? sensor::SurfaceLimits{} : surface_.limits(),
                                          known.empty() ? nullptr : &known);
  }

 private:
  const Terrain& terrain_;
  const sensor::SarGeometry& geometry_;
  const TerrainSurface& surface_;
  std::optional<render::GridProfileSweep> sweep_;
};

// 12 x 12 nodes; where part of the image sees no terrain (a rotated image
// around a DEM), a denser lattice until at least 100 GCPs hit it.
geo::Georeference LatticeGcps(LatticeGeoreference& lattice, sensor::GeoreferenceReport* report) {
  geo::Georeference g;
  for (int grid = 12;; grid += 4) {
    g = lattice(grid, report);
    if (g.gcps.size() >= 100 || grid >= 40) break;
  }
  return g;
}

// The terrain points of a dense lattice not in or next to layover, shadow
// or outside the footprint (`mask`, when it is the image's size): there the
// pixel-to-ground map folds and no spline can follow it.
std::vector<geo::GroundControlPoint> TpsCandidates(const std::vector<geo::GroundControlPoint>& dense_gcps,
                                                   const std::vector<uint8_t>* mask, int w, int h) {
  std::vector<geo::GroundControlPoint> candidates;
  for (const auto& p : dense_gcps) {
    bool clear = true;
    if (mask != nullptr && mask->size() == size_t(w) * h) {
      const int c = int(std::floor(p.pixel)), r = int(std::floor(p.line));
      for (int dr = -1; dr <= 1 && clear; ++dr) {
        for (int dc = -1; dc <= 1 && clear; ++dc) {
          const int cc = std::clamp(c + dc, 0, w - 1), rr = std::clamp(r + dr, 0, h - 1);
          clear = (*mask)[size_t(rr) * w + cc] == 0;
        }
      }
    }
    if (clear) candidates.push_back(p);
  }
  return candidates;
}

// How far the spline gdalwarp -tps builds through the GCPs misses each
// candidate, in metres on the ground (infinite where it gives no point). The
// spline: GDAL's interpolant, forward only and vectorised, each Measure
// extending the last one's fit (geo::IncrementalThinPlateSpline); a fit from
// scratch (geo::ThinPlateSpline), then GDAL's transformer, where that
// refuses the GCPs.
class TpsMisses {
 public:
  TpsMisses(const std::vector<geo::GroundControlPoint>& candidates, const geo::LocalFrame& frame)
      : frame_(frame), error_m_(candidates.size(), 0.0) {
    for (const auto& p : candidates) {
      pixels_.emplace_back(p.pixel, p.line);
      truth_xy_.push_back(frame.EnuFromGeodetic(p.lon_deg, p.lat_deg, 0.0).head<2>());
    }
  }

  // Throws InputError when GDAL cannot build the spline (degenerate GCPs).
  void Measure(const std::vector<geo::GroundControlPoint>& gcps) {
    const std::vector<Eigen::Vector2d> lonlat = SplineLonLat(gcps);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, pixels_.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        error_m_[i] = lonlat[i].allFinite() ? (frame_.EnuFromGeodetic(lonlat[i].x(), lonlat[i].y(), 0.0).head<2>() -
                                               truth_xy_[i]).norm()
                                            : std::numeric_limits<double>::infinity();
      }
    });
  }

  const std::vector<double>& error_m() const { return error_m_; }

 private:
  std::vector<Eigen::Vector2d> SplineLonLat(const std::vector<geo::GroundControlPoint>& gcps) {
    std::vector<Eigen::Vector2d> nodes, values;
    auto gcps_from = [&](size_t first) {
      nodes.clear();
      values.clear();
      for (size_t i = first; i < gcps.size(); ++i) {
        nodes.emplace_back(gcps[i].pixel, gcps[i].line);
        values.emplace_back(gcps[i].lon_deg, gcps[i].lat_deg);
      }
    };
    std::optional<geo::ThinPlateSpline> spline;
    if (incremental_ok_) {
      gcps_from(size_t(incremental_.node_count()));
      if (incremental_.Add(nodes, values)) spline = incremental_.Spline();
      incremental_ok_ = spline.has_value();
    }
    if (!spline) {
      gcps_from(0);
      spline = geo::ThinPlateSpline::Fit(nodes, values);
    }
    return spline ? spline->Evaluate(pixels_) : geo::TpsLonLat(gcps, pixels_);
  }

  const geo::LocalFrame& frame_;
  std::vector<Eigen::Vector2d> pixels_;
  std::vector<Eigen::Vector2d> truth_xy_;
  std::vector<double> error_m_;
  geo::IncrementalThinPlateSpline incremental_;
  bool incremental_ok_ = true;
};

// One round: the candidates the spline misses by more than tolerance_m,
// worst first, become GCPs unless within kTpsMinSeparationPx of one, up to
// kTpsMaxAddedPerRound and kMaxGcps. How many were added.
int AddWorstCandidates(std::vector<geo::GroundControlPoint>& gcps,
                       const std::vector<geo::GroundControlPoint>& candidates, const std::vector<double>& error_m,
                       double tolerance_m) {
  // Sorted only as far as the round reads (a few times the GCPs it may
  // add), the rest on demand.
  std::vector<size_t> order;
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (error_m[i] > tolerance_m) order.push_back(i);
  }
  const auto worse = [&](size_t a, size_t b) { return error_m[a] > error_m[b]; };
  size_t sorted = std::min(order.size(), size_t(8 * kTpsMaxAddedPerRound));
  std::partial_sort(order.begin(), order.begin() + std::ptrdiff_t(sorted), order.end(), worse);
  constexpr double kMinSeparation2 = kTpsMinSeparationPx * kTpsMinSeparationPx;
  int added = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    if (int(gcps.size()) >= kMaxGcps || added >= kTpsMaxAddedPerRound) break;
    if (k == sorted) {
      std::sort(order.begin() + std::ptrdiff_t(k), order.end(), worse);
      sorted = order.size();
    }
    const geo::GroundControlPoint& candidate = candidates[order[k]];
    bool far = true;
    for (const auto& q : gcps) {
      const double dx = q.pixel - candidate.pixel, dy = q.line - candidate.line;
      if (dx * dx + dy * dy < kMinSeparation2) {
        far = false;
        break;
      }
    }
    if (!far) continue;
    gcps.push_back(candidate);
    ++added;
  }
  return added;
}

}  // namespace

geo::Georeference SimulationGeoreference(const Terrain& terrain, const sensor::SarGeometry& geometry,
                                         bool refine_for_tps, sensor::GeoreferenceReport* report,
                                         const std::vector<uint8_t>* mask, TpsRefinement* refinement) {
  const TerrainSurface surface(terrain);
  LatticeGeoreference lattice(terrain, geometry, surface);
  geo::Georeference g = LatticeGcps(lattice, report);
  if (refinement != nullptr) *refinement = TpsRefinement{.enabled = refine_for_tps};
  if (!refine_for_tps) {
    if (report != nullptr) report->gcp_count = int(g.gcps.size());
    return g;
  }

  // Refinement for TPS users (gdalwarp -tps): candidate terrain points on a
  // dense lattice (about one every 3 pixels); wherever the spline through the
  // GCPs misses a candidate by more than kTpsToleranceSpacings of the finer
  // pixel spacing on the ground, the worst candidates become GCPs, a few
  // pixels apart, until none misses or kMaxGcps is reached.
  const int w = geometry.width(), h = geometry.height();
  const int dense = std::clamp(std::max(w, h) / 3, 12, kTpsCandidateLattice);
  const std::vector<geo::GroundControlPoint> candidates = TpsCandidates(lattice(dense, nullptr).gcps, mask, w, h);
  if (candidates.empty()) return g;
  const double spacing_m = std::min(geometry.range_spacing_m(), geometry.azimuth_spacing_m());
  const double tolerance_m = kTpsToleranceSpacings * spacing_m;
  TpsMisses misses(candidates, terrain.frame);
  int rounds = 0, added_total = 0;
  bool measured = false;
  for (;;) {
    try {
      misses.Measure(g.gcps);  // the errors of the GCPs as they are now
      measured = true;
    } catch (const InputError&) {
      break;  // GDAL could not build the spline (degenerate GCPs): keep what there is
    }
    if (rounds >= kTpsMaxRounds || int(g.gcps.size()) >= kMaxGcps) break;
    const int added = AddWorstCandidates(g.gcps, candidates, misses.error_m(), tolerance_m);
    if (added == 0) break;
    added_total += added;
    ++rounds;
  }
  if (refinement != nullptr && measured) {
    std::vector<double> sorted = misses.error_m();
    std::sort(sorted.begin(), sorted.end());
    refinement->candidates = int(candidates.size());
    refinement->added_gcps = added_total;
    refinement->rounds = rounds;
    refinement->tolerance_m = tolerance_m;
    refinement->max_error_m = sorted.back();
    refinement->p95_error_m = sorted[std::min(sorted.size() - 1, sorted.size() * 95 / 100)];
  }
  if (report != nullptr) report->gcp_count = int(g.gcps.size());
  return g;
}

}  // namespace gissar::pipeline
