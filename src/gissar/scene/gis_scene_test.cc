#include "gissar/scene/gis_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <random>
#include <set>

#include "gissar/geo/dem.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::scene {
namespace {

using Eigen::Vector2d;
namespace fs = std::filesystem;

// A local transverse Mercator CRS (scale 1 on its central meridian): map
// metres equal ENU metres to ~1e-6 near the origin.
const char* kLocalTm =
    "+proj=tmerc +lat_0=42.5 +lon_0=1.6 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";

// Flat DEM at 100 m: 101 x 101 posts, 10 m spacing, centred on the origin.
std::string FlatDem(const fs::path& dir) {
  const auto path = dir / "flat.tif";
  geo::WriteDemGeoTiff(path, std::vector<float>(101 * 101, 100.0f), 101, 101,
                       {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, kLocalTm);
  return path.string();
}

// GeoJSON in WGS84 of features given in the local TM metres.
struct Feature {
  std::string type;  // "Polygon" or "LineString"
  std::vector<std::vector<Vector2d>> parts;
  std::string properties = "{}";
};

std::string WriteGeoJson(const fs::path& path, const std::vector<Feature>& features) {
  const geo::CrsTransform tm(kLocalTm);
  std::ofstream out(path);
  out.precision(12);
  out << R"({"type":"FeatureCollection","features":[)";
  for (size_t f = 0; f < features.size(); ++f) {
    out << (f ? "," : "") << R"({"type":"Feature","properties":)" << features[f].properties
        << R"(,"geometry":{"type":")" << features[f].type << R"(","coordinates":)";
    const bool polygon = features[f].type == "Polygon";
    out << (polygon ? "[" : "");
    for (size_t p = 0; p < features[f].parts.size(); ++p) {
      std::vector<double> x, y;
      for (const auto& q : features[f].parts[p]) {
        x.push_back(q.x());
        y.push_back(q.y());
      }
      tm.ToLonLat(x, y);
      out << (p ? "," : "") << "[";
      for (size_t i = 0; i < x.size(); ++i) out << (i ? "," : "") << "[" << x[i] << "," << y[i] << "]";
      out << "]";
    }
    out << (polygon ? "]" : "") << "}}";
  }
  out << "]}";
  return path.string();
}

std::vector<Vector2d> Rect(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}};
}

LayerSpec Spec(const std::string& path, ClassId cls, LayerKind kind, double width = 0) {
  LayerSpec s;
  s.source.path = path;
  s.class_id = cls;
  s.kind = kind;
  s.line_width_m = width;
  return s;
}

// Every boundary segment must be a union of mesh edges: the mesh edges lying
// on it (within 10 micrometres) cover it end to end.
void ExpectBoundariesAreMeshEdges(const GisScene& scene) {
  // Mesh edges in plan (roofs and walls repeat ground edges or have none).
  std::set<std::pair<int, int>> edges;
  for (const auto& t : scene.mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      int a = t[k], b = t[(k + 1) % 3];
      if ((scene.planar[a] - scene.planar[b]).norm() < 1e-9) continue;
      if (a > b) std::swap(a, b);
      edges.emplace(a, b);
    }
  }
  // Hash edges by the grid cells their plan bounding boxes touch.
  constexpr double kCell = 25.0;
  std::map<std::pair<int64_t, int64_t>, std::vector<std::pair<int, int>>> grid;
  auto cell = [&](double v) { return static_cast<int64_t>(std::floor(v / kCell)); };
  for (const auto& e : edges) {
    const Vector2d& p = scene.planar[e.first];
    const Vector2d& q = scene.planar[e.second];
    for (int64_t i = cell(std::min(p.x(), q.x())); i <= cell(std::max(p.x(), q.x())); ++i)
      for (int64_t j = cell(std::min(p.y(), q.y())); j <= cell(std::max(p.y(), q.y())); ++j)
        grid[{i, j}].push_back(e);
  }
  int64_t failures = 0;
  for (const auto& [a, b] : scene.boundary_segments) {
    const double length = (b - a).norm();
    const Vector2d dir = (b - a) / length;
    auto lateral = [&](const Vector2d& p) { const Vector2d d = p - a; return std::abs(d.x() * dir.y() - d.y() * dir.x()); };
    std::vector<std::pair<double, double>> spans;
    std::set<std::pair<int, int>> used;
    for (int64_t i = cell(std::min(a.x(), b.x())); i <= cell(std::max(a.x(), b.x())); ++i) {
      for (int64_t j = cell(std::min(a.y(), b.y())); j <= cell(std::max(a.y(), b.y())); ++j) {
        auto it = grid.find({i, j});
        if (it == grid.end()) continue;
        for (const auto& e : it->second) {
          const Vector2d& p = scene.planar[e.first];
          const Vector2d& q = scene.planar[e.second];
          if (lateral(p) > 1e-5 || lateral(q) > 1e-5 || !used.insert(e).second) continue;
          double s0 = (p - a).dot(dir), s1 = (q - a).dot(dir);
          if (s0 > s1) std::swap(s0, s1);
          spans.emplace_back(s0, s1);
        }
      }
    }
    std::sort(spans.begin(), spans.end());
    double covered = 0.0;
    for (const auto& [s0, s1] : spans) {
      if (s0 > covered + 1e-4) break;
      covered = std::max(covered, s1);
    }
    if (covered < length - 1e-4) {
      if (failures < 5 && scene.stats.steep_slivers == 0) {
        double nearest = 1e18;
        int nearest_id = -1;
        for (size_t v = 0; v < scene.planar.size(); ++v) {
          if ((scene.planar[v] - a).norm() < nearest) { nearest = (scene.planar[v] - a).norm(); nearest_id = int(v); }
        }
        std::string detail;
        for (const auto& e : edges) {
          if (e.first != nearest_id && e.second != nearest_id) continue;
          const int o = e.first == nearest_id ? e.second : e.first;
          detail += " [s=" + std::to_string((scene.planar[o] - a).dot(dir)) + " lat=" + std::to_string(lateral(scene.planar[o])) + "]";
        }
        ADD_FAILURE() << "segment (" << a.transpose() << ") -> (" << b.transpose() << ") covered to "
                      << covered << " of " << length << "; nearest vertex " << nearest << " m away, edges" << detail;
      }
      ++failures;
    }
  }
  // A dropped steep terrain sliver (< 10 cm wide) may uncover at most its
  // three edges.
  EXPECT_LE(failures, 3 * scene.stats.steep_slivers) << "of " << scene.boundary_segments.size() << " boundary segments";
}

void ExpectAreasMatch(const GisScene& scene) {
  for (int c = 0; c < kClassCount; ++c) {
    const double region = scene.stats.region_area_m2[c];
    const double mesh = scene.stats.mesh_area_m2[c];
    if (region < 1.0) {
      EXPECT_LT(mesh, 1.0) << ClassNames()[c];
      continue;
    }
    EXPECT_NEAR(mesh / region, 1.0, 0.005) << ClassNames()[c] << " mesh " << mesh << " region " << region;
  }
}

GisScene Build(const std::string& dem_path, const SceneConfig& config) {
  const geo::Dem dem = geo::ReadDem(dem_path);
  const geo::GeoPoint centre = geo::ResolveSceneCentre(dem, std::nullopt, std::nullopt);
  return BuildGisScene(dem, geo::LocalFrame(centre.lon_deg, centre.lat_deg), config);
}

