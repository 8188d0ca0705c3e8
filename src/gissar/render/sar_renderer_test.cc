#include "gissar/render/sar_renderer.h"
#include "gissar/render/embree_scene.h"
#include "gissar/render/image_agreement.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <optional>

#include "gissar/util/error.h"

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

// Heights of a kPosts x kPosts grid (row-major): ridges steep enough to
// shadow and lay over at 40 degrees, plus steps of `step_m` in a 4-post
// pattern.
std::vector<float> SteepRidgeHeights(int posts, double step_m) {
  std::vector<float> heights(size_t(posts) * posts);
  for (int r = 0; r < posts; ++r) {
    for (int c = 0; c < posts; ++c) {
      heights[size_t(r) * posts + c] = float(120.0 * std::sin(0.23 * c) * std::cos(0.19 * r) +
                                             60.0 * std::sin(0.61 * c + 0.37 * r) + step_m * ((c * 5 + r * 3) % 4));
    }
  }
  return heights;
}

// The steep ridge (SteepRidgeHeights, 7 m steps) on a 90 x 90 grid whose
// posts are sheared and rotated in plan as a geographic DEM's are in ENU,
// with `bend_per_row2_m` bending the rows (x += bend * (r - 45)^2).
std::vector<Vector3f> WarpedRidgePosts(double bend_per_row2_m) {
  constexpr int kPosts = 90;
  const std::vector<float> heights = SteepRidgeHeights(kPosts, 7.0);
  std::vector<Vector3f> posts;
  for (int r = 0; r < kPosts; ++r) {
    for (int c = 0; c < kPosts; ++c) {
      posts.emplace_back(float(10.0 * (c - 45) + 0.7 * (r - 45) + bend_per_row2_m * (r - 45) * (r - 45)),
                         float(9.0 * (r - 45) - 0.4 * (c - 45)), heights[size_t(r) * kPosts + c]);
    }
  }
  return posts;
}

// The steep-ridge tests' view of `mesh`: depression 40 degrees, 5 m pixels,
// 5 km slant range, covering the mesh.
sensor::SarGeometry RidgeGeometry(sensor::ProjectionMode mode, sensor::LookSide side, double heading,
                                  const std::vector<Eigen::Vector3f>& vertices) {
  sensor::SarGeometryOptions o = Options(heading, 40.0, 5.0);
  o.mode = mode;
  o.look_side = side;
  o.slant_range_m = 5000.0;
  return sensor::SarGeometry::Covering(o, Vector3d::Zero(), vertices);
}

RenderOptions Quiet(double rays_per_cell = 4.0) {
  RenderOptions r;
  r.rays_per_cell = rays_per_cell;
  return r;
}

// Adds the rectangle a-b-c-d, ordered so that its normal points along `facing`.
void AddFacingQuad(scene::TriangleMesh& mesh, Vector3f a, Vector3f b, Vector3f c, Vector3f d,
                   const Vector3f& facing) {
  if ((b - a).cross(c - a).dot(facing) < 0) std::swap(b, d);
  mesh.AddQuad(a, b, c, d);
}

// Flat ground z = 0 over [x0, x1] x [y0, y1].
void AddGround(scene::TriangleMesh& mesh, float x0, float x1, float y0, float y1) {
  AddFacingQuad(mesh, {x0, y0, 0}, {x1, y0, 0}, {x1, y1, 0}, {x0, y1, 0}, Vector3f::UnitZ());
}

// One unit Lambertian class (albedo 1): sigma0 = 4 cos^2(theta_l).
material::MaterialTable UnitLambert() {
  material::MaterialTable table;
  table.Set(0, material::Material{"default", 1.0});
  return table;
}

// The image is beta0: a Lambertian surface of albedo rho reads
// 4 rho cos^2(theta_l) over its area per image area. Flat ground at
// depression d: 4 rho sin^2(d) / cos(d) = rho sin(d) * Calibrated(d).
double Calibrated(double depression_rad) { return 4.0 * std::tan(depression_rad); }

SarImage Render(const scene::TriangleMesh& mesh, const sensor::SarGeometry& g,
                double rays_per_cell = 4.0) {
  const EmbreeScene embree(mesh);
  return RenderSar(embree, mesh, UnitLambert(), g, Quiet(rays_per_cell));
}

// Flat ground reads 4 rho sin^2(d) / cos(d) (beta0 of sigma0 = 4 rho cos^2)
// everywhere, with no speckle-like ripple from the ray layout.
TEST(SarRendererTest, FlatPlaneReadsTheLambertianValue) {
  for (double depression : {25.0, 40.0, 60.0}) {
    for (double heading : {0.0, 30.0, 200.0}) {
      scene::TriangleMesh mesh;
      AddGround(mesh, -300, 300, -300, 300);
      const auto g = sensor::SarGeometry::Covering(Options(heading, depression, 2.0),
                                                   Vector3d::Zero(), mesh.vertices);
      const SarImage image = Render(mesh, g);
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
      const double expected = std::sin(depression * kDeg) * Calibrated(depression * kDeg);
      EXPECT_NEAR(mean / expected, 1.0, 0.01) << "depression " << depression << " heading " << heading;
      EXPECT_LT(cv, 0.02) << "depression " << depression << " heading " << heading;
    }
  }
}

