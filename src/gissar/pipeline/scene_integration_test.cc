// Integration tests of `scene build` on the bundled real data (data/monaco,
// data/andorra): the geometry promises of docs/scene.md measured on the built
// mesh by code that is independent of the builder's own decisions (it
// recomputes every triangle's normal from its vertices, decides a wall's
// side from the roofs of the mesh, and derives the reference sea from the
// DEM file with its own geodesy), like scripts/scene_metrics.py.
// CTest label: `scene_integration_test` (ctest -L scene_integration).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "gissar/geo/dem.h"
#include "gissar/pipeline/locate.h"
#include "gissar/pipeline/locate_door.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/simulate.h"
#include "gissar/render/image_agreement.h"
#include "gissar/scene/scene_config.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

const double kCos80 = std::cos(80.0 * M_PI / 180.0);

Eigen::Vector3d V(const scene::TriangleMesh& m, int i) { return m.vertices[size_t(i)].cast<double>(); }

Eigen::Vector3d Cross(const scene::TriangleMesh& m, size_t t) {
  const Eigen::Vector3i& f = m.triangles[t];
  const Eigen::Vector3d a = V(m, f[0]);
  return (V(m, f[1]) - a).cross(V(m, f[2]) - a);
}

// Triangles hashed by plan grid cells, for point-in-triangle queries in plan.
class PlanIndex {
 public:
  PlanIndex(const scene::TriangleMesh& mesh, std::vector<size_t> tris, double cell_m)
      : mesh_(mesh), tris_(std::move(tris)), cell_m_(cell_m) {
    for (size_t k = 0; k < tris_.size(); ++k) {
      Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
      for (int j = 0; j < 3; ++j) {
        const Eigen::Vector2d p = V(mesh_, mesh_.triangles[tris_[k]][j]).head<2>();
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      for (int64_t i = Cell(lo.x()); i <= Cell(hi.x()); ++i)
        for (int64_t j = Cell(lo.y()); j <= Cell(hi.y()); ++j) grid_[Key(i, j)].push_back(tris_[k]);
    }
  }

  // Triangles (mesh indices) whose plan projection contains (x, y), edges
  // included, with the height of their plane there.
  std::vector<std::pair<size_t, double>> Find(double x, double y) const {
    std::vector<std::pair<size_t, double>> out;
    const auto it = grid_.find(Key(Cell(x), Cell(y)));
    if (it == grid_.end()) return out;
    for (size_t t : it->second) {
      const Eigen::Vector3i& f = mesh_.triangles[t];
      const Eigen::Vector3d a = V(mesh_, f[0]), b = V(mesh_, f[1]), c = V(mesh_, f[2]);
      const double d = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
      if (d == 0) continue;
      const double s = ((x - a.x()) * (c.y() - a.y()) - (y - a.y()) * (c.x() - a.x())) / d;
      const double u = ((b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x())) / d;
      if (s >= 0 && u >= 0 && s + u <= 1) out.push_back({t, a.z() + s * (b.z() - a.z()) + u * (c.z() - a.z())});
    }
    return out;
  }

 private:
  int64_t Cell(double v) const { return static_cast<int64_t>(std::floor(v / cell_m_)); }
  static int64_t Key(int64_t i, int64_t j) { return i * 1000003 + j; }
  const scene::TriangleMesh& mesh_;
  std::vector<size_t> tris_;
  double cell_m_;
  std::unordered_map<int64_t, std::vector<size_t>> grid_;
};

struct TerrainMetrics {
  int64_t downward_triangles = 0;
  double near_vertical_area_m2 = 0;
  int64_t near_vertical_triangles = 0;
};

// Terrain = every class but building: no triangle faces down, none is
// steeper than 80 degrees.
TerrainMetrics MeasureTerrain(const scene::TriangleMesh& mesh) {
  TerrainMetrics m;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] == scene::kClassBuilding) continue;
    const Eigen::Vector3d n = Cross(mesh, t);
    const double norm = n.norm();
    if (!(norm > 0)) continue;
    if (n.z() < 0) ++m.downward_triangles;
    if (n.z() / norm < kCos80) {
      ++m.near_vertical_triangles;
      m.near_vertical_area_m2 += 0.5 * norm;
    }
  }
  return m;
}

