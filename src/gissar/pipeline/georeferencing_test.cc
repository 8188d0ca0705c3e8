#include "gissar/pipeline/georeferencing.h"
#include "gissar/pipeline/simulation_output.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <random>

#include <nlohmann/json.hpp>

#include "gissar/geo/raster_io.h"
#include "gissar/geo/warp.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/progress.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

// Andorra's relief as the georeferencing tests see it: SRTM 3" with its
// voids filled, heading 30, depression 40, 150 m pixels (affine).
SimulateRequest AndorraRequest(const std::string& out_prefix) {
  SimulateRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_raw.tif").string();
  o.fill_nodata = true;
  o.geometry.heading_deg = 30.0;
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = 150.0;
  o.geometry.azimuth_spacing_m = 150.0;
  o.tps_gcps = true;  // the GCPs refined for gdalwarp -tps (off by default)
  o.out_prefix = out_prefix;
  return o;
}

// A plain DEM grid (searched as a grid) and the same surface as a general
// mesh (binned triangles) give the height of a tilted plane, exactly, on a
// sheared and rotated grid of posts; NaN off the grid. A post that is not
// finite sends the grid to the binned path, which skips its triangles.
TEST(TerrainSurfaceTest, GridAndBinnedMeshGiveThePlaneHeight) {
  auto plane = [](double x, double y) { return 0.1 * x - 0.05 * y + 100.0; };
  Terrain grid;
  grid.grid_width = 41;
  grid.grid_height = 31;
  for (int r = 0; r < grid.grid_height; ++r) {
    for (int c = 0; c < grid.grid_width; ++c) {
      const double x = 30.0 * c + 4.0 * r + 0.02 * c * r, y = -3.0 * c + 30.0 * r;
      grid.mesh.vertices.emplace_back(float(x), float(y), float(plane(double(float(x)), double(float(y)))));
    }
  }
  Terrain mesh = grid;
  mesh.mesh = scene::MeshFromGrid(grid.mesh.vertices, grid.grid_width, grid.grid_height);
  mesh.grid_width = mesh.grid_height = 0;  // a general mesh
  Terrain grid_with_triangles = mesh;
  grid_with_triangles.grid_width = grid.grid_width;
  grid_with_triangles.grid_height = grid.grid_height;
  const TerrainSurface a(grid), b(mesh), c(grid_with_triangles);
  EXPECT_NEAR(a.z_min_m(), b.z_min_m(), 1e-9);
  EXPECT_NEAR(a.z_max_m(), b.z_max_m(), 1e-9);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int k = 0; k < 500; ++k) {
    // A point inside the grid: bilinear in the grid's parameters.
    const double gc = u(rng) * (grid.grid_width - 1), gr = u(rng) * (grid.grid_height - 1);
    const double x = 30.0 * gc + 4.0 * gr + 0.02 * gc * gr, y = -3.0 * gc + 30.0 * gr;
    for (const TerrainSurface* s : {&a, &b, &c}) ASSERT_NEAR((*s)(x, y), plane(x, y), 2e-3) << k;
  }
  for (const TerrainSurface* s : {&a, &b, &c}) {
    EXPECT_TRUE(std::isnan((*s)(-50.0, -50.0)));
    EXPECT_TRUE(std::isnan((*s)(5000.0, 100.0)));
  }
  Terrain holed = grid;
  holed.mesh.vertices[0].z() = std::numeric_limits<float>::quiet_NaN();
  const TerrainSurface h(holed);
  EXPECT_TRUE(std::isnan(h(1.0, 1.0)));  // the corner cell's first triangle has the NaN post
  EXPECT_NEAR(h(600.0, 450.0), plane(600.0, 450.0), 2e-3);
}