TEST(GisSceneTest, PolygonsBecomeConstrainedClassRegions) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  // Water square, an overlapping forest (water wins), a self-intersecting
  // bow-tie (repaired), and a polygon entirely outside the DEM.
  const std::string water = WriteGeoJson(dir / "water.geojson", {{"Polygon", {Rect(-200, -150, 33, 77)}}});
  const std::string forest = WriteGeoJson(
      dir / "forest.geojson",
      {{"Polygon", {{{-50, -300}, {300, -280}, {260, 150}, {-80, 100}, {-50, -300}}}},
       {"Polygon", {Rect(2000, 2000, 2100, 2100)}}});
  const std::string urban = WriteGeoJson(
      dir / "urban.geojson", {{"Polygon", {{{100, 200}, {300, 400}, {300, 200}, {100, 400}, {100, 200}}}}});
  SceneConfig config;
  config.layers = {Spec(water, kClassWater, LayerKind::kPolygon),
                   Spec(forest, kClassForest, LayerKind::kPolygon),
                   Spec(urban, kClassUrban, LayerKind::kPolygon)};
  const GisScene scene = Build(dem, config);
  EXPECT_EQ(scene.stats.repaired_geometries, 1);
  EXPECT_EQ(scene.stats.features_outside, 1);
  EXPECT_GE(scene.warnings.size(), 2u);
  // Water: its full square (233 x 227 m^2).
  EXPECT_NEAR(scene.stats.region_area_m2[kClassWater], 233.0 * 227.0, 1.0);
  // The bow-tie becomes two triangles of 100 x 100 m^2 each.
  EXPECT_NEAR(scene.stats.region_area_m2[kClassUrban], 2 * 0.5 * 200 * 100, 1.0);
  ExpectAreasMatch(scene);
  ExpectBoundariesAreMeshEdges(scene);
  // All vertices on the flat DEM sit at 100 m.
  for (const auto& v : scene.mesh.vertices) EXPECT_NEAR(v.z(), 100.0f - v.head<2>().squaredNorm() / (2 * 6378137.0f), 0.05f);
}

// Width of the union of the road triangles' plan along x = x0, in ENU.
double StripWidthAt(const TriangleMesh& mesh, double x0) {
  std::vector<std::pair<double, double>> spans;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassRoad) continue;
    std::vector<double> ys;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3f a = mesh.vertices[mesh.triangles[t][k]];
      const Eigen::Vector3f b = mesh.vertices[mesh.triangles[t][(k + 1) % 3]];
      if ((a.x() - x0) * (b.x() - x0) > 0 || a.x() == b.x()) continue;
      const double s = (x0 - a.x()) / (b.x() - a.x());
      ys.push_back(a.y() + s * (b.y() - a.y()));
    }
    if (ys.size() >= 2) spans.emplace_back(*std::min_element(ys.begin(), ys.end()), *std::max_element(ys.begin(), ys.end()));
  }
  std::sort(spans.begin(), spans.end());
  double total = 0, end = -1e18;
  for (auto [lo, hi] : spans) {
    lo = std::max(lo, end);
    if (hi > lo) total += hi - lo;
    end = std::max(end, hi);
  }
  return total;
}

TEST(GisSceneTest, RoadsAreStripsOfTheirClassWidth) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  const std::string roads = WriteGeoJson(
      dir / "roads.geojson",
      {{"LineString", {{{-400, -200}, {400, -200}}}, R"({"highway": "primary"})"},
       {"LineString", {{{-400, 150}, {400, 150}}}, R"({"highway": "primary", "width": "7.5 m"})"},
       {"LineString", {{{-400, 300}, {400, 300}}}, R"({"highway": "unknown_kind"})"}});
  SceneConfig config;
  config.line_widths_m = DefaultLineWidths();
  config.layers = {Spec(roads, kClassRoad, LayerKind::kLine)};
  const GisScene scene = Build(dem, config);
  // Measure each strip separately by clipping the mesh to its y band.
  auto width_near = [&](double y) {
    TriangleMesh band;
    for (size_t t = 0; t < scene.mesh.triangle_count(); ++t) {
      const Eigen::Vector3f c = (scene.mesh.vertices[scene.mesh.triangles[t][0]] +
                                 scene.mesh.vertices[scene.mesh.triangles[t][1]] +
                                 scene.mesh.vertices[scene.mesh.triangles[t][2]]) / 3.0f;
      if (std::abs(c.y() - y) < 40) {
        band.AddTriangle(scene.mesh.vertices[scene.mesh.triangles[t][0]],
                         scene.mesh.vertices[scene.mesh.triangles[t][1]],
                         scene.mesh.vertices[scene.mesh.triangles[t][2]], scene.mesh.classes[t]);
      }
    }
    return StripWidthAt(band, 13.7);
  };
  EXPECT_NEAR(width_near(-200), 12.0, 0.12);  // primary: 12 m
  EXPECT_NEAR(width_near(150), 7.5, 0.075);   // the width tag wins
  EXPECT_NEAR(width_near(300), config.default_road_width_m, 0.05);
  ExpectBoundariesAreMeshEdges(scene);
  ExpectAreasMatch(scene);
}

TEST(GisSceneTest, BuildingsAreExtrudedWithVerticalWalls) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  const std::string buildings = WriteGeoJson(
      dir / "buildings.geojson",
      {{"Polygon", {Rect(-20, -15, 20, 15)}, R"({"height": "12"})"},
       {"Polygon", {Rect(100, 100, 130, 120)}, R"({"building:levels": "4"})"},
       {"Polygon", {Rect(-300, 200, -280, 215)}, "{}"}});
  SceneConfig config;
  config.layers = {Spec(buildings, kClassBuilding, LayerKind::kBuilding)};
  const GisScene scene = Build(dem, config);
  EXPECT_EQ(scene.stats.buildings, 3);
  const TriangleMesh& mesh = scene.mesh;
  auto centre_of = [&](size_t t) {
    return Eigen::Vector3f((mesh.vertices[mesh.triangles[t][0]] + mesh.vertices[mesh.triangles[t][1]] +
                            mesh.vertices[mesh.triangles[t][2]]) / 3.0f);
  };
  // Building near (0,0): roof 12 m above the 100 m ground, walls vertical
  // from ground to roof, outward; roof area 40 x 30 m^2.
  double roof_area = 0;
  int walls = 0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassBuilding) continue;
    const Eigen::Vector3f c = centre_of(t);
    if (c.head<2>().norm() > 40) continue;
    const Eigen::Vector3f n = mesh.Normal(t);
    if (std::abs(n.z()) < 1e-3f) {
      ++walls;
      float zmin = 1e9f, zmax = -1e9f;
      for (int k = 0; k < 3; ++k) {
        zmin = std::min(zmin, mesh.vertices[mesh.triangles[t][k]].z());
        zmax = std::max(zmax, mesh.vertices[mesh.triangles[t][k]].z());
      }
      EXPECT_NEAR(zmax - zmin, 12.0f, 1e-3f);
      EXPECT_NEAR(zmin, 100.0f, 0.01f);
      EXPECT_GT(n.head<2>().dot(c.head<2>()), 0.0f) << "wall normal must point outwards";
    } else {
      EXPECT_GT(n.z(), 0.999f);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(mesh.vertices[mesh.triangles[t][k]].z(), 112.0f, 0.01f);
      const Eigen::Vector3f a = mesh.vertices[mesh.triangles[t][0]];
      roof_area += 0.5 * (mesh.vertices[mesh.triangles[t][1]] - a).cross(mesh.vertices[mesh.triangles[t][2]] - a).norm();
    }
  }
  EXPECT_GE(walls, 8);
  EXPECT_NEAR(roof_area, 1200.0, 6.0);
  // Levels: 4 x 3 m; default height 10 m.
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassBuilding || mesh.Normal(t).z() < 0.999f) continue;
    const Eigen::Vector3f c = centre_of(t);
    if (c.x() > 90) {
      EXPECT_NEAR(c.z(), 112.0f, 0.01f);
    }
    if (c.x() < -200) {
      EXPECT_NEAR(c.z(), 110.0f, 0.05f);  // Earth curvature: 0.01 m at 350 m
    }
  }
  ExpectBoundariesAreMeshEdges(scene);
}