struct WallMetrics {
  int64_t walls = 0;
  int64_t inverted = 0;   // the normal points into the roof the wall carries
  int64_t confirmed = 0;  // behind the wall (against its normal) lies its own roof
  int64_t pit_or_step = 0;  // in front of it lies a roof at its foot
};

// A wall (building triangle steeper than 80 degrees) is a vertical strip of
// a footprint edge; its own roof is the flat building triangle at the
// wall's top height on one side of that edge. Probing a short distance from
// the middle of the wall's plan segment along the normal must not land on
// that roof (it lands on open ground or on a lower roof: a step), and
// probing against the normal lands on it. The probe is at most a quarter of
// the segment's length, so it does not leave the wall's own edge at a
// concave footprint corner.
WallMetrics MeasureWalls(const scene::TriangleMesh& mesh) {
  std::vector<size_t> walls, roofs;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.classes[t] != scene::kClassBuilding) continue;
    const Eigen::Vector3d n = Cross(mesh, t);
    const double norm = n.norm();
    if (!(norm > 0)) continue;
    if (std::abs(n.z()) / norm < kCos80) walls.push_back(t);
    if (n.z() / norm > 0.99) roofs.push_back(t);
  }
  const PlanIndex roof_index(mesh, roofs, 10.0);
  WallMetrics m;
  m.walls = static_cast<int64_t>(walls.size());
  for (size_t t : walls) {
    const Eigen::Vector3d n = Cross(mesh, t);
    const Eigen::Vector2d out = n.head<2>().normalized();
    const Eigen::Vector2d along(-out.y(), out.x());
    double s_lo = 1e300, s_hi = -1e300, top = -1e300, foot = 1e300;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d p = V(mesh, mesh.triangles[t][j]);
      s_lo = std::min(s_lo, p.head<2>().dot(along));
      s_hi = std::max(s_hi, p.head<2>().dot(along));
      top = std::max(top, p.z());
      foot = std::min(foot, p.z());
      mean += p.head<2>() / 3.0;
    }
    // Middle of the plan segment (the wall's vertices lie on one line in plan).
    const Eigen::Vector2d mid = mean + (0.5 * (s_lo + s_hi) - mean.dot(along)) * along;
    const double probe_m = std::min(0.05, 0.25 * (s_hi - s_lo));
    if (!(probe_m > 1e-3)) continue;  // a sliver narrower than 4 mm: no side to probe
    auto roof_at = [&](const Eigen::Vector2d& q, bool at_top) {
      for (const auto& [roof, z] : roof_index.Find(q.x(), q.y())) {
        if (at_top && std::abs(z - top) < 0.05 && std::abs(z - top) < std::abs(z - foot)) return true;
        if (!at_top && std::abs(z - foot) < 0.05 && std::abs(z - foot) <= std::abs(z - top)) return true;
      }
      return false;
    };
    if (roof_at(mid + probe_m * out, true)) ++m.inverted;
    if (roof_at(mid - probe_m * out, true)) ++m.confirmed;
    if (roof_at(mid + probe_m * out, false)) ++m.pit_or_step;
  }
  return m;
}

