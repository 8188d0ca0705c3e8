#include "gissar/scene/gis_scene.h"

#include <geos_c.h>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <Eigen/LU>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <deque>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <unordered_map>

#include "gissar/geo/vector_io.h"
#include "gissar/util/check.h"
#include "gissar/util/error.h"
#include "gissar/util/progress.h"
#include "gissar/util/reporter.h"

namespace gissar::scene {
namespace {

using Eigen::Vector2d;

// ---------------------------------------------------------------- GEOS RAII
void GeosMessage(const char* /*fmt*/, ...) {}

class Geos {
 public:
  Geos() : ctx_(GEOS_init_r()) {
    GEOSContext_setNoticeHandler_r(ctx_, GeosMessage);
    GEOSContext_setErrorHandler_r(ctx_, GeosMessage);
  }
  ~Geos() { GEOS_finish_r(ctx_); }
  Geos(const Geos&) = delete;
  Geos& operator=(const Geos&) = delete;
  GEOSContextHandle_t ctx() const { return ctx_; }

 private:
  GEOSContextHandle_t ctx_;
};

struct GeomDeleter {
  GEOSContextHandle_t ctx;
  void operator()(GEOSGeometry* g) const {
    if (g != nullptr) GEOSGeom_destroy_r(ctx, g);
  }
};
using GeomPtr = std::unique_ptr<GEOSGeometry, GeomDeleter>;

struct PreparedDeleter {
  GEOSContextHandle_t ctx;
  void operator()(const GEOSPreparedGeometry* g) const {
    if (g != nullptr) GEOSPreparedGeom_destroy_r(ctx, g);
  }
};
using PreparedPtr = std::unique_ptr<const GEOSPreparedGeometry, PreparedDeleter>;

GeomPtr Own(const Geos& geos, GEOSGeometry* g) { return GeomPtr(g, GeomDeleter{geos.ctx()}); }

GEOSGeometry* MakeRing(const Geos& geos, const std::vector<Vector2d>& points) {
  GEOSCoordSequence* seq = GEOSCoordSeq_create_r(geos.ctx(), points.size(), 2);
  for (size_t i = 0; i < points.size(); ++i) {
    GEOSCoordSeq_setXY_r(geos.ctx(), seq, i, points[i].x(), points[i].y());
  }
  return GEOSGeom_createLinearRing_r(geos.ctx(), seq);
}

GeomPtr MakePolygon(const Geos& geos, const std::vector<std::vector<Vector2d>>& rings) {
  if (rings.empty() || rings[0].size() < 4) return nullptr;
  GEOSGeometry* shell = MakeRing(geos, rings[0]);
  if (shell == nullptr) return nullptr;
  std::vector<GEOSGeometry*> holes;
  for (size_t i = 1; i < rings.size(); ++i) {
    if (rings[i].size() < 4) continue;
    if (GEOSGeometry* h = MakeRing(geos, rings[i])) holes.push_back(h);
  }
  return Own(geos, GEOSGeom_createPolygon_r(geos.ctx(), shell, holes.data(),
                                            static_cast<unsigned>(holes.size())));
}

GeomPtr MakeLine(const Geos& geos, const std::vector<Vector2d>& points) {
  if (points.size() < 2) return nullptr;
  GEOSCoordSequence* seq = GEOSCoordSeq_create_r(geos.ctx(), points.size(), 2);
  for (size_t i = 0; i < points.size(); ++i) {
    GEOSCoordSeq_setXY_r(geos.ctx(), seq, i, points[i].x(), points[i].y());
  }
  return Own(geos, GEOSGeom_createLineString_r(geos.ctx(), seq));
}

// Polygonal part of `g` (MakeValid and intersections may add lines/points).
GeomPtr PolygonalPart(const Geos& geos, GeomPtr g) {
  if (!g) return g;
  const int type = GEOSGeomTypeId_r(geos.ctx(), g.get());
  if (type == GEOS_POLYGON || type == GEOS_MULTIPOLYGON) return g;
  if (type != GEOS_GEOMETRYCOLLECTION) return nullptr;
  std::vector<GEOSGeometry*> parts;
  for (int i = 0; i < GEOSGetNumGeometries_r(geos.ctx(), g.get()); ++i) {
    const GEOSGeometry* part = GEOSGetGeometryN_r(geos.ctx(), g.get(), i);
    const int t = GEOSGeomTypeId_r(geos.ctx(), part);
    if (t == GEOS_POLYGON || t == GEOS_MULTIPOLYGON) parts.push_back(GEOSGeom_clone_r(geos.ctx(), part));
  }
  if (parts.empty()) return nullptr;
  return Own(geos, GEOSUnaryUnion_r(geos.ctx(),
                                    GEOSGeom_createCollection_r(geos.ctx(), GEOS_GEOMETRYCOLLECTION,
                                                                parts.data(), parts.size())));
}

bool IsEmpty(const Geos& geos, const GEOSGeometry* g) {
  return g == nullptr || GEOSisEmpty_r(geos.ctx(), g) == 1;
}

// Union of many geometries (consumed).
GeomPtr UnionAll(const Geos& geos, std::vector<GeomPtr>& parts) {
  std::vector<GEOSGeometry*> raw;
  for (GeomPtr& p : parts) {
    if (p) raw.push_back(p.release());
  }
  parts.clear();
  if (raw.empty()) return nullptr;
  GeomPtr collection = Own(geos, GEOSGeom_createCollection_r(
                                     geos.ctx(), GEOS_GEOMETRYCOLLECTION, raw.data(), raw.size()));
  return PolygonalPart(geos, Own(geos, GEOSUnaryUnion_r(geos.ctx(), collection.get())));
}

void AppendRingSegments(const Geos& geos, const GEOSGeometry* ring,
                        std::vector<std::array<Vector2d, 2>>& out) {
  const GEOSCoordSequence* seq = GEOSGeom_getCoordSeq_r(geos.ctx(), ring);
  unsigned n = 0;
  GEOSCoordSeq_getSize_r(geos.ctx(), seq, &n);
  Vector2d prev;
  for (unsigned i = 0; i < n; ++i) {
    double x = 0, y = 0;
    GEOSCoordSeq_getXY_r(geos.ctx(), seq, i, &x, &y);
    const Vector2d p(x, y);
    if (i > 0 && (p - prev).norm() > 1e-9) out.push_back({prev, p});
    prev = p;
  }
}

void AppendBoundarySegments(const Geos& geos, const GEOSGeometry* g,
                            std::vector<std::array<Vector2d, 2>>& out) {
  if (IsEmpty(geos, g)) return;
  const int type = GEOSGeomTypeId_r(geos.ctx(), g);
  if (type == GEOS_LINESTRING || type == GEOS_LINEARRING) {
    AppendRingSegments(geos, g, out);
  } else if (type == GEOS_POLYGON) {
    AppendRingSegments(geos, GEOSGetExteriorRing_r(geos.ctx(), g), out);
    for (int i = 0; i < GEOSGetNumInteriorRings_r(geos.ctx(), g); ++i) {
      AppendRingSegments(geos, GEOSGetInteriorRingN_r(geos.ctx(), g, i), out);
    }
  } else if (type == GEOS_MULTIPOLYGON || type == GEOS_MULTILINESTRING ||
             type == GEOS_GEOMETRYCOLLECTION) {
    for (int i = 0; i < GEOSGetNumGeometries_r(geos.ctx(), g); ++i) {
      AppendBoundarySegments(geos, GEOSGetGeometryN_r(geos.ctx(), g, i), out);
    }
  }
}

GeomPtr MakePoint(const Geos& geos, const Vector2d& p) {
  GEOSCoordSequence* seq = GEOSCoordSeq_create_r(geos.ctx(), 1, 2);
  GEOSCoordSeq_setXY_r(geos.ctx(), seq, 0, p.x(), p.y());
  return Own(geos, GEOSGeom_createPoint_r(geos.ctx(), seq));
}

// ---------------------------------------------------------------- coastline
// Sea from coastline ways (plan M; OSM: land on the left of the way), in the
// steps of CoastlineSea below: chains merged head to tail keeping their
// direction (MergeCoastChains); an end inside the extent extended straight,
// along the direction of the chain's last 200 m, until it leaves the
// extent's bounding box (ExtendOpenEnds: the extract ends there, the coast
// goes on); the extent cut along the chains and its boundary
// (PolygonizeAlongChains); a face is sea when the coastline edges on its
// boundary have it on their right (length-weighted vote, CoastVote), land
// when on their left; faces without a coastline edge are land.

// The axis-aligned bounding box of a ring (M) and its diagonal (m).
struct PlanBox {
  Vector2d lo, hi;
  double diag = 0.0;
};

// Takes a non-empty ring; gives its bounding box.
PlanBox BoxOf(const std::vector<Vector2d>& ring) {
  PlanBox box;
  box.lo = ring[0];
  box.hi = ring[0];
  for (const Vector2d& p : ring) {
    box.lo = box.lo.cwiseMin(p);
    box.hi = box.hi.cwiseMax(p);
  }
  box.diag = (box.hi - box.lo).norm();
  return box;
}

// The vertices of a GEOS line string or linear ring, in order.
std::vector<Vector2d> LinePoints(const Geos& geos, const GEOSGeometry* line) {
  const GEOSCoordSequence* seq = GEOSGeom_getCoordSeq_r(geos.ctx(), line);
  unsigned n = 0;
  GEOSCoordSeq_getSize_r(geos.ctx(), seq, &n);
  std::vector<Vector2d> pts(n);
  for (unsigned i = 0; i < n; ++i) GEOSCoordSeq_getXY_r(geos.ctx(), seq, i, &pts[i].x(), &pts[i].y());
  return pts;
}

// Takes coastline ways (M, land on the left); gives them merged head to tail
// where one ends where another starts (GEOS's directed line merge, no way
// reversed), chains of fewer than 2 vertices dropped. Fails (nullopt) when
// no way has 2 vertices or GEOS cannot merge them.
std::optional<std::vector<std::vector<Vector2d>>> MergeCoastChains(
    const Geos& geos, const std::vector<std::vector<Vector2d>>& lines) {
  std::vector<GEOSGeometry*> raw;
  for (const auto& l : lines) {
    if (GeomPtr g = MakeLine(geos, l)) raw.push_back(g.release());
  }
  if (raw.empty()) return std::nullopt;
  GeomPtr multi = Own(geos, GEOSGeom_createCollection_r(geos.ctx(), GEOS_MULTILINESTRING, raw.data(), raw.size()));
  GeomPtr merged = Own(geos, GEOSLineMergeDirected_r(geos.ctx(), multi.get()));
  if (!merged) return std::nullopt;
  std::vector<std::vector<Vector2d>> chains;
  for (int i = 0; i < GEOSGetNumGeometries_r(geos.ctx(), merged.get()); ++i) {
    std::vector<Vector2d> pts = LinePoints(geos, GEOSGetGeometryN_r(geos.ctx(), merged.get(), i));
    if (pts.size() >= 2) chains.push_back(std::move(pts));
  }
  return chains;
}

// Distance (m) from p along unit direction d to the box's boundary, capped at
// the box's diagonal, plus 1 m so that the end lands outside.
double ExitDistance(const PlanBox& box, const Vector2d& p, const Vector2d& d) {
  double t = box.diag;
  for (int k = 0; k < 2; ++k) {
    if (d[k] > 1e-12) t = std::min(t, (box.hi[k] - p[k]) / d[k]);
    if (d[k] < -1e-12) t = std::min(t, (box.lo[k] - p[k]) / d[k]);
  }
  return std::max(t, 0.0) + 1.0;
}

// Unit vector pointing out of a chain (>= 2 vertices) at its end (from_end)
// or its start: from the vertex about 200 m back along the chain (the first
// at or beyond 200 m, else the other end) to the end vertex. Zero when those
// coincide.
Vector2d DirectionOut(const std::vector<Vector2d>& pts, bool from_end) {
  const Vector2d end = from_end ? pts.back() : pts.front();
  double length = 0.0;
  Vector2d q = end;
  for (size_t k = 1; k < pts.size() && length < 200.0; ++k) {
    const Vector2d& next = from_end ? pts[pts.size() - 1 - k] : pts[k];
    length += (next - q).norm();
    q = next;
  }
  const Vector2d d = end - q;
  return d.norm() > 0 ? Vector2d(d / d.norm()) : Vector2d(0, 0);
}

// Takes the chains, the extent (M) and its bounding box; extends each end
// of an open chain that lies inside the extent straight out of the box (a
// vertex added before the start or after the end), start first. Closed
// chains are left alone. Adds one to *extended_ends per end extended.
void ExtendOpenEnds(const Geos& geos, const GEOSGeometry* extent, const PlanBox& box,
                    std::vector<std::vector<Vector2d>>& chains, int64_t* extended_ends) {
  const PreparedPtr prepared(GEOSPrepare_r(geos.ctx(), extent), PreparedDeleter{geos.ctx()});
  auto inside = [&](const Vector2d& p) {
    GeomPtr point = MakePoint(geos, p);
    return GEOSPreparedIntersects_r(geos.ctx(), prepared.get(), point.get()) == 1;
  };
  for (auto& chain : chains) {
    if ((chain.front() - chain.back()).norm() < 1e-9) continue;
    if (inside(chain.front())) {
      const Vector2d d = DirectionOut(chain, false);
      if (d.norm() > 0) {
        chain.insert(chain.begin(), chain.front() + ExitDistance(box, chain.front(), d) * d);
        ++*extended_ends;
      }
    }
    if (inside(chain.back())) {
      const Vector2d d = DirectionOut(chain, true);
      if (d.norm() > 0) {
        chain.push_back(chain.back() + ExitDistance(box, chain.back(), d) * d);
        ++*extended_ends;
      }
    }
  }
}

// The chains' directed segments (M), hashed by the grid cells (side: the
// box's diagonal / 512, at least 1 mm) they pass through, so that a point's
// nearby segments are found without a scan.
struct CoastSegmentIndex {
  struct Segment {
    Vector2d s, t;
  };
  using Key = std::pair<int64_t, int64_t>;