// DEM of 101 x 101 posts, 10 m spacing, centred on the origin, with
// height(x, y) at post (x, y) (local TM metres).
template <typename F>
std::string DemOf(const fs::path& path, F height) {
  std::vector<float> h(101 * 101);
  for (int r = 0; r < 101; ++r) {
    for (int c = 0; c < 101; ++c) h[size_t(r) * 101 + c] = static_cast<float>(height(-500.0 + 10 * c, 500.0 - 10 * r));
  }
  geo::WriteDemGeoTiff(path, h, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, kLocalTm);
  return path.string();
}

Eigen::Vector3f CentreOf(const TriangleMesh& mesh, size_t t) {
  return (mesh.vertices[mesh.triangles[t][0]] + mesh.vertices[mesh.triangles[t][1]] +
          mesh.vertices[mesh.triangles[t][2]]) / 3.0f;
}

double AreaOf(const TriangleMesh& mesh, size_t t) {
  const Eigen::Vector3f a = mesh.vertices[mesh.triangles[t][0]];
  return 0.5 * (mesh.vertices[mesh.triangles[t][1]] - a).cross(mesh.vertices[mesh.triangles[t][2]] - a).norm();
}

// Strictly inside a simple polygon (closed ring), by crossings.
bool Inside(const std::vector<Vector2d>& ring, const Vector2d& p) {
  bool in = false;
  for (size_t i = 0, j = ring.size() - 2; i + 1 < ring.size(); j = i++) {
    const Vector2d& a = ring[i];
    const Vector2d& b = ring[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      in = !in;
    }
  }
  return in;
}

// Property: random triangles and rectangles whose corners are DEM posts (so
// their edges pass through posts, the case where a nearly collinear rounded
// vertex used to flip walls), on rough sloped terrain: every wall's normal
// points away from its footprint: a point 5 cm along the normal from the
// wall's centre is outside the footprint, 5 cm against it inside.
TEST(GisSceneTest, WallsOfRandomPostSnappedFootprintsFaceOutwards) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = DemOf(dir / "rough.tif", [](double x, double y) {
    return 300.0 + 0.15 * x - 0.1 * y + 3.0 * std::sin(x / 37.0) * std::cos(y / 23.0);
  });
  std::mt19937 rng(16);
  auto post = [&](int lo, int hi) { return 10.0 * std::uniform_int_distribution<int>(lo, hi)(rng); };
  std::vector<Feature> features;
  std::vector<std::vector<Vector2d>> rings;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      const double x0 = -480 + 160.0 * i, y0 = -480 + 160.0 * j;  // one 150 m tile each
      std::vector<Vector2d> ring;
      if ((i + j) % 2 == 0) {
        Vector2d a, b, c;
        do {
          a = {x0 + post(0, 15), y0 + post(0, 15)};
          b = {x0 + post(0, 15), y0 + post(0, 15)};
          c = {x0 + post(0, 15), y0 + post(0, 15)};
        } while (std::abs((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x()) < 400.0);
        ring = {a, b, c, a};  // either orientation: the ring decides
      } else {
        const double w = post(2, 14), h = post(2, 14);
        ring = Rect(x0, y0, x0 + w, y0 + h);
        if (j % 2 == 0) std::reverse(ring.begin(), ring.end());  // clockwise shell
      }
      rings.push_back(ring);
      features.push_back({"Polygon", {ring}, R"({"height": "60"})"});
    }
  }
  SceneConfig config;
  config.layers = {Spec(WriteGeoJson(dir / "b.geojson", features), kClassBuilding, LayerKind::kBuilding)};
  const GisScene scene = Build(dem, config);
  EXPECT_EQ(scene.stats.buildings, 36);
  EXPECT_EQ(scene.stats.buried_wall_triangles, 0);
  const TriangleMesh& mesh = scene.mesh;
  int walls = 0, inverted = 0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassBuilding) continue;
    const Eigen::Vector3f n = mesh.Normal(t);
    if (std::abs(n.z()) > 0.01f) {
      EXPECT_GT(n.z(), 0.9999f) << "roofs are flat and face up: " << mesh.vertices[mesh.triangles[t][0]].transpose() << " / "
                                << mesh.vertices[mesh.triangles[t][1]].transpose() << " / " << mesh.vertices[mesh.triangles[t][2]].transpose();
      continue;
    }
    ++walls;
    const Vector2d c = CentreOf(mesh, t).head<2>().cast<double>();
    const Vector2d d = n.head<2>().cast<double>().normalized() * 0.05;
    bool out_inside = false, in_inside = false;
    for (const auto& ring : rings) {
      out_inside |= Inside(ring, c + d);
      in_inside |= Inside(ring, c - d);
    }
    if (out_inside || !in_inside) ++inverted;
  }
  EXPECT_GT(walls, 36 * 6);
  EXPECT_EQ(inverted, 0) << "of " << walls << " wall triangles";
}

// Roof on a slope: ground 100 + 0.1 x; a 40 x 30 m footprint from x = 0 to
// 40 with height 12 has its lowest contact at x = 0 (100 m): roof at 112 m;
// its walls are 12 m high at x = 0 and 8 m at x = 40. With height 2 the roof
// (102 m) is below the ground beyond x = 20 (pit sides, facing in).
// A round building outlined by 10^6 vertices (1.3 mm apart): the outline is
// simplified to 1/1000 of a cell (1 cm here), so the triangulation stays
// small; the roof keeps the circle's area pi r^2 (a chord tolerance of 1 cm
// changes it by at most perimeter x 1 cm = 0.01 %) and every wall faces out.
TEST(GisSceneTest, MillionVertexOutlineIsSimplifiedNotTriangulated) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  constexpr int kVertices = 1000000;
  constexpr double kRadius = 200.0;
  std::vector<Vector2d> ring;
  ring.reserve(kVertices + 1);
  for (int i = 0; i < kVertices; ++i) {
    const double a = 2.0 * M_PI * i / kVertices;
    ring.emplace_back(kRadius * std::cos(a), kRadius * std::sin(a));
  }
  ring.push_back(ring.front());
  const std::string buildings =
      WriteGeoJson(dir / "round.geojson", {{"Polygon", {ring}, R"({"height": "10"})"}});
  SceneConfig config;
  config.layers = {Spec(buildings, kClassBuilding, LayerKind::kBuilding)};
  const GisScene scene = Build(dem, config);
  EXPECT_EQ(scene.stats.simplified_outlines, 1);
  EXPECT_LT(scene.stats.constraint_segments, 20000);
  const TriangleMesh& mesh = scene.mesh;
  double roof_area = 0.0;
  int64_t walls = 0, inward = 0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassBuilding) continue;
    const Eigen::Vector3f& a = mesh.vertices[mesh.triangles[t][0]];
    const Eigen::Vector3f& b = mesh.vertices[mesh.triangles[t][1]];
    const Eigen::Vector3f& c = mesh.vertices[mesh.triangles[t][2]];
    const Eigen::Vector3d cross = ((b - a).cross(c - a)).cast<double>();
    const Eigen::Vector3f centre = (a + b + c) / 3.0f;
    if (cross.z() > 0.999 * cross.norm()) {
      roof_area += 0.5 * cross.norm();
    } else if (std::abs(cross.z()) < 1e-3 * cross.norm()) {
      ++walls;
      if (cross.head<2>().dot(centre.head<2>().cast<double>()) <= 0.0) ++inward;
    }
  }
  EXPECT_NEAR(roof_area, M_PI * kRadius * kRadius, 1e-4 * M_PI * kRadius * kRadius);
  EXPECT_GT(walls, 100);
  EXPECT_EQ(inward, 0);
}