// Smooth terrain: the first bounce's sigma0 law takes its local incidence
// from the mesh's interpolated shading normal; the footprint stays the
// facet's. Flat ground whose vertices all carry the shading normal
// n = (-0.5, 0, 1) / |.| reads the flat value scaled by the unit Lambertian
// law's ratio (n . (-look))^2 / sin^2(depression); a zero shading normal at
// a vertex falls back to the facet: the flat value sin(d) * Calibrated(d).
TEST(SarRendererTest, ShadingNormalsDriveTheDiffuseTerm) {
  for (double heading : {0.0, 30.0}) {
    for (bool flat : {false, true}) {
      scene::TriangleMesh mesh;
      AddGround(mesh, -300, 300, -300, 300);
      const Vector3f n = Vector3f(-0.5f, 0.0f, 1.0f).normalized();
      mesh.shading_normals.assign(mesh.vertices.size(), n);
      if (flat) mesh.shading_normals[0] = mesh.shading_normals[2] = Vector3f::Zero();  // in both triangles
      const auto g = sensor::SarGeometry::Covering(Options(heading, 40.0, 2.0), Vector3d::Zero(), mesh.vertices);
      const SarImage image = Render(mesh, g);
      double sum = 0;
      int count = 0;
      for (int r = int(g.v0()) - 40; r <= int(g.v0()) + 40; ++r) {
        for (int c = int(g.u0()) - 30; c <= int(g.u0()) + 30; ++c) {
          sum += image.intensity[size_t(r) * image.width + c];
          ++count;
        }
      }
      const double d = 40.0 * kDeg;
      const double cos_shade = n.cast<double>().dot(-g.look_direction());
      const double flat_value = std::sin(d) * Calibrated(d);
      const double expected = flat ? flat_value : flat_value * (cos_shade * cos_shade) / (std::sin(d) * std::sin(d));
      EXPECT_NEAR(sum / count / expected, 1.0, 0.01) << "heading " << heading << " flat " << flat;
    }
  }
}

TEST(SarRendererTest, ReflectivityScalesTheImage) {
  scene::TriangleMesh mesh;
  AddGround(mesh, -100, 100, -100, 100);
  mesh.classes.assign(mesh.triangle_count(), 2);
  material::MaterialTable materials;
  materials.Set(0, material::Material{"default", 1.0});
  materials.Set(2, material::Material{"dark", 0.25});
  const auto g = sensor::SarGeometry::Covering(Options(0, 40, 1.0), Vector3d::Zero(), mesh.vertices);
  const EmbreeScene embree(mesh);
  const SarImage image = RenderSar(embree, mesh, materials, g, Quiet());
  const size_t centre = size_t(g.v0()) * image.width + size_t(g.u0());
  EXPECT_NEAR(image.intensity[centre], 0.25 * std::sin(40 * kDeg) * Calibrated(40 * kDeg), 4e-4);
}

// A box of height H with vertical walls on flat ground, radar looking east
// (heading 0, right-looking). In slant range the front wall spans H sin(d)
// in front of its foot (layover); behind the box, the self-shadowed back wall
// and the shadowed ground span H sin(d) + H cos^2(d) / sin(d) = H / sin(d).
// The box edges are placed so that the layover band ends and the shadow band
// starts on pixel boundaries; counting pixel centres then gives the closed
// forms rounded to the nearest pixel.
TEST(SarRendererTest, BoxLayoverAndShadowMatchClosedForms) {
  struct Case {
    double height, depression;
  };
  for (const Case& k : {Case{10, 30}, Case{10, 45}, Case{23, 40}, Case{17, 60}, Case{31, 35}}) {
    const double d = k.depression * kDeg, H = k.height;
    const double spacing = 1.0;
    // Front foot and back roof edge at half-integer slant ranges (u0 is an
    // integer: pixel boundaries are at half-integer columns).
    const float x0 = static_cast<float>((20 + 0.5) / std::cos(d));
    const float x1 = static_cast<float>((60 + 0.5 + H * std::sin(d)) / std::cos(d));
    scene::TriangleMesh mesh;
    const float X = 400, Y = 200, B = 50;  // ground half-extent, box half-width
    AddGround(mesh, -X, X, -Y, -B);
    AddGround(mesh, -X, X, B, Y);
    AddGround(mesh, -X, x0, -B, B);
    AddGround(mesh, x1, X, -B, B);
    const float h = static_cast<float>(H);
    AddFacingQuad(mesh, {x0, -B, 0}, {x0, B, 0}, {x0, B, h}, {x0, -B, h}, -Vector3f::UnitX());
    AddFacingQuad(mesh, {x1, -B, 0}, {x1, B, 0}, {x1, B, h}, {x1, -B, h}, Vector3f::UnitX());
    AddFacingQuad(mesh, {x0, -B, 0}, {x1, -B, 0}, {x1, -B, h}, {x0, -B, h}, -Vector3f::UnitY());
    AddFacingQuad(mesh, {x0, B, 0}, {x1, B, 0}, {x1, B, h}, {x0, B, h}, Vector3f::UnitY());
    AddFacingQuad(mesh, {x0, -B, h}, {x1, -B, h}, {x1, B, h}, {x0, B, h}, Vector3f::UnitZ());

    const auto g = sensor::SarGeometry::Covering(Options(0, k.depression, spacing),
                                                 Vector3d::Zero(), mesh.vertices);
    ASSERT_EQ(g.u0(), std::round(g.u0()));
    const SarImage image = Render(mesh, g);
    const int row = static_cast<int>(g.v0());  // azimuth line through the box middle
    int layover = 0, shadow = 0, both = 0;
    for (int c = 0; c < image.width; ++c) {
      const uint8_t m = image.mask[size_t(row) * image.width + c];
      layover += m == kMaskLayover;
      shadow += m == kMaskShadow;
      both += m == (kMaskLayover | kMaskShadow);
    }
    const double layover_px = H * std::sin(d) / spacing;
    const double shadow_px = H / std::sin(d) / spacing;
    SCOPED_TRACE("H=" + std::to_string(H) + " depression=" + std::to_string(k.depression));
    EXPECT_LE(std::abs(layover - layover_px), 0.5) << layover << " vs " << layover_px;
    EXPECT_LE(std::abs(shadow - shadow_px), 0.5) << shadow << " vs " << shadow_px;
    EXPECT_EQ(both, 0);
    // Layover band: right in front of the wall foot. Shadow band: after the
    // roof's back edge. Shadow pixels (away from their edges) are black,
    // layover pixels brighter than open ground.
    const int foot_col = static_cast<int>(std::floor(g.Project(Vector3d(x0, 0, 0)).x()));
    EXPECT_EQ(image.mask[size_t(row) * image.width + foot_col], kMaskLayover);
    EXPECT_EQ(image.mask[size_t(row) * image.width + foot_col + 1], kMaskNone);
    const int roof_back_col = static_cast<int>(std::ceil(g.Project(Vector3d(x1, 0, H)).x()));
    EXPECT_EQ(image.mask[size_t(row) * image.width + roof_back_col], kMaskShadow);
    EXPECT_EQ(image.mask[size_t(row) * image.width + roof_back_col - 1], kMaskNone);
    const float ground = static_cast<float>(std::sin(d) * Calibrated(d));
    EXPECT_EQ(image.intensity[size_t(row) * image.width + roof_back_col + 2], 0.0f);
    EXPECT_GT(image.intensity[size_t(row) * image.width + foot_col - 1], 1.2f * ground);
  }
}

