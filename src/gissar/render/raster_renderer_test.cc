#include "gissar/render/raster_renderer.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <tuple>

#include "gissar/render/embree_scene.h"
#include "gissar/render/image_agreement.h"
#include "gissar/scene/fractal_terrain.h"

namespace gissar::render {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;
constexpr double kDeg = M_PI / 180.0;

sensor::SarGeometryOptions Options(double heading, double depression, double spacing) {
  sensor::SarGeometryOptions o;
  o.heading_deg = heading;
  o.depression_deg = depression;
  o.range_spacing_m = spacing;
  o.azimuth_spacing_m = spacing;
  return o;
}

// A height grid: post (c, r) at (x0 + c s, y0 + r s, z(x, y)).
struct Grid {
  int width = 0, height = 0;
  std::vector<Vector3f> posts;
};

template <typename Height>
Grid MakeGrid(int width, int height, double spacing, double x0, double y0, Height z) {
  Grid g{width, height, {}};
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const double x = x0 + c * spacing, y = y0 + r * spacing;
      g.posts.emplace_back(float(x), float(y), float(z(x, y)));
    }
  }
  return g;
}

// One unit Lambertian class (albedo 1): sigma0 = 4 cos^2(theta_l).
material::MaterialTable UnitLambert() {
  material::MaterialTable table;
  table.Set(0, material::Material{"default", 1.0});
  return table;
}

// The image is beta0: the legacy expectations (rho sin(d) on flat ground)
// times 4 tan(d), d the scene-centre depression (docs/radiometry.md).
double Calibrated(double depression_rad) { return 4.0 * std::tan(depression_rad); }

SarImage Raster(const Grid& grid, const sensor::SarGeometry& g,
                const material::MaterialTable& materials = UnitLambert(),
                const std::vector<scene::ClassId>& classes = {}) {
  return RenderSarRaster(grid.posts, grid.width, grid.height, materials, g, classes);
}

SarImage Trace(const Grid& grid, const sensor::SarGeometry& g, double rays_per_cell = 64.0) {
  const scene::TriangleMesh mesh = scene::MeshFromGrid(grid.posts, grid.width, grid.height);
  const EmbreeScene embree(mesh);
  RenderOptions o;
  o.rays_per_cell = rays_per_cell;
  o.max_bounces = 1;
  return RenderSar(embree, mesh, UnitLambert(), g, o);
}

// Flat ground reads rho sin(d) everywhere at any heading; the sampling of
// the triangles (sub-triangles at most a pixel wide, splatted bilinearly)
// leaves a ripple of a few percent.
TEST(RasterRendererTest, FlatGroundReadsTheLambertianValue) {
  for (double depression : {25.0, 40.0, 60.0}) {
    for (double heading : {0.0, 30.0, 200.0, 290.0}) {
      const Grid grid = MakeGrid(151, 151, 4.0, -300, -300, [](double, double) { return 0.0; });
      const auto g = sensor::SarGeometry::Covering(Options(heading, depression, 2.0), Vector3d::Zero(),
                                                   grid.posts);
      const SarImage image = Raster(grid, g);
      double sum = 0, sum2 = 0;
      int n = 0;
      for (int r = int(g.v0()) - 60; r <= int(g.v0()) + 60; ++r) {
        for (int c = int(g.u0()) - 40; c <= int(g.u0()) + 40; ++c) {
          const double v = image.intensity[size_t(r) * image.width + c];
          sum += v;
          sum2 += v * v;
          ++n;
          EXPECT_EQ(image.mask[size_t(r) * image.width + c], kMaskNone);
        }
      }
      const double mean = sum / n;
      const double cv = std::sqrt(std::max(0.0, sum2 / n - mean * mean)) / mean;
      SCOPED_TRACE("depression " + std::to_string(depression) + " heading " + std::to_string(heading));
      EXPECT_NEAR(mean / (std::sin(depression * kDeg) * Calibrated(depression * kDeg)), 1.0, 0.01);
      EXPECT_LT(cv, 0.04);
      EXPECT_EQ(image.stats.cells, 150 * 150);
      EXPECT_EQ(image.bounce_layers[0], image.intensity);
    }
  }
}