// ENU metres (frame at lon0, lat0, height 0) of a WGS84 point, written out
// here rather than taken from geo::LocalFrame.
Eigen::Vector3d EnuFromGeodetic(double lon_deg, double lat_deg, double h_m, double lon0_deg, double lat0_deg) {
  const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2 - f);
  auto ecef = [&](double lo_deg, double la_deg, double hh) {
    const double lo = lo_deg * M_PI / 180, la = la_deg * M_PI / 180;
    const double n = a / std::sqrt(1 - e2 * std::sin(la) * std::sin(la));
    return Eigen::Vector3d((n + hh) * std::cos(la) * std::cos(lo), (n + hh) * std::cos(la) * std::sin(lo),
                           (n * (1 - e2) + hh) * std::sin(la));
  };
  const Eigen::Vector3d d = ecef(lon_deg, lat_deg, h_m) - ecef(lon0_deg, lat0_deg, 0.0);
  const double lo = lon0_deg * M_PI / 180, la = lat0_deg * M_PI / 180;
  const Eigen::Vector3d e(-std::sin(lo), std::cos(lo), 0);
  const Eigen::Vector3d n(-std::sin(la) * std::cos(lo), -std::sin(la) * std::sin(lo), std::cos(la));
  const Eigen::Vector3d u(std::cos(la) * std::cos(lo), std::cos(la) * std::sin(lo), std::sin(la));
  return {d.dot(e), d.dot(n), d.dot(u)};
}

struct SeaMetrics {
  int64_t reference_cells = 0;
  int64_t sea_cells = 0;  // reference cells whose centre lies on a `sea` triangle
  double reference_area_m2 = 0;
};

// Reference sea of an EPSG:4326 DEM: the cells whose four posts are valid,
// at or below 0 m and 4-connected (through such posts) to the DEM border,
// i.e. the seaward side of the coastline inside the extent as the DEM sees
// it. Each cell's centre is looked up on the mesh's ground triangles.
SeaMetrics MeasureSea(const scene::SceneFile& file, const std::string& dem_path) {
  geo::DemReadOptions ro;
  ro.fill_nodata = true;
  const geo::Dem dem = geo::ReadDem(dem_path, ro);
  const int w = dem.width, h = dem.height;
  std::vector<uint8_t> low(size_t(w) * h, 0), sea(size_t(w) * h, 0);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) low[size_t(r) * w + c] = !dem.IsNodata(c, r) && dem.HeightAt(c, r) <= 0.0f;
  std::deque<std::pair<int, int>> queue;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c)
      if ((r == 0 || c == 0 || r == h - 1 || c == w - 1) && low[size_t(r) * w + c]) {
        sea[size_t(r) * w + c] = 1;
        queue.push_back({r, c});
      }
  while (!queue.empty()) {
    const auto [r, c] = queue.front();
    queue.pop_front();
    const int dr[4] = {-1, 1, 0, 0}, dc[4] = {0, 0, -1, 1};
    for (int k = 0; k < 4; ++k) {
      const int rr = r + dr[k], cc = c + dc[k];
      if (rr < 0 || cc < 0 || rr >= h || cc >= w) continue;
      const size_t i = size_t(rr) * w + cc;
      if (low[i] && !sea[i]) {
        sea[i] = 1;
        queue.push_back({rr, cc});
      }
    }
  }
  const scene::TriangleMesh& mesh = file.mesh;
  std::vector<size_t> ground;
  for (size_t t = 0; t < mesh.triangle_count(); ++t)
    if (mesh.classes[t] != scene::kClassBuilding) ground.push_back(t);
  const PlanIndex index(mesh, ground, 50.0);
  const std::array<double, 6>& gt = dem.geotransform;
  SeaMetrics m;
  for (int r = 0; r + 1 < h; ++r)
    for (int c = 0; c + 1 < w; ++c) {
      if (!(sea[size_t(r) * w + c] && sea[size_t(r) * w + c + 1] && sea[size_t(r + 1) * w + c] &&
            sea[size_t(r + 1) * w + c + 1])) {
        continue;
      }
      // Posts are at cell centres of the raster: post (c, r) at pixel
      // (c + 0.5, r + 0.5), so the middle of the four posts is at (c + 1, r + 1).
      auto enu = [&](double px, double py) {
        return EnuFromGeodetic(gt[0] + px * gt[1] + py * gt[2], gt[3] + px * gt[4] + py * gt[5], 0.0,
                               file.origin_lon_deg, file.origin_lat_deg);
      };
      const Eigen::Vector3d p = enu(c + 1.0, r + 1.0);
      const Eigen::Vector3d ex = enu(c + 1.5, r + 1.0) - enu(c + 0.5, r + 1.0);
      const Eigen::Vector3d ey = enu(c + 1.0, r + 1.5) - enu(c + 1.0, r + 0.5);
      ++m.reference_cells;
      m.reference_area_m2 += std::abs(ex.x() * ey.y() - ex.y() * ey.x());
      const auto hits = index.Find(p.x(), p.y());
      if (!hits.empty() && mesh.classes[hits.front().first] == scene::kClassSea) ++m.sea_cells;
    }
  return m;
}