// A small raised plate: the centroid of its return (image with the plate
// minus image without) lands on the projection of its centre.
Eigen::Vector2d TargetCentroid(const sensor::SarGeometry& g, const Vector3d& target) {
  scene::TriangleMesh ground;
  AddGround(ground, -150, 150, -150, 150);
  scene::TriangleMesh with_target = ground;
  const float s = 1.0f;  // plate half-size, metres
  const Vector3f t = target.cast<float>();
  AddFacingQuad(with_target, t + Vector3f(-s, -s, 0), t + Vector3f(s, -s, 0), t + Vector3f(s, s, 0),
                t + Vector3f(-s, s, 0), Vector3f::UnitZ());
  const SarImage a = Render(with_target, g, 16.0);
  const SarImage b = Render(ground, g, 16.0);
  const Eigen::Vector2d predicted = g.Project(target);
  double w = 0, wc = 0, wr = 0;
  for (int r = int(predicted.y()) - 6; r <= int(predicted.y()) + 6; ++r) {
    for (int c = int(predicted.x()) - 6; c <= int(predicted.x()) + 6; ++c) {
      const double v = a.intensity[size_t(r) * a.width + c] - b.intensity[size_t(r) * a.width + c];
      if (v <= 0) continue;
      w += v;
      wc += v * c;
      wr += v * r;
    }
  }
  EXPECT_GT(w, 0.0);
  return {wc / w, wr / w};
}

TEST(SarRendererTest, RaisedTargetLandsOnItsPredictedPixelInBothModes) {
  const Vector3d target(37.0, -21.0, 30.0);
  for (auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (double heading : {0.0, 30.0}) {
      sensor::SarGeometryOptions o = Options(heading, 40.0, 0.5);
      o.mode = mode;
      o.slant_range_m = 1500.0;
      // A 300 x 300 image about the scene centre (+-75 m): the target lands
      // within 100 px of the centre in every case, and only its 13 x 13
      // neighbourhood is measured.
      const sensor::SarGeometry g(o, Vector3d::Zero(), 150, 150, 300, 300);
      const Eigen::Vector2d predicted = g.Project(target);
      ASSERT_TRUE(predicted.x() > 10 && predicted.x() < 290 && predicted.y() > 10 && predicted.y() < 290)
          << predicted.transpose();
      const Eigen::Vector2d centroid = TargetCentroid(g, target);
      EXPECT_LT((centroid - g.Project(target)).norm(), 0.5)
          << sensor::ToString(mode) << " heading " << heading << ": " << centroid.transpose()
          << " vs " << g.Project(target).transpose();
    }
  }
}

TEST(SarRendererTest, ExactRenderingFollowsTrueRangeAtShortRange) {
  // At 1.5 km the exact and affine positions of the target differ by
  // several pixels; the exact-mode image follows the exact prediction.
  const Vector3d target(120.0, 10.0, 30.0);
  sensor::SarGeometryOptions o = Options(0.0, 40.0, 0.5);
  o.slant_range_m = 1500.0;
  const sensor::SarGeometry affine(o, Vector3d::Zero(), 300, 300, 600, 600);
  o.mode = sensor::ProjectionMode::kExact;
  const sensor::SarGeometry exact(o, Vector3d::Zero(), 300, 300, 600, 600);
  const double shift = exact.Project(target).x() - affine.Project(target).x();
  EXPECT_GT(std::abs(shift), 3.0);
  const Eigen::Vector2d centroid = TargetCentroid(exact, target);
  EXPECT_LT((centroid - exact.Project(target)).norm(), 0.5);
}

TEST(SarRendererTest, SlopeTurnedAwayIsShadowAndFacingSlopeIsBrighter) {
  // A ridge along north-south: the west slope faces the radar (brighter, and
  // in layover when steeper than 90 - depression); the east slope at 60 deg
  // is steeper than the 40 deg depression: shadow.
  std::vector<float> heights;
  const int n = 81;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const double x = -80.0 + 2.0 * c;  // metres
      heights.push_back(static_cast<float>(x < 0 ? 60.0 + 0.5 * x : 60.0 - std::tan(60 * kDeg) * x));
    }
  scene::TriangleMesh mesh = scene::MeshFromHeights(heights, n, n, 2.0, -80.0, -80.0);
  for (auto& v : mesh.vertices) v.z() = std::max(v.z(), 0.0f);
  const auto g = sensor::SarGeometry::Covering(Options(0, 40, 1.0), Vector3d::Zero(), mesh.vertices);
  const SarImage image = Render(mesh, g);
  const int row = static_cast<int>(g.v0());
  // West slope (z = 60 + 0.5x): local incidence from normal (-0.5, 0, 1).
  const Vector3d west_normal = Vector3d(-0.5, 0, 1).normalized();
  const double cos_west = west_normal.dot(-g.look_direction());
  const Eigen::Vector2d west_px = g.Project(Vector3d(-40, 0, 40));
  // Rays are de apart across the beam; on a surface of local incidence t
  // consecutive hits are de * tan(t) apart in slant range, so a pixel gets
  // tan(t_flat) / tan(t) times flat ground's rays, each returning cos(t):
  // I = cot(d) * cos^2(t) / sin(t) (flat ground: sin(d)).
  const double d = 40 * kDeg;
  const double expected =
      Calibrated(d) * (1 / std::tan(d)) * cos_west * cos_west / std::sqrt(1 - cos_west * cos_west);
  const double measured = image.intensity[size_t(row) * image.width + std::lround(west_px.x())];
  EXPECT_NEAR(measured, expected, 0.02 * expected);
  EXPECT_GT(measured, 1.3 * std::sin(d) * Calibrated(d));
  const Eigen::Vector2d east_px = g.Project(Vector3d(10, 0, 60 - std::tan(60 * kDeg) * 10));
  EXPECT_EQ(image.mask[size_t(row) * image.width + std::lround(east_px.x())], kMaskShadow);
}