TEST(GisSceneTest, RoofsSitAtTheLowestGroundContactPlusHeight) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = DemOf(dir / "slope.tif", [](double x, double) { return 100.0 + 0.1 * x; });
  const std::string buildings = WriteGeoJson(
      dir / "b.geojson", {{"Polygon", {Rect(0, 0, 40, 30)}, R"({"height": "12"})"},
                          {"Polygon", {Rect(0, 200, 40, 230)}, R"({"height": "2"})"}});
  SceneConfig config;
  config.layers = {Spec(buildings, kClassBuilding, LayerKind::kBuilding)};
  const GisScene scene = Build(dem, config);
  const TriangleMesh& mesh = scene.mesh;
  // Earth curvature lowers ENU z by x^2 / 2R: < 5 mm within 250 m.
  double wall_area_tall = 0.0, roof_area = 0.0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != kClassBuilding) continue;
    const Eigen::Vector3f c = CentreOf(mesh, t), n = mesh.Normal(t);
    if (c.y() > 100) continue;
    if (n.z() > 0.99f) {
      roof_area += AreaOf(mesh, t);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(mesh.vertices[mesh.triangles[t][k]].z(), 112.0f, 0.01f);
    } else {
      wall_area_tall += AreaOf(mesh, t);
    }
  }
  EXPECT_NEAR(roof_area, 1200.0, 1.0);
  // Walls: x = 0: 30 x 12; x = 40: 30 x 8; y = 0 and y = 30: trapezoids
  // 40 x (12 + 8) / 2 each.
  EXPECT_NEAR(wall_area_tall, 360.0 + 240.0 + 2 * 400.0, 1.0);
  // Second building: walls facing out where the roof is above the ground
  // (x = 0: 30 x 2 m; y = 200 and 230 from x = 0 to 20: triangles 20 x 2 / 2),
  // facing in where it is below (x = 40: 30 x 2; the other halves of y = 200
  // and 230).
  EXPECT_GT(scene.stats.buried_wall_triangles, 0);
  const std::vector<Vector2d> low = Rect(0, 200, 40, 230);
  double facing_out = 0.0, facing_in = 0.0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Eigen::Vector3f c = CentreOf(mesh, t), n = mesh.Normal(t);
    if (mesh.classes[t] != kClassBuilding || c.y() < 100 || std::abs(n.z()) > 0.01f) continue;
    const Vector2d d = n.head<2>().cast<double>().normalized() * 0.05;
    const Vector2d p = c.head<2>().cast<double>();
    (Inside(low, p + d) ? facing_in : facing_out) += AreaOf(mesh, t);
    if (std::abs(c.x() - 40.0f) < 0.1f) {
      EXPECT_LT(n.x(), -0.99f) << "pit side faces into the footprint";
    }
  }
  EXPECT_NEAR(facing_out, 60.0 + 2 * 20.0, 0.2);
  EXPECT_NEAR(facing_in, 60.0 + 2 * 20.0, 0.2);
}

// Touching footprints: equal heights merge (no wall inside the block);
// different heights keep only the step above the lower roof, facing the
// lower building.
TEST(GisSceneTest, SharedWallsAreRemovedAndStepsKept) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  for (const char* right_height : {"12", "20"}) {
    const std::string buildings = WriteGeoJson(
        dir / (std::string("b") + right_height + ".geojson"),
        {{"Polygon", {Rect(-20, -15, 0, 15)}, R"({"height": "12"})"},
         {"Polygon", {Rect(0, -15, 20, 15)}, std::string(R"({"height": ")") + right_height + "\"}"}});
    SceneConfig config;
    config.layers = {Spec(buildings, kClassBuilding, LayerKind::kBuilding)};
    const GisScene scene = Build(dem, config);
    const TriangleMesh& mesh = scene.mesh;
    double inner = 0.0, outer = 0.0;
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const Eigen::Vector3f c = CentreOf(mesh, t), n = mesh.Normal(t);
      if (mesh.classes[t] != kClassBuilding || std::abs(n.z()) > 0.01f) continue;
      if (std::abs(c.x()) < 0.01f) {
        inner += AreaOf(mesh, t);
        EXPECT_LT(n.x(), -0.99f) << "the step faces the lower (left) building";
        EXPECT_GT(c.z(), 112.0f - 0.01f) << "the step starts at the lower roof";
      } else {
        outer += AreaOf(mesh, t);
      }
    }
    if (std::string(right_height) == "12") {
      EXPECT_EQ(scene.stats.merged_buildings, 1);
      EXPECT_NEAR(inner, 0.0, 1e-6);
      EXPECT_NEAR(outer, 2 * (40 + 30) * 12.0, 0.5);
    } else {
      EXPECT_EQ(scene.stats.merged_buildings, 0);
      EXPECT_EQ(scene.stats.step_walls > 0, true);
      EXPECT_NEAR(inner, 30 * 8.0, 0.1);
      // Left: 3 sides of 12 m; right: 3 sides of 20 m.
      EXPECT_NEAR(outer, (30 + 2 * 20) * 12.0 + (30 + 2 * 20) * 20.0, 0.5);
    }
  }
}

GisScene BuildWith(const std::string& dem_path, const SceneConfig& config, const geo::DemReadOptions& options) {
  const geo::Dem dem = geo::ReadDem(dem_path, options);
  const geo::GeoPoint centre = geo::ResolveSceneCentre(dem, std::nullopt, std::nullopt);
  return BuildGisScene(dem, geo::LocalFrame(centre.lon_deg, centre.lat_deg), config);
}

double PlanArea(const TriangleMesh& mesh, ClassId cls) {
  double area = 0.0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != cls) continue;
    const Eigen::Vector3d a = mesh.vertices[mesh.triangles[t][0]].cast<double>();
    area += 0.5 * std::abs((mesh.vertices[mesh.triangles[t][1]].cast<double>() - a)
                               .cross(mesh.vertices[mesh.triangles[t][2]].cast<double>() - a).z());
  }
  return area;
}

