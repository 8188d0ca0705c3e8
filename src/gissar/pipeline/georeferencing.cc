#include "gissar/pipeline/georeferencing.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gissar/geo/warp.h"
#include "gissar/util/error.h"

namespace gissar::pipeline {

TerrainSurface::TerrainSurface(const Terrain& terrain) : vertices_(terrain.mesh.vertices) {
  // One pass for the bounds of the finite vertices (both paths need the
  // height range) and whether every vertex is finite.
  double x_min = 1e300, x_max = -1e300, y_min = 1e300, y_max = -1e300;
  z_min_ = 1e300;
  z_max_ = -1e300;
  bool all_finite = true;
  for (const auto& v : vertices_) {
    if (!v.allFinite()) {
      all_finite = false;
      continue;
    }
    x_min = std::min<double>(x_min, v.x());
    x_max = std::max<double>(x_max, v.x());
    y_min = std::min<double>(y_min, v.y());
    y_max = std::max<double>(y_max, v.y());
    z_min_ = std::min<double>(z_min_, v.z());
    z_max_ = std::max<double>(z_max_, v.z());
  }
  const size_t cells = terrain.grid_width > 1 && terrain.grid_height > 1
                           ? size_t(terrain.grid_width - 1) * (terrain.grid_height - 1)
                           : 0;
  const bool plain_grid = cells > 0 && all_finite && vertices_.size() == size_t(terrain.grid_width) * terrain.grid_height &&
                          (terrain.mesh.triangles.empty() || terrain.mesh.triangles.size() == 2 * cells);
  if (plain_grid) {
    grid_.emplace(vertices_, terrain.grid_width, terrain.grid_height);
    return;
  }
  if (!terrain.mesh.triangles.empty()) {
    triangles_ = &terrain.mesh.triangles;
    triangle_count_ = terrain.mesh.triangles.size();
  } else if (cells > 0) {
    grid_width_ = terrain.grid_width;
    grid_height_ = terrain.grid_height;
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

Eigen::Vector3i TerrainSurface::Triangle(size_t t) const {
  if (triangles_ != nullptr) return (*triangles_)[t];
  const size_t quad = t / 2;
  const int i = int(quad % (grid_width_ - 1)), j = int(quad / (grid_width_ - 1));
  const int a = j * grid_width_ + i, b = a + 1, c = a + grid_width_, d = c + 1;
  return t % 2 == 0 ? Eigen::Vector3i(a, b, d) : Eigen::Vector3i(a, d, c);
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

geo::Georeference SimulationGeoreference(const Terrain& terrain, const sensor::SarGeometry& geometry,
                                         sensor::GeoreferenceReport* report, const std::vector<uint8_t>* mask,
                                         TpsRefinement* refinement) {
  const TerrainSurface surface(terrain);
  const auto height_at = [&](double x, double y) { return surface(x, y); };
  // 12 x 12 nodes; where part of the image sees no terrain (a rotated image
  // around a DEM), a denser lattice until at least 100 GCPs hit it.
  geo::Georeference g;
  for (int grid = 12;; grid += 4) {
    g = sensor::SlantRangeGeoreference(geometry, terrain.frame, height_at, surface.z_min_m(), surface.z_max_m(),
                                       grid, report);
    if (g.gcps.size() >= 100 || grid >= 40) break;
  }
  if (refinement != nullptr) *refinement = TpsRefinement{};

  // Refinement for TPS users (gdalwarp -tps): candidate terrain points on a
  // dense lattice (about one every 3 pixels); wherever the spline through the
  // GCPs misses a candidate by more than kTpsToleranceSpacings of the finer
  // pixel spacing on the ground, the worst candidates become GCPs, a few
  // pixels apart, until none misses or kMaxGcps is reached. Candidates in or
  // next to layover, shadow or outside the footprint are not used: there the
  // pixel-to-ground map folds and no spline can follow it.
  const int w = geometry.width(), h = geometry.height();
  const int dense = std::clamp(std::max(w, h) / 3, 12, kTpsCandidateLattice);
  const std::vector<geo::GroundControlPoint> lattice =
      sensor::SlantRangeGeoreference(geometry, terrain.frame, height_at, surface.z_min_m(), surface.z_max_m(), dense)
          .gcps;
  std::vector<geo::GroundControlPoint> candidates;
  for (const auto& p : lattice) {
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
  if (candidates.empty()) return g;
  const double spacing_m = std::min(geometry.range_spacing_m(), geometry.azimuth_spacing_m());
  const double tolerance_m = kTpsToleranceSpacings * spacing_m;
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector2d> truth_xy;
  for (const auto& p : candidates) {
    pixels.emplace_back(p.pixel, p.line);
    truth_xy.push_back(terrain.frame.EnuFromGeodetic(p.lon_deg, p.lat_deg, 0.0).head<2>());
  }
  std::vector<double> error_m(candidates.size(), 0.0);
  auto measure = [&] {
    const std::vector<Eigen::Vector2d> lonlat = geo::TpsLonLat(g.gcps, pixels);
    for (size_t i = 0; i < candidates.size(); ++i) {
      error_m[i] = lonlat[i].allFinite()
                       ? (terrain.frame.EnuFromGeodetic(lonlat[i].x(), lonlat[i].y(), 0.0).head<2>() - truth_xy[i]).norm()
                       : std::numeric_limits<double>::infinity();
    }
  };
  int rounds = 0, added_total = 0;
  bool measured = false;
  for (;;) {
    try {
      measure();  // the errors of the GCPs as they are now
      measured = true;
    } catch (const InputError&) {
      break;  // GDAL could not build the spline (degenerate GCPs): keep what there is
    }
    if (rounds >= kTpsMaxRounds || int(g.gcps.size()) >= kMaxGcps) break;
    std::vector<size_t> order(candidates.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return error_m[a] > error_m[b]; });
    int added = 0;
    for (size_t i : order) {
      if (!(error_m[i] > tolerance_m) || int(g.gcps.size()) >= kMaxGcps || added >= kTpsMaxAddedPerRound) break;
      bool far = true;
      for (const auto& q : g.gcps) {
        if (std::hypot(q.pixel - candidates[i].pixel, q.line - candidates[i].line) < kTpsMinSeparationPx) {
          far = false;
          break;
        }
      }
      if (!far) continue;
      g.gcps.push_back(candidates[i]);
      ++added;
    }
    if (added == 0) break;
    added_total += added;
    ++rounds;
  }
  if (refinement != nullptr && measured) {
    std::vector<double> sorted = error_m;
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