// Exact mode: flat ground at local depression d_p reads
// rho sin(d_p) tan(d_p) / tan(d) (docs/geometry.md), near and far range
// (averaged over 5 x 5 pixels, each against its own ground point).
TEST(RasterRendererTest, ExactModeFlatGroundFollowsTheLocalDepression) {
  const Grid grid = MakeGrid(201, 101, 5.0, -500, -250, [](double, double) { return 0.0; });
  sensor::SarGeometryOptions o = Options(0.0, 40.0, 2.0);
  o.mode = sensor::ProjectionMode::kExact;
  o.slant_range_m = 1500.0;
  const auto g = sensor::SarGeometry::Covering(o, Vector3d::Zero(), grid.posts);
  const SarImage image = Raster(grid, g);
  const Vector3d sensor = g.SensorPosition(0.0);
  for (double x : {-350.0, 0.0, 350.0}) {
    const Eigen::Vector2d px = g.Project(Vector3d(x, 0.0, 0.0));
    double measured = 0, expected = 0;
    for (int dr = -2; dr <= 2; ++dr) {
      for (int dc = -2; dc <= 2; ++dc) {
        const long c = std::lround(px.x()) + dc, r = std::lround(px.y()) + dr;
        // Ground point of column c: slant range |p - P(a)| on z = 0.
        const double range = g.slant_range_m() + (c - g.u0()) * g.range_spacing_m();
        const double ground = std::sqrt(range * range - sensor.z() * sensor.z());
        const double dp = std::atan2(sensor.z(), ground);
        expected += std::sin(dp) * std::tan(dp) / std::tan(40 * kDeg) * Calibrated(40 * kDeg) / 25.0;
        measured += image.intensity[size_t(r) * image.width + c] / 25.0;
      }
    }
    EXPECT_NEAR(measured, expected, 0.01 * expected) << "x = " << x;
  }
}

// A slope facing the radar at local incidence t reads
// rho cot(d) cos^2(t) / sin(t); a back slope steeper than the depression is
// turned away from the radar: shadow.
TEST(RasterRendererTest, FacingSlopeIsForeshortenedAndSteepBackSlopeIsShadow) {
  const Grid grid = MakeGrid(161, 81, 1.0, -80.0, -40.0, [](double x, double) {
    return std::max(0.0, x < 0 ? 60.0 + 0.5 * x : 60.0 - std::tan(60 * kDeg) * x);
  });
  const auto g = sensor::SarGeometry::Covering(Options(0, 40, 1.0), Vector3d::Zero(), grid.posts);
  const SarImage image = Raster(grid, g);
  const int row = static_cast<int>(g.v0());
  const double d = 40 * kDeg;
  const double cos_t = Vector3d(-0.5, 0, 1).normalized().dot(-g.look_direction());
  const double expected = Calibrated(d) * (1 / std::tan(d)) * cos_t * cos_t / std::sqrt(1 - cos_t * cos_t);
  const Eigen::Vector2d west = g.Project(Vector3d(-40, 0, 40));
  EXPECT_NEAR(image.intensity[size_t(row) * image.width + std::lround(west.x())], expected, 0.02 * expected);
  const Eigen::Vector2d east = g.Project(Vector3d(10, 0, 60 - std::tan(60 * kDeg) * 10));
  EXPECT_EQ(image.mask[size_t(row) * image.width + std::lround(east.x())], kMaskShadow);
  EXPECT_EQ(image.intensity[size_t(row) * image.width + std::lround(east.x())], 0.0f);
}