// One row of `scene info`: "<class> <triangles> <plan km2> <surface km2>".
bool InfoRow(const std::string& info, const std::string& name, int64_t* triangles, double* plan_km2) {
  std::istringstream in(info);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string first;
    double surface = 0;
    if (row >> first && first == name && row >> *triangles >> *plan_km2 >> surface) return true;
  }
  return false;
}

std::string MonacoDem() { return testing::DataPath("monaco/monaco_srtm3_dem.tif").string(); }

// The Monaco scene as the demo builds it: SRTM DEM + OpenStreetMap
// (buildings, roads, the coastline).
TEST(SceneIntegration, MonacoWallsTerrainAndSea) {
  const fs::path dir = testing::MakeTempDir();
  SceneBuildRequest o;
  o.dem = MonacoDem();
  o.fill_nodata = true;
  o.osm = testing::DataPath("monaco/monaco.osm.gz").string();
  o.out_prefix = (dir / "monaco").string();
  RunSceneBuild(o, "test");
  const scene::SceneFile file = scene::ReadScene(dir / "monaco.gscene");

  const WallMetrics walls = MeasureWalls(file.mesh);
  // Monaco has ~1000 buildings: thousands of walls, none facing inwards, and
  // nearly all of them with their own roof behind them or, for the sides of
  // a pit (a roof below the uphill ground) and steps, a roof in front at
  // their foot.
  EXPECT_GT(walls.walls, 5000);
  EXPECT_EQ(walls.inverted, 0);
  EXPECT_GT(walls.confirmed + walls.pit_or_step, 0.99 * walls.walls)
      << walls.walls << " walls, " << walls.confirmed << " confirmed, " << walls.pit_or_step << " pit/step";

  const TerrainMetrics terrain = MeasureTerrain(file.mesh);
  EXPECT_EQ(terrain.downward_triangles, 0);
  EXPECT_EQ(terrain.near_vertical_triangles, 0);
  EXPECT_EQ(terrain.near_vertical_area_m2, 0.0);

  const SeaMetrics sea = MeasureSea(file, MonacoDem());
  std::printf("monaco: %lld walls, %lld inverted, %lld own roof behind, %lld pit/step; sea %lld of %lld reference cells\n",
              (long long)walls.walls, (long long)walls.inverted, (long long)walls.confirmed,
              (long long)walls.pit_or_step, (long long)sea.sea_cells, (long long)sea.reference_cells);
  // The Mediterranean covers several hundred of the DEM's 95 x 71 cells.
  EXPECT_GT(sea.reference_cells, 500);
  EXPECT_GE(double(sea.sea_cells), 0.95 * double(sea.reference_cells));

  std::ostringstream info;
  PrintSceneInfo((dir / "monaco.gscene").string(), info);
  int64_t sea_triangles = 0;
  double sea_plan_km2 = 0;
  ASSERT_TRUE(InfoRow(info.str(), "sea", &sea_triangles, &sea_plan_km2)) << info.str();
  EXPECT_GT(sea_triangles, 0);
  // Class `sea` covers at least 95 % of the reference sea's area (the
  // coastline also puts the strip between the shore and the 0 m posts in it).
  EXPECT_GE(sea_plan_km2 * 1e6, 0.95 * sea.reference_area_m2) << info.str();
}