// Andorra's relief (SRTM, 150 m pixels, heading 30, depression 40): the
// image's GCPs and RPCs, read back through GDAL's own transformers
// (GDALCreateGenImgProjTransformer2, as gdalwarp -rpc / -tps), put DEM posts
// seen by the radar (no layover/shadow, at least 5 pixels from every GCP) at
// their true longitude/latitude.
TEST(GeoreferencingTest, AndorraReliefFeaturesLandOnTheirMapPosition) {
  const fs::path dir = testing::MakeTempDir();
  const SimulateRequest o = AndorraRequest((dir / "andorra").string());
  SimulationOutputs reserved;
  ReserveSimulationOutputs(o, reserved);
  SimulatedImage simulated = SimulateImage(o);
  WriteSimulation(o, simulated, "test", reserved, Stopwatch());
  const sensor::SarGeometry& geometry = *simulated.geometry;
  const geo::LocalFrame& frame = simulated.terrain.frame;
  const fs::path tif = o.out_prefix + ".tif";

  const geo::Georeference g = geo::ReadGeoreference(tif);
  EXPECT_GE(g.gcps.size(), 100u);
  EXPECT_LE(g.gcps.size(), size_t(kMaxGcps));
  ASSERT_EQ(g.rpc.count("SAMP_NUM_COEFF"), 1u);
  nlohmann::json provenance;
  std::ifstream(o.out_prefix + ".json") >> provenance;
  EXPECT_LT(provenance["georeference"]["rpc_max_error_px"].get<double>(), 0.01);
  std::printf("[ measured ] GCPs %zu, TPS refinement %s\n", g.gcps.size(),
              provenance["georeference"]["tps_refinement"].dump().c_str());
  // Every GCP lies on the terrain and projects to its pixel.
  for (const auto& p : g.gcps) {
    const Eigen::Vector2d px = geometry.Project(frame.EnuFromGeodetic(p.lon_deg, p.lat_deg, p.height_m));
    EXPECT_NEAR(px.x() + 0.5, p.pixel, 1e-3);
    EXPECT_NEAR(px.y() + 0.5, p.line, 1e-3);
  }

  int w = 0, h = 0;
  const std::vector<uint8_t> mask = geo::ReadByteRaster(o.out_prefix + "_mask.tif", &w, &h);
  std::vector<Eigen::Vector2d> pixels;
  std::vector<Eigen::Vector3d> truth;
  const auto& vertices = simulated.terrain.mesh.vertices;
  // Features at least 0.02 deg (~2 km, 13 px) inside the DEM: GDAL's RPC
  // inversion steps off a DEM's edge and fails there.
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const auto& v : vertices) {
    const Eigen::Vector2d ll = frame.GeodeticFromEnu(v.cast<double>()).head<2>();
    lo = lo.cwiseMin(ll);
    hi = hi.cwiseMax(ll);
  }
  for (size_t i = 0; i < vertices.size(); i += 3) {
    const Eigen::Vector3d v = vertices[i].cast<double>();
    const Eigen::Vector2d ll = frame.GeodeticFromEnu(v).head<2>();
    if ((ll - lo).minCoeff() < 0.02 || (hi - ll).minCoeff() < 0.02) continue;
    const Eigen::Vector2d px = geometry.Project(v);
    const int c = int(std::lround(px.x())), r = int(std::lround(px.y()));
    if (c < 2 || r < 2 || c >= w - 2 || r >= h - 2) continue;
    bool clear = true;  // no layover/shadow in the 5 x 5 neighbourhood
    for (int dr = -2; dr <= 2; ++dr)
      for (int dc = -2; dc <= 2; ++dc) clear = clear && mask[size_t(r + dr) * w + c + dc] == 0;
    if (!clear) continue;
    double nearest = 1e9;
    for (const auto& p : g.gcps) nearest = std::min(nearest, std::hypot(p.pixel - px.x() - 0.5, p.line - px.y() - 0.5));
    if (nearest < 5.0) continue;
    pixels.push_back(px + Eigen::Vector2d(0.5, 0.5));
    truth.push_back(v);
  }
  ASSERT_GE(pixels.size(), 300u);
  const std::string dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  // Measured (docs/georeferencing.md), 600 features: RPC + DEM median
  // 0.053 px, 95 % 0.145 px, max 0.242 px; TPS through the refined GCPs
  // (1024, of which 910 added where the spline missed the terrain) median
  // 0.286 px, 95 % 0.771 px, max 1.27 px (12 x 12 GCPs alone: 0.76 / 2.27 /
  // 3.10 px).
  struct Method {
    const char* name;
    std::vector<std::string> options;
    double median_limit_px, p95_limit_px;
  };
  for (const Method& m : {Method{"rpc+dem", {"METHOD=RPC", "RPC_DEM=" + dem, "RPC_DEM_INTERPOLATION=bilinear"}, 0.2, 1.0},
                          Method{"tps", {"METHOD=GCP_TPS"}, 0.5, 1.0}}) {
    const std::vector<Eigen::Vector2d> lonlat = geo::PixelsToLonLat(tif, m.options, pixels);
    std::vector<double> errors;
    for (size_t i = 0; i < pixels.size(); ++i) {
      ASSERT_TRUE(std::isfinite(lonlat[i].x())) << m.name << " pixel " << pixels[i].transpose() << " truth "
                                                << frame.GeodeticFromEnu(truth[i]).transpose();
      const Eigen::Vector3d got = frame.EnuFromGeodetic(lonlat[i].x(), lonlat[i].y(), 0.0);
      const Eigen::Vector3d want = frame.EnuFromGeodetic(frame.GeodeticFromEnu(truth[i]).x(),
                                                         frame.GeodeticFromEnu(truth[i]).y(), 0.0);
      errors.push_back((got - want).head<2>().norm() / 150.0);
    }
    std::sort(errors.begin(), errors.end());
    const double median = errors[errors.size() / 2], p95 = errors[errors.size() * 95 / 100];
    std::printf("[ measured ] %s: %zu relief features, map error median %.3f px, 95%% %.3f px, max %.3f px\n",
                m.name, errors.size(), median, p95, errors.back());
    EXPECT_LT(median, m.median_limit_px) << m.name;
    EXPECT_LT(p95, m.p95_limit_px) << m.name;
  }
}