// Behind a plateau of height H whose back slope b is steeper than the
// depression d, the back slope (turned away) and the ground it hides span
// H cos(d) / tan(b) + H sin(d) + (H / tan(d) - H / tan(b)) cos(d) = H / sin(d)
// of slant range, whatever b. Counted along an azimuth line, within a
// pixel.
TEST(RasterRendererTest, ShadowBehindAPlateauSpansHeightOverSinDepression) {
  for (double depression : {30.0, 45.0}) {
    for (double back : {55.0, 70.0}) {
      const double H = 24.0;
      const Grid grid = MakeGrid(201, 41, 1.0, -100.0, -20.0, [&](double x, double) {
        if (x < -60) return 0.0;
        if (x < -20) return (x + 60) / 40 * H;  // gentle front slope: no layover
        if (x < 0) return H;
        return std::max(0.0, H - std::tan(back * kDeg) * x);
      });
      const auto g = sensor::SarGeometry::Covering(Options(0, depression, 0.5), Vector3d::Zero(), grid.posts);
      const SarImage image = Raster(grid, g);
      const int row = static_cast<int>(g.v0());
      int shadow = 0;
      for (int c = 0; c < image.width; ++c) shadow += image.mask[size_t(row) * image.width + c] == kMaskShadow;
      const double expected = H / std::sin(depression * kDeg) / 0.5;
      EXPECT_NEAR(shadow, expected, 1.5) << "depression " << depression << " back slope " << back;
    }
  }
}

// Heading 0 looks east. A front slope of angle b > 90 deg - d rising
// eastwards (away from the radar) towards a plateau of height H is imaged
// flipped: its top comes H sin(d) - H cos(d) / tan(b) of slant range before
// its foot, and that band is layover.
TEST(RasterRendererTest, SteepFrontSlopeIsLayover) {
  const double depression = 40.0, H = 30.0, b = 70.0;
  const Grid grid = MakeGrid(201, 41, 0.5, -50.0, -10.0, [&](double x, double) {
    return std::clamp(x * std::tan(b * kDeg), 0.0, H);
  });
  const auto g = sensor::SarGeometry::Covering(Options(0, depression, 0.5), Vector3d::Zero(), grid.posts);
  const SarImage image = Raster(grid, g);
  const int row = static_cast<int>(g.v0());
  int layover = 0;
  for (int c = 0; c < image.width; ++c) layover += image.mask[size_t(row) * image.width + c] == kMaskLayover;
  const double d = depression * kDeg;
  const double expected = (H * std::sin(d) - H * std::cos(d) / std::tan(b * kDeg)) / 0.5;
  EXPECT_NEAR(layover, expected, 1.5);
}

// Two classes: reflectivity 0.25 on the cells west of x = 0.
TEST(RasterRendererTest, CellClassesSelectTheMaterial) {
  const Grid grid = MakeGrid(101, 101, 2.0, -100, -100, [](double, double) { return 0.0; });
  std::vector<scene::ClassId> classes(100 * 100, 0);
  for (int r = 0; r < 100; ++r)
    for (int c = 0; c < 50; ++c) classes[size_t(r) * 100 + c] = 3;
  material::MaterialTable materials = UnitLambert();
  materials.Set(3, material::Material{"dark", 0.25});
  const auto g = sensor::SarGeometry::Covering(Options(0, 40, 2.0), Vector3d::Zero(), grid.posts);
  const SarImage image = Raster(grid, g, materials, classes);
  auto mean = [&](const Eigen::Vector2d& px) {
    double sum = 0;
    for (int dr = -2; dr <= 2; ++dr)
      for (int dc = -2; dc <= 2; ++dc)
        sum += image.intensity[size_t(std::lround(px.y()) + dr) * image.width + std::lround(px.x()) + dc];
    return sum / 25.0;
  };
  EXPECT_NEAR(mean(g.Project(Vector3d(-50, 0, 0))), 0.25 * std::sin(40 * kDeg) * Calibrated(40 * kDeg),
              0.0025 * Calibrated(40 * kDeg));
  EXPECT_NEAR(mean(g.Project(Vector3d(50, 0, 0))), std::sin(40 * kDeg) * Calibrated(40 * kDeg),
              0.01 * Calibrated(40 * kDeg));
}

