#include "gissar/scene/gis_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
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
      if (failures < 5) {
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
  EXPECT_EQ(failures, 0) << "of " << scene.boundary_segments.size() << " boundary segments";
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