// A DEM reprojected from a source rotated by 30 degrees: a tilted plane
// (z = 100 + 0.2 x) inside the rotated 700 m square, no-data outside (the
// collar in the corners). The collar is left out (no --fill-nodata needed),
// a road crossing it is clipped to the valid area, and every terrain
// triangle is the plane: facing up with the plane's normal, none steep.
TEST(GisSceneTest, ReprojectionCollarIsOutsideTheScene) {
  const fs::path dir = testing::MakeTempDir();
  const double kNodata = -9999.0;
  const double angle = 30.0 * M_PI / 180.0;
  auto valid = [&](double x, double y) {
    const double u = std::cos(angle) * x + std::sin(angle) * y, v = -std::sin(angle) * x + std::cos(angle) * y;
    return std::abs(u) <= 350.0 && std::abs(v) <= 350.0;
  };
  const std::string dem = (dir / "collar.tif").string();
  {
    std::vector<float> h(101 * 101);
    for (int r = 0; r < 101; ++r)
      for (int c = 0; c < 101; ++c) {
        const double x = -500.0 + 10 * c, y = 500.0 - 10 * r;
        h[size_t(r) * 101 + c] = valid(x, y) ? static_cast<float>(100.0 + 0.2 * x) : static_cast<float>(kNodata);
      }
    geo::WriteDemGeoTiff(dem, h, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, kLocalTm, kNodata);
  }
  const std::string roads = WriteGeoJson(dir / "roads.geojson",
                                         {{"LineString", {{{-600, 13}, {600, 13}}}, R"({"highway": "primary"})"}});
  SceneConfig config;
  config.line_widths_m = DefaultLineWidths();
  config.layers = {Spec(roads, kClassRoad, LayerKind::kLine)};
  geo::DemReadOptions options;
  options.border_nodata_outside = true;
  const GisScene scene = BuildWith(dem, config, options);
  EXPECT_GT(scene.stats.outside_posts, 0);
  EXPECT_GT(scene.stats.dropped_faces, 0);
  const TriangleMesh& mesh = scene.mesh;
  const Eigen::Vector3f plane = Eigen::Vector3f(-0.2f, 0.0f, 1.0f).normalized();
  int bad_normal = 0, steep = 0, outside_vertices = 0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (AreaOf(mesh, t) < 1e-3) continue;
    // Every triangle faces up and is not steep; short ones are the plane
    // itself (long needles along the road strip follow Earth's curvature:
    // 800 m chords sag 1 cm).
    if (mesh.Normal(t).z() < std::cos(80.0 * M_PI / 180.0)) ++steep;
    float longest = 0.0f;
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (mesh.vertices[mesh.triangles[t][k]] - mesh.vertices[mesh.triangles[t][(k + 1) % 3]]).norm());
    }
    if (longest < 100.0f && mesh.Normal(t).dot(plane) < std::cos(0.2 * M_PI / 180.0)) ++bad_normal;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3f v = mesh.vertices[mesh.triangles[t][k]];
      if (!valid(v.x() * 0.999, v.y() * 0.999)) ++outside_vertices;  // 0.1 % inward: on the border is fine
    }
  }
  EXPECT_EQ(steep, 0) << "no terrain triangle faces down or stands steeper than 80 degrees";
  EXPECT_EQ(bad_normal, 0) << "the triangles are the tilted plane";
  EXPECT_EQ(outside_vertices, 0);
  // The road (12 m wide) runs along y = 13 across the valid area only: its
  // length there is at most the square's chord (700 / cos 30 = 808 m).
  const double road = PlanArea(mesh, kClassRoad);
  EXPECT_GT(road, 12.0 * 600.0);
  EXPECT_LT(road, 12.0 * 808.3);
  ExpectBoundariesAreMeshEdges(scene);
}