TEST(SarRendererTest, RejectsBadRaysPerCell) {
  RenderOptions o;
  o.rays_per_cell = 0.5;
  EXPECT_THROW(o.Check(), ConfigError);
}

// Over a pure height field each packet of primary rays starts at the hit of
// the highest ray of the packet below it (RenderOptions::
// skip_to_previous_hit): on steep terrain with shadow, layover and three
// bounces the image, its layers and its mask are the same bit for bit as
// with every ray traced from its origin, in both modes and both look sides
// (left: the rays fall with j, nothing is skipped). A building makes the
// scene no longer a height field.
TEST(SarRendererTest, PrimaryRaysSkippingToThePreviousHitChangeNoBit) {
  constexpr int kPosts = 90;
  const std::vector<float> heights = SteepRidgeHeights(kPosts, 7.0);
  scene::TriangleMesh mesh = scene::MeshFromHeights(heights, kPosts, kPosts, 10.0, -445.0, -445.0);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(heightfield.HeightfieldOnly());
  int64_t shadow = 0, layover = 0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (const auto side : {sensor::LookSide::kRight, sensor::LookSide::kLeft}) {
      const auto g = RidgeGeometry(mode, side, 30.0, mesh.vertices);
      RenderOptions options = Quiet(4.0);
      options.max_bounces = 3;
      options.profile_sweep = false;  // every primary ray traced
      const SarImage skipping = RenderSar(heightfield, mesh, UnitLambert(), g, options);
      options.skip_to_previous_hit = false;
      const SarImage plain = RenderSar(heightfield, mesh, UnitLambert(), g, options);
      ASSERT_EQ(skipping.intensity.size(), plain.intensity.size());
      EXPECT_EQ(std::memcmp(skipping.intensity.data(), plain.intensity.data(), plain.intensity.size() * sizeof(float)), 0);
      ASSERT_EQ(skipping.bounce_layers.size(), plain.bounce_layers.size());
      for (size_t k = 0; k < plain.bounce_layers.size(); ++k) {
        // Layers beyond max_bounces are empty in both (nothing to compare).
        ASSERT_EQ(skipping.bounce_layers[k].size(), plain.bounce_layers[k].size());
        EXPECT_EQ(plain.bounce_layers[k].empty(), int(k) >= options.max_bounces);
        if (plain.bounce_layers[k].empty()) continue;
        EXPECT_EQ(std::memcmp(skipping.bounce_layers[k].data(), plain.bounce_layers[k].data(),
                              plain.bounce_layers[k].size() * sizeof(float)),
                  0);
      }
      EXPECT_EQ(skipping.mask, plain.mask);
      EXPECT_EQ(skipping.stats.hits, plain.stats.hits);
      for (uint8_t m : plain.mask) {
        shadow += m == kMaskShadow;
        layover += m == kMaskLayover;
      }
    }
  }
  EXPECT_GT(shadow, 500);  // the terrain does cast shadows and lay over
  EXPECT_GT(layover, 500);
  mesh.AddQuad(Vector3f(0, 0, 0), Vector3f(20, 0, 0), Vector3f(20, 0, 300), Vector3f(0, 0, 300));
  EXPECT_FALSE(EmbreeScene(mesh, TerrainGrid{kPosts, kPosts, {}}).HeightfieldOnly());
}

// Fixed sampling (RenderOptions::adaptive_sampling false) traces exactly the
// ray grid's primary rays: no sub-rays on terrain steep enough to need
// them, and the same total power to within the sampling's noise (both
// integrate sigma0 over the lit surface).
TEST(SarRendererTest, FixedSamplingTracesNoSubRaysAndKeepsThePower) {
  constexpr int kPosts = 90;
  const std::vector<float> heights = SteepRidgeHeights(kPosts, 0.0);
  const scene::TriangleMesh mesh = scene::MeshFromHeights(heights, kPosts, kPosts, 10.0, -445.0, -445.0);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  const auto g = sensor::SarGeometry::Covering(Options(30.0, 40.0, 5.0), Vector3d::Zero(), mesh.vertices);
  RenderOptions options = Quiet(4.0);
  const SarImage adaptive = RenderSar(heightfield, mesh, UnitLambert(), g, options);
  options.adaptive_sampling = false;
  const SarImage fixed = RenderSar(heightfield, mesh, UnitLambert(), g, options);
  EXPECT_GT(adaptive.stats.sub_rays, 1000);
  EXPECT_EQ(fixed.stats.sub_rays, 0);
  EXPECT_EQ(fixed.stats.rays, adaptive.stats.rays);
  double sum_adaptive = 0.0, sum_fixed = 0.0;
  for (size_t i = 0; i < fixed.intensity.size(); ++i) {
    sum_adaptive += adaptive.intensity[i];
    sum_fixed += fixed.intensity[i];
  }
  EXPECT_NEAR(sum_fixed / sum_adaptive, 1.0, 0.02);
}

// The ridge of the closed-form mask tests: kRidgeCols x kRidgeRows posts
// 10 m apart, kRidgeHeightM high along x = 0 with 5:1 slopes (78.7 deg),
// flat ground at z = 0 beyond x = +-10 m.
constexpr int kRidgeCols = 61, kRidgeRows = 41;
constexpr double kRidgeHeightM = 50.0;
std::vector<Vector3f> RidgePosts() {
  std::vector<Vector3f> posts;
  for (int r = 0; r < kRidgeRows; ++r) {
    for (int c = 0; c < kRidgeCols; ++c) {
      const double x = 10.0 * (c - 30);
      posts.emplace_back(float(x), float(10.0 * (r - 20)),
                         float(std::max(0.0, kRidgeHeightM - 5.0 * std::abs(x))));
    }
  }
  return posts;
}