  // Takes the (extended) chains and the extent's bounding box.
  CoastSegmentIndex(const std::vector<std::vector<Vector2d>>& chains, const PlanBox& box)
      : lo(box.lo), cell(std::max(box.diag / 512.0, 1e-3)) {
    for (const auto& chain : chains) {
      for (size_t k = 0; k + 1 < chain.size(); ++k) {
        if ((chain[k + 1] - chain[k]).norm() > 0) segments.push_back({chain[k], chain[k + 1]});
      }
    }
    for (size_t i = 0; i < segments.size(); ++i) {
      const Vector2d d = segments[i].t - segments[i].s;
      const int n = static_cast<int>(std::ceil(d.norm() / (0.5 * cell))) + 1;
      Key last{std::numeric_limits<int64_t>::min(), 0};
      for (int k = 0; k <= n; ++k) {
        const Key c = KeyOf(segments[i].s + (double(k) / n) * d);
        if (c == last) continue;
        last = c;
        auto& bucket = grid[c];
        if (bucket.empty() || bucket.back() != static_cast<int>(i)) bucket.push_back(static_cast<int>(i));
      }
    }
  }

  // The grid cell holding p.
  Key KeyOf(const Vector2d& p) const {
    return std::make_pair(static_cast<int64_t>(std::floor((p.x() - lo.x()) / cell)),
                          static_cast<int64_t>(std::floor((p.y() - lo.y()) / cell)));
  }

  Vector2d lo;
  double cell;
  std::vector<Segment> segments;
  std::map<Key, std::vector<int>> grid;  // cell -> segments through it, ascending
};

// Takes the extent and the (extended) chains (M); gives the faces the
// extent's boundary and the whole chains cut the plane into (the chains
// cross the boundary: noding splits both there; the parts outside are
// dangles that polygonizing drops). Fails (null) when GEOS cannot node or
// polygonize them.
GeomPtr PolygonizeAlongChains(const Geos& geos, const GEOSGeometry* extent,
                              const std::vector<std::vector<Vector2d>>& chains) {
  std::vector<GEOSGeometry*> pieces;
  pieces.push_back(GEOSBoundary_r(geos.ctx(), extent));
  for (const auto& chain : chains) {
    if (GeomPtr line = MakeLine(geos, chain)) pieces.push_back(line.release());
  }
  GeomPtr all = Own(geos, GEOSGeom_createCollection_r(geos.ctx(), GEOS_GEOMETRYCOLLECTION, pieces.data(), pieces.size()));
  GeomPtr noded = Own(geos, GEOSUnaryUnion_r(geos.ctx(), all.get()));
  if (!noded) return nullptr;
  const GEOSGeometry* noded_raw = noded.get();
  return Own(geos, GEOSPolygonize_r(geos.ctx(), &noded_raw, 1));
}

// A ring's vertices oriented counter-clockwise (want_ccw) or clockwise.
std::vector<Vector2d> OrientedRing(const Geos& geos, const GEOSGeometry* ring, bool want_ccw) {
  std::vector<Vector2d> pts = LinePoints(geos, ring);
  double area2 = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); ++i) area2 += pts[i].x() * pts[i + 1].y() - pts[i + 1].x() * pts[i].y();
  if ((area2 > 0) != want_ccw) std::reverse(pts.begin(), pts.end());
  return pts;
}

// Takes a face's rings, each with the face on its left (M); gives the
// length-weighted vote (m) of the coastline segments its edges lie on (an
// edge's midpoint within 0.1 mm of a segment near it, first such segment):
// +length where the face is on the coast's left (land), -length where on its
// right (sea). Edges on no coastline do not vote.
double CoastVote(const CoastSegmentIndex& index, const std::vector<std::vector<Vector2d>>& rings) {
  double vote = 0.0;
  for (const auto& ring : rings) {
    for (size_t k = 0; k + 1 < ring.size(); ++k) {
      const Vector2d p = ring[k], q = ring[k + 1], m = 0.5 * (p + q);
      const double len = (q - p).norm();
      if (len <= 0) continue;
      const auto centre = index.KeyOf(m);
      std::vector<int> candidates;
      for (int64_t di = -1; di <= 1; ++di) {
        for (int64_t dj = -1; dj <= 1; ++dj) {
          auto it = index.grid.find({centre.first + di, centre.second + dj});
          if (it != index.grid.end()) candidates.insert(candidates.end(), it->second.begin(), it->second.end());
        }
      }
      for (int i : candidates) {
        const Vector2d st = index.segments[i].t - index.segments[i].s;
        const double st_len = st.norm();
        const Vector2d rel = m - index.segments[i].s;
        const double along = rel.dot(st) / st_len;
        const double off = std::abs(rel.x() * st.y() - rel.y() * st.x()) / st_len;
        if (along < -1e-6 || along > st_len + 1e-6 || off > 1e-4) continue;
        vote += (q - p).dot(st) > 0 ? len : -len;  // face on the left of the coast: land
        break;
      }
    }
  }
  return vote;
}

// Takes the extent (polygon and ring, M) and the coastline ways (M, land on
// their left); gives the sea: the union of the faces voted sea (null when
// none, or when merging, noding or polygonizing fails). Adds the number of
// chain ends extended to *extended_ends (counted even when it then fails).
GeomPtr CoastlineSea(const Geos& geos, const GEOSGeometry* extent, const std::vector<Vector2d>& extent_ring,
                     const std::vector<std::vector<Vector2d>>& lines, int64_t* extended_ends) {
  const PlanBox box = BoxOf(extent_ring);
  std::optional<std::vector<std::vector<Vector2d>>> chains = MergeCoastChains(geos, lines);
  if (!chains) return nullptr;
  ExtendOpenEnds(geos, extent, box, *chains, extended_ends);
  const CoastSegmentIndex index(*chains, box);
  GeomPtr faces = PolygonizeAlongChains(geos, extent, *chains);
  if (!faces) return nullptr;
  std::vector<GeomPtr> sea_faces;
  for (int f = 0; f < GEOSGetNumGeometries_r(geos.ctx(), faces.get()); ++f) {
    const GEOSGeometry* face = GEOSGetGeometryN_r(geos.ctx(), faces.get(), f);
    // Rings with the face on their left: shell counter-clockwise, holes clockwise.
    std::vector<std::vector<Vector2d>> rings = {OrientedRing(geos, GEOSGetExteriorRing_r(geos.ctx(), face), true)};
    for (int h = 0; h < GEOSGetNumInteriorRings_r(geos.ctx(), face); ++h) {
      rings.push_back(OrientedRing(geos, GEOSGetInteriorRingN_r(geos.ctx(), face, h), false));
    }
    if (CoastVote(index, rings) < 0) sea_faces.push_back(Own(geos, GEOSGeom_clone_r(geos.ctx(), face)));
  }
  return UnionAll(geos, sea_faces);
}

}  // namespace

std::vector<uint8_t> OutsidePostMask(const geo::Dem& dem, const std::vector<uint8_t>& sea_posts) {
  if (dem.nodata_mask.empty()) return {};
  const int w = dem.width, h = dem.height;
  std::vector<uint8_t> outside(size_t(w) * h, 0);
  std::vector<size_t> stack;
  int64_t count = 0;
  auto push = [&](int c, int r) {
    const size_t i = size_t(r) * w + c;
    if (outside[i] || !dem.nodata_mask[i] || (!sea_posts.empty() && sea_posts[i])) return;
    outside[i] = 1;
    ++count;
    stack.push_back(i);
  };
  for (int c = 0; c < w; ++c) {
    push(c, 0);
    push(c, h - 1);
  }
  for (int r = 0; r < h; ++r) {
    push(0, r);
    push(w - 1, r);
  }
  while (!stack.empty()) {
    const size_t i = stack.back();
    stack.pop_back();
    const int r = static_cast<int>(i / w), c = static_cast<int>(i % w);
    if (c > 0) push(c - 1, r);
    if (c + 1 < w) push(c + 1, r);
    if (r > 0) push(c, r - 1);
    if (r + 1 < h) push(c, r + 1);
  }
  if (count == 0) outside.clear();
  return outside;
}

std::vector<uint8_t> SeaPostMask(const geo::Dem& dem, double sea_level_m) {
  const int w = dem.width, h = dem.height;
  std::vector<uint8_t> sea(size_t(w) * h, 0);
  auto low = [&](size_t i) {
    return (dem.nodata_mask.empty() || dem.nodata_mask[i] == 0) && dem.heights_m[i] <= sea_level_m;
  };
  std::deque<size_t> queue;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      if (r != 0 && r != h - 1 && c != 0 && c != w - 1) continue;
      const size_t i = size_t(r) * w + c;
      if (!sea[i] && low(i)) {
        sea[i] = 1;
        queue.push_back(i);
      }
    }
  }
  while (!queue.empty()) {
    const size_t i = queue.front();
    queue.pop_front();
    const int r = static_cast<int>(i / w), c = static_cast<int>(i % w);
    const std::pair<int, int> next[4] = {{c - 1, r}, {c + 1, r}, {c, r - 1}, {c, r + 1}};
    for (const auto& [nc, nr] : next) {
      if (nc < 0 || nr < 0 || nc >= w || nr >= h) continue;
      const size_t j = size_t(nr) * w + nc;
      if (sea[j]) continue;
      if (low(j) || dem.IsNodata(nc, nr)) {  // a void joins the sea only from a sea post
        sea[j] = 1;
        queue.push_back(j);
      }
    }
  }
  return sea;
}

int64_t MarkSeaTriangles(TriangleMesh& mesh, const std::vector<uint8_t>& sea_posts) {
  int64_t marked = 0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassDefault) continue;
    const Eigen::Vector3i tri = mesh.Triangle(t);
    if (sea_posts[size_t(tri[0])] && sea_posts[size_t(tri[1])] && sea_posts[size_t(tri[2])]) {
      mesh.classes[t] = kClassSea;
      ++marked;
    }
  }
  return marked;
}