// Issue 16: positioning on the Monaco scene succeeds in at least 95 % of the
// trials of the command pinned in docs/navigation.md (`gissar evaluate
// --scene monaco_scene.gscene --trials 200 --seed 1 --spacing 15 --size 128
// --slant-range 8000`; the matcher comparison, which does not change the
// fixes, is skipped here). Success: converged, 3-D position error <= 2 cells
// and heading error <= 0.2 deg. The observed images carry 4-look speckle,
// -25 dB noise, +-3 dB material errors and a smoothed DEM.
TEST(SceneIntegration, MonacoPositioningSucceedsInAtLeast95PercentOfTrials) {
  const fs::path dir = testing::MakeTempDir();
  SceneBuildRequest build;
  build.dem = MonacoDem();
  build.fill_nodata = true;
  build.osm = testing::DataPath("monaco/monaco.osm.gz").string();
  build.out_prefix = (dir / "monaco").string();
  RunSceneBuild(build, "test");
  EvaluateRequest o;
  o.scene = (dir / "monaco.gscene").string();
  o.trials = 200;
  o.seed = 1;
  o.spacing_m = 15.0;
  o.size_px = 128;
  o.slant_range_m = 8000.0;
  o.compare_matchers = false;
  o.out_prefix = (dir / "monaco200").string();
  const nlohmann::json s = RunEvaluate(o, "test");
  const double rate = s["success_rate"].get<double>();
  std::printf("monaco evaluate: success %.3f, position median %.1f m, p95 %.1f m\n", rate,
              s["position_error_m"]["median"].get<double>(), s["position_error_m"]["p95"].get<double>());
  EXPECT_GE(rate, 0.95);
  // Median position error below one cell (15 m).
  EXPECT_LT(s["position_error_m"]["median"].get<double>(), 15.0);
}

// Without vectors the sea comes from the DEM (--sea auto fallback): posts at
// or below 0 m connected to the border.
TEST(SceneIntegration, MonacoSeaFallbackWithoutVectors) {
  const fs::path dir = testing::MakeTempDir();
  SceneBuildRequest o;
  o.dem = MonacoDem();
  o.fill_nodata = true;
  o.out_prefix = (dir / "monaco_dem").string();
  RunSceneBuild(o, "test");
  const scene::SceneFile file = scene::ReadScene(dir / "monaco_dem.gscene");
  const SeaMetrics sea = MeasureSea(file, MonacoDem());
  EXPECT_GT(sea.reference_cells, 500);
  EXPECT_GE(double(sea.sea_cells), 0.95 * double(sea.reference_cells));
  const TerrainMetrics terrain = MeasureTerrain(file.mesh);
  EXPECT_EQ(terrain.downward_triangles, 0);
  EXPECT_EQ(terrain.near_vertical_area_m2, 0.0);
}

// The Andorra scene as the demo builds it: the raw SRTM DEM (403 voids, some
// on the border) with OpenStreetMap layers. Landlocked: no sea, even where
// border voids sit next to low posts; a clean border with no curtains.
TEST(SceneIntegration, AndorraTerrainBorderAndNoSea) {
  const fs::path dir = testing::MakeTempDir();
  SceneBuildRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_raw.tif").string();
  o.fill_nodata = true;
  o.vectors = {testing::DataPath("andorra/andorra_osm.gpkg").string()};
  o.out_prefix = (dir / "andorra").string();
  RunSceneBuild(o, "test");
  const scene::SceneFile file = scene::ReadScene(dir / "andorra.gscene");
  ASSERT_GT(file.mesh.triangle_count(), 100000u);
  const TerrainMetrics terrain = MeasureTerrain(file.mesh);
  EXPECT_EQ(terrain.downward_triangles, 0);
  EXPECT_EQ(terrain.near_vertical_triangles, 0);
  EXPECT_EQ(terrain.near_vertical_area_m2, 0.0);
  int64_t sea = 0;
  for (size_t t = 0; t < file.mesh.triangle_count(); ++t) sea += file.mesh.classes[t] == scene::kClassSea;
  EXPECT_EQ(sea, 0);
  // Andorra's heights are 809-3067 m: the scene spans them (no collar at 0 m).
  EXPECT_GT(file.mesh.Bounds().min().z(), 700.0);
}