// --sea auto without coastline: a DEM whose west half is a 0 m sea (x < 0)
// and whose east half rises from 10 m: the sea is the 49 x 100 cells whose
// four posts are at 0 m (x from -500 to -10), 490 000 m^2. A void in the sea
// next to sea posts is sea; voids on the border of a landlocked DEM are not.
TEST(GisSceneTest, DemWithoutCoastlineGetsTheFallbackSea) {
  const fs::path dir = testing::MakeTempDir();
  const double kNodata = -32768.0;
  std::vector<float> h(101 * 101);
  for (int r = 0; r < 101; ++r)
    for (int c = 0; c < 101; ++c) {
      const double x = -500.0 + 10 * c;
      h[size_t(r) * 101 + c] = x < 0 ? 0.0f : static_cast<float>(10.0 + 0.1 * x);
    }
  h[size_t(50) * 101 + 20] = static_cast<float>(kNodata);  // a void in the sea
  const std::string coast = (dir / "coast.tif").string();
  geo::WriteDemGeoTiff(coast, h, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, kLocalTm, kNodata);
  geo::DemReadOptions options;
  options.fill_nodata = true;
  options.border_nodata_outside = true;
  const GisScene scene = BuildWith(coast, SceneConfig(), options);
  EXPECT_TRUE(scene.stats.sea_from_dem);
  EXPECT_NEAR(PlanArea(scene.mesh, kClassSea), 490000.0, 50.0);
  EXPECT_NEAR(scene.stats.mesh_area_m2[kClassSea], 490000.0, 1.0);
  // --sea off: no sea.
  SceneConfig off;
  off.sea_auto = false;
  EXPECT_EQ(PlanArea(BuildWith(coast, off, options).mesh, kClassSea), 0.0);
  // A sea level of -1 m: nothing is at or below it.
  SceneConfig low;
  low.sea_level_m = -1.0;
  EXPECT_EQ(PlanArea(BuildWith(coast, low, options).mesh, kClassSea), 0.0);

  // Landlocked (Andorra-like): 1000 m and up, voids on the border: no sea,
  // the border voids are left out, the interior void is filled.
  for (int r = 0; r < 101; ++r)
    for (int c = 0; c < 101; ++c) h[size_t(r) * 101 + c] = static_cast<float>(1000.0 + c);
  for (int c : {10, 11, 12, 60}) h[c] = static_cast<float>(kNodata);   // row 0
  h[size_t(40) * 101 + 100] = static_cast<float>(kNodata);              // last column
  h[size_t(50) * 101 + 50] = static_cast<float>(kNodata);               // interior
  const std::string land = (dir / "land.tif").string();
  geo::WriteDemGeoTiff(land, h, 101, 101, {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, kLocalTm, kNodata);
  const GisScene landlocked = BuildWith(land, SceneConfig(), options);
  EXPECT_FALSE(landlocked.stats.sea_from_dem);
  EXPECT_EQ(PlanArea(landlocked.mesh, kClassSea), 0.0);
  EXPECT_EQ(landlocked.stats.outside_posts, 5);
  // The 100 x 100 cells minus those touching a border void: cells 9..12 of
  // row 0 (posts 10..12), 59..60 (post 60), rows 39..40 of the last column
  // (post row 40): 8 cells of 100 m^2.
  EXPECT_NEAR(landlocked.stats.mesh_area_m2[kClassDefault], (10000.0 - 8.0) * 100.0, 1.0);
}

// Coastlines (land on the left) closed against the extent. A straight coast
// heading east-north-east through the centre crosses the extent twice: the
// sea is south of it, half the 1000 x 1000 m^2 extent. Reversed, the sea is
// north (also half; checked on the side of a point). A bay (the coast runs
// north along x = -300, east along y = 200, south along x = 300) crossing
// the south border twice: the sea is inside the U, 600 x 700 m^2. A coast
// that ends inside the extent is extended straight along its last
// direction.
TEST(GisSceneTest, CoastlinesClosedAgainstTheExtentGiveTheSeaSide) {
  const fs::path dir = testing::MakeTempDir();
  // A 0 m sea south of the line y = x / 6 and 10 m land north of it: the
  // DEM agrees with the coastlines below (the straight and dangling ones).
  std::string dem_path = DemOf(dir / "coast.tif", [](double x, double y) { return y < x / 6.0 ? 0.0 : 10.0; });
  auto sea_scene = [&](const std::vector<std::vector<Vector2d>>& lines, const std::string& name) {
    std::vector<Feature> features;
    for (const auto& l : lines) features.push_back({"LineString", {l}, R"({"natural": "coastline"})"});
    SceneConfig config;
    config.layers = {Spec(WriteGeoJson(dir / name, features), kClassSea, LayerKind::kCoastline)};
    return Build(dem_path, config);
  };
  auto sea_at = [](const GisScene& scene, const Vector2d& p) {
    for (size_t t = 0; t < scene.mesh.triangle_count(); ++t) {
      const auto& tri = scene.mesh.triangles[t];
      // ENU (the frame is centred on the DEM centre, the TM origin).
      const Vector2d a = scene.mesh.vertices[tri[0]].head<2>().cast<double>();
      const Vector2d b = scene.mesh.vertices[tri[1]].head<2>().cast<double>();
      const Vector2d c = scene.mesh.vertices[tri[2]].head<2>().cast<double>();
      const double d = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
      const double s = ((p - a).x() * (c - a).y() - (p - a).y() * (c - a).x()) / d;
      const double u = ((b - a).x() * (p - a).y() - (b - a).y() * (p - a).x()) / d;
      if (s >= 0 && u >= 0 && s + u <= 1) return scene.mesh.classes[t] == kClassSea;
    }
    return false;
  };
  {
    const GisScene scene = sea_scene({{{-600, -100}, {0, 0}}, {{0, 0}, {600, 100}}}, "straight.geojson");
    EXPECT_NEAR(PlanArea(scene.mesh, kClassSea), 500000.0, 500.0);
    EXPECT_TRUE(sea_at(scene, {0, -300}));
    EXPECT_FALSE(sea_at(scene, {0, 300}));
    ExpectAreasMatch(scene);
  }
  {
    const GisScene scene = sea_scene({{{600, 100}, {-600, -100}}}, "reversed.geojson");
    EXPECT_NEAR(PlanArea(scene.mesh, kClassSea), 500000.0, 500.0);
    EXPECT_TRUE(sea_at(scene, {0, 300}));
    EXPECT_FALSE(sea_at(scene, {0, -300}));
  }
  {
    const GisScene scene = sea_scene({{{-300, -600}, {-300, 200}, {300, 200}, {300, -600}}}, "bay.geojson");
    EXPECT_NEAR(PlanArea(scene.mesh, kClassSea), 600.0 * 700.0, 500.0);
    EXPECT_TRUE(sea_at(scene, {0, 0}));
    EXPECT_FALSE(sea_at(scene, {-400, 0}));
    EXPECT_FALSE(sea_at(scene, {0, 400}));
  }
  {
    // Ends at the origin, inside: extended along (6, 1) to the east border.
    // The DEM (0 m south of the line, 10 m north) agrees with the guess to
    // within a post: beyond 20 m of the mapped coast the shore is the DEM's
    // 1 m contour, which runs 1 m north of the last 0 m post, so up to one
    // post (10 m) short of the line along the extension's 500 m.
    const GisScene scene = sea_scene({{{-600, -100}, {-300, -50}, {0, 0}}}, "dangling.geojson");
    EXPECT_EQ(scene.stats.coastline_extended_ends, 1);
    EXPECT_LE(PlanArea(scene.mesh, kClassSea), 500000.0 + 500.0);
    EXPECT_GE(PlanArea(scene.mesh, kClassSea), 500000.0 - 500.0 * 10.0);
    EXPECT_TRUE(sea_at(scene, {300, -300}));
  }
  {
    // The same coast on a DEM whose shore turns south-east of the origin:
    // the sea floor is 0 m west of the line x + 0.4 y = 200 and rises 0.1 m
    // per metre east of it, so the 1 m contour is the oblique line
    // x + 0.4 y = 210. Beyond 2 posts (20 m) of the mapped coast, the
    // extension's sea stops on that contour: 6 m (0.6 post) either side of it
    // is sea and land. (The former rule, sea within 2 posts of a post at most
    // 1 m high, drew a staircase of cells reaching up to 20 m inland.)
    dem_path = DemOf(dir / "turn.tif", [](double x, double y) {
      return y < x / 6.0 ? 0.1 * std::max(0.0, x + 0.4 * y - 200.0) : 10.0;
    });
    const GisScene scene = sea_scene({{{-600, -100}, {-300, -50}, {0, 0}}}, "dangling2.geojson");
    for (const double y : {-450.0, -400.0, -333.0, -300.0, -250.0, -200.0}) {
      const double shore_x = 210.0 - 0.4 * y;
      EXPECT_TRUE(sea_at(scene, {shore_x - 6.0, y})) << y;
      EXPECT_FALSE(sea_at(scene, {shore_x + 6.0, y})) << y;
    }
    EXPECT_TRUE(sea_at(scene, {100, -300}));
    EXPECT_FALSE(sea_at(scene, {400, -300}));
    EXPECT_GT(scene.stats.sea_trimmed_m2, 50000.0);
    ExpectAreasMatch(scene);
  }
  {
    // A flat sea: the DEM says 5 m over the sea (noise, a smoothed cliff);
    // every vertex of a sea face is at the sea level (0 m, ENU z within the
    // Earth's curvature over 700 m: 4 cm), the shore included, except shore
    // vertices a few metres from a 10 m land post (a face steeper than 75
    // degrees: those keep their DEM height); the land away from the shore
    // stays at 10 m.
    dem_path = DemOf(dir / "noisy.tif", [](double x, double y) { return y < x / 6.0 ? 5.0 : 10.0; });
    const GisScene scene = sea_scene({{{-600, -100}, {0, 0}}, {{0, 0}, {600, 100}}}, "straight2.geojson");
    EXPECT_GT(scene.stats.sea_level_vertices, 0);
    std::set<int> sea_vertices, land_vertices;
    for (size_t t = 0; t < scene.mesh.triangle_count(); ++t) {
      for (int k = 0; k < 3; ++k) {
        (scene.mesh.classes[t] == kClassSea ? sea_vertices : land_vertices).insert(scene.mesh.triangles[t][k]);
      }
    }
    ASSERT_FALSE(sea_vertices.empty());
    int shore = 0, shore_at_sea_level = 0;
    for (int v : sea_vertices) {
      const float z = scene.mesh.vertices[v].z();
      if (!land_vertices.count(v)) {
        EXPECT_NEAR(z, 0.0, 0.05) << v;
        continue;
      }
      ++shore;
      if (std::abs(z) < 0.05) ++shore_at_sea_level;
    }
    EXPECT_GT(shore, 50);
    EXPECT_GE(shore_at_sea_level, 0.5 * shore);
    // And no terrain face is steeper than 75 degrees.
    for (size_t t = 0; t < scene.mesh.triangle_count(); ++t) {
      const auto& tri = scene.mesh.triangles[t];
      const Eigen::Vector3d a = scene.mesh.vertices[tri[0]].cast<double>();
      const Eigen::Vector3d n = (scene.mesh.vertices[tri[1]].cast<double>() - a)
                                    .cross(scene.mesh.vertices[tri[2]].cast<double>() - a);
      EXPECT_GE(n.z(), std::cos(75.5 * M_PI / 180.0) * n.norm()) << t;
    }
    for (size_t v = 0; v < scene.mesh.vertices.size(); ++v) {
      const Eigen::Vector3f p = scene.mesh.vertices[v];
      if (p.y() > p.x() / 6.0 + 30.0) {
        EXPECT_NEAR(p.z(), 10.0, 0.05) << v;
      }
    }
    EXPECT_NEAR(PlanArea(scene.mesh, kClassSea), 500000.0, 500.0);
  }
}

// The rule simulate --dem applies: posts at or below the sea level
// connected to the border, voids only next to sea posts. 6 x 4 posts,
// columns 0-2 at 0 m, 3-5 at 5 m: sea cells are columns 0-1 of the 3 cell
// rows, 12 grid triangles. A void inside the sea (2, 2) is sea; voids on
// the land border (4, 0) and (5, 3) are not.
TEST(GisSceneTest, SeaPostMaskAndGridTriangles) {
  geo::Dem dem;
  dem.width = 6;
  dem.height = 4;
  dem.heights_m.assign(24, 5.0f);
  dem.nodata_mask.assign(24, 0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 3; ++c) dem.heights_m[size_t(r) * 6 + c] = 0.0f;
  for (int i : {2 * 6 + 2, 0 * 6 + 4, 3 * 6 + 5}) {
    dem.nodata_mask[i] = 1;
    dem.heights_m[i] = 3.0f;  // filled by interpolation: above the sea level
  }
  const std::vector<uint8_t> sea = SeaPostMask(dem, 0.0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 6; ++c) EXPECT_EQ(sea[size_t(r) * 6 + c], c < 3 ? 1 : 0) << c << "," << r;
  TriangleMesh mesh = MeshFromHeights(dem.heights_m, 6, 4, 10.0);
  EXPECT_EQ(MarkSeaTriangles(mesh, sea), 12);
  EXPECT_EQ(std::count(mesh.classes.begin(), mesh.classes.end(), kClassSea), 12);
  // Landlocked at 1000 m with border voids: no sea at all.
  dem.heights_m.assign(24, 1000.0f);
  const std::vector<uint8_t> none = SeaPostMask(dem, 0.0);
  EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);
}