namespace {

// Snaps constraint segments to the DEM post lattice (posts at A * (col, row)):
// an end within `tol` of a post moves onto it, and a segment passing within
// `tol` of a post is split there. Otherwise a footprint edge running through
// posts (after reprojection, a few micrometres beside them) leaves sliver
// triangles between the constraint and the posts whose rounded normals point
// anywhere and whose centroids lie on the boundary (neither inside nor
// outside). Moves boundaries by less than `tol`.
// Ends for which on_border(cell coordinates) holds snap within
// border_fraction of a cell (in cell units along each axis).
std::vector<std::array<Vector2d, 2>> SnapToPosts(const std::vector<std::array<Vector2d, 2>>& segments,
                                                 const Eigen::Matrix2d& A, int width, int height, double tol,
                                                 const std::function<bool(const Vector2d&)>& on_border,
                                                 double border_fraction) {
  const Eigen::Matrix2d inv = A.inverse();
  auto post = [&](int c, int r) { return Vector2d(A * Vector2d(c, r)); };
  auto snap_end = [&](const Vector2d& p) {
    const Vector2d cell = inv * p;
    const int c = static_cast<int>(std::lround(cell.x())), r = static_cast<int>(std::lround(cell.y()));
    if (c < 0 || r < 0 || c >= width || r >= height) return p;
    const Vector2d q = post(c, r);
    if ((q - p).norm() < tol) return q;
    if (std::abs(cell.x() - c) < border_fraction && std::abs(cell.y() - r) < border_fraction && on_border(cell)) {
      return q;
    }
    return p;
  };
  std::vector<std::array<Vector2d, 2>> out;
  out.reserve(segments.size());
  for (const auto& [a0, b0] : segments) {
    const Vector2d a = snap_end(a0), b = snap_end(b0);
    const double length = (b - a).norm();
    if (length == 0.0) continue;  // both ends on one post
    const Vector2d dir = (b - a) / length;
    const Vector2d ca = inv * a, cb = inv * b;
    const int c0 = std::max(0, static_cast<int>(std::floor(std::min(ca.x(), cb.x()))) - 1);
    const int c1 = std::min(width - 1, static_cast<int>(std::ceil(std::max(ca.x(), cb.x()))) + 1);
    const int r0 = std::max(0, static_cast<int>(std::floor(std::min(ca.y(), cb.y()))) - 1);
    const int r1 = std::min(height - 1, static_cast<int>(std::ceil(std::max(ca.y(), cb.y()))) + 1);
    std::vector<std::pair<double, Vector2d>> splits;
    if (double(c1 - c0 + 1) * double(r1 - r0 + 1) < 4e6) {
      for (int r = r0; r <= r1; ++r) {
        for (int c = c0; c <= c1; ++c) {
          const Vector2d q = post(c, r);
          const double t = (q - a).dot(dir);
          if (t <= tol || t >= length - tol) continue;
          const Vector2d d = q - a;
          if (std::abs(d.x() * dir.y() - d.y() * dir.x()) < tol) splits.emplace_back(t, q);
        }
      }
    }
    // Crossings with the lattice's column and row lines: every vertex of a
    // constraint then lies on a cell edge or inside one cell, so its edges
    // follow the DEM (bilinear heights) instead of chords across many cells
    // that leave steep slivers beside them. A crossing within `tol` of a
    // post is the post.
    for (int axis = 0; axis < 2; ++axis) {
      const double u0 = ca[axis], u1 = cb[axis];
      if (std::abs(u1 - u0) < 1e-12) continue;
      for (int k = static_cast<int>(std::floor(std::min(u0, u1))) + 1; k < std::max(u0, u1); ++k) {
        const double f = (k - u0) / (u1 - u0);
        Vector2d cell = ca + f * (cb - ca);
        cell[axis] = k;
        const double other = std::round(cell[1 - axis]);
        Vector2d q = A * cell;
        const Vector2d snapped = A * (axis == 0 ? Vector2d(k, other) : Vector2d(other, k));
        if ((snapped - q).norm() < tol) q = snapped;
        const double t = (q - a).dot(dir);
        if (t <= tol || t >= length - tol) continue;
        splits.emplace_back(t, q);
      }
    }
    std::sort(splits.begin(), splits.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    Vector2d prev = a;
    for (const auto& [t, q] : splits) {
      if ((q - prev).norm() < tol) continue;
      out.push_back({prev, q});
      prev = q;
    }
    out.push_back({prev, b});  // |b - prev| >= tol unless there was no split
  }
  return out;
}

// ---------------------------------------------------------------- CGAL
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
// DEM post index + 1; 0 for vertices inserted by constraints (CGAL
// default-constructs the info of vertices it creates).
struct PostInfo {
  int64_t post = 0;
  int ground = -1;  // index of the vertex in the ground mesh (BuildGisScene), once numbered
};
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<PostInfo, Kernel>;
using FaceBase0 = CGAL::Constrained_triangulation_face_base_2<Kernel>;
using FaceBase = CGAL::Triangulation_face_base_with_info_2<int, Kernel, FaceBase0>;  // region
using Tds = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;
using CdtPoint = Cdt::Point;

double ParseMetres(const std::string& text, bool* ok) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  std::string rest(end);
  while (!rest.empty() && rest.front() == ' ') rest.erase(rest.begin());
  // Beyond 10 km no height, width or level count is real (height=1e300 once
  // built a scene with infinite vertices): such a tag is ignored like a malformed one.
  *ok = end != text.c_str() && std::isfinite(v) && v >= 0 && v <= 1e4 && (rest.empty() || rest == "m");
  return v;
}

struct Building {
  GeomPtr footprint;
  PreparedPtr prepared;
  double height_m = 0.0;
};

}  // namespace

double BuildingHeight(const std::map<std::string, std::string>& tags, double default_height_m,
                      double level_height_m) {
  bool ok = false;
  if (auto it = tags.find("height"); it != tags.end()) {
    const double h = ParseMetres(it->second, &ok);
    if (ok && h > 0) return h;
  }
  if (auto it = tags.find("building:levels"); it != tags.end()) {
    const double levels = ParseMetres(it->second, &ok);
    if (ok && levels > 0) return levels * level_height_m;
  }
  return default_height_m;
}

double LineWidth(const std::map<std::string, std::string>& tags,
                 const std::map<std::string, double>& table, double fallback_m) {
  bool ok = false;
  if (auto it = tags.find("width"); it != tags.end()) {
    const double w = ParseMetres(it->second, &ok);
    if (ok && w > 0) return w;
  }
  for (const char* key : {"highway", "waterway"}) {
    if (auto it = tags.find(key); it != tags.end()) {
      if (auto w = table.find(it->second); w != table.end()) return w->second;
    }
  }
  return fallback_m;
}

namespace {

// ------------------------------------------------------- BuildGisScene state
// Frames: the DEM's post lattice (col, row), its map CRS (dem.crs_wkt), and
// the plan M: metres, ENU-aligned at the DEM centre, M = A * (col, row) (A =
// GisScene::planar_from_cell, the Jacobian there). Everything in 2-D below is
// in M unless said otherwise; heights are metres in the DEM's datum.

// The class region of a face or directly triangulated cell group.
struct Region {
  ClassId cls = kClassDefault;
  int building = -1;
  bool outside = false;  // beyond the valid area: not in the scene
};

// State carried from phase to phase of BuildGisScene; each member names the
// phase that fills it. Geos comes before every GEOS geometry member, so that
// they are destroyed before its context.
struct SceneBuildState {
  SceneBuildState(const geo::Dem& dem_in, const geo::LocalFrame& frame_in, const SceneConfig& config_in,
                  Reporter& reporter_in, TerrainTriangulation triangulation_in, GisScene& scene_in)
      : dem(dem_in),
        frame(frame_in),
        config(config_in),
        reporter(reporter_in),
        triangulation(triangulation_in),
        // Progress over the build's steps (stage "scene build": each vector
        // layer, the sea, the posts' triangulation, the constraints, the
        // classes); a run cancelled through the reporter (Python's Ctrl-C)
        // stops at the next step.
        progress("scene build", static_cast<int64_t>(config_in.layers.size()) + 5, reporter_in),
        scene(scene_in),
        stats(scene_in.stats),
        crs(dem_in.crs_wkt),
        W(dem_in.width),
        H(dem_in.height),
        cells_x(dem_in.width - 1),
        cells_y(dem_in.height - 1) {}

  void Say(const std::string& line) { reporter.Info("scene: " + line); }
  void Step() {
    progress.Advance(1);
    ThrowIfCancelled(reporter, "scene build");
  }

  // Inputs.
  const geo::Dem& dem;
  const geo::LocalFrame& frame;
  const SceneConfig& config;
  Reporter& reporter;
  const TerrainTriangulation triangulation;
  Stopwatch watch;
  Progress progress;
  GisScene& scene;  // the output
  GisSceneStats& stats;
  const Geos geos;
  const geo::CrsTransform crs;
  const int W, H;                // DEM posts
  const int cells_x, cells_y;    // DEM cells
  size_t CellAt(int c, int r) const { return size_t(r) * cells_x + c; }

  // SetUpPlanarFrame: A (M from (col, row)), its inverse, the smaller cell side (m).
  Eigen::Matrix2d A;
  Eigen::Matrix2d cell_from_planar;
  double cell_size_m = 0.0;
  Vector2d ToPlanar(const Vector2d& map_xy) const {
    double c = 0, r = 0;
    dem.PostFromMap(map_xy.x(), map_xy.y(), &c, &r);
    return Vector2d(A * Vector2d(c, r));
  }

  // PrepareExtent: the DEM's rectangle (ring), the valid area (polygon) and
  // the posts out of it.
  std::vector<Vector2d> extent_ring;
  GeomPtr extent;
  PreparedPtr extent_prepared;
  std::vector<uint8_t> dem_sea;  // per post: --sea auto's DEM sea, or empty
  std::vector<uint8_t> outside;  // per post: out of the scene, or empty (none)
  // A cell is in the scene when its four posts are.
  bool CellValid(int c, int r) const {
    if (outside.empty()) return true;
    const size_t i = size_t(r) * dem.width + c;
    return !outside[i] && !outside[i + 1] && !outside[i + dem.width] && !outside[i + dem.width + 1];
  }

  // ReadLayers: clipped polygons per class, buildings, coastlines.
  std::array<std::vector<GeomPtr>, kClassCount> parts;
  std::vector<Building> buildings;
  std::vector<std::vector<Vector2d>> coast_lines;  // land on the left
  std::vector<GeomPtr> islands;                     // closed coastlines: land

  // ChooseDemSea: per post, the DEM's sea when no coastline gave one, or empty.
  std::vector<uint8_t> sea_posts;
  bool CellIsSea(const Vector2d& centroid) const {
    const Vector2d cell = cell_from_planar * centroid;
    const int c = std::clamp(static_cast<int>(std::floor(cell.x())), 0, dem.width - 2);
    const int r = std::clamp(static_cast<int>(std::floor(cell.y())), 0, dem.height - 2);
    const size_t i = size_t(r) * dem.width + c;
    return sea_posts[i] && sea_posts[i + 1] && sea_posts[i + dem.width] && sea_posts[i + dem.width + 1];
  }

  // ResolveClassRegions: union per class (prepared), classes by priority.
  std::array<GeomPtr, kClassCount> unions;
  std::array<PreparedPtr, kClassCount> prepared;
  std::vector<int> order;

  // MarkCdtCells, Triangulate: the cells triangulated by the CDT, the CDT
  // (vertex info: post + 1 or 0; face info: region once flooded).
  std::vector<uint8_t> in_cdt;
  Cdt cdt;

  // FloodRegions: the regions; per directly triangulated cell its region (-1: none).
  std::vector<Region> regions;
  std::vector<int32_t> cell_region;

  // GroundVertices (then roofs, wall feet, wall crossings): vertex plan
  // positions (M) and heights (m). Vertex r * W + c is post (c, r).
  std::vector<Vector2d> planar;
  std::vector<double> heights;

  // GroupBuildings, RoofHeights: each building's block (its lowest building
  // index) and each block's roof height (m).
  std::vector<int> group;
  std::vector<double> roof_height;
  std::map<std::pair<int, int>, int> roof_index;  // (group, ground vertex) -> vertex
  std::unordered_map<int, int> foot_index;        // ground vertex -> wall foot vertex
  // The roof copy of ground vertex `ground` for block g.
  int RoofVertex(int g, int ground) {
    auto [it, inserted] = roof_index.emplace(std::make_pair(g, ground), 0);
    if (inserted) {
      it->second = static_cast<int>(planar.size());
      planar.push_back(planar[ground]);
      heights.push_back(roof_height[g]);
    }
    return it->second;
  }
  // Feet of walls on the ground: copies of the ground vertices, so that the
  // terrain's smooth shading normals (per vertex) do not reach the walls.
  int WallFoot(int ground) {
    auto [it, inserted] = foot_index.emplace(ground, 0);
    if (inserted) {
      it->second = static_cast<int>(planar.size());
      planar.push_back(planar[ground]);
      heights.push_back(heights[ground]);
    }
    return it->second;
  }