Grid Fractal(int n, double spacing, double relief, uint64_t seed) {
  scene::FractalTerrainOptions o;
  o.width = o.height = n;
  o.relief_m = relief;
  o.hurst = 0.8;
  o.seed = seed;
  const std::vector<float> heights = scene::FractalHeights(o);
  const double half = (n - 1) * spacing / 2;
  return MakeGrid(n, n, spacing, -half, -half, [&](double x, double y) {
    const int c = int(std::lround((x + half) / spacing)), r = int(std::lround((y + half) / spacing));
    return heights[size_t(r) * n + c];
  });
}

// Whether the zero-Doppler plane through the centres of image row `row`
// contains an edge of the grid's outline (both ends within 1 mm of it).
bool OnOutlinePlane(const Grid& grid, const sensor::SarGeometry& g, int row) {
  const double a_row = (row - g.v0()) * g.azimuth_spacing_m();
  auto on = [&](int c, int r) {
    return std::abs(g.AlongTrack(grid.posts[size_t(r) * grid.width + c].cast<double>()) - a_row) < 1e-3;
  };
  for (int c = 0; c + 1 < grid.width; ++c) {
    for (int r : {0, grid.height - 1}) {
      if (on(c, r) && on(c + 1, r)) return true;
    }
  }
  for (int r = 0; r + 1 < grid.height; ++r) {
    for (int c : {0, grid.width - 1}) {
      if (on(c, r) && on(c, r + 1)) return true;
    }
  }
  return false;
}

// The raster engine renders what the ray tracer renders on single-bounce
// terrain (rough: 450 m of relief over 1.3 km): the dB images correlate
// (r >= 0.98 where both are non-zero) and the masks are identical within
// one pixel of their edges, in both modes, both look sides and at oblique
// headings. The only exception allowed is a tie: a pixel centre whose
// zero-Doppler plane contains an edge of the mesh's outline.
TEST(RasterRendererTest, AgreesWithTheRayTracerOnFractalTerrain) {
  const Grid grid = Fractal(129, 10.0, 450.0, 5);
  struct Case {
    double heading;
    sensor::ProjectionMode mode;
    sensor::LookSide look;
  };
  for (const Case& k : {Case{0, sensor::ProjectionMode::kAffine, sensor::LookSide::kRight},
                        Case{30, sensor::ProjectionMode::kAffine, sensor::LookSide::kRight},
                        Case{135, sensor::ProjectionMode::kAffine, sensor::LookSide::kLeft},
                        Case{250, sensor::ProjectionMode::kExact, sensor::LookSide::kRight},
                        Case{250, sensor::ProjectionMode::kAffine, sensor::LookSide::kRight}}) {
    sensor::SarGeometryOptions o = Options(k.heading, 40.0, 10.0);
    o.mode = k.mode;
    o.look_side = k.look;
    o.slant_range_m = 20000.0;
    const Vector3d centre(0, 0, grid.posts[64 * 129 + 64].z());
    const auto g = sensor::SarGeometry::Covering(o, centre, grid.posts);
    const SarImage raster = Raster(grid, g);
    const SarImage traced = Trace(grid, g);
    const IntensityAgreement intensity = CompareIntensities(raster.intensity, traced.intensity);
    const MaskAgreement mask = CompareMasks(raster.mask, traced.mask, g.width(), g.height());
    SCOPED_TRACE("heading " + std::to_string(k.heading));
    EXPECT_GE(intensity.db_pearson, 0.98);
    EXPECT_GT(intensity.compared_pixels, 10000);
    EXPECT_GT(mask.flagged, 100);  // the terrain has shadow and layover to compare
    // Every unexplained pixel must be a tie: its centre's zero-Doppler plane
    // contains an edge of the mesh's outline (heading 0: the grid's first
    // and last rows), so the tracer's visibility ray runs along that edge
    // and hits it or not by rounding.
    ASSERT_LT(mask.away_from_edges, MaskAgreement::kMaxListed);
    std::string listed;
    for (const auto& p : mask.unexplained) {
      if (OnOutlinePlane(grid, g, p.row)) continue;
      listed += " (" + std::to_string(p.col) + ", " + std::to_string(p.row) + "): raster " + std::to_string(p.a) +
                " tracer " + std::to_string(p.b);
    }
    EXPECT_EQ(listed, "") << mask.differing << " of " << mask.flagged << " differ";
  }
}