// The mask code of a ground centre x metres across the ridge (radar on the
// -x side): shadow from the back slope's foot (10 m) to shadow_end_x;
// layover and shadow from layover_from_x to the front slope's foot (-10 m)
// (ground lit, the front slope lit and flipped, the back slope turned
// away, all at those slant ranges); none beyond both. nullopt within
// `margin` metres of an edge, and on the ridge.
std::optional<uint8_t> ExpectedRidgeCode(double x, double layover_from_x, double shadow_end_x, double margin) {
  if (x > 10.0 + margin && x < shadow_end_x - margin) return kMaskShadow;
  if (x > layover_from_x + margin && x < -10.0 - margin) return uint8_t(kMaskLayover | kMaskShadow);
  if (x > shadow_end_x + margin || x < layover_from_x - margin) return kMaskNone;
  return std::nullopt;
}

// A ridge H = 50 m high across flat ground, 10 m posts, seen at depression
// 40 deg across it, as a whole grid's height field (the mask read off each
// row's profile) and as an ordinary mesh (a visibility ray per centre). The
// front slope (78.7 deg) lays over the ground 10-41.9 m before the ridge
// (slant ranges of both slopes: -32.1 to -7.7 m and -32.1 to 7.7 m), the
// back slope is turned away, and the ridge's shadow on the ground behind it ends at x = H / tan(40 deg) =
// 59.6 m: a ground centre at x is lit beyond it and in shadow before it.
TEST(SarRendererTest, RidgeShadowEndsAtTheClosedFormDistanceInBothMasks) {
  constexpr int kCols = kRidgeCols, kRows = kRidgeRows;
  constexpr double kH = kRidgeHeightM, kDep = 40.0;
  const std::vector<Vector3f> posts = RidgePosts();
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, kCols, kRows);
  // Flight north, looking east (+x): azimuth lines run along the rows.
  const auto g = sensor::SarGeometry::Covering(Options(0.0, kDep, 2.0), Vector3d::Zero(), mesh.vertices);
  ASSERT_NEAR(g.look_direction().x(), std::cos(kDep * kDeg), 1e-12);
  const double shadow_end_x = kH / std::tan(kDep * kDeg);
  for (const bool sweep : {true, false}) {
    const EmbreeScene embree(mesh, TerrainGrid{kCols, kRows, {}});
    int64_t rays = -1;
    const std::vector<uint8_t> mask = RenderLayoverShadowMask(embree, mesh, g, &rays, nullptr, nullptr, nullptr, sweep);
    EXPECT_EQ(rays == 0, sweep);
    int64_t checked = 0;
    for (int r = 0; r < g.height(); ++r) {
      const double y = (r - g.v0()) * g.azimuth_spacing_m();
      if (std::abs(y) > 190.0) continue;  // lines near the grid's sides
      for (int c = 0; c < g.width(); ++c) {
        // The flat-ground point of this centre: xl = x cos(dep) at z = 0.
        const double xl = (c - g.u0()) * g.range_spacing_m();
        const double x = xl / std::cos(kDep * kDeg) + g.scene_centre().dot(Vector3d(1, 0, 0));
        if (x < -280.0 || x > 280.0) continue;
        // Slant ranges of the slopes: front [-32.1, -7.7] m, back [-32.1, 7.7] m;
        // 3 m of ground clear of the edges.
        const std::optional<uint8_t> expected = ExpectedRidgeCode(x, -41.9, shadow_end_x, 3.0);
        if (!expected) continue;
        ASSERT_EQ(mask[size_t(r) * g.width() + c], *expected) << "sweep " << sweep << " x " << x << " y " << y;
        ++checked;
      }
    }
    EXPECT_GT(checked, 10000);
  }
}

// The same ridge in exact geometry from 2 km slant range: the sensor of
// each azimuth line sits D = R0 cos(40 deg) = 1532.1 m before the ridge and
// Z = R0 sin(40 deg) = 1285.6 m above the ground, so the ridge's shadow ends
// where the ray from the sensor over the top reaches the ground,
// x = H D / (Z - H) = 62.0 m (2.4 m beyond the parallel rays' 59.6 m), and
// the front slope lays over the ground whose slant range lies between the
// top's, hypot(D, Z - H), and its foot's: x = sqrt(R^2 - Z^2) - D from
// -41.7 to -10 m. Both masks (profile and rays) to within 1 m of ground.
TEST(SarRendererTest, ExactRidgeShadowEndsWhereTheSensorsRayOverTheTopLands) {
  constexpr int kCols = kRidgeCols, kRows = kRidgeRows;
  constexpr double kH = kRidgeHeightM, kDep = 40.0, kRange0 = 2000.0;
  const std::vector<Vector3f> posts = RidgePosts();
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, kCols, kRows);
  sensor::SarGeometryOptions o = Options(0.0, kDep, 2.0);
  o.mode = sensor::ProjectionMode::kExact;
  o.slant_range_m = kRange0;
  const auto g = sensor::SarGeometry::Covering(o, Vector3d::Zero(), mesh.vertices);
  const double d = kRange0 * std::cos(kDep * kDeg), z = kRange0 * std::sin(kDep * kDeg);
  const double shadow_end_x = kH * d / (z - kH);
  ASSERT_GT(shadow_end_x - kH / std::tan(kDep * kDeg), 2.0);
  auto ground_x = [&](double range) { return std::sqrt(range * range - z * z) - d; };
  const double layover_from_x = ground_x(std::hypot(d, z - kH));
  ASSERT_NEAR(ground_x(std::hypot(d - 10.0, z)), -10.0, 1e-9);
  for (const bool sweep : {true, false}) {
    const EmbreeScene embree(mesh, TerrainGrid{kCols, kRows, {}});
    int64_t rays = -1, swept_rows = -1;
    const std::vector<uint8_t> mask =
        RenderLayoverShadowMask(embree, mesh, g, &rays, nullptr, nullptr, nullptr, sweep, &swept_rows);
    EXPECT_EQ(rays == 0, sweep);
    EXPECT_EQ(swept_rows, sweep ? g.height() : 0);
    int64_t checked = 0, shadowed = 0;
    for (int r = 0; r < g.height(); ++r) {
      const double y = (r - g.v0()) * g.azimuth_spacing_m();
      if (std::abs(y) > 190.0) continue;  // lines near the grid's sides
      for (int c = 0; c < g.width(); ++c) {
        const double range = kRange0 + (c - g.u0()) * g.range_spacing_m();
        if (!(range > z)) continue;
        const double x = ground_x(range);  // the flat-ground point of this centre
        if (x < -280.0 || x > 280.0) continue;
        // 1 m of ground clear of the edges.
        const std::optional<uint8_t> expected = ExpectedRidgeCode(x, layover_from_x, shadow_end_x, 1.0);
        if (!expected) continue;
        shadowed += *expected == kMaskShadow;
        ASSERT_EQ(mask[size_t(r) * g.width() + c], *expected) << "sweep " << sweep << " x " << x << " y " << y;
        ++checked;
      }
    }
    EXPECT_GT(checked, 10000);
    EXPECT_GT(shadowed, 1000);
  }
}