  // Emit*: triangles (vertex indices) and their classes.
  std::vector<Eigen::Vector3i> triangles;
  std::vector<ClassId> classes;
  bool column_cross_row_up = false;  // (col, row) turns counter-clockwise in M
  double cell_triangle_area_m2 = 0.0;
  // The two triangles of directly split cell (c, r) as vertex (= post)
  // indices: MeshFromGrid's, split from post (c + 1, r) to (c, r + 1) and
  // counter-clockwise in M (M is ENU-aligned: counter-clockwise seen from
  // above, normals up).
  std::array<Eigen::Vector3i, 2> CellTriangles(int c, int r) const {
    return GridCellTriangles(W, c, r, column_cross_row_up);
  }
};

// ------------------------------------------------------ extent and the posts

// Takes the DEM (posts, CRS) and the local frame; gives A =
// scene.planar_from_cell, the Jacobian of (col, row) -> ENU (x, y) in metres
// at the DEM centre, its inverse, the smaller cell side (m), the lattice's
// handedness in M and a grid triangle's area (m2).
void SetUpPlanarFrame(SceneBuildState& s) {
  const geo::Dem& dem = s.dem;
  const double c = std::floor((dem.width - 1) / 2.0), r = std::floor((dem.height - 1) / 2.0);
  std::vector<double> x, y;
  for (const auto& [dc, dr] : {std::pair{0.0, 0.0}, {1.0, 0.0}, {0.0, 1.0}}) {
    const Vector2d m = dem.MapFromPost(c + dc, r + dr);
    x.push_back(m.x());
    y.push_back(m.y());
  }
  s.crs.ToLonLat(x, y);
  const Eigen::Vector3d p0 = s.frame.EnuFromGeodetic(x[0], y[0], 0.0);
  const Eigen::Vector3d pc = s.frame.EnuFromGeodetic(x[1], y[1], 0.0);
  const Eigen::Vector3d pr = s.frame.EnuFromGeodetic(x[2], y[2], 0.0);
  s.scene.planar_from_cell.col(0) = (pc - p0).head<2>();
  s.scene.planar_from_cell.col(1) = (pr - p0).head<2>();
  s.A = s.scene.planar_from_cell;
  s.cell_from_planar = s.A.inverse();
  s.cell_size_m = std::min(s.A.col(0).norm(), s.A.col(1).norm());
  s.column_cross_row_up = s.A.determinant() > 0.0;
  s.cell_triangle_area_m2 = 0.5 * std::abs(s.A.determinant());
}

// Takes the DEM and A; gives the extent (the DEM's rectangle in M, or the
// union of its valid cells), the posts outside the scene and --sea auto's
// DEM sea posts. Valid area: DEM no-data connected to the border (a
// reprojection collar, voids on the edge) is outside the scene unless it
// joins the sea (the --sea auto rule); a cell is in the scene when its four
// posts are.
void PrepareExtent(SceneBuildState& s) {
  const geo::Dem& dem = s.dem;
  const Geos& geos = s.geos;
  const Eigen::Matrix2d& A = s.A;
  s.extent_ring = {A * Vector2d(0, 0), A * Vector2d(dem.width - 1, 0), A * Vector2d(dem.width - 1, dem.height - 1),
                   A * Vector2d(0, dem.height - 1), A * Vector2d(0, 0)};
  s.extent = MakePolygon(geos, {s.extent_ring});
  if (GEOSisValid_r(geos.ctx(), s.extent.get()) != 1) {
    s.extent = Own(geos, GEOSMakeValid_r(geos.ctx(), s.extent.get()));
  }

  s.dem_sea = s.config.sea_auto ? SeaPostMask(dem, s.config.sea_level_m) : std::vector<uint8_t>();
  s.outside = OutsidePostMask(dem, s.dem_sea);
  s.stats.outside_posts = std::count(s.outside.begin(), s.outside.end(), uint8_t{1});
  if (!s.outside.empty()) {
    // Union of row runs of valid cells.
    std::vector<GeomPtr> runs;
    for (int r = 0; r + 1 < dem.height; ++r) {
      for (int c = 0; c + 1 < dem.width;) {
        if (!s.CellValid(c, r)) {
          ++c;
          continue;
        }
        int e = c;
        while (e + 1 < dem.width && s.CellValid(e, r)) ++e;
        runs.push_back(MakePolygon(geos, {{A * Vector2d(c, r), A * Vector2d(e, r), A * Vector2d(e, r + 1),
                                           A * Vector2d(c, r + 1), A * Vector2d(c, r)}}));
        c = e;
      }
    }
    s.extent = UnionAll(geos, runs);
    if (IsEmpty(geos, s.extent.get())) throw InputError("the DEM has no valid cell", dem.source);
    s.Say(std::to_string(s.stats.outside_posts) + " no-data posts on the DEM border left out of the scene");
  }
  s.extent_prepared = PreparedPtr(GEOSPrepare_r(geos.ctx(), s.extent.get()), PreparedDeleter{geos.ctx()});
}

// ---------------------------------------------------------- vector layers

// Over-sampled outlines (mean vertex spacing under 1 % of a DEM cell, e.g.
// a polygon of 10^6 vertices) are simplified (GEOS, topology preserved)
// to 1/1000 of a cell, the tolerance of the post snapping below: the mesh
// cannot use finer detail, and the triangulation would grow with it.
// Ordinary outlines (OSM vertices metres apart) are kept as they are, so
// that neighbours sharing a wall keep identical vertices.
GeomPtr SimplifyIfOversampled(SceneBuildState& s, GeomPtr g) {
  const Geos& geos = s.geos;
  const int count = GEOSGetNumCoordinates_r(geos.ctx(), g.get());
  double length = 0.0;
  if (count < 1000 || GEOSLength_r(geos.ctx(), g.get(), &length) != 1) return g;
  if (length / count >= 0.01 * s.cell_size_m) return g;
  GeomPtr simple = Own(geos, GEOSTopologyPreserveSimplify_r(geos.ctx(), g.get(), 1e-3 * s.cell_size_m));
  if (!simple || IsEmpty(geos, simple.get())) return g;
  ++s.stats.simplified_outlines;
  return simple;
}

// A polygon's rings (map coordinates, the DEM's CRS) in M, each closed.
std::vector<std::vector<Vector2d>> PlanarRings(const SceneBuildState& s, const geo::PolygonRings& polygon) {
  std::vector<std::vector<Vector2d>> rings;
  for (const geo::Ring& ring : polygon) {
    std::vector<Vector2d> pts;
    for (const Vector2d& p : ring) pts.push_back(s.ToPlanar(p));
    if (!pts.empty() && (pts.front() - pts.back()).norm() > 0) pts.push_back(pts.front());
    rings.push_back(std::move(pts));
  }
  return rings;
}

// Takes a coastline feature (map coordinates); gives its ways to
// coast_lines (M, land on the left) and its closed rings to islands (land).
void AddCoastlineFeature(SceneBuildState& s, const geo::VectorFeature& feature) {
  const Geos& geos = s.geos;
  ++s.stats.coastline_features;
  for (const geo::LinePoints& line : feature.lines) {
    std::vector<Vector2d> pts;
    for (const Vector2d& p : line) pts.push_back(s.ToPlanar(p));
    if (pts.size() >= 2) s.coast_lines.push_back(std::move(pts));
  }
  for (const geo::PolygonRings& polygon : feature.polygons) {
    GeomPtr g = MakePolygon(geos, PlanarRings(s, polygon));
    if (g && GEOSisValid_r(geos.ctx(), g.get()) != 1) {
      g = PolygonalPart(geos, Own(geos, GEOSMakeValid_r(geos.ctx(), g.get())));
    }
    if (g) s.islands.push_back(std::move(g));
  }
}

// Takes a line or polygon feature (map coordinates); gives its polygons in
// M, unclipped: lines buffered to their width (m), invalid polygons
// repaired (counted in *repaired).
std::vector<GeomPtr> FeaturePieces(SceneBuildState& s, const LayerSpec& layer, const geo::VectorFeature& feature,
                                   int64_t* repaired) {
  const Geos& geos = s.geos;
  const SceneConfig& config = s.config;
  std::vector<GeomPtr> pieces;
  if (layer.kind == LayerKind::kLine) {
    const double width = layer.line_width_m > 0
                             ? layer.line_width_m
                             : LineWidth(feature.fields, config.line_widths_m,
                                         layer.class_id == kClassRoad ? config.default_road_width_m
                                                                      : config.default_waterway_width_m);
    for (const geo::LinePoints& line : feature.lines) {
      std::vector<Vector2d> pts;
      for (const Vector2d& p : line) pts.push_back(s.ToPlanar(p));
      GeomPtr g = MakeLine(geos, pts);
      if (!g) continue;
      pieces.push_back(Own(geos, GEOSBuffer_r(geos.ctx(), g.get(), width / 2.0, 4)));
    }
  } else {
    for (const geo::PolygonRings& polygon : feature.polygons) {
      GeomPtr g = MakePolygon(geos, PlanarRings(s, polygon));
      if (!g) {
        ++*repaired;
        continue;
      }
      if (GEOSisValid_r(geos.ctx(), g.get()) != 1) {
        ++*repaired;
        g = PolygonalPart(geos, Own(geos, GEOSMakeValid_r(geos.ctx(), g.get())));
      }
      if (g) pieces.push_back(std::move(g));
    }
  }
  return pieces;
}

// Takes a feature's pieces (M); gives them clipped to the extent (simplified
// when over-sampled, densified per config) to parts[class], and to
// buildings for a building layer. Returns whether any piece was inside.
bool AddClippedPieces(SceneBuildState& s, const LayerSpec& layer, const geo::VectorFeature& feature,
                      std::vector<GeomPtr>& pieces) {
  const Geos& geos = s.geos;
  const SceneConfig& config = s.config;
  bool any_inside = false;
  for (GeomPtr& piece : pieces) {
    if (IsEmpty(geos, piece.get())) continue;
    if (GEOSPreparedIntersects_r(geos.ctx(), s.extent_prepared.get(), piece.get()) != 1) continue;
    GeomPtr clipped = PolygonalPart(geos, Own(geos, GEOSIntersection_r(geos.ctx(), piece.get(), s.extent.get())));
    if (IsEmpty(geos, clipped.get())) continue;
    clipped = SimplifyIfOversampled(s, std::move(clipped));
    any_inside = true;
    if (config.densify_m > 0) {
      clipped = Own(geos, GEOSDensify_r(geos.ctx(), clipped.get(), config.densify_m));
    }
    if (layer.kind == LayerKind::kBuilding) {
      Building b;
      b.height_m = BuildingHeight(feature.fields, config.building_default_height_m, config.building_level_height_m);
      b.footprint = Own(geos, GEOSGeom_clone_r(geos.ctx(), clipped.get()));
      s.buildings.push_back(std::move(b));
    }
    s.parts[layer.class_id].push_back(std::move(clipped));
  }
  return any_inside;
}

// Takes the vector layers (any CRS, read in the DEM's) and the extent; gives
// clipped polygons per class (M), the buildings with their heights (m), the
// coastlines and islands, and a warning per layer with repaired or dropped
// features. One progress step per layer.
void ReadLayers(SceneBuildState& s) {
  for (const LayerSpec& layer : s.config.layers) {
    const std::vector<geo::VectorFeature> features = geo::ReadVectorLayer(layer.source, s.dem.crs_wkt);
    const std::string name = layer.source.path + ", layer " +
                             (layer.source.layer.empty() ? "(only)" : layer.source.layer);
    if (features.empty()) {
      s.scene.warnings.push_back("layer has no features: " + name);
      continue;
    }
    int64_t repaired = 0, outside = 0, used = 0;
    for (const geo::VectorFeature& feature : features) {
      ++s.stats.features_read;
      if (layer.kind == LayerKind::kCoastline) {
        if (!s.config.sea_auto) continue;
        AddCoastlineFeature(s, feature);
        ++used;
        continue;
      }
      std::vector<GeomPtr> pieces = FeaturePieces(s, layer, feature, &repaired);
      if (AddClippedPieces(s, layer, feature, pieces)) {
        ++used;
      } else {
        ++outside;
      }
    }
    s.stats.repaired_geometries += repaired;
    s.stats.features_outside += outside;
    if (repaired > 0) {
      s.scene.warnings.push_back(std::to_string(repaired) + " invalid geometries repaired (GEOS MakeValid) in " +
                                 name);
    }
    if (outside > 0) {
      s.scene.warnings.push_back(std::to_string(outside) + " features outside the DEM dropped from " + name);
    }
    s.Say(name + ": " + std::to_string(used) + " features");
    s.Step();
  }
  s.stats.buildings = static_cast<int64_t>(s.buildings.size());
}

// ------------------------------------------------------------------- sea

// Where a coastline had to be extended beyond the data, the extension is
// a guess: its sea is kept only where the DEM is low (the contour at 1 m
// above the sea level, interpolated between posts, so the shore follows
// the terrain rather than the post grid), except within 2 posts of the
// coastline as mapped, which is trusted over the DEM. Takes the sea (M);
// gives it trimmed (or null), the area removed in stats (m2).
GeomPtr TrimExtendedSea(SceneBuildState& s, GeomPtr sea) {
  const Geos& geos = s.geos;
  std::vector<GeomPtr> keep;
  for (const auto& polygon : geo::LowlandPolygons(s.dem, s.config.sea_level_m + 1.0)) {
    std::vector<std::vector<Vector2d>> rings;
    for (const geo::PostRing& ring : polygon) {
      std::vector<Vector2d> pts;
      for (const Vector2d& p : ring) pts.push_back(s.A * p);
      rings.push_back(std::move(pts));
    }
    GeomPtr g = MakePolygon(geos, rings);
    if (g && GEOSisValid_r(geos.ctx(), g.get()) != 1) {
      g = PolygonalPart(geos, Own(geos, GEOSMakeValid_r(geos.ctx(), g.get())));
    }
    if (g) keep.push_back(std::move(g));
  }
  for (const auto& line : s.coast_lines) {
    if (GeomPtr l = MakeLine(geos, line)) {
      keep.push_back(Own(geos, GEOSBuffer_r(geos.ctx(), l.get(), 2.0 * s.cell_size_m, 8)));
    }
  }
  double before = 0.0, after = 0.0;
  GEOSArea_r(geos.ctx(), sea.get(), &before);
  if (GeomPtr allowed = UnionAll(geos, keep)) {
    sea = PolygonalPart(geos, Own(geos, GEOSIntersection_r(geos.ctx(), sea.get(), allowed.get())));
  } else {
    sea = nullptr;
  }
  if (sea) GEOSArea_r(geos.ctx(), sea.get(), &after);
  s.stats.sea_trimmed_m2 = before - after;
  return sea;
}

// Sea: coastline ways closed against the extent (islands are land); else
// the DEM fallback (ChooseDemSea, per triangle after the triangulation).
// Takes coast_lines, islands and the extent (M); gives the sea polygon to
// parts[kClassSea].
void BuildCoastlineSea(SceneBuildState& s) {
  if (s.coast_lines.empty() && s.islands.empty()) return;
  const Geos& geos = s.geos;
  GeomPtr sea = s.coast_lines.empty() ? Own(geos, GEOSGeom_clone_r(geos.ctx(), s.extent.get()))
                                      : CoastlineSea(geos, s.extent.get(), s.extent_ring, s.coast_lines,
                                                     &s.stats.coastline_extended_ends);
  if (sea && !s.islands.empty()) {
    GeomPtr land = UnionAll(geos, s.islands);
    if (land) sea = PolygonalPart(geos, Own(geos, GEOSDifference_r(geos.ctx(), sea.get(), land.get())));
  }
  if (sea) sea = PolygonalPart(geos, Own(geos, GEOSIntersection_r(geos.ctx(), sea.get(), s.extent.get())));
  if (sea && s.stats.coastline_extended_ends > 0) sea = TrimExtendedSea(s, std::move(sea));
  double area = 0.0;
  if (!IsEmpty(geos, sea.get())) {
    GEOSArea_r(geos.ctx(), sea.get(), &area);
    s.parts[kClassSea].push_back(std::move(sea));
  }
  if (s.stats.coastline_extended_ends > 0) {
    s.scene.warnings.push_back(std::to_string(s.stats.coastline_extended_ends) +
                               " coastline ends inside the DEM extended straight to its edge");
  }
  s.Say("coastline: " + std::to_string(s.stats.coastline_features) + " features, sea " +
        std::to_string(area / 1e6) + " km2");
}

// --sea auto without any sea polygon: the DEM's sea posts (dem_sea) become
// sea_posts, which classify default-class triangles as sea when emitted.
void ChooseDemSea(SceneBuildState& s) {
  if (s.config.sea_auto && s.coast_lines.empty() && s.islands.empty() && s.parts[kClassSea].empty()) {
    s.sea_posts = s.dem_sea;
    s.stats.sea_from_dem = std::find(s.sea_posts.begin(), s.sea_posts.end(), 1) != s.sea_posts.end();
    if (!s.stats.sea_from_dem) s.sea_posts.clear();
  }
}

// ------------------------------------------------------ classes, buildings

// Class regions: union per class, then priority-resolved areas. Takes
// parts (consumed); gives unions (prepared), the classes in priority order
// and each class's area (m2) in stats.region_area_m2.
void ResolveClassRegions(SceneBuildState& s) {
  const Geos& geos = s.geos;
  GisSceneStats& stats = s.stats;
  for (int c = 0; c < kClassCount; ++c) {
    s.unions[c] = UnionAll(geos, s.parts[c]);
    if (s.unions[c]) {
      s.prepared[c] = PreparedPtr(GEOSPrepare_r(geos.ctx(), s.unions[c].get()), PreparedDeleter{geos.ctx()});
    }
  }
  s.order.resize(kClassCount);
  for (int c = 0; c < kClassCount; ++c) s.order[c] = c;
  std::stable_sort(s.order.begin(), s.order.end(),
                   [&](int a, int b) { return s.config.priority[a] > s.config.priority[b]; });
  GeomPtr covered;
  double covered_area = 0.0;
  for (int c : s.order) {
    if (c == kClassDefault || !s.unions[c]) continue;
    GeomPtr region = covered ? Own(geos, GEOSDifference_r(geos.ctx(), s.unions[c].get(), covered.get()))
                             : Own(geos, GEOSGeom_clone_r(geos.ctx(), s.unions[c].get()));
    double area = 0.0;
    if (region) GEOSArea_r(geos.ctx(), region.get(), &area);
    stats.region_area_m2[c] = area;
    covered_area += area;
    covered = covered ? Own(geos, GEOSUnion_r(geos.ctx(), covered.get(), s.unions[c].get()))
                      : Own(geos, GEOSGeom_clone_r(geos.ctx(), s.unions[c].get()));
  }
  double extent_area = 0.0;
  GEOSArea_r(geos.ctx(), s.extent.get(), &extent_area);
  stats.region_area_m2[kClassDefault] = extent_area - covered_area;
}

// ------------------------------------------------------------ constraints

// Constraints: every class and building boundary, noded together by GEOS
// (all crossings become explicit vertices), so the triangulation never has
// to construct an intersection point and every segment is exactly a chain
// of mesh edges. Takes unions, buildings and the extent (M); gives
// scene.boundary_segments (M, snapped to the posts) and the buildings'
// prepared footprints.
void NodeConstraints(SceneBuildState& s) {
  const Geos& geos = s.geos;
  const geo::Dem& dem = s.dem;
  GisScene& scene = s.scene;
  {
    std::vector<GeomPtr> boundaries;
    for (int c = 1; c < kClassCount; ++c) {
      if (s.unions[c]) boundaries.push_back(Own(geos, GEOSBoundary_r(geos.ctx(), s.unions[c].get())));
    }
    for (const Building& b : s.buildings) {
      boundaries.push_back(Own(geos, GEOSBoundary_r(geos.ctx(), b.footprint.get())));
    }
    std::vector<GEOSGeometry*> raw;
    for (GeomPtr& g : boundaries) {
      if (g) raw.push_back(g.release());
    }
    if (!raw.empty()) {
      GeomPtr all = Own(geos, GEOSGeom_createCollection_r(geos.ctx(), GEOS_GEOMETRYCOLLECTION,
                                                          raw.data(), raw.size()));
      GeomPtr noded = Own(geos, GEOSUnaryUnion_r(geos.ctx(), all.get()));
      if (!noded) throw Error("GEOS could not node the class boundaries", s.config.source);
      AppendBoundarySegments(geos, noded.get(), scene.boundary_segments);
    }
  }
  for (Building& b : s.buildings) {
    b.prepared = PreparedPtr(GEOSPrepare_r(geos.ctx(), b.footprint.get()), PreparedDeleter{geos.ctx()});
  }
  if (!s.outside.empty()) AppendBoundarySegments(geos, s.extent.get(), scene.boundary_segments);
  const double cell_m = std::min(s.A.col(0).norm(), s.A.col(1).norm());
  // Ends on the scene's border (the DEM edge or the edge of its valid
  // area: lattice lines next to a cell outside) also merge into a post
  // along the border within 5 % of a cell, so that no sliver forms there.
  auto on_border = [&](const Vector2d& cell) {
    const double tol = 1e-3;
    const bool on_col = std::abs(cell.x() - std::round(cell.x())) < tol;
    const bool on_row = std::abs(cell.y() - std::round(cell.y())) < tol;
    if (!on_col && !on_row) return false;
    const int c = static_cast<int>(std::round(cell.x())), r = static_cast<int>(std::round(cell.y()));
    if ((on_col && (c <= 0 || c >= dem.width - 1)) || (on_row && (r <= 0 || r >= dem.height - 1))) return true;
    if (s.outside.empty()) return false;
    const int fc = std::clamp(static_cast<int>(std::floor(cell.x())), 0, dem.width - 2);
    const int fr = std::clamp(static_cast<int>(std::floor(cell.y())), 0, dem.height - 2);
    if (on_col) return !s.CellValid(std::max(0, c - 1), fr) || !s.CellValid(std::min(dem.width - 2, c), fr);
    return !s.CellValid(fc, std::max(0, r - 1)) || !s.CellValid(fc, std::min(dem.height - 2, r));
  };
  scene.boundary_segments =
      SnapToPosts(scene.boundary_segments, s.A, dem.width, dem.height, 1e-3 * cell_m, on_border, 0.05);
  s.stats.constraint_segments = static_cast<int64_t>(scene.boundary_segments.size());
}

// ---------------------------------------------------------- triangulation

// Triangulation. A cell that no constraint touches lies inside one class
// region (every class and building boundary is a constraint): it is split
// directly into MeshFromGrid's two triangles (a DEM's own split; in a
// rectangular cell either diagonal is Delaunay). Only the cells that constraints touch go through
// CGAL's constrained Delaunay triangulation, with their posts, the
// constraints and the border between them and the other cells (also
// constrained), so that both parts meet edge to edge. A constraint vertex
// that splits such a border edge (a T-junction) sends the cell beyond it
// to the CDT as well, and the CDT is rebuilt. On a large DEM constraints
// touch a few percent of the cells; the CDT of every post
// (TerrainTriangulation::kEveryPost) took 3.9 GB and 30 s at 4096^2.
//
// MarkCdtCells takes the constraints (M); gives in_cdt (per cell: 1 for
// the CDT).
void MarkCdtCells(SceneBuildState& s) {
  const int cells_x = s.cells_x, cells_y = s.cells_y;
  std::vector<uint8_t>& in_cdt = s.in_cdt;
  in_cdt.assign(size_t(cells_x) * cells_y, 0);
  if (s.triangulation == TerrainTriangulation::kEveryPost) {
    for (int r = 0; r < cells_y; ++r) {
      for (int c = 0; c < cells_x; ++c) in_cdt[s.CellAt(c, r)] = s.CellValid(c, r);
    }
    return;
  }
  // Every cell whose closure a constraint comes within kTouch of (cell
  // units; the post snapping moves points by 1e-3 cell at most).
  constexpr double kTouch = 0.01;
  auto mark = [&](const Vector2d& cell) {
    const int c0 = std::max(0, static_cast<int>(std::floor(cell.x() - kTouch)));
    const int c1 = std::min(cells_x - 1, static_cast<int>(std::floor(cell.x() + kTouch)));
    const int r0 = std::max(0, static_cast<int>(std::floor(cell.y() - kTouch)));
    const int r1 = std::min(cells_y - 1, static_cast<int>(std::floor(cell.y() + kTouch)));
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) {
        if (s.CellValid(c, r)) in_cdt[s.CellAt(c, r)] = 1;
      }
    }
  };
  for (const auto& [a, b] : s.scene.boundary_segments) {
    const Vector2d ca = s.cell_from_planar * a, cb = s.cell_from_planar * b;
    // Samples at most a quarter of a cell apart (a snapped segment lies in
    // one cell; this does not rely on it).
    const int n = 1 + static_cast<int>(std::ceil(4.0 * (cb - ca).lpNorm<Eigen::Infinity>()));
    for (int k = 0; k <= n; ++k) mark(ca + (double(k) / n) * (cb - ca));
  }
}