// The height field of the raster engine's reflectors: the surface height of
// a tilted plane (z = 0.1 x - 0.05 y + 7) at any point, nothing off the
// grid; on 450 m of fractal relief, seen from 2,000 points on the surface
// (5 cm to 3 m up) towards random sensor directions 5-80 deg up, its line
// of sight agrees with Embree's on the same triangles (MeshFromGrid) for
// every ray but those grazing an edge (within 1 cm of a triangle: none
// expected here), and reflector returns are identical.
TEST(GridHeightfieldTest, SurfaceAndLineOfSightMatchTheMesh) {
  const Grid plane = MakeGrid(21, 31, 5.0, -50.0, -75.0, [](double x, double y) { return 0.1 * x - 0.05 * y + 7.0; });
  const GridHeightfield tilted(plane.posts, plane.width, plane.height);
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, std::pair{-49.9, 74.9}, std::pair{12.3, -33.3}}) {
    ASSERT_TRUE(tilted.SurfaceHeight(x, y).has_value()) << x << " " << y;
    EXPECT_NEAR(*tilted.SurfaceHeight(x, y), 0.1 * x - 0.05 * y + 7.0, 1e-4) << x << " " << y;
  }
  EXPECT_FALSE(tilted.SurfaceHeight(-50.5, 0.0).has_value());
  EXPECT_FALSE(tilted.SurfaceHeight(0.0, 76.0).has_value());

  const Grid grid = Fractal(129, 10.0, 450.0, 7);
  const GridHeightfield field(grid.posts, grid.width, grid.height);
  const scene::TriangleMesh mesh = scene::MeshFromGrid(grid.posts, grid.width, grid.height);
  const EmbreeScene embree(mesh);
  uint64_t state = 12345;
  auto uniform = [&]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) / double(1ULL << 53);
  };
  int occluded = 0, differ = 0;
  for (int k = 0; k < 2000; ++k) {
    const double x = -600.0 + 1200.0 * uniform(), y = -600.0 + 1200.0 * uniform();
    const std::optional<double> z = field.SurfaceHeight(x, y);
    ASSERT_TRUE(z.has_value());
    const Vector3d origin(x, y, *z + 0.05 + 3.0 * uniform());
    const double azimuth = 2.0 * M_PI * uniform(), elevation = (5.0 + 75.0 * uniform()) * kDeg;
    const Vector3d dir(std::cos(elevation) * std::sin(azimuth), std::cos(elevation) * std::cos(azimuth),
                       std::sin(elevation));
    const bool a = field.Occluded(origin, dir, 0.05, 1e5);
    const bool b = embree.Occluded(origin.cast<float>(), dir.cast<float>(), 0.05f, 1e5f);
    occluded += a;
    differ += a != b;
  }
  std::printf("height field vs Embree: %d of 2000 lines of sight occluded, %d differ\n", occluded, differ);
  EXPECT_GT(occluded, 200);   // the relief hides many
  EXPECT_LT(occluded, 1800);  // and not all
  EXPECT_EQ(differ, 0);

  // Reflector returns: the same whichever test decides visibility.
  sensor::SarGeometryOptions o = Options(30.0, 35.0, 5.0);
  const auto g = sensor::SarGeometry::Covering(o, Vector3d(0, 0, grid.posts[64 * 129 + 64].z()), grid.posts);
  std::vector<SceneReflector> reflectors;
  for (int k = 0; k < 200; ++k) {
    const double x = -600.0 + 1200.0 * uniform(), y = -600.0 + 1200.0 * uniform();
    SceneReflector r;
    r.apex_enu = Vector3d(x, y, *field.SurfaceHeight(x, y) + 0.5);
    r.boresight_enu = -g.look_direction();
    reflectors.push_back(r);
  }
  const auto from_field = ReflectorReturns(field, reflectors, g, 0.0555);
  const auto from_embree = ReflectorReturns(embree, reflectors, g, 0.0555);
  ASSERT_EQ(from_field.size(), from_embree.size());
  EXPECT_GT(from_field.size(), 20u);
  EXPECT_LT(from_field.size(), 200u);
  for (size_t k = 0; k < from_field.size(); ++k) {
    EXPECT_EQ(from_field[k].col, from_embree[k].col);
    EXPECT_EQ(from_field[k].beta0_sum, from_embree[k].beta0_sum);
  }
}