// The lattice's terrain points from the profiles under its rows are the
// march's points: Andorra's relief (SRTM 3", affine, 150 m pixels,
// heading 30, depression 40), a 60 x 60 lattice. Each point also lies on
// the terrain and projects to its node's pixel.
// --no-tps-gcps (SimulateRequest::tps_gcps false): the GCPs are the lattice
// the refinement starts from (it only appends), the RPCs are the same fit,
// and the refinement record says it did not run.
TEST(GeoreferencingTest, WithoutTpsRefinementTheLatticeAloneAndTheSameRpcs) {
  const fs::path dir = testing::MakeTempDir();
  const SimulateRequest o = AndorraRequest((dir / "andorra").string());
  const SimulatedImage simulated = SimulateImage(o);
  sensor::GeoreferenceReport refined_report, lattice_report;
  TpsRefinement refined_record, lattice_record;
  const geo::Georeference refined = SimulationGeoreference(simulated.terrain, *simulated.geometry, true,
                                                           &refined_report, &simulated.image.mask, &refined_record);
  const geo::Georeference lattice = SimulationGeoreference(simulated.terrain, *simulated.geometry, false,
                                                           &lattice_report, &simulated.image.mask, &lattice_record);
  EXPECT_TRUE(refined_record.enabled);
  EXPECT_GT(refined_record.added_gcps, 0);
  EXPECT_FALSE(lattice_record.enabled);
  EXPECT_EQ(lattice_record.added_gcps, 0);
  EXPECT_EQ(lattice_record.rounds, 0);
  ASSERT_EQ(lattice.gcps.size() + size_t(refined_record.added_gcps), refined.gcps.size());
  EXPECT_EQ(lattice_report.gcp_count, int(lattice.gcps.size()));
  EXPECT_GE(lattice.gcps.size(), 100u);  // the 12 x 12 lattice, or a denser one until 100 see the terrain
  for (size_t i = 0; i < lattice.gcps.size(); ++i) {
    EXPECT_EQ(lattice.gcps[i].pixel, refined.gcps[i].pixel) << i;
    EXPECT_EQ(lattice.gcps[i].line, refined.gcps[i].line) << i;
    EXPECT_EQ(lattice.gcps[i].lon_deg, refined.gcps[i].lon_deg) << i;
    EXPECT_EQ(lattice.gcps[i].lat_deg, refined.gcps[i].lat_deg) << i;
  }
  EXPECT_EQ(lattice.rpc, refined.rpc);
  EXPECT_EQ(lattice_report.rpc_max_error_px, refined_report.rpc_max_error_px);
}