// One CDT of the in_cdt cells: their posts (vertex info: post + 1), the
// border of those cells and the constraints (M). Returns whether a
// constraint split a border edge shared with a directly triangulated cell
// (that cell then joins in_cdt); *cdt_posts gives the posts inserted.
bool TriangulateCdtCells(SceneBuildState& s, int attempt, int64_t* cdt_posts) {
  const int W = s.W, H = s.H, cells_x = s.cells_x, cells_y = s.cells_y;
  std::vector<uint8_t>& in_cdt = s.in_cdt;
  Cdt& cdt = s.cdt;
  cdt.clear();
  int64_t cdt_cells = 0;
  for (uint8_t f : in_cdt) cdt_cells += f;
  s.stats.cdt_cells = cdt_cells;
  s.Say("triangulating " + std::to_string(cdt_cells) + " of " + std::to_string(int64_t{cells_x} * cells_y) +
        " cells (those constraints touch) with " + std::to_string(s.stats.constraint_segments) +
        " constraint segments; the other cells directly");
  // Posts of the CDT's cells; their handles by post.
  std::vector<int32_t> slot(size_t(W) * H, -1);
  std::vector<std::pair<CdtPoint, PostInfo>> posts;
  for (int r = 0; r < cells_y; ++r) {
    for (int c = 0; c < cells_x; ++c) {
      if (!in_cdt[s.CellAt(c, r)]) continue;
      for (const auto& [dc, dr] : {std::pair{0, 0}, {1, 0}, {0, 1}, {1, 1}}) slot[size_t(r + dr) * W + c + dc] = 0;
    }
  }
  for (int r = 0; r < H; ++r) {
    for (int c = 0; c < W; ++c) {
      if (slot[size_t(r) * W + c] < 0) continue;
      const Vector2d m = s.A * Vector2d(c, r);
      posts.emplace_back(CdtPoint(m.x(), m.y()), PostInfo{int64_t{r} * W + c + 1});
    }
  }
  *cdt_posts = static_cast<int64_t>(posts.size());
  cdt.insert(posts.begin(), posts.end());
  std::vector<Cdt::Vertex_handle> handle(posts.size());
  {
    int32_t next = 0;
    for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) {
      slot[size_t(v->info().post - 1)] = next;
      handle[size_t(next++)] = v;
    }
  }
  if (attempt == 0) s.Step();
  // The CDT's border: cell edges with a cell beyond that is not in the CDT
  // (a directly triangulated cell, an invalid one, or none: the DEM's edge).
  struct BorderEdge {
    int64_t a, b;  // posts
    int64_t beyond = -1;  // the directly triangulated cell beyond, or -1
  };
  std::vector<BorderEdge> border;
  auto add_border = [&](int ca, int ra, int cb, int rb, int c_beyond, int r_beyond) {
    BorderEdge e{int64_t{ra} * W + ca, int64_t{rb} * W + cb};
    if (c_beyond >= 0 && r_beyond >= 0 && c_beyond < cells_x && r_beyond < cells_y) {
      const size_t beyond = s.CellAt(c_beyond, r_beyond);
      if (in_cdt[beyond]) return;
      if (s.CellValid(c_beyond, r_beyond)) e.beyond = static_cast<int64_t>(beyond);
    }
    border.push_back(e);
  };
  for (int r = 0; r < cells_y; ++r) {
    for (int c = 0; c < cells_x; ++c) {
      if (!in_cdt[s.CellAt(c, r)]) continue;
      add_border(c, r, c + 1, r, c, r - 1);
      add_border(c, r + 1, c + 1, r + 1, c, r + 1);
      add_border(c, r, c, r + 1, c - 1, r);
      add_border(c + 1, r, c + 1, r + 1, c + 1, r);
    }
  }
  for (const BorderEdge& e : border) {
    cdt.insert_constraint(handle[size_t(slot[size_t(e.a)])], handle[size_t(slot[size_t(e.b)])]);
  }
  // Boundaries come as chains (a segment starts where the previous one
  // ended): each end is located from the previous vertex's face, so the
  // point location is a short walk and a polygon of 10^6 vertices
  // triangulates in seconds (a walk from an arbitrary face crosses the
  // fans of earlier constraints: quadratic).
  Cdt::Vertex_handle previous;
  Vector2d previous_point(std::numeric_limits<double>::quiet_NaN(), 0.0);
  for (const auto& [a, b] : s.scene.boundary_segments) {
    const Cdt::Face_handle hint = previous != Cdt::Vertex_handle() ? previous->face() : Cdt::Face_handle();
    const Cdt::Vertex_handle va = a == previous_point ? previous : cdt.insert(CdtPoint(a.x(), a.y()), hint);
    const Cdt::Vertex_handle vb = cdt.insert(CdtPoint(b.x(), b.y()), va->face());
    if (va != vb) cdt.insert_constraint(va, vb);
    previous = vb;
    previous_point = b;
  }
  // Border edges shared with a directly triangulated cell must have stayed
  // whole.
  bool split = false;
  for (const BorderEdge& e : border) {
    if (e.beyond < 0 || cdt.is_edge(handle[size_t(slot[size_t(e.a)])], handle[size_t(slot[size_t(e.b)])])) continue;
    in_cdt[size_t(e.beyond)] = 1;
    split = true;
  }
  return split;
}