// A grid that is not a parallelogram lattice (columns fanning out and rows
// bending, as a geographic DEM's posts in ENU far from the frame's origin):
// the surface height at random points equals that of the one mesh triangle
// whose plan holds the point, found by testing every triangle.
TEST(GridHeightfieldTest, SurfaceHeightOfACurvedGridIsItsTrianglesHeight) {
  const int w = 40, h = 30;
  std::vector<Vector3f> posts;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const double x = (10.0 + 0.35 * r) * c + 0.02 * r * r;
      const double y = 9.0 * r + 0.04 * c * c - 0.002 * c * r * r;
      posts.emplace_back(float(x), float(y), float(300.0 + 40.0 * std::sin(0.7 * c) * std::cos(0.9 * r) + 3.0 * c));
    }
  }
  const GridHeightfield field(posts, w, h);
  auto brute_force = [&](double x, double y) -> std::optional<double> {
    for (int r = 0; r + 1 < h; ++r) {
      for (int c = 0; c + 1 < w; ++c) {
        auto p = [&](int cc, int rr) { return posts[size_t(rr) * w + cc].cast<double>(); };
        const Vector3d a = p(c, r), b = p(c + 1, r), d = p(c, r + 1), e = p(c + 1, r + 1);
        for (const auto& [p0, p1, p2] : {std::tuple{a, b, d}, std::tuple{b, e, d}}) {
          const Eigen::Vector2d u = (p1 - p0).head<2>(), v = (p2 - p0).head<2>(), q = Eigen::Vector2d(x, y) - p0.head<2>();
          const double det = u.x() * v.y() - u.y() * v.x();
          const double s = (q.x() * v.y() - q.y() * v.x()) / det, t = (u.x() * q.y() - u.y() * q.x()) / det;
          if (s >= 1e-7 && t >= 1e-7 && s + t <= 1.0 - 1e-7) return p0.z() + s * (p1.z() - p0.z()) + t * (p2.z() - p0.z());
        }
      }
    }
    return std::nullopt;
  };
  uint64_t state = 99;
  auto uniform = [&]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(state >> 11) / double(1ULL << 53);
  };
  int inside = 0;
  for (int k = 0; k < 3000; ++k) {
    const double x = 700.0 * uniform(), y = 300.0 * uniform();
    const std::optional<double> want = brute_force(x, y);
    if (!want) continue;  // outside the grid's plan, or on an edge
    ++inside;
    const std::optional<double> got = field.SurfaceHeight(x, y);
    ASSERT_TRUE(got.has_value()) << x << " " << y;
    EXPECT_NEAR(*got, *want, 1e-6) << x << " " << y;
  }
  EXPECT_GT(inside, 1000);
}

