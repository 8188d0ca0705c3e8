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
#include <map>
#include <memory>
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

// ---------------------------------------------------------------- CGAL
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
// DEM post index + 1; 0 for vertices inserted by constraints (CGAL
// default-constructs the info of vertices it creates).
struct PostInfo {
  int64_t post = 0;
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

GisScene BuildGisScene(const geo::Dem& dem, const geo::LocalFrame& frame,
                       const SceneConfig& config, Reporter& reporter) {
  Stopwatch watch;
  auto say = [&](const std::string& line) { reporter.Info("scene: " + line); };
  GisScene scene;
  GisSceneStats& stats = scene.stats;
  const Geos geos;

  // Planar frame M: Jacobian of (col, row) -> ENU (x, y) at the DEM centre.
  const geo::CrsTransform crs(dem.crs_wkt);
  {
    const double c = std::floor((dem.width - 1) / 2.0), r = std::floor((dem.height - 1) / 2.0);
    std::vector<double> x, y;
    for (const auto& [dc, dr] : {std::pair{0.0, 0.0}, {1.0, 0.0}, {0.0, 1.0}}) {
      const Vector2d m = dem.MapFromPost(c + dc, r + dr);
      x.push_back(m.x());
      y.push_back(m.y());
    }
    crs.ToLonLat(x, y);
    const Eigen::Vector3d p0 = frame.EnuFromGeodetic(x[0], y[0], 0.0);
    const Eigen::Vector3d pc = frame.EnuFromGeodetic(x[1], y[1], 0.0);
    const Eigen::Vector3d pr = frame.EnuFromGeodetic(x[2], y[2], 0.0);
    scene.planar_from_cell.col(0) = (pc - p0).head<2>();
    scene.planar_from_cell.col(1) = (pr - p0).head<2>();
  }
  const Eigen::Matrix2d A = scene.planar_from_cell;
  const Eigen::Matrix2d cell_from_planar = A.inverse();
  auto to_planar = [&](const Vector2d& map_xy) {
    double c = 0, r = 0;
    dem.PostFromMap(map_xy.x(), map_xy.y(), &c, &r);
    return Vector2d(A * Vector2d(c, r));
  };
  const std::vector<Vector2d> extent_ring = {A * Vector2d(0, 0), A * Vector2d(dem.width - 1, 0),
                                             A * Vector2d(dem.width - 1, dem.height - 1),
                                             A * Vector2d(0, dem.height - 1), A * Vector2d(0, 0)};
  GeomPtr extent = MakePolygon(geos, {extent_ring});
  if (GEOSisValid_r(geos.ctx(), extent.get()) != 1) extent = Own(geos, GEOSMakeValid_r(geos.ctx(), extent.get()));
  const PreparedPtr extent_prepared(GEOSPrepare_r(geos.ctx(), extent.get()), PreparedDeleter{geos.ctx()});

  // Vector layers -> clipped polygons per class (and individual buildings).
  std::array<std::vector<GeomPtr>, kClassCount> parts;
  std::vector<Building> buildings;
  for (const LayerSpec& layer : config.layers) {
    const std::vector<geo::VectorFeature> features =
        geo::ReadVectorLayer(layer.source, dem.crs_wkt);
    const std::string name = layer.source.path + ", layer " +
                             (layer.source.layer.empty() ? "(only)" : layer.source.layer);
    if (features.empty()) {
      scene.warnings.push_back("layer has no features: " + name);
      continue;
    }
    int64_t repaired = 0, outside = 0, used = 0;
    for (const geo::VectorFeature& feature : features) {
      ++stats.features_read;
      std::vector<GeomPtr> pieces;
      if (layer.kind == LayerKind::kLine) {
        const double width = layer.line_width_m > 0
                                 ? layer.line_width_m
                                 : LineWidth(feature.fields, config.line_widths_m,
                                             layer.class_id == kClassRoad ? config.default_road_width_m
                                                                          : config.default_waterway_width_m);
        for (const geo::LinePoints& line : feature.lines) {
          std::vector<Vector2d> pts;
          for (const Vector2d& p : line) pts.push_back(to_planar(p));
          GeomPtr g = MakeLine(geos, pts);
          if (!g) continue;
          pieces.push_back(Own(geos, GEOSBuffer_r(geos.ctx(), g.get(), width / 2.0, 4)));
        }
      } else {
        for (const geo::PolygonRings& polygon : feature.polygons) {
          std::vector<std::vector<Vector2d>> rings;
          for (const geo::Ring& ring : polygon) {
            std::vector<Vector2d> pts;
            for (const Vector2d& p : ring) pts.push_back(to_planar(p));
            if (!pts.empty() && (pts.front() - pts.back()).norm() > 0) pts.push_back(pts.front());
            rings.push_back(std::move(pts));
          }
          GeomPtr g = MakePolygon(geos, rings);
          if (!g) {
            ++repaired;
            continue;
          }
          if (GEOSisValid_r(geos.ctx(), g.get()) != 1) {
            ++repaired;
            g = PolygonalPart(geos, Own(geos, GEOSMakeValid_r(geos.ctx(), g.get())));
          }
          if (g) pieces.push_back(std::move(g));
        }
      }
      bool any_inside = false;
      for (GeomPtr& piece : pieces) {
        if (IsEmpty(geos, piece.get())) continue;
        if (GEOSPreparedIntersects_r(geos.ctx(), extent_prepared.get(), piece.get()) != 1) continue;
        GeomPtr clipped = PolygonalPart(geos, Own(geos, GEOSIntersection_r(geos.ctx(), piece.get(), extent.get())));
        if (IsEmpty(geos, clipped.get())) continue;
        any_inside = true;
        if (config.densify_m > 0) {
          clipped = Own(geos, GEOSDensify_r(geos.ctx(), clipped.get(), config.densify_m));
        }
        if (layer.kind == LayerKind::kBuilding) {
          Building b;
          b.height_m = BuildingHeight(feature.fields, config.building_default_height_m,
                                      config.building_level_height_m);
          b.footprint = Own(geos, GEOSGeom_clone_r(geos.ctx(), clipped.get()));
          buildings.push_back(std::move(b));
        }
        parts[layer.class_id].push_back(std::move(clipped));
      }
      if (any_inside) {
        ++used;
      } else {
        ++outside;
      }
    }
    stats.repaired_geometries += repaired;
    stats.features_outside += outside;
    if (repaired > 0) {
      scene.warnings.push_back(std::to_string(repaired) + " invalid geometries repaired (GEOS MakeValid) in " + name);
    }
    if (outside > 0) {
      scene.warnings.push_back(std::to_string(outside) + " features outside the DEM dropped from " + name);
    }
    say(name + ": " + std::to_string(used) + " features");
  }
  stats.buildings = static_cast<int64_t>(buildings.size());

  // Class regions: union per class, then priority-resolved areas.
  std::array<GeomPtr, kClassCount> unions;
  std::array<PreparedPtr, kClassCount> prepared;
  for (int c = 0; c < kClassCount; ++c) {
    unions[c] = UnionAll(geos, parts[c]);
    if (unions[c]) {
      prepared[c] = PreparedPtr(GEOSPrepare_r(geos.ctx(), unions[c].get()), PreparedDeleter{geos.ctx()});
    }
  }
  std::vector<int> order(kClassCount);
  for (int c = 0; c < kClassCount; ++c) order[c] = c;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return config.priority[a] > config.priority[b]; });
  {
    GeomPtr covered;
    double covered_area = 0.0;
    for (int c : order) {
      if (c == kClassDefault || !unions[c]) continue;
      GeomPtr region = covered ? Own(geos, GEOSDifference_r(geos.ctx(), unions[c].get(), covered.get()))
                               : Own(geos, GEOSGeom_clone_r(geos.ctx(), unions[c].get()));
      double area = 0.0;
      if (region) GEOSArea_r(geos.ctx(), region.get(), &area);
      stats.region_area_m2[c] = area;
      covered_area += area;
      covered = covered ? Own(geos, GEOSUnion_r(geos.ctx(), covered.get(), unions[c].get()))
                        : Own(geos, GEOSGeom_clone_r(geos.ctx(), unions[c].get()));
    }
    double extent_area = 0.0;
    GEOSArea_r(geos.ctx(), extent.get(), &extent_area);
    stats.region_area_m2[kClassDefault] = extent_area - covered_area;
  }
  // Constraints: every class and building boundary, noded together by GEOS
  // (all crossings become explicit vertices), so the triangulation never has
  // to construct an intersection point and every segment is exactly a chain
  // of mesh edges.
  {
    std::vector<GeomPtr> boundaries;
    for (int c = 1; c < kClassCount; ++c) {
      if (unions[c]) boundaries.push_back(Own(geos, GEOSBoundary_r(geos.ctx(), unions[c].get())));
    }
    for (const Building& b : buildings) {
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
      if (!noded) throw Error("GEOS could not node the class boundaries", config.source);
      AppendBoundarySegments(geos, noded.get(), scene.boundary_segments);
    }
  }
  for (Building& b : buildings) {
    b.prepared = PreparedPtr(GEOSPrepare_r(geos.ctx(), b.footprint.get()), PreparedDeleter{geos.ctx()});
  }
  stats.constraint_segments = static_cast<int64_t>(scene.boundary_segments.size());

  // Constrained Delaunay triangulation of the DEM posts and the boundaries.
  say("triangulating " + std::to_string(int64_t{dem.width} * dem.height) + " posts and " +
      std::to_string(stats.constraint_segments) + " constraint segments");
  Cdt cdt;
  {
    std::vector<std::pair<CdtPoint, PostInfo>> posts;
    posts.reserve(size_t(dem.width) * dem.height);
    for (int r = 0; r < dem.height; ++r) {
      for (int c = 0; c < dem.width; ++c) {
        const Vector2d m = A * Vector2d(c, r);
        posts.emplace_back(CdtPoint(m.x(), m.y()), PostInfo{int64_t{r} * dem.width + c + 1});
      }
    }
    cdt.insert(posts.begin(), posts.end());
    stats.dem_posts = static_cast<int64_t>(posts.size());
  }
  for (const auto& [a, b] : scene.boundary_segments) {
    cdt.insert_constraint(CdtPoint(a.x(), a.y()), CdtPoint(b.x(), b.y()));
  }

  // Regions: faces connected without crossing a constraint share a class.
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = -1;
  struct Region {
    ClassId cls = kClassDefault;
    int building = -1;
  };
  std::vector<Region> regions;
  for (auto seed = cdt.finite_faces_begin(); seed != cdt.finite_faces_end(); ++seed) {
    if (seed->info() >= 0) continue;
    const int id = static_cast<int>(regions.size());
    const auto& p0 = seed->vertex(0)->point();
    const auto& p1 = seed->vertex(1)->point();
    const auto& p2 = seed->vertex(2)->point();
    const Vector2d centroid((p0.x() + p1.x() + p2.x()) / 3.0, (p0.y() + p1.y() + p2.y()) / 3.0);
    Region region;
    GeomPtr point = MakePoint(geos, centroid);
    for (int c : order) {
      if (c != kClassDefault && prepared[c] &&
          GEOSPreparedContains_r(geos.ctx(), prepared[c].get(), point.get()) == 1) {
        region.cls = static_cast<ClassId>(c);
        break;
      }
    }
    if (region.cls == kClassBuilding) {
      for (size_t b = 0; b < buildings.size(); ++b) {
        if (GEOSPreparedContains_r(geos.ctx(), buildings[b].prepared.get(), point.get()) == 1) {
          region.building = static_cast<int>(b);
          break;
        }
      }
      if (region.building < 0) region.cls = kClassUrban;  // sliver between overlapping footprints
    }
    regions.push_back(region);
    std::deque<Cdt::Face_handle> queue{seed};
    seed->info() = id;
    while (!queue.empty()) {
      const Cdt::Face_handle f = queue.front();
      queue.pop_front();
      for (int i = 0; i < 3; ++i) {
        const Cdt::Face_handle n = f->neighbor(i);
        if (cdt.is_infinite(n) || n->info() >= 0 || f->is_constrained(i)) continue;
        n->info() = id;
        queue.push_back(n);
      }
    }
  }

  // Vertices: ground vertices with DEM heights; roof copies per building.
  std::unordered_map<Cdt::Vertex_handle, int> ground_index;
  std::vector<Vector2d> planar;
  std::vector<double> heights;
  for (auto v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v) {
    const Vector2d m(v->point().x(), v->point().y());
    double h;
    if (v->info().post > 0) {
      h = dem.heights_m[size_t(v->info().post - 1)];
    } else {
      ++stats.inserted_vertices;
      Vector2d cell = cell_from_planar * m;
      cell.x() = std::clamp(cell.x(), 0.0, dem.width - 1.0);
      cell.y() = std::clamp(cell.y(), 0.0, dem.height - 1.0);
      h = *dem.InterpolateHeight(cell.x(), cell.y());
    }
    ground_index[v] = static_cast<int>(planar.size());
    planar.push_back(m);
    heights.push_back(h);
  }
  std::vector<double> roof_height(buildings.size(), -std::numeric_limits<double>::infinity());
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    const Region& region = regions[f->info()];
    if (region.building < 0) continue;
    for (int i = 0; i < 3; ++i) {
      roof_height[region.building] = std::max(roof_height[region.building], heights[ground_index[f->vertex(i)]]);
    }
  }
  for (size_t b = 0; b < buildings.size(); ++b) roof_height[b] += buildings[b].height_m;
  std::map<std::pair<int, int>, int> roof_index;  // (building, ground vertex) -> vertex
  auto roof_vertex = [&](int building, int ground) {
    auto [it, inserted] = roof_index.emplace(std::make_pair(building, ground), 0);
    if (inserted) {
      it->second = static_cast<int>(planar.size());
      planar.push_back(planar[ground]);
      heights.push_back(roof_height[building]);
    }
    return it->second;
  };

  std::vector<Eigen::Vector3i> triangles;
  std::vector<ClassId> classes;
  struct Wall {
    int a, b, opposite;  // ground vertices of the edge, vertex inside the roof face
    int building;
  };
  std::vector<Wall> walls;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    const Region& region = regions[f->info()];
    int g[3];
    for (int i = 0; i < 3; ++i) g[i] = ground_index[f->vertex(i)];
    const double area =
        0.5 * std::abs((planar[g[1]] - planar[g[0]]).x() * (planar[g[2]] - planar[g[0]]).y() -
                       (planar[g[1]] - planar[g[0]]).y() * (planar[g[2]] - planar[g[0]]).x());
    stats.mesh_area_m2[region.cls] += area;
    if (region.building < 0) {
      triangles.emplace_back(g[0], g[1], g[2]);
      classes.push_back(region.cls);
      continue;
    }
    triangles.emplace_back(roof_vertex(region.building, g[0]), roof_vertex(region.building, g[1]),
                           roof_vertex(region.building, g[2]));
    classes.push_back(kClassBuilding);
    for (int i = 0; i < 3; ++i) {
      const Cdt::Face_handle n = f->neighbor(i);
      const bool outside = cdt.is_infinite(n) || regions[n->info()].building != region.building;
      if (!outside) continue;
      walls.push_back({g[Cdt::ccw(i)], g[Cdt::cw(i)], g[i], region.building});
    }
  }

  // 3-D positions: cell -> map -> WGS84 -> ENU at the vertex height.
  std::vector<double> x(planar.size()), y(planar.size());
  for (size_t i = 0; i < planar.size(); ++i) {
    const Vector2d cell = cell_from_planar * planar[i];
    const Vector2d map = dem.MapFromPost(cell.x(), cell.y());
    x[i] = map.x();
    y[i] = map.y();
  }
  crs.ToLonLat(x, y);
  TriangleMesh& mesh = scene.mesh;
  mesh.vertices.resize(planar.size());
  for (size_t i = 0; i < planar.size(); ++i) {
    mesh.vertices[i] = frame.EnuFromGeodetic(x[i], y[i], heights[i]).cast<float>();
  }
  mesh.triangles = std::move(triangles);
  mesh.classes = std::move(classes);
  for (const Wall& w : walls) {
    const int ra = roof_vertex(w.building, w.a), rb = roof_vertex(w.building, w.b);
    if (ra >= static_cast<int>(mesh.vertices.size()) || rb >= static_cast<int>(mesh.vertices.size())) {
      GISSAR_CHECK_MSG(false, "roof vertex created after placement");
    }
    // The roof face lies to the left of a -> b (counter-clockwise in M):
    // the wall's outward normal points to the right, away from `opposite`.
    const Eigen::Vector3f pa = mesh.vertices[w.a], pb = mesh.vertices[w.b];
    const Eigen::Vector3f qa = mesh.vertices[ra], qb = mesh.vertices[rb];
    const Eigen::Vector3f inward = mesh.vertices[w.opposite] - 0.5f * (pa + pb);
    Eigen::Vector3i t1(w.a, w.b, rb), t2(w.a, rb, ra);
    const Eigen::Vector3f n = (pb - pa).cross(qb - pa);
    if (n.dot(inward) > 0) {
      t1 = Eigen::Vector3i(w.a, rb, w.b);
      t2 = Eigen::Vector3i(w.a, ra, rb);
    }
    (void)qa;
    if ((qb - pb).norm() < 1e-4f && (qa - pa).norm() < 1e-4f) continue;  // zero-height wall
    mesh.triangles.push_back(t1);
    mesh.triangles.push_back(t2);
    mesh.classes.push_back(kClassBuilding);
    mesh.classes.push_back(kClassBuilding);
  }
  scene.planar = std::move(planar);
  for (ClassId c : mesh.classes) ++stats.triangles[c];
  stats.seconds = watch.ElapsedSeconds();
  say("built " + std::to_string(mesh.triangle_count()) + " triangles in " +
      std::to_string(stats.seconds) + " s");
  return scene;
}

}  // namespace gissar::scene