// Over a whole grid's height field the primary hits come from one profile
// walk per azimuth line and the affine mask from one profile per image row
// (RenderOptions::profile_sweep), and the mask from one profile per image
// row in both modes. On the steep terrain above, warped in plan as a
// geographic DEM is in ENU, with three bounces, both modes and both look
// sides: the image is the traced one to float rounding and the masks agree
// but for pixel centres at a shadow or layover edge.
TEST(SarRendererTest, ProfileSweepGivesTheTracedImageAndMask) {
  constexpr int kPosts = 90;
  const scene::TriangleMesh mesh = scene::MeshFromGrid(WarpedRidgePosts(0.01), kPosts, kPosts);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(heightfield.HeightfieldOnly());
  int64_t shadow = 0, layover = 0, differing = 0, flagged = 0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (const auto side : {sensor::LookSide::kRight, sensor::LookSide::kLeft}) {
      for (double heading : {0.0, 30.0, 160.0}) {
        const auto g = RidgeGeometry(mode, side, heading, mesh.vertices);
        RenderOptions options = Quiet(4.0);
        options.max_bounces = 3;
        const SarImage swept = RenderSar(heightfield, mesh, UnitLambert(), g, options);
        options.profile_sweep = false;
        const SarImage traced = RenderSar(heightfield, mesh, UnitLambert(), g, options);
        // With one ray line per image row (rays per cell below 2.25) the
        // tracer's walk of each line also paints the row's mask
        // (traced_mask_rows): the rows' lines are the ray lines
        // (RowLineAlongTrack), so the mask and footprint are those the mask
        // phase walks itself at two lines per row, bit for bit.
        options.profile_sweep = true;
        options.rays_per_cell = 1.5;
        const SarImage painted = RenderSar(heightfield, mesh, UnitLambert(), g, options);
        EXPECT_EQ(painted.stats.traced_mask_rows, g.height()) << heading;
        EXPECT_EQ(painted.stats.profile_swept_mask_rows, g.height()) << heading;
        EXPECT_EQ(painted.stats.shadow_rays, 0) << heading;
        EXPECT_EQ(swept.stats.traced_mask_rows, 0) << heading;
        EXPECT_EQ(painted.mask, swept.mask) << heading;
        EXPECT_EQ(painted.footprint, swept.footprint) << heading;
        const IntensityAgreement image = CompareIntensities(traced.intensity, swept.intensity);
        EXPECT_GT(image.db_pearson, 0.99999) << heading;
        EXPECT_LT(std::abs(image.mean_db_difference), 1e-3) << heading;
        EXPECT_LE(image.one_sided_zero, image.compared_pixels / 5000) << heading;
        EXPECT_NEAR(double(swept.stats.hits), double(traced.stats.hits), 1e-4 * double(traced.stats.hits));
        const MaskAgreement masks = CompareMasks(traced.mask, swept.mask, g.width(), g.height());
        // A centre at the bottom of a shadowed valley (on the edge between a
        // slope turned away and a flipped one) is lit for the tracer when
        // the occluding slope is within its visibility ray's t_near (a few
        // centimetres): at most one such pixel per image.
        EXPECT_LE(masks.away_from_edges, 1) << heading;
        EXPECT_LE(masks.differing, std::max<int64_t>(2, masks.flagged / 500)) << heading;
        if (mode == sensor::ProjectionMode::kAffine) {
          EXPECT_EQ(swept.footprint, traced.footprint) << heading;
        } else {
          // Exact mode: the ray pass interpolates in the projected triangle,
          // whose edges are straight in the image while a straight edge's
          // true image is curved; the sweep places the edge exactly. A centre
          // within that curvature (a thousandth of a pixel here) of the
          // footprint's border may differ: at most two per image, each on
          // the border (a neighbour outside the traced footprint).
          int64_t footprint_differing = 0;
          for (int r = 0; r < g.height(); ++r) {
            for (int c = 0; c < g.width(); ++c) {
              const size_t q = size_t(r) * g.width() + c;
              if (swept.footprint[q] == traced.footprint[q]) continue;
              ++footprint_differing;
              bool border = false;
              for (const auto& [dc, dr] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
                const int cc = c + dc, rr = r + dr;
                border = border || cc < 0 || rr < 0 || cc >= g.width() || rr >= g.height() ||
                         traced.footprint[size_t(rr) * g.width() + cc] == 0;
              }
              EXPECT_TRUE(border) << heading << " " << c << "," << r;
            }
          }
          EXPECT_LE(footprint_differing, 2) << heading;
        }
        // Near-grazing hits split into sub-rays, which start at the swept
        // hit of the ray below them.
        EXPECT_GT(swept.stats.sub_rays, 0);
        EXPECT_NEAR(double(swept.stats.sub_rays), double(traced.stats.sub_rays), 1e-3 * double(traced.stats.sub_rays));
        EXPECT_GT(swept.stats.profile_swept_lines, 0);
        EXPECT_EQ(traced.stats.profile_swept_lines, 0);
        EXPECT_EQ(traced.stats.profile_swept_mask_rows, 0);
        // Both modes' masks come from the profiles: no visibility ray.
        EXPECT_EQ(swept.stats.shadow_rays, 0);
        EXPECT_EQ(swept.stats.profile_swept_mask_rows, g.height());
        EXPECT_GT(traced.stats.shadow_rays, 0);
        differing += masks.differing;
        flagged += masks.flagged;
        for (uint8_t m : swept.mask) {
          shadow += m == kMaskShadow;
          layover += m == kMaskLayover;
        }
      }
    }
  }
  EXPECT_GT(shadow, 2000);  // the terrain does cast shadows and lay over
  EXPECT_GT(layover, 2000);
  std::printf("mask pixels flagged %lld, differing %lld\n", (long long)flagged, (long long)differing);
}