// Takes in_cdt and the constraints; gives the CDT (rebuilt until no border
// edge is split), the final in_cdt and the post and cell counts in stats.
void Triangulate(SceneBuildState& s) {
  int64_t cdt_posts = 0;
  for (int attempt = 0;; ++attempt) {
    if (!TriangulateCdtCells(s, attempt, &cdt_posts)) break;
    ++s.stats.cdt_rebuilds;
    if (attempt >= 2) {
      // Never seen; the CDT of every valid cell has no such border.
      for (int r = 0; r < s.cells_y; ++r) {
        for (int c = 0; c < s.cells_x; ++c) s.in_cdt[s.CellAt(c, r)] = s.CellValid(c, r);
      }
    }
  }
  s.stats.dem_posts = int64_t{s.W} * s.H;
  s.stats.cdt_posts = cdt_posts;
  s.stats.grid_cells = 0;
  for (int r = 0; r < s.cells_y; ++r) {
    for (int c = 0; c < s.cells_x; ++c) s.stats.grid_cells += !s.in_cdt[s.CellAt(c, r)] && s.CellValid(c, r);
  }
}

// ---------------------------------------------------------------- regions

// Faces whose three vertices are DEM posts of one lattice row or column:
// along the hull the posts of a border row are collinear only up to the
// rounding of A * (col, row), and the exact predicates fill the gap with
// needle faces spanning many posts (in 3-D, curtains hanging between
// distant posts). They are not part of the scene and do not connect
// regions.
bool LatticeDegenerate(const SceneBuildState& s, Cdt::Face_handle f) {
  const geo::Dem& dem = s.dem;
  int64_t post[3];
  bool all_posts = true;
  Vector2d cell[3];
  for (int k = 0; k < 3; ++k) {
    post[k] = f->vertex(k)->info().post - 1;
    all_posts &= post[k] >= 0;
    cell[k] = s.cell_from_planar * Vector2d(f->vertex(k)->point().x(), f->vertex(k)->point().y());
  }
  if (all_posts) {
    const int64_t w = dem.width;
    if ((post[0] / w == post[1] / w && post[1] / w == post[2] / w) ||
        (post[0] % w == post[1] % w && post[1] % w == post[2] % w)) {
      return true;
    }
  }
  // All three on one border line of the DEM (with vertices inserted there).
  for (int axis = 0; axis < 2; ++axis) {
    for (const double line : {0.0, (axis == 0 ? dem.width : dem.height) - 1.0}) {
      if (std::abs(cell[0][axis] - line) < 1e-6 && std::abs(cell[1][axis] - line) < 1e-6 &&
          std::abs(cell[2][axis] - line) < 1e-6) {
        return true;
      }
    }
  }
  return false;
}

// The class region of a point (M): priority order, then the building it is in.
Region Classify(const SceneBuildState& s, const Vector2d& point_m) {
  const Geos& geos = s.geos;
  Region region;
  if (!s.outside.empty()) {
    const Vector2d cell = s.cell_from_planar * point_m;
    region.outside = !s.CellValid(std::clamp(static_cast<int>(std::floor(cell.x())), 0, s.dem.width - 2),
                                  std::clamp(static_cast<int>(std::floor(cell.y())), 0, s.dem.height - 2));
  }
  GeomPtr point = MakePoint(geos, point_m);
  for (int c : s.order) {
    if (region.outside) break;
    if (c != kClassDefault && s.prepared[c] &&
        GEOSPreparedContains_r(geos.ctx(), s.prepared[c].get(), point.get()) == 1) {
      region.cls = static_cast<ClassId>(c);
      break;
    }
  }
  if (region.cls == kClassBuilding) {
    for (size_t b = 0; b < s.buildings.size(); ++b) {
      if (GEOSPreparedContains_r(geos.ctx(), s.buildings[b].prepared.get(), point.get()) == 1) {
        region.building = static_cast<int>(b);
        break;
      }
    }
    if (region.building < 0) region.cls = kClassUrban;  // sliver between overlapping footprints
  }
  return region;
}

// Regions of the CDT: faces connected without crossing a constraint share
// a class. Face info: -1 for a face of the CDT's cells (its centroid in one
// of them: a constraint vertex comes no nearer than kTouch to the border of
// the CDT's cells, so no centroid of a face on either side lies near it),
// -2 for the rest (the directly triangulated cells, the invalid area,
// beyond the hull, needles), dropped; then the region of each -1 face.
void FloodCdtRegions(SceneBuildState& s) {
  Cdt& cdt = s.cdt;
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = -2;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (LatticeDegenerate(s, f)) {
      ++s.stats.needle_faces;
      continue;
    }
    const auto& p0 = f->vertex(0)->point();
    const auto& p1 = f->vertex(1)->point();
    const auto& p2 = f->vertex(2)->point();
    const Vector2d cell =
        s.cell_from_planar * Vector2d((p0.x() + p1.x() + p2.x()) / 3.0, (p0.y() + p1.y() + p2.y()) / 3.0);
    const int c = static_cast<int>(std::floor(cell.x())), r = static_cast<int>(std::floor(cell.y()));
    if (c >= 0 && r >= 0 && c < s.cells_x && r < s.cells_y && s.in_cdt[s.CellAt(c, r)]) f->info() = -1;
  }
  for (auto seed = cdt.finite_faces_begin(); seed != cdt.finite_faces_end(); ++seed) {
    if (seed->info() != -1) continue;
    const int id = static_cast<int>(s.regions.size());
    const auto& p0 = seed->vertex(0)->point();
    const auto& p1 = seed->vertex(1)->point();
    const auto& p2 = seed->vertex(2)->point();
    s.regions.push_back(Classify(s, Vector2d((p0.x() + p1.x() + p2.x()) / 3.0, (p0.y() + p1.y() + p2.y()) / 3.0)));
    std::deque<Cdt::Face_handle> queue{seed};
    seed->info() = id;
    while (!queue.empty()) {
      const Cdt::Face_handle f = queue.front();
      queue.pop_front();
      for (int i = 0; i < 3; ++i) {
        const Cdt::Face_handle n = f->neighbor(i);
        if (cdt.is_infinite(n) || n->info() != -1 || f->is_constrained(i)) continue;
        n->info() = id;
        queue.push_back(n);
      }
    }
  }
}

// Directly triangulated cells: connected groups (across cell edges, which
// no constraint touches) lie in one region each. Gives cell_region.
void FloodCellRegions(SceneBuildState& s) {
  const int cells_x = s.cells_x, cells_y = s.cells_y;
  const std::vector<uint8_t>& in_cdt = s.in_cdt;
  std::vector<int32_t>& cell_region = s.cell_region;
  cell_region.assign(size_t(cells_x) * cells_y, -1);
  std::vector<std::pair<int, int>> stack;
  for (int r0 = 0; r0 < cells_y; ++r0) {
    for (int c0 = 0; c0 < cells_x; ++c0) {
      if (in_cdt[s.CellAt(c0, r0)] || cell_region[s.CellAt(c0, r0)] >= 0 || !s.CellValid(c0, r0)) continue;
      const int id = static_cast<int>(s.regions.size());
      s.regions.push_back(Classify(s, s.A * Vector2d(c0 + 0.5, r0 + 0.5)));
      cell_region[s.CellAt(c0, r0)] = id;
      stack.assign(1, {c0, r0});
      while (!stack.empty()) {
        const auto [c, r] = stack.back();
        stack.pop_back();
        for (const auto& [nc, nr] : {std::pair{c - 1, r}, {c + 1, r}, {c, r - 1}, {c, r + 1}}) {
          if (nc < 0 || nr < 0 || nc >= cells_x || nr >= cells_y) continue;
          const size_t k = s.CellAt(nc, nr);
          if (in_cdt[k] || cell_region[k] >= 0 || !s.CellValid(nc, nr)) continue;
          cell_region[k] = id;
          stack.push_back({nc, nr});
        }
      }
    }
  }
}