TEST(GisSceneTest, BuildingHeightAndLineWidthRules) {
  EXPECT_EQ(BuildingHeight({{"height", "12.5 m"}}, 10, 3), 12.5);
  EXPECT_EQ(BuildingHeight({{"height", "tall"}, {"building:levels", "5"}}, 10, 3), 15.0);
  EXPECT_EQ(BuildingHeight({}, 10, 3), 10.0);
  // Beyond 10 km a tag is ignored (the default, or the next rule, applies).
  EXPECT_EQ(BuildingHeight({{"height", "1e300"}}, 10, 3), 10.0);
  EXPECT_EQ(BuildingHeight({{"height", "1e300"}, {"building:levels", "4"}}, 10, 3), 12.0);
  EXPECT_EQ(LineWidth({{"highway", "motorway"}, {"width", "1e300"}}, DefaultLineWidths(), 5), 25.0);
  const auto table = DefaultLineWidths();
  EXPECT_EQ(LineWidth({{"highway", "motorway"}}, table, 5), 25.0);
  EXPECT_EQ(LineWidth({{"highway", "motorway"}, {"width", "9"}}, table, 5), 9.0);
  EXPECT_EQ(LineWidth({{"waterway", "river"}}, table, 5), 15.0);
  EXPECT_EQ(LineWidth({{"highway", "bridleway"}}, table, 5), 5.0);
}

TEST(GisSceneTest, AndorraLayersAreConstrainedAndAreasMatch) {
  std::vector<std::string> warnings;
  const SceneConfig config =
      LayerNamePreset({testing::DataPath("andorra/andorra_osm.gpkg").string()}, &warnings);
  const GisScene scene = Build(testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string(), config);
  EXPECT_GT(scene.stats.features_read, 1800);
  for (int c : {kClassWater, kClassForest, kClassUrban, kClassRoad}) {
    EXPECT_GT(scene.stats.region_area_m2[c], 1e4) << ClassNames()[c];
  }
  ExpectAreasMatch(scene);
  ExpectBoundariesAreMeshEdges(scene);
}