// Issue 18: a GIS scene's terrain traced as a height field (its directly
// split cells; the cells its constraints triangulate, walls and roofs
// through the BVH) against the BVH over every triangle, on both demo scenes
// with three bounces: the same triangles, so the images agree to the last
// bits of the distances (r >= 0.999 of dB, mean difference <= 0.05 dB).
TEST(SceneIntegration, GisScenesTraceTheirTerrainAsAHeightField) {
  const fs::path dir = testing::MakeTempDir();
  struct Case {
    std::string name;
    SceneBuildRequest build;
    double spacing_m;
  };
  std::vector<Case> cases(2);
  cases[0].name = "monaco";
  cases[0].build.dem = MonacoDem();
  cases[0].build.osm = testing::DataPath("monaco/monaco.osm.gz").string();
  cases[0].spacing_m = 15.0;
  cases[1].name = "andorra";
  cases[1].build.dem = testing::DataPath("andorra/andorra_srtm3_dem_raw.tif").string();
  cases[1].build.vectors = {testing::DataPath("andorra/andorra_osm.gpkg").string()};
  cases[1].spacing_m = 60.0;
  for (Case& c : cases) {
    SCOPED_TRACE(c.name);
    c.build.fill_nodata = true;
    c.build.out_prefix = (dir / c.name).string();
    RunSceneBuild(c.build, "test");
    const scene::SceneFile file = scene::ReadScene(c.build.out_prefix + ".gscene");
    const int64_t cells = int64_t(file.grid.width - 1) * (file.grid.height - 1);
    EXPECT_GT(file.grid.cells, cells / 2);
    SimulateRequest o;
    o.scene = c.build.out_prefix + ".gscene";
    o.geometry.heading_deg = 30.0;
    o.geometry.depression_deg = 40.0;
    o.geometry.range_spacing_m = c.spacing_m;
    o.geometry.azimuth_spacing_m = c.spacing_m;
    o.bounces = 3;
    o.out_prefix = (dir / (c.name + "_sim")).string();
    const SimulatedImage heightfield = SimulateImage(o);
    o.heightfield = false;
    const SimulatedImage bvh = SimulateImage(o);
    EXPECT_EQ(heightfield.image.stats.heightfield_cells, file.grid.cells);
    EXPECT_EQ(bvh.image.stats.heightfield_cells, 0);
    ASSERT_EQ(heightfield.image.intensity.size(), bvh.image.intensity.size());
    const render::IntensityAgreement a = render::CompareIntensities(bvh.image.intensity, heightfield.image.intensity);
    std::printf("%s: terrain grid %lld of %lld cells; height field vs BVH: r = %.7f over %lld pixels, mean "
                "difference %.2e dB, %lld pixels zero in one only\n",
                c.name.c_str(), (long long)file.grid.cells, (long long)cells, a.db_pearson,
                (long long)a.compared_pixels, a.mean_db_difference, (long long)a.one_sided_zero);
    EXPECT_GT(a.compared_pixels, 20000);
    EXPECT_GE(a.db_pearson, 0.999);
    EXPECT_LE(std::abs(a.mean_db_difference), 0.05);
    EXPECT_LE(a.one_sided_zero, a.compared_pixels / 1000);
  }
}

}  // namespace
}  // namespace gissar::pipeline