// Classes per triangle (MeshFromGrid's order: first the triangle holding
// post (c, r), then the one holding (c + 1, r + 1)): with 20 m cells and 1 m
// pixels, the middle of each triangle reads its own class, at every sweep
// orientation. Triangle 0 of a cell with corner (x0, y0) covers
// (x - x0) + (y - y0) < 20; its centroid is at (20/3, 20/3), triangle 1's at
// (40/3, 40/3), both 4.7 m from the diagonal.
TEST(RasterRendererTest, TriangleClassesSelectTheMaterialOfEachHalfCell) {
  const Grid grid = MakeGrid(11, 11, 20.0, -100, -100, [](double, double) { return 0.0; });
  std::vector<scene::ClassId> classes(2 * 10 * 10, 0);
  for (size_t cell = 0; cell < 100; ++cell) classes[2 * cell] = 3;  // the (c, r) halves are dark
  material::MaterialTable materials = UnitLambert();
  materials.Set(3, material::Material{"dark", 0.25});
  for (double heading : {0.0, 90.0, 200.0, 290.0}) {
    const auto g = sensor::SarGeometry::Covering(Options(heading, 40, 1.0), Vector3d::Zero(), grid.posts);
    const SarImage image = Raster(grid, g, materials, classes);
    auto mean = [&](double x, double y) {
      const Eigen::Vector2d px = g.Project(Vector3d(x, y, 0));
      double sum = 0;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc)
          sum += image.intensity[size_t(std::lround(px.y()) + dr) * image.width + std::lround(px.x()) + dc];
      return sum / 9.0;
    };
    const double flat = std::sin(40 * kDeg) * Calibrated(40 * kDeg);
    SCOPED_TRACE("heading " + std::to_string(heading));
    // Cell with corner (0, 0) and cell with corner (-40, 20).
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0, 0), Eigen::Vector2d(-40, 20)}) {
      // (The sub-triangle sampling leaves a ripple of a few percent.)
      EXPECT_NEAR(mean(corner.x() + 20.0 / 3, corner.y() + 20.0 / 3), 0.25 * flat, 0.05 * flat);
      EXPECT_NEAR(mean(corner.x() + 40.0 / 3, corner.y() + 40.0 / 3), flat, 0.05 * flat);
    }
  }
}

// Smooth shading: flat ground whose posts all carry a shading normal tilted
// by t towards (or away from) the radar returns the unit Lambertian law at
// the tilted normal over the flat ground's projected area:
//   4 cos^2(theta_s) / cos(d),  cos(theta_s) = sin(d + t)
// (heading 0 looks east: the normal (-sin t, 0, cos t) faces the radar),
// against 4 sin^2(d) / cos(d) = sin(d) Calibrated(d) without normals. A zero
// normal at a post makes the triangles that use it flat-shaded.
TEST(RasterRendererTest, ShadingNormalsSetTheLocalIncidence) {
  const Grid grid = MakeGrid(101, 101, 2.0, -100, -100, [](double, double) { return 0.0; });
  const double d = 40 * kDeg;
  const auto g = sensor::SarGeometry::Covering(Options(0, 40, 2.0), Vector3d::Zero(), grid.posts);
  auto mean = [&](const SarImage& image, double x, double y) {
    const Eigen::Vector2d px = g.Project(Vector3d(x, y, 0));
    double sum = 0;
    for (int dr = -2; dr <= 2; ++dr)
      for (int dc = -2; dc <= 2; ++dc)
        sum += image.intensity[size_t(std::lround(px.y()) + dr) * image.width + std::lround(px.x()) + dc];
    return sum / 25.0;
  };
  for (double tilt_deg : {-20.0, 20.0}) {
    const double t = tilt_deg * kDeg;
    std::vector<Vector3f> normals(grid.posts.size(), Vector3f(float(-std::sin(t)), 0.0f, float(std::cos(t))));
    // A flat-shaded hole: the posts of x in [40, 60] carry no normal.
    for (size_t i = 0; i < grid.posts.size(); ++i) {
      if (grid.posts[i].x() >= 39.0f && grid.posts[i].x() <= 61.0f) normals[i].setZero();
    }
    const SarImage image = RenderSarRaster(grid.posts, grid.width, grid.height, UnitLambert(), g, {}, 0.031,
                                           material::Polarization::kVV, normals);
    const double cos_s = std::sin(d + t);
    const double expected = 4.0 * cos_s * cos_s / std::cos(d);
    SCOPED_TRACE("tilt " + std::to_string(tilt_deg));
    EXPECT_NEAR(mean(image, -40, 0), expected, 0.01 * expected);
    EXPECT_NEAR(mean(image, 0, 30), expected, 0.01 * expected);
    // Cells whose posts all lack a normal (x in [42, 58]): the facet.
    EXPECT_NEAR(mean(image, 50, 0), std::sin(d) * Calibrated(d), 0.01 * Calibrated(d));
  }
}