TEST(GeoreferencingTest, ProfileLatticePointsAreTheMarchsPoints) {
  // The filled DEM: the raw one's border voids are left out of the scene,
  // which makes it a grid with holes, not a plain grid.
  SimulateRequest o = AndorraRequest("unused");
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  const Terrain terrain = LoadTerrain(o);
  const sensor::SarGeometry geometry =
      sensor::SarGeometry::Covering(ResolvedGeometry(o, terrain), terrain.centre_enu, terrain.mesh.vertices);
  ASSERT_EQ(geometry.mode(), sensor::ProjectionMode::kAffine);
  const TerrainSurface surface(terrain);
  ASSERT_TRUE(surface.plain_grid());
  const render::GridProfileSweep sweep(terrain.mesh.vertices.data(), terrain.grid_width, terrain.grid_height,
                                       geometry);
  const int grid = 60;
  const std::vector<sensor::KnownLatticePoint> known = ProfileLatticePoints(sweep, geometry, grid);
  ASSERT_EQ(known.size(), size_t(grid) * grid);
  // The march alone (no known points), node by node.
  const geo::Georeference marched =
      sensor::SlantRangeGeoreference(geometry, terrain.frame, [&](double x, double y) { return surface(x, y); },
                                     surface.z_min_m(), surface.z_max_m(), grid, nullptr, surface.limits());
  std::vector<std::optional<Eigen::Vector3d>> march(known.size());
  for (const auto& gcp : marched.gcps) {
    const int i = int(std::lround((gcp.pixel - 0.5) * (grid - 1) / (geometry.width() - 1)));
    const int j = int(std::lround((gcp.line - 0.5) * (grid - 1) / (geometry.height() - 1)));
    march[size_t(j) * grid + i] = terrain.frame.EnuFromGeodetic(gcp.lon_deg, gcp.lat_deg, gcp.height_m);
  }
  int both = 0, profile_only = 0, march_only = 0;
  double worst_m = 0.0;
  for (int j = 0; j < grid; ++j) {
    for (int i = 0; i < grid; ++i) {
      const sensor::KnownLatticePoint& k = known[size_t(j) * grid + i];
      ASSERT_TRUE(k.known) << i << " " << j;  // every row crosses Andorra's grid in one piece
      const auto& m = march[size_t(j) * grid + i];
      if (k.enu && m) {
        ++both;
        worst_m = std::max(worst_m, (*k.enu - *m).norm());
      }
      profile_only += k.enu && !m;
      march_only += !k.enu && m;
      if (!k.enu) continue;
      // On the terrain, at the node's pixel.
      EXPECT_NEAR(k.enu->z(), surface(k.enu->x(), k.enu->y()), 1e-6) << i << " " << j;
      const Eigen::Vector2d px = geometry.Project(*k.enu), want = sensor::LatticePixel(geometry, grid, i, j);
      EXPECT_NEAR(px.x(), want.x(), 1e-9) << i << " " << j;
      EXPECT_NEAR(px.y(), want.y(), 1e-9) << i << " " << j;
    }
  }
  std::printf("[ measured ] %d nodes found by both (largest distance %.3g m), %d by the profile only, %d by the "
              "march only\n", both, worst_m, profile_only, march_only);
  EXPECT_GT(both, grid * grid / 3);
  EXPECT_LT(worst_m, 1e-3);
  EXPECT_EQ(march_only, 0);
  EXPECT_LE(profile_only, 2);
}

}  // namespace
}  // namespace gissar::pipeline