// Forest rectangles on the post lattice, free water quadrilaterals, roads
// (one along a lattice row) and buildings on a tilted plane: the cells the
// constraints touch go through the CDT, the others are split directly.
// Against the CDT of every post: the same plan area per class and the same
// walls, computed from the triangles; and the terrain is closed: an edge
// that only one terrain triangle uses lies on the DEM's border or at the
// foot of a wall (a T-junction between the two parts would leave one
// inside).
// Both on a map grid (square cells) and on a geographic grid (cells of
// 0.00012 x 0.00009 deg, sheared in M by the meridians' convergence).
TEST(GisSceneTest, DirectlyTriangulatedCellsMeetTheCdtEdgeToEdge) {
  const fs::path dir = testing::MakeTempDir();
  auto plane = [](double x, double y) { return 200.0 + 0.1 * x - 0.05 * y; };
  std::string geographic = (dir / "geographic.tif").string();
  {
    // 101 x 101 posts over the same square kilometre, heights of the plane
    // at each post's local TM coordinates.
    const double lon0 = 1.6 - 0.00612, lat0 = 42.5 + 0.0045, dlon = 0.0001224, dlat = 0.00009;
    std::vector<double> lon, lat;
    for (int r = 0; r < 101; ++r)
      for (int c = 0; c < 101; ++c) {
        lon.push_back(lon0 + dlon * c);
        lat.push_back(lat0 - dlat * r);
      }
    geo::CrsTransform tm(kLocalTm);
    std::vector<double> x = lon, y = lat;
    tm.FromLonLat(x, y);
    std::vector<float> h(101 * 101);
    for (size_t i = 0; i < h.size(); ++i) h[i] = static_cast<float>(plane(x[i], y[i]));
    geo::WriteDemGeoTiff(geographic, h, 101, 101, {lon0 - dlon / 2, dlon, 0.0, lat0 + dlat / 2, 0.0, -dlat}, "EPSG:4326");
  }
  for (const std::string& dem_path : {DemOf(dir / "tilted.tif", plane), geographic}) {
  SCOPED_TRACE(dem_path);
  std::mt19937 rng(23);
  auto post = [&](int lo, int hi) { return 10.0 * std::uniform_int_distribution<int>(lo, hi)(rng); };
  std::uniform_real_distribution<double> anywhere(-470.0, 420.0);
  std::vector<Feature> forest, water, buildings;
  for (int i = 0; i < 12; ++i) {
    const double x0 = post(-48, 30), y0 = post(-48, 30);
    forest.push_back({"Polygon", {Rect(x0, y0, x0 + post(2, 15), y0 + post(2, 15))}});
    const Vector2d c(anywhere(rng), anywhere(rng));
    water.push_back({"Polygon", {{c, c + Vector2d(37.3, 4.1), c + Vector2d(41.0, 52.7), c + Vector2d(-3.3, 47.9), c}}});
    const double bx = post(-45, 40), by = post(-45, 40);
    buildings.push_back({"Polygon", {Rect(bx, by, bx + post(1, 4), by + post(1, 4))}, R"({"height": "15"})"});
  }
  const std::vector<Feature> roads = {{"LineString", {{{-600, 0}, {600, 0}}}, R"({"highway": "primary"})"},
                                      {"LineString", {{{-400, -430}, {380, 410}}}, R"({"highway": "residential"})"}};
  SceneConfig config;
  config.line_widths_m = DefaultLineWidths();
  config.layers = {Spec(WriteGeoJson(dir / "forest.geojson", forest), kClassForest, LayerKind::kPolygon),
                   Spec(WriteGeoJson(dir / "water.geojson", water), kClassWater, LayerKind::kPolygon),
                   Spec(WriteGeoJson(dir / "roads.geojson", roads), kClassRoad, LayerKind::kLine),
                   Spec(WriteGeoJson(dir / "buildings.geojson", buildings), kClassBuilding, LayerKind::kBuilding)};
  const geo::Dem dem = geo::ReadDem(dem_path);
  const geo::GeoPoint centre = geo::ResolveSceneCentre(dem, std::nullopt, std::nullopt);
  const geo::LocalFrame frame(centre.lon_deg, centre.lat_deg);
  const GisScene fast = BuildGisScene(dem, frame, config);
  const GisScene every = BuildGisScene(dem, frame, config, NullReporter(), TerrainTriangulation::kEveryPost);
  EXPECT_EQ(fast.stats.cdt_cells + fast.stats.grid_cells, 100 * 100);
  EXPECT_GT(fast.stats.grid_cells, 100 * 100 / 2);
  EXPECT_EQ(every.stats.cdt_cells, 100 * 100);
  EXPECT_EQ(every.stats.grid_cells, 0);
  // The directly split terrain cells open the mesh as a terrain grid on the
  // posts (the roofs of directly split cells inside buildings come later).
  EXPECT_EQ(fast.grid.width, 101);
  EXPECT_EQ(fast.grid.height, 101);
  EXPECT_GT(fast.grid.cells, fast.stats.grid_cells * 9 / 10);
  EXPECT_LE(fast.grid.cells, fast.stats.grid_cells);
  const auto cells = GridPrefixCells(fast.mesh, fast.grid);
  ASSERT_TRUE(cells.has_value());
  EXPECT_EQ(std::count(cells->begin(), cells->end(), 1), fast.grid.cells);
  EXPECT_EQ(every.grid.cells, 0);

  struct Summary {
    std::array<double, kClassCount> plan_area_m2{};
    int walls = 0;
    double wall_area_m2 = 0.0;
  };
  auto summarise = [](const GisScene& scene) {
    Summary s;
    const TriangleMesh& mesh = scene.mesh;
    for (size_t t = 0; t < mesh.triangle_count(); ++t) {
      const Eigen::Vector3i& tri = mesh.triangles[t];
      const Vector2d e1 = scene.planar[tri[1]] - scene.planar[tri[0]], e2 = scene.planar[tri[2]] - scene.planar[tri[0]];
      s.plan_area_m2[mesh.classes[t]] += 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
      if (mesh.classes[t] == kClassBuilding && std::abs(mesh.Normal(t).z()) < 0.01f) {
        ++s.walls;
        s.wall_area_m2 += AreaOf(mesh, t);
      }
    }
    return s;
  };
  const Summary a = summarise(fast), b = summarise(every);
  for (int c = 0; c < kClassCount; ++c) {
    EXPECT_NEAR(a.plan_area_m2[c], b.plan_area_m2[c], 1e-3) << ClassNames()[c];
    EXPECT_NEAR(fast.stats.mesh_area_m2[c], every.stats.mesh_area_m2[c], 1e-3) << ClassNames()[c];
  }
  EXPECT_GT(a.plan_area_m2[kClassForest], 1e4);
  EXPECT_GT(a.plan_area_m2[kClassWater], 1e4);
  EXPECT_GT(a.plan_area_m2[kClassRoad], 1e4);
  EXPECT_GT(a.walls, 12 * 8);
  EXPECT_EQ(a.walls, b.walls);
  EXPECT_NEAR(a.wall_area_m2, b.wall_area_m2, 1e-3);
  ExpectAreasMatch(fast);
  ExpectBoundariesAreMeshEdges(fast);

  // Closed terrain: edges used by one terrain triangle, not on the DEM's
  // border nor at the foot of a wall. The CDT leaves a few of its own
  // (both sides of a terrain sliver narrower than 10 um, dropped, between two
  // constraints that nearly touch); the direct cells must add none.
  struct Openness {
    int open_inside = 0, over_used = 0, border_edges = 0;
  };
  auto openness = [&](const GisScene& scene) {
    Openness o;
    const Eigen::Matrix2d cell_from_planar = scene.planar_from_cell.inverse();
    auto plan_key = [](const Vector2d& p, const Vector2d& q) {
      std::array<int64_t, 4> k = {std::llround(p.x() * 1e4), std::llround(p.y() * 1e4), std::llround(q.x() * 1e4),
                                  std::llround(q.y() * 1e4)};
      if (std::make_pair(k[2], k[3]) < std::make_pair(k[0], k[1])) k = {k[2], k[3], k[0], k[1]};
      return k;
    };
    std::map<std::pair<int, int>, int> uses;
    std::set<std::array<int64_t, 4>> building_edges;
    for (size_t t = 0; t < scene.mesh.triangle_count(); ++t) {
      const Eigen::Vector3i& tri = scene.mesh.triangles[t];
      for (int k = 0; k < 3; ++k) {
        const int p = tri[k], q = tri[(k + 1) % 3];
        if (scene.mesh.classes[t] == kClassBuilding) {
          building_edges.insert(plan_key(scene.planar[p], scene.planar[q]));
        } else {
          ++uses[{std::min(p, q), std::max(p, q)}];
        }
      }
    }
    auto on_dem_border = [&](const Vector2d& p, const Vector2d& q) {
      const Vector2d cp = cell_from_planar * p, cq = cell_from_planar * q;
      for (int axis = 0; axis < 2; ++axis) {
        for (const double line : {0.0, 100.0}) {
          if (std::abs(cp[axis] - line) < 1e-6 && std::abs(cq[axis] - line) < 1e-6) return true;
        }
      }
      return false;
    };
    for (const auto& [edge, count] : uses) {
      if (count > 2) ++o.over_used;
      if (count != 1) continue;
      const Vector2d& p = scene.planar[edge.first];
      const Vector2d& q = scene.planar[edge.second];
      if (on_dem_border(p, q)) {
        ++o.border_edges;
      } else if (building_edges.count(plan_key(p, q)) == 0) {
        ++o.open_inside;
      }
    }
    return o;
  };
  const Openness of_fast = openness(fast), of_every = openness(every);
  EXPECT_EQ(of_fast.over_used, 0);
  EXPECT_EQ(of_every.over_used, 0);
  EXPECT_EQ(of_fast.open_inside, of_every.open_inside);
  EXPECT_LE(of_fast.open_inside, 2 * fast.stats.sliver_faces);
  EXPECT_EQ(of_fast.border_edges, of_every.border_edges);
  EXPECT_GE(of_fast.border_edges, 4 * 100);
  }
}

TEST(GisSceneTest, BadVectorInputIsAClearError) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  SceneConfig config;
  config.layers = {Spec((dir / "missing.geojson").string(), kClassWater, LayerKind::kPolygon)};
  EXPECT_THROW(Build(dem, config), InputError);
  LayerSpec bad_layer = Spec(testing::DataPath("andorra/andorra_osm.gpkg").string(), kClassWater,
                             LayerKind::kPolygon);
  bad_layer.source.layer = "lakes";
  config.layers = {bad_layer};
  try {
    Build(dem, config);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(e.message().find("no layer 'lakes' (layers: water, forest, roads, waterways, urban)"),
              std::string::npos) << e.what();
  }
  // An empty layer is a warning, not an error.
  const std::string empty = WriteGeoJson(dir / "empty.geojson", {});
  config.layers = {Spec(empty, kClassWater, LayerKind::kPolygon)};
  const GisScene scene = Build(dem, config);
  ASSERT_EQ(scene.warnings.size(), 1u);
  EXPECT_NE(scene.warnings[0].find("no features"), std::string::npos);
}

}  // namespace
}  // namespace gissar::scene