// A swept line's rays shaded one by one (RenderOptions::one_pass_swept_lines)
// give the image of the 16-lane packets bit for bit, every plane, with the
// same hits and sub-rays (those met on the profile's frontiers): one and
// three bounces (the mirror rays traced on from the one-pass hits), both
// modes, with and without adaptive sampling.
TEST(SarRendererTest, OnePassSweptLinesAreThePacketsBitForBit) {
  constexpr int kPosts = 90;
  const scene::TriangleMesh mesh = scene::MeshFromGrid(WarpedRidgePosts(0.0), kPosts, kPosts);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  // Half Lambertian, half the smooth-surface reflection going on as a mirror
  // ray: the ridge's slopes return later bounces.
  material::MaterialTable materials;
  materials.Set(0, material::Material{"partly_mirror", 0.5, 0.0, 1.0, 0.5});
  int64_t later_bounce_pixels = 0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (const int bounces : {1, 3}) {
      for (const bool adaptive : {true, false}) {
        const auto g = RidgeGeometry(mode, sensor::LookSide::kRight, 30.0, mesh.vertices);
        RenderOptions options = Quiet(4.0);
        options.adaptive_sampling = adaptive;
        options.max_bounces = bounces;
        const SarImage one_pass = RenderSar(heightfield, mesh, materials, g, options);
        options.one_pass_swept_lines = false;
        const SarImage packets = RenderSar(heightfield, mesh, materials, g, options);
        ASSERT_EQ(one_pass.stats.profile_swept_lines, packets.stats.profile_swept_lines);
        EXPECT_GT(one_pass.stats.profile_swept_lines, 0);
        EXPECT_EQ(one_pass.stats.hits, packets.stats.hits);
        EXPECT_EQ(one_pass.stats.sub_rays, packets.stats.sub_rays);
        if (adaptive) {
          EXPECT_GT(one_pass.stats.sub_rays, 0);
        }
        ASSERT_EQ(one_pass.intensity.size(), packets.intensity.size());
        int64_t lit = 0;
        for (size_t q = 0; q < one_pass.intensity.size(); ++q) {
          ASSERT_EQ(one_pass.intensity[q], packets.intensity[q]) << "pixel " << q;
          lit += one_pass.intensity[q] > 0.0f;
        }
        EXPECT_GT(lit, 10000);
        for (size_t layer = 0; layer < one_pass.bounce_layers.size(); ++layer) {
          ASSERT_EQ(one_pass.bounce_layers[layer], packets.bounce_layers[layer]) << "layer " << layer;
          if (layer == 0) continue;
          for (const float v : one_pass.bounce_layers[layer]) later_bounce_pixels += v > 0.0f;
        }
      }
    }
  }
  // The ridge's slopes return later bounces too.
  EXPECT_GT(later_bounce_pixels, 100);
}