// With the same shading normals (the area-weighted vertex normals of the
// grid mesh), the raster engine renders what the ray tracer renders (as
// closely as without them: dB Pearson 0.988 both ways), and smoothing
// changes the image (flat raster against smooth tracer: 0.946).
TEST(RasterRendererTest, AgreesWithTheRayTracerWithShadingNormals) {
  const Grid grid = Fractal(97, 10.0, 300.0, 7);
  scene::TriangleMesh mesh = scene::MeshFromGrid(grid.posts, grid.width, grid.height);
  mesh.SmoothShadingNormals(scene::ClassId(255));  // no class excluded
  const auto g = sensor::SarGeometry::Covering(Options(30, 40, 10.0), Vector3d(0, 0, grid.posts[48 * 97 + 48].z()),
                                               grid.posts);
  const SarImage raster = RenderSarRaster(grid.posts, grid.width, grid.height, UnitLambert(), g, {}, 0.031,
                                          material::Polarization::kVV, mesh.shading_normals);
  const SarImage flat = Raster(grid, g);
  const EmbreeScene embree(mesh);
  RenderOptions o;
  o.rays_per_cell = 64.0;
  o.max_bounces = 1;
  const SarImage traced = RenderSar(embree, mesh, UnitLambert(), g, o);
  const IntensityAgreement smooth_agreement = CompareIntensities(raster.intensity, traced.intensity);
  const IntensityAgreement flat_agreement = CompareIntensities(flat.intensity, traced.intensity);
  EXPECT_GE(smooth_agreement.db_pearson, 0.98);
  EXPECT_GT(smooth_agreement.compared_pixels, 5000);
  EXPECT_LT(flat_agreement.db_pearson, smooth_agreement.db_pearson - 0.02);
}

TEST(RasterRendererTest, ResultDoesNotDependOnTheThreadCount) {
  const Grid grid = Fractal(129, 10.0, 450.0, 9);
  const auto g = sensor::SarGeometry::Covering(Options(30, 40, 5.0), Vector3d::Zero(), grid.posts);
  SarImage one, two;
  {
    tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 1);
    one = Raster(grid, g);
  }
  {
    tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
    two = Raster(grid, g);
  }
  EXPECT_EQ(one.intensity, two.intensity);
  EXPECT_EQ(one.mask, two.mask);
}

TEST(ImageAgreementTest, IdenticalAndScaledImagesCorrelatePerfectly) {
  const std::vector<float> a = {1.0f, 2.0f, 0.0f, 8.0f, 0.5f};
  std::vector<float> b = a;
  for (float& v : b) v *= 3.0f;  // +4.77 dB everywhere
  b[2] = 1.0f;
  const IntensityAgreement agreement = CompareIntensities(a, b);
  EXPECT_NEAR(agreement.db_pearson, 1.0, 1e-12);
  EXPECT_EQ(agreement.compared_pixels, 4);
  EXPECT_EQ(agreement.one_sided_zero, 1);
}

TEST(ImageAgreementTest, MaskEdgesWithinOnePixelAreExplained) {
  const int w = 8, h = 5;
  std::vector<uint8_t> a(w * h, kMaskNone), b(w * h, kMaskNone);
  for (int r = 0; r < h; ++r) {
    for (int c = 2; c < 5; ++c) a[r * w + c] = kMaskShadow;
    for (int c = 3; c < 5; ++c) b[r * w + c] = kMaskShadow;  // edge one pixel later
  }
  MaskAgreement m = CompareMasks(a, b, w, h);
  EXPECT_EQ(m.differing, h);
  EXPECT_EQ(m.away_from_edges, 0);
  EXPECT_EQ(m.flagged, 3 * h);
  b[0 * w + 7] = kMaskLayover;  // a lone layover pixel far from any in a
  m = CompareMasks(a, b, w, h);
  EXPECT_EQ(m.away_from_edges, 1);
}

}  // namespace
}  // namespace gissar::render