// The region across edge i of CDT face f: its neighbour's, or across the
// CDT's border that of the directly triangulated cell beyond; -1 for none.
int RegionAcross(const SceneBuildState& s, Cdt::Face_handle f, int i) {
  const int W = s.W, cells_x = s.cells_x, cells_y = s.cells_y;
  const Cdt::Face_handle n = f->neighbor(i);
  if (!s.cdt.is_infinite(n) && n->info() >= 0) return n->info();
  const int64_t a = f->vertex(Cdt::ccw(i))->info().post - 1, b = f->vertex(Cdt::cw(i))->info().post - 1;
  if (a < 0 || b < 0) return -1;
  const int ca = static_cast<int>(a % W), ra = static_cast<int>(a / W);
  const int cb = static_cast<int>(b % W), rb = static_cast<int>(b / W);
  if (std::abs(ca - cb) + std::abs(ra - rb) != 1) return -1;
  const std::array<std::pair<int, int>, 2> beside =
      ra == rb ? std::array<std::pair<int, int>, 2>{{{std::min(ca, cb), ra - 1}, {std::min(ca, cb), ra}}}
               : std::array<std::pair<int, int>, 2>{{{ca - 1, std::min(ra, rb)}, {ca, std::min(ra, rb)}}};
  for (const auto& [c, r] : beside) {
    if (c < 0 || r < 0 || c >= cells_x || r >= cells_y || s.in_cdt[s.CellAt(c, r)]) continue;
    if (s.cell_region[s.CellAt(c, r)] >= 0) return s.cell_region[s.CellAt(c, r)];
  }
  return -1;
}

// --------------------------------------------------------------- vertices

// Vertices: ground vertices with DEM heights (m). Every DEM post first,
// row-major (vertex r * W + c: the terrain grid of the directly split
// cells, GisScene::grid), then the vertices the constraints inserted
// (bilinear DEM height); each CDT vertex's index lives in its info
// (ground). Posts of no valid cell are in no triangle; they take their DEM
// height, or when it is no-data the lowest height of the scene's posts
// (finite, and inside the scene's bounds). Gives planar (M) and heights.
void GroundVertices(SceneBuildState& s) {
  const geo::Dem& dem = s.dem;
  const SceneConfig& config = s.config;
  const int W = s.W, H = s.H;
  std::vector<uint8_t> post_used(size_t(W) * H, 0);
  for (int r = 0; r < s.cells_y; ++r) {
    for (int c = 0; c < s.cells_x; ++c) {
      if (!s.CellValid(c, r)) continue;
      for (const auto& [dc, dr] : {std::pair{0, 0}, {1, 0}, {0, 1}, {1, 1}}) post_used[size_t(r + dr) * W + c + dc] = 1;
    }
  }
  std::vector<Vector2d>& planar = s.planar;
  std::vector<double>& heights = s.heights;
  planar.resize(size_t(W) * H);
  heights.assign(size_t(W) * H, std::numeric_limits<double>::quiet_NaN());
  double lowest = std::numeric_limits<double>::infinity();
  for (int r = 0; r < H; ++r) {
    for (int c = 0; c < W; ++c) {
      const size_t post = size_t(r) * W + c;
      planar[post] = s.A * Vector2d(c, r);
      double h = dem.heights_m[post];
      // A void that joined the sea lies at sea level.
      if (!s.dem_sea.empty() && s.dem_sea[post] && !dem.nodata_mask.empty() && dem.nodata_mask[post]) {
        h = config.sea_level_m;
      }
      const bool nodata = !dem.nodata_mask.empty() && dem.nodata_mask[post] && h != config.sea_level_m;
      if (post_used[post]) {
        heights[post] = h;
        lowest = std::min(lowest, h);
      } else if (!nodata && std::isfinite(h)) {
        heights[post] = h;
      }
    }
  }
  if (!std::isfinite(lowest)) lowest = 0.0;
  for (size_t post = 0; post < heights.size(); ++post) {
    if (!post_used[post] && !std::isfinite(heights[post])) heights[post] = lowest;
  }
  std::vector<uint8_t>().swap(post_used);
  for (auto v = s.cdt.finite_vertices_begin(); v != s.cdt.finite_vertices_end(); ++v) {
    if (v->info().post > 0) {
      v->info().ground = static_cast<int>(v->info().post - 1);
      continue;
    }
    ++s.stats.inserted_vertices;
    const Vector2d m(v->point().x(), v->point().y());
    Vector2d cell = s.cell_from_planar * m;
    cell.x() = std::clamp(cell.x(), 0.0, dem.width - 1.0);
    cell.y() = std::clamp(cell.y(), 0.0, dem.height - 1.0);
    v->info().ground = static_cast<int>(planar.size());
    planar.push_back(m);
    heights.push_back(*dem.InterpolateHeight(cell.x(), cell.y()));
  }
}

// -------------------------------------------------------------- buildings

// Building groups: footprints that share a mesh edge and have the same
// height tag merge into one block (one roof, no walls between them). Gives
// group (per building: its block, the lowest building index in it).
void GroupBuildings(SceneBuildState& s) {
  std::vector<int>& group = s.group;
  group.resize(s.buildings.size());
  for (size_t b = 0; b < s.buildings.size(); ++b) group[b] = static_cast<int>(b);
  std::function<int(int)> find = [&](int b) { return group[b] == b ? b : group[b] = find(group[b]); };
  for (auto f = s.cdt.finite_faces_begin(); f != s.cdt.finite_faces_end(); ++f) {
    if (f->info() < 0) continue;
    const int b = s.regions[f->info()].building;
    if (b < 0) continue;
    for (int i = 0; i < 3; ++i) {
      const int across = RegionAcross(s, f, i);
      if (across < 0) continue;
      const int o = s.regions[across].building;
      if (o < 0 || o == b || s.buildings[o].height_m != s.buildings[b].height_m) continue;
      const int ra = find(b), rb = find(o);
      if (ra != rb) group[std::max(ra, rb)] = std::min(ra, rb);
    }
  }
  for (size_t b = 0; b < s.buildings.size(); ++b) group[b] = find(static_cast<int>(b));
  for (size_t b = 0; b < s.buildings.size(); ++b) {
    if (group[b] != static_cast<int>(b)) ++s.stats.merged_buildings;
  }
}

// Flat roof at the group's lowest ground contact + its height (OSM's
// `height` is measured from the lowest point where the building meets the
// ground). Gives roof_height (m, per block; infinite for a block with no
// face).
void RoofHeights(SceneBuildState& s) {
  const std::vector<int>& group = s.group;
  std::vector<double>& roof_height = s.roof_height;
  roof_height.assign(s.buildings.size(), std::numeric_limits<double>::infinity());
  for (auto f = s.cdt.finite_faces_begin(); f != s.cdt.finite_faces_end(); ++f) {
    if (f->info() < 0) continue;
    const Region& region = s.regions[f->info()];
    if (region.building < 0) continue;
    const int g = group[region.building];
    for (int i = 0; i < 3; ++i) roof_height[g] = std::min(roof_height[g], s.heights[f->vertex(i)->info().ground]);
  }
  for (int r = 0; r < s.cells_y; ++r) {
    for (int c = 0; c < s.cells_x; ++c) {
      const int32_t id = s.cell_region[s.CellAt(c, r)];
      if (id < 0 || s.regions[size_t(id)].building < 0) continue;
      const int g = group[s.regions[size_t(id)].building];
      for (const auto& [dc, dr] : {std::pair{0, 0}, {1, 0}, {0, 1}, {1, 1}}) {
        roof_height[g] = std::min(roof_height[g], s.heights[size_t(r + dr) * s.W + c + dc]);
      }
    }
  }
  for (size_t b = 0; b < s.buildings.size(); ++b) {
    if (group[b] == static_cast<int>(b) && std::isfinite(roof_height[b])) roof_height[b] += s.buildings[b].height_m;
  }
}

// ---------------------------------------------------------------- triangles

// First the directly split terrain cells, row-major, on the posts: the
// mesh's terrain grid (GisScene::grid), which the ray tracer can trace as
// a height field with the other cells as holes. Default-class cells on the
// DEM's sea become sea; areas (m2) go to stats.
void EmitGridCells(SceneBuildState& s) {
  GisSceneStats& stats = s.stats;
  {
    const size_t expected = size_t(2 * stats.grid_cells) + size_t(s.cdt.number_of_faces()) + size_t(1024);
    s.triangles.reserve(expected);
    s.classes.reserve(expected);
  }
  for (int r = 0; r < s.cells_y; ++r) {
    for (int c = 0; c < s.cells_x; ++c) {
      const int32_t id = s.cell_region[s.CellAt(c, r)];
      if (id < 0 || s.regions[size_t(id)].building >= 0) continue;
      ClassId cls = s.regions[size_t(id)].cls;
      if (cls == kClassDefault && !s.sea_posts.empty() && s.CellIsSea(s.A * Vector2d(c + 0.5, r + 0.5))) {
        cls = kClassSea;
        stats.region_area_m2[kClassDefault] -= 2.0 * s.cell_triangle_area_m2;
        stats.region_area_m2[kClassSea] += 2.0 * s.cell_triangle_area_m2;
      }
      stats.mesh_area_m2[cls] += 2.0 * s.cell_triangle_area_m2;
      for (const Eigen::Vector3i& t : s.CellTriangles(c, r)) {
        s.triangles.push_back(t);
        s.classes.push_back(cls);
      }
      ++s.scene.grid.cells;
    }
  }
  s.scene.grid.width = s.W;
  s.scene.grid.height = s.H;
}

// A wall triangle, ordered so that the horizontal part of its normal
// (computed in double precision from the plan coordinates and heights)
// points along `out` (a plan direction), or against it when `facing_out`
// is false. Vertical extent below 1 mm: dropped.
void AddWall(SceneBuildState& s, int p, int q, int r, const Vector2d& out, bool facing_out) {
  const std::vector<Vector2d>& planar = s.planar;
  const std::vector<double>& heights = s.heights;
  const Eigen::Vector3d a(planar[p].x(), planar[p].y(), heights[p]);
  const Eigen::Vector3d b(planar[q].x(), planar[q].y(), heights[q]);
  const Eigen::Vector3d c(planar[r].x(), planar[r].y(), heights[r]);
  const Eigen::Vector3d n = (b - a).cross(c - a);
  if (n.norm() < 1e-6) return;
  const double along = n.x() * out.x() + n.y() * out.y();
  s.triangles.push_back((along > 0) == facing_out ? Eigen::Vector3i(p, q, r) : Eigen::Vector3i(p, r, q));
  s.classes.push_back(kClassBuilding);
}

// The wall of edge a -> b (plan, counter-clockwise around its footprint:
// the footprint lies to the left) from the bottom vertices to the top
// vertices at ground vertices a and b. Where the bottom is above the top
// (ground higher than the roof on a slope) that section is the side of a
// pit and faces into the footprint; the edge is split where they cross.
void AddEdgeWalls(SceneBuildState& s, int a, int b, int bottom_a, int bottom_b, int top_a, int top_b) {
  std::vector<Vector2d>& planar = s.planar;
  std::vector<double>& heights = s.heights;
  const Vector2d d = planar[b] - planar[a];
  const Vector2d out(d.y(), -d.x());  // right of a -> b
  const double ha = heights[top_a] - heights[bottom_a], hb = heights[top_b] - heights[bottom_b];
  if (ha >= 0 && hb >= 0) {
    AddWall(s, bottom_a, bottom_b, top_b, out, true);
    AddWall(s, bottom_a, top_b, top_a, out, true);
    return;
  }
  if (ha <= 0 && hb <= 0) {
    s.stats.buried_wall_triangles += 2;
    AddWall(s, bottom_a, bottom_b, top_b, out, false);
    AddWall(s, bottom_a, top_b, top_a, out, false);
    return;
  }
  // Crossing at fraction f along a -> b: one vertex on the top surface.
  const double f = ha / (ha - hb);
  const int c = static_cast<int>(planar.size());
  planar.push_back(planar[a] + f * d);
  heights.push_back(heights[top_a] + f * (heights[top_b] - heights[top_a]));
  ++s.stats.buried_wall_triangles;
  AddWall(s, bottom_a, c, top_a, out, ha > 0);
  AddWall(s, c, bottom_b, top_b, out, hb > 0);
}