// An affine image of part of a scene traces only the rays whose returns
// can reach it (RenderOptions::image_rays_only): every plane, the mask and
// the footprint are those of tracing the whole ray box, bit for bit, with
// one bounce and with three (a partly mirror surface: later bounces from
// hits nearer than the image), both look sides, with and without sub-rays,
// over a triangle mesh (the heights near the image from its tiles) and over
// the same terrain as a height field (the profile sweep; the box's heights).
TEST(SarRendererTest, ImageRaysOnlyGiveTheWholeBoxsImageBitForBit) {
  constexpr int kPosts = 90;
  // The steep ridge stretched to 2.7 km in plan.
  std::vector<Vector3f> posts = WarpedRidgePosts(0.01);
  for (Vector3f& p : posts) p.head<2>() *= 3.0f;
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, kPosts, kPosts);
  const EmbreeScene triangles(mesh);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_FALSE(triangles.heightfield());
  ASSERT_TRUE(heightfield.HeightfieldOnly());
  material::MaterialTable materials;
  materials.Set(0, material::Material{"partly_mirror", 0.5, 0.0, 1.0, 0.5});
  int64_t later_bounce_pixels = 0, lit_pixels = 0;
  for (const EmbreeScene* embree : {&triangles, &heightfield}) {
    for (const auto side : {sensor::LookSide::kRight, sensor::LookSide::kLeft}) {
      for (const double heading : {30.0, 200.0}) {
        // 48 x 32 pixels of 2.5 m (120 m x 80 m) off the centre of the
        // terrain.
        sensor::SarGeometryOptions o = Options(heading, 40.0, 2.5);
        o.look_side = side;
        o.slant_range_m = 5000.0;
        const sensor::SarGeometry g(o, Vector3d(120.0, -90.0, 0.0), 23.5, 15.5, 48, 32);
        for (const int bounces : {1, 3}) {
          for (const bool adaptive : {true, false}) {
            RenderOptions options = Quiet(4.0);
            options.max_bounces = bounces;
            options.adaptive_sampling = adaptive;
            const SarImage culled = RenderSar(*embree, mesh, materials, g, options);
            options.image_rays_only = false;
            const SarImage whole = RenderSar(*embree, mesh, materials, g, options);
            const std::string what = std::string(embree == &triangles ? "mesh" : "height field") + " heading " +
                                     std::to_string(heading) + " bounces " + std::to_string(bounces);
            ASSERT_EQ(culled.intensity, whole.intensity) << what;
            ASSERT_EQ(culled.bounce_layers, whole.bounce_layers) << what;
            EXPECT_EQ(culled.mask, whole.mask) << what;
            EXPECT_EQ(culled.footprint, whole.footprint) << what;
            // The terrain is about 1000 pixels across: with one bounce
            // only the rays of the image and its reach (48 + 2 x 34
            // columns) over the terrain's height range are traced, with
            // three also the nearer ones.
            EXPECT_LT(culled.stats.rays, whole.stats.rays * (bounces == 1 ? 0.5 : 0.9)) << what;
            int64_t lit = 0;
            for (const float v : culled.intensity) lit += v > 0.0f;
            EXPECT_GT(lit, g.width() * g.height() / 8) << what;
            lit_pixels += lit;
            for (size_t layer = 1; layer < culled.bounce_layers.size(); ++layer) {
              for (const float v : culled.bounce_layers[layer]) later_bounce_pixels += v > 0.0f;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(lit_pixels, 32 * 48 * 32 / 3);
  EXPECT_GT(later_bounce_pixels, 100);
}

// The mask's ray pass over a triangle mesh in affine mode visits only the
// tiles whose bounds project onto the image (EmbreeScene::Tiles): an image
// of part of the terrain gets the codes of the same pixels of an image
// covering it all (which visits every tile).
TEST(SarRendererTest, MaskOfPartOfASceneIsThatOfTheWholeScenesPixels) {
  constexpr int kPosts = 90;
  const scene::TriangleMesh mesh = scene::MeshFromGrid(WarpedRidgePosts(0.01), kPosts, kPosts);
  const EmbreeScene embree(mesh);
  int64_t flagged = 0;
  for (const auto side : {sensor::LookSide::kRight, sensor::LookSide::kLeft}) {
    for (const double heading : {30.0, 200.0}) {
      const sensor::SarGeometry whole =
          RidgeGeometry(sensor::ProjectionMode::kAffine, side, heading, mesh.vertices);
      // 60 x 40 pixels of it, from column 50 and row 70: the same pixel
      // centres (the scene centre moved by whole pixels along l and h).
      const int c0 = 50, r0 = 70, w = 60, h = 40;
      ASSERT_GT(whole.width(), c0 + w);
      ASSERT_GT(whole.height(), r0 + h);
      const sensor::SarGeometry part(whole.options(), whole.scene_centre(), whole.u0() - c0, whole.v0() - r0, w, h);
      const std::vector<uint8_t> whole_mask = RenderLayoverShadowMask(embree, mesh, whole);
      const std::vector<uint8_t> part_mask = RenderLayoverShadowMask(embree, mesh, part);
      std::vector<uint8_t> expected;
      for (int r = 0; r < h; ++r) {
        for (int c = 0; c < w; ++c) expected.push_back(whole_mask[size_t(r0 + r) * whole.width() + c0 + c]);
      }
      EXPECT_EQ(part_mask, expected) << heading;
      for (const uint8_t m : part_mask) flagged += m != kMaskNone;
    }
  }
  EXPECT_GT(flagged, 500);  // the part holds shadow and layover
}

// A grid whose first row of posts zigzags along track: the azimuth lines
// through the zigzag cross the grid's boundary more than twice, so the
// sweep refuses them and only their image rows get visibility rays; every
// other row comes from its profile. The mask is the all-rays mask but for
// centres at an edge, in both modes.
TEST(SarRendererTest, MaskRowsTheSweepRefusesGetVisibilityRays) {
  constexpr int kPosts = 90;
  const std::vector<float> heights = SteepRidgeHeights(kPosts, 7.0);
  std::vector<Vector3f> posts;
  for (int r = 0; r < kPosts; ++r) {
    for (int c = 0; c < kPosts; ++c) {
      // Row 0 zigzags 4 m across y = -405 m (flight along +y: along track).
      const double y = r == 0 ? -405.0 + (c % 2 == 0 ? -4.0 : 4.0) : 9.0 * (r - 45);
      posts.emplace_back(float(10.0 * (c - 45)), float(y), heights[size_t(r) * kPosts + c]);
    }
  }
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, kPosts, kPosts);
  const EmbreeScene heightfield(mesh, TerrainGrid{kPosts, kPosts, {}});
  ASSERT_TRUE(heightfield.HeightfieldOnly());
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    const auto g = RidgeGeometry(mode, sensor::LookSide::kRight, 0.0, mesh.vertices);
    int64_t swept_rows = 0, mixed_rays = 0, all_rays = 0;
    std::vector<uint8_t> mixed_footprint, all_footprint;
    const std::vector<uint8_t> mixed =
        RenderLayoverShadowMask(heightfield, mesh, g, &mixed_rays, nullptr, &mixed_footprint, nullptr, true, &swept_rows);
    const std::vector<uint8_t> all =
        RenderLayoverShadowMask(heightfield, mesh, g, &all_rays, nullptr, &all_footprint, nullptr, false);
    // The zigzag spans 8 m of along track: 8 m / 5 m rows, one or two rows
    // refused, and rays only for them.
    EXPECT_LT(swept_rows, g.height());
    EXPECT_GE(swept_rows, g.height() - 3);
    EXPECT_GT(mixed_rays, 0);
    EXPECT_LT(mixed_rays, all_rays / 20);
    const MaskAgreement masks = CompareMasks(all, mixed, g.width(), g.height());
    EXPECT_GT(masks.flagged, 1000);
    EXPECT_LE(masks.away_from_edges, 1);
    EXPECT_LE(masks.differing, std::max<int64_t>(2, masks.flagged / 500));
    int64_t footprint_differing = 0;
    for (size_t q = 0; q < all_footprint.size(); ++q) footprint_differing += all_footprint[q] != mixed_footprint[q];
    EXPECT_LE(footprint_differing, 2);
  }
}

}  // namespace
}  // namespace gissar::render