// The CDT's faces in CGAL's order: terrain faces on the ground vertices
// (default class on the DEM's sea becomes sea), building faces as roofs
// on their block's roof copies with walls along the edges to the ground or
// to a lower block. Faces outside the scene and terrain slivers narrower
// than 10 micrometres are dropped; areas (m2) go to stats.
void EmitCdtFaces(SceneBuildState& s) {
  GisSceneStats& stats = s.stats;
  const std::vector<Vector2d>& planar = s.planar;
  for (auto f = s.cdt.finite_faces_begin(); f != s.cdt.finite_faces_end(); ++f) {
    if (f->info() < 0) {
      ++stats.dropped_faces;
      continue;
    }
    const Region& region = s.regions[f->info()];
    if (region.outside) {
      ++stats.dropped_faces;
      continue;
    }
    int g[3];
    for (int i = 0; i < 3; ++i) g[i] = f->vertex(i)->info().ground;
    const double area =
        0.5 * std::abs((planar[g[1]] - planar[g[0]]).x() * (planar[g[2]] - planar[g[0]]).y() -
                       (planar[g[1]] - planar[g[0]]).y() * (planar[g[2]] - planar[g[0]]).x());
    // Rounding slivers: no visible surface, arbitrary normals (a building's
    // sliver still has its walls).
    double longest = 0.0;
    for (int k = 0; k < 3; ++k) longest = std::max(longest, (planar[g[k]] - planar[g[(k + 1) % 3]]).norm());
    const bool sliver = 2.0 * area < 1e-5 * longest;  // narrower than 10 micrometres
    if (sliver) ++stats.sliver_faces;
    if (sliver && region.building < 0) continue;
    if (region.building < 0) {
      ClassId cls = region.cls;
      if (cls == kClassDefault && !s.sea_posts.empty() &&
          s.CellIsSea((planar[g[0]] + planar[g[1]] + planar[g[2]]) / 3.0)) {
        cls = kClassSea;
        stats.region_area_m2[kClassDefault] -= area;
        stats.region_area_m2[kClassSea] += area;
      }
      stats.mesh_area_m2[cls] += area;
      s.triangles.emplace_back(g[0], g[1], g[2]);
      s.classes.push_back(cls);
      continue;
    }
    stats.mesh_area_m2[region.cls] += area;
    const int own = s.group[region.building];
    if (!sliver) {
      s.triangles.emplace_back(s.RoofVertex(own, g[0]), s.RoofVertex(own, g[1]), s.RoofVertex(own, g[2]));
      s.classes.push_back(kClassBuilding);
    }
    for (int i = 0; i < 3; ++i) {
      // CGAL faces are counter-clockwise in M (ENU-aligned): edge i runs
      // ccw(i) -> cw(i) with this face on its left.
      const int a = g[Cdt::ccw(i)], b = g[Cdt::cw(i)];
      const int across = RegionAcross(s, f, i);
      const int other = across < 0 || s.regions[across].building < 0 ? -1 : s.group[s.regions[across].building];
      if (other == own) continue;
      if (other < 0) {
        AddEdgeWalls(s, a, b, s.WallFoot(a), s.WallFoot(b), s.RoofVertex(own, a), s.RoofVertex(own, b));
      } else if (s.roof_height[other] < s.roof_height[own]) {
        // A step between touching blocks: only the part above the lower
        // roof, on the higher block's side (the lower block emits nothing).
        ++stats.step_walls;
        AddEdgeWalls(s, a, b, s.RoofVertex(other, a), s.RoofVertex(other, b), s.RoofVertex(own, a),
                     s.RoofVertex(own, b));
      }
    }
  }
}

// The directly split cells inside buildings: roofs (no walls: no
// footprint edge touches them). Then the triangulation and the per-cell
// tables are done with (memory for the 3-D positions).
void EmitBuildingCellRoofs(SceneBuildState& s) {
  for (int r = 0; r < s.cells_y; ++r) {
    for (int c = 0; c < s.cells_x; ++c) {
      const int32_t id = s.cell_region[s.CellAt(c, r)];
      if (id < 0 || s.regions[size_t(id)].building < 0) continue;
      const Region& region = s.regions[size_t(id)];
      const int own = s.group[region.building];
      s.stats.mesh_area_m2[region.cls] += 2.0 * s.cell_triangle_area_m2;
      for (const Eigen::Vector3i& t : s.CellTriangles(c, r)) {
        s.triangles.emplace_back(s.RoofVertex(own, t[0]), s.RoofVertex(own, t[1]), s.RoofVertex(own, t[2]));
        s.classes.push_back(kClassBuilding);
      }
    }
  }
  s.cdt.clear();
  std::vector<uint8_t>().swap(s.in_cdt);
  std::vector<int32_t>().swap(s.cell_region);
}

// ------------------------------------------------------ sealing and 3-D

// The sea surface lies at the sea level: DEM heights over the sea (SRTM's
// noise, filled voids, a cliff smoothed over the 90 m posts) are not its
// shape, and tilted sea facets would glint. The shore as mapped (the
// vertices a sea face shares with the land) is at the sea level too,
// except where that would stand a terrain face steeper than 75 degrees (a
// DEM post high on a cliff a few metres from the mapped shore): such
// vertices keep their DEM height, repeated until no face is that steep
// (each round only restores heights, so it ends at worst where it began).
// Takes and gives heights (m).
void SealSeaSurface(SceneBuildState& s) {
  const double sea_level_m = s.config.sea_level_m;
  const std::vector<Eigen::Vector3i>& triangles = s.triangles;
  const std::vector<ClassId>& classes = s.classes;
  const std::vector<Vector2d>& planar = s.planar;
  std::vector<double>& heights = s.heights;
  std::vector<uint8_t> lowered(heights.size(), 0);
  const std::vector<double> dem_heights = heights;
  for (size_t t = 0; t < triangles.size(); ++t) {
    if (classes[t] != kClassSea) continue;
    for (int k = 0; k < 3; ++k) {
      const size_t v = size_t(triangles[t][k]);
      if (heights[v] != sea_level_m) {
        heights[v] = sea_level_m;
        lowered[v] = 1;
      }
    }
  }
  const double tan_max = std::tan(75.0 * M_PI / 180.0);
  for (bool changed = true; changed;) {
    changed = false;
    for (size_t t = 0; t < triangles.size(); ++t) {
      if (classes[t] == kClassBuilding) continue;
      const Eigen::Vector3i& tri = triangles[t];
      if (!lowered[tri[0]] && !lowered[tri[1]] && !lowered[tri[2]]) continue;
      const Vector2d e1 = planar[tri[1]] - planar[tri[0]], e2 = planar[tri[2]] - planar[tri[0]];
      const double dh1 = heights[tri[1]] - heights[tri[0]], dh2 = heights[tri[2]] - heights[tri[0]];
      // Normal (e1, dh1) x (e2, dh2): horizontal part over vertical part = tan(slope).
      const double nz = e1.x() * e2.y() - e1.y() * e2.x();
      const Vector2d nxy(e1.y() * dh2 - dh1 * e2.y(), dh1 * e2.x() - e1.x() * dh2);
      if (nxy.norm() <= tan_max * std::abs(nz)) continue;
      for (int k = 0; k < 3; ++k) {
        if (!lowered[tri[k]]) continue;
        heights[tri[k]] = dem_heights[tri[k]];
        lowered[tri[k]] = 0;
        changed = true;
      }
    }
  }
  s.stats.sea_level_vertices = std::count(lowered.begin(), lowered.end(), 1);
}

// 3-D positions: cell -> map -> WGS84 -> ENU at the vertex height. Takes
// planar (M) and heights (m); gives scene.mesh.vertices (ENU, float).
void PlaceVertices(SceneBuildState& s) {
  const std::vector<Vector2d>& planar = s.planar;
  std::vector<double> x(planar.size()), y(planar.size());
  for (size_t i = 0; i < planar.size(); ++i) {
    const Vector2d cell = s.cell_from_planar * planar[i];
    const Vector2d map = s.dem.MapFromPost(cell.x(), cell.y());
    x[i] = map.x();
    y[i] = map.y();
  }
  s.crs.ToLonLat(x, y);
  TriangleMesh& mesh = s.scene.mesh;
  mesh.vertices.resize(planar.size());
  for (size_t i = 0; i < planar.size(); ++i) {
    mesh.vertices[i] = s.frame.EnuFromGeodetic(x[i], y[i], s.heights[i]).cast<float>();
  }
}

// Terrain slivers narrower than 10 cm in plan that stand steeper than 80
// degrees or face down once placed (three nearly collinear vertices on a
// curved bilinear cell or on Earth's curvature): dropped, a gap no radar
// pixel resolves, so that only buildings are near-vertical. Takes and
// gives triangles and classes (the grid prefix is cleared if one goes).
void DropSteepSlivers(SceneBuildState& s) {
  const std::vector<Vector2d>& planar = s.planar;
  const TriangleMesh& mesh = s.scene.mesh;
  std::vector<Eigen::Vector3i>& triangles = s.triangles;
  std::vector<ClassId>& classes = s.classes;
  const float cos80 = static_cast<float>(std::cos(80.0 * M_PI / 180.0));
  size_t kept = 0;
  for (size_t t = 0; t < triangles.size(); ++t) {
    const Eigen::Vector3i& tri = triangles[t];
    if (classes[t] != kClassBuilding) {
      const Eigen::Vector3d a = mesh.vertices[tri[0]].cast<double>();
      const Eigen::Vector3d n =
          (mesh.vertices[tri[1]].cast<double>() - a).cross(mesh.vertices[tri[2]].cast<double>() - a);
      double longest = 0.0;
      for (int k = 0; k < 3; ++k) longest = std::max(longest, (planar[tri[k]] - planar[tri[(k + 1) % 3]]).norm());
      const Vector2d e1 = planar[tri[1]] - planar[tri[0]], e2 = planar[tri[2]] - planar[tri[0]];
      const double width = std::abs(e1.x() * e2.y() - e1.y() * e2.x()) / std::max(longest, 1e-12);
      if (n.z() <= cos80 * n.norm() && width < 0.1) {
        ++s.stats.steep_slivers;
        // A grid cell's triangle (never this narrow): the mesh no longer
        // starts with the grid.
        if (t < size_t(2 * s.scene.grid.cells)) s.scene.grid = GridPrefix{};
        continue;
      }
    }
    triangles[kept] = triangles[t];
    classes[kept] = classes[t];
    ++kept;
  }
  triangles.resize(kept);
  classes.resize(kept);
}

// Moves triangles, classes and planar into the scene; gives the triangle
// counts per class and the build time in stats.
void FinishScene(SceneBuildState& s) {
  GisScene& scene = s.scene;
  TriangleMesh& mesh = scene.mesh;
  mesh.triangles = std::move(s.triangles);
  // The grid's orientation in ENU must be MeshFromGrid's (it is: M is the
  // ENU-aligned Jacobian of the grid).
  if (scene.grid.cells > 0 && !GridPrefixCells(mesh, scene.grid)) scene.grid = GridPrefix{};
  mesh.classes = std::move(s.classes);
  scene.planar = std::move(s.planar);
  for (ClassId c : mesh.classes) ++s.stats.triangles[c];
  s.stats.seconds = s.watch.ElapsedSeconds();
  s.progress.Done();
  s.Say("built " + std::to_string(mesh.triangle_count()) + " triangles in " + std::to_string(s.stats.seconds) +
        " s");
}

}  // namespace

// The recipe. Frames and units: see SceneBuildState.
GisScene BuildGisScene(const geo::Dem& dem, const geo::LocalFrame& frame,
                       const SceneConfig& config, Reporter& reporter, TerrainTriangulation triangulation) {
  GisScene scene;
  SceneBuildState s(dem, frame, config, reporter, triangulation, scene);

  // Extent and the posts inside it.
  SetUpPlanarFrame(s);
  PrepareExtent(s);
  // Classes and buildings: each layer's features cleaned (MakeValid), roads
  // and waterways buffered to their width, clipped to the extent.
  ReadLayers(s);
  // Sea: coastlines closed against the extent, else --sea auto's DEM sea.
  BuildCoastlineSea(s);
  s.Step();
  ChooseDemSea(s);
  // Class regions: union per class, areas resolved by priority.
  ResolveClassRegions(s);
  // Constraints: every class and building boundary noded by GEOS.
  NodeConstraints(s);
  // Triangulation: CGAL's constrained Delaunay triangulation of the cells
  // constraints touch; the others split directly.
  MarkCdtCells(s);
  Triangulate(s);
  s.Step();
  // Regions: classes flooded across the faces and the cells.
  FloodCdtRegions(s);
  FloodCellRegions(s);
  s.Step();
  // Vertices: ground with DEM heights; blocks of buildings and their roofs.
  GroundVertices(s);
  GroupBuildings(s);
  RoofHeights(s);
  // Triangles: terrain grid, CDT faces with roofs and walls, roofs on cells.
  EmitGridCells(s);
  EmitCdtFaces(s);
  EmitBuildingCellRoofs(s);
  // Sealing: the sea at sea level; 3-D positions; steep slivers out.
  SealSeaSurface(s);
  PlaceVertices(s);
  DropSteepSlivers(s);
  // Statistics.
  FinishScene(s);
  return scene;
}

}  // namespace gissar::scene
