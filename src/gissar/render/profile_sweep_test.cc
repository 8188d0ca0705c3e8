#include "gissar/render/profile_sweep.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "gissar/render/embree_scene.h"
#include "gissar/render/profile_mask.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

sensor::SarGeometryOptions Options(double heading, double depression, sensor::ProjectionMode mode) {
  sensor::SarGeometryOptions o;
  o.heading_deg = heading;
  o.depression_deg = depression;
  o.slant_range_m = 3000.0;
  o.range_spacing_m = 5.0;
  o.azimuth_spacing_m = 5.0;
  o.mode = mode;
  return o;
}

// The rough terrain of the Embree comparisons: kRoughWidth x kRoughHeight
// posts on a warped grid (not a lattice in ENU, as a geographic DEM's),
// heights with noise drawn from `rng`.
constexpr int kRoughWidth = 90, kRoughHeight = 70;
std::vector<Vector3f> WarpedRoughPosts(std::mt19937& rng) {
  std::normal_distribution<float> bump(0.0f, 6.0f);
  std::vector<Vector3f> posts;
  for (int r = 0; r < kRoughHeight; ++r) {
    for (int c = 0; c < kRoughWidth; ++c) {
      const float x = 12.0f * (c - 45) + 0.8f * (r - 35) + 0.004f * float((r - 35) * (r - 35));
      const float y = 9.0f * (r - 35) - 0.5f * (c - 45);
      const float z = 60.0f * std::sin(0.09f * c) * std::cos(0.07f * r) + 0.3f * x + bump(rng);
      posts.emplace_back(x, y, z);
    }
  }
  return posts;
}

// The extent of `posts` in the ray coordinate e of `g`'s lines (affine:
// metres along n; exact: radians from l seen from the sensor).
std::pair<double, double> RayCoordinateExtent(const std::vector<Vector3f>& posts, const sensor::SarGeometry& g) {
  const bool affine = g.mode() == sensor::ProjectionMode::kAffine;
  const Vector3d& l = g.look_direction();
  const Vector3d& n = g.range_plane_normal();
  double e_lo = 1e300, e_hi = -1e300;
  for (const Vector3f& p : posts) {
    const Vector3d q = p.cast<double>() - g.scene_centre();
    const double e = affine ? q.dot(n) : std::atan2(q.dot(n), g.slant_range_m() + q.dot(l));
    e_lo = std::min(e_lo, e);
    e_hi = std::max(e_hi, e);
  }
  return {e_lo, e_hi};
}

// `count` rays spread over the terrain's extent in e (RayCoordinateExtent)
// and ten spacings beyond it on either side: the first one's coordinate and
// the spacing.
struct RaysAcross {
  double e0, de;
};
RaysAcross RaysAcrossTerrain(const std::vector<Vector3f>& posts, const sensor::SarGeometry& g, int count) {
  const auto [e_lo, e_hi] = RayCoordinateExtent(posts, g);
  const double de = (e_hi - e_lo) / (count - 20);
  return {e_lo - 10 * de, de};
}

// The ray of coordinate e on the line at along-track a (sensor at
// `sensor_pos` in exact mode) as Embree gets it: its origin and direction;
// returns the origin's depth in the sweep's terms (affine: along l from the
// scene centre; exact: from the sensor).
double FloatRay(const sensor::SarGeometry& g, double a, double e, const Vector3d& sensor_pos, Vector3d* origin,
                Vector3d* dir) {
  const Vector3d& l = g.look_direction();
  const Vector3d& n = g.range_plane_normal();
  if (g.mode() == sensor::ProjectionMode::kAffine) {
    *dir = l;
    *origin = g.scene_centre() + a * g.flight_direction() + e * n - 5000.0 * l;
    return -5000.0;
  }
  *dir = std::cos(e) * l + std::sin(e) * n;
  *origin = sensor_pos + 1000.0 * *dir;
  return 1000.0;
}

// A flat grid at z = 0: ray e meets it where g (n . ground) = e, at depth
// g cos(depression) along l (affine; n . ground = +-sin(depression)).
TEST(GridProfileSweepTest, FlatPlaneHitsAtTheClosedFormDepth) {
  const int w = 60, h = 50;
  std::vector<Vector3f> posts;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) posts.emplace_back(10.0f * (c - 30), 10.0f * (r - 25), 0.0f);
  }
  for (double heading : {0.0, 30.0, 135.0}) {
    const auto g = sensor::SarGeometry::Covering(Options(heading, 40.0, sensor::ProjectionMode::kAffine),
                                                 Vector3d::Zero(), posts);
    const GridProfileSweep sweep(posts.data(), w, h, g);
    const Vector3d ground = Vector3d(g.look_direction().x(), g.look_direction().y(), 0.0).normalized();
    const double n_ground = g.range_plane_normal().dot(ground);
    ASSERT_NEAR(std::abs(n_ground), std::sin(40.0 * M_PI / 180.0), 1e-12);
    const int count = 400;
    const double e0 = -200.0, de = 1.0;
    std::vector<double> depth(count);
    std::vector<uint32_t> tri(count);
    int hits = 0;
    for (double a : {-101.3, 0.25, 77.7}) {
      ASSERT_TRUE(sweep.Trace(a, e0, de, count, depth.data(), tri.data()));
      for (int j = 0; j < count; ++j) {
        const double e = e0 + j * de;
        // The plane point of ray j: X = (e / n_ground) ground + a h.
        const Vector3d x = e / n_ground * ground + a * g.flight_direction();
        const bool inside = std::abs(x.x()) < 290.0 && std::abs(x.y()) < 240.0;
        const bool outside = std::abs(x.x()) > 300.0 || std::abs(x.y()) > 250.0;
        if (outside) {
          EXPECT_EQ(tri[j], GridProfileSweep::kNoHit) << heading << " " << a << " " << j;
        }
        if (!inside) continue;
        ASSERT_NE(tri[j], GridProfileSweep::kNoHit) << heading << " " << a << " " << j;
        ++hits;
        EXPECT_NEAR(depth[j], x.dot(g.look_direction()), 1e-9);
        EXPECT_NEAR(depth[j], e / n_ground * std::cos(40.0 * M_PI / 180.0), 1e-9);
        // The named triangle is the cell's half that holds the point.
        const double fc = (x.x() + 300.0) / 10.0, fr = (x.y() + 250.0) / 10.0;
        const int c = int(std::floor(fc)), r = int(std::floor(fr));
        const int half = (fc - c) + (fr - r) > 1.0 ? 1 : 0;
        if (std::abs((fc - c) + (fr - r) - 1.0) > 1e-6 && fc - c > 1e-6 && fr - r > 1e-6) {
          EXPECT_EQ(tri[j], uint32_t(2 * (r * (w - 1) + c) + half));
        }
      }
    }
    EXPECT_GT(hits, 100);
  }
}

// Rough terrain on a warped grid (posts not on a lattice in ENU, as a
// geographic DEM's), every heading and both projection modes: each ray's
// sweep hit is the first hit Embree finds for the same ray.
TEST(GridProfileSweepTest, EveryRayHitsWhereEmbreeDoes) {
  const int w = kRoughWidth, h = kRoughHeight;
  std::mt19937 rng(7);
  const std::vector<Vector3f> posts = WarpedRoughPosts(rng);
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, w, h);
  const EmbreeScene embree(mesh);
  int64_t rays = 0, hits = 0, other_triangle = 0, disagree = 0;
  double worst_depth = 0.0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (double heading : {0.0, 30.0, 90.0, 135.0, 250.0}) {
      for (double depression : {20.0, 45.0, 70.0}) {
        const auto g = sensor::SarGeometry::Covering(Options(heading, depression, mode), Vector3d::Zero(), posts);
        const GridProfileSweep sweep(posts.data(), w, h, g);
        const int count = 300;
        // The rays span the terrain's extent in e (metres or radians).
        const auto [e0, de] = RaysAcrossTerrain(posts, g, count);
        std::vector<double> depth(count);
        std::vector<uint32_t> tri(count);
        for (double a = -420.0; a <= 420.0; a += 37.0) {
          ASSERT_TRUE(sweep.Trace(a, e0, de, count, depth.data(), tri.data()));
          const Vector3d sensor_pos = g.SensorPosition(a);
          for (int j = 0; j < count; ++j) {
            const double e = e0 + j * de;
            Vector3d origin, dir;
            const double before = FloatRay(g, a, e, sensor_pos, &origin, &dir);  // depth of the origin
            const auto hit = embree.Intersect(origin.cast<float>(), dir.cast<float>(), 0.0f,
                                              std::numeric_limits<float>::infinity());
            ++rays;
            if (hit.has_value() != (tri[j] != GridProfileSweep::kNoHit)) {
              ++disagree;
              continue;
            }
            if (!hit) continue;
            ++hits;
            // A ray that grazes a ridge within float rounding may meet the
            // next slope instead: another triangle, another depth.
            if (hit->triangle != tri[j]) {
              ++other_triangle;
              continue;
            }
            worst_depth = std::max(worst_depth, std::abs(before + double(hit->t) - depth[j]));
          }
        }
      }
    }
  }
  // Float rays (origins rounded to about a millimetre) against the exact
  // walk: the same hits but for rays grazing a ridge or an edge.
  EXPECT_GT(hits, 50000);
  EXPECT_LE(disagree, rays / 10000) << disagree << " of " << rays;
  EXPECT_LE(other_triangle, hits / 1000) << other_triangle << " of " << hits;
  EXPECT_LT(worst_depth, 0.05);
  std::printf("rays %lld hits %lld disagree %lld other triangle %lld worst depth %.2e m\n", (long long)rays,
              (long long)hits, (long long)disagree, (long long)other_triangle, worst_depth);
}

// A slice of a line's rays (LineRays::first, count) gets the hits the same
// rays get traced with all of them, bit for bit: the rays of a line need
// not start at the bottom of the terrain (RenderOptions::image_rays_only).
TEST(GridProfileSweepTest, ASliceOfTheRaysGetsTheirHitsBitForBit) {
  const int w = kRoughWidth, h = kRoughHeight;
  std::mt19937 rng(5);
  const std::vector<Vector3f> posts = WarpedRoughPosts(rng);
  int64_t hits = 0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (double heading : {30.0, 250.0}) {
      const auto g = sensor::SarGeometry::Covering(Options(heading, 45.0, mode), Vector3d::Zero(), posts);
      const GridProfileSweep sweep(posts.data(), w, h, g);
      const int count = 400;
      const auto [e0, de] = RaysAcrossTerrain(posts, g, count);
      std::vector<double> depth(count), slice_depth(count);
      std::vector<uint32_t> tri(count), slice_tri(count);
      for (double a = -420.0; a <= 420.0; a += 37.0) {
        ASSERT_TRUE(sweep.Trace(a, e0, de, count, depth.data(), tri.data()));
        for (const auto& [first, n] : {std::pair{0, 96}, {112, 160}, {208, 192}, {384, 16}}) {
          GridProfileSweep::LineRays line{a, e0, de, first, n, slice_depth.data(), slice_tri.data(), nullptr};
          uint8_t ok = 0;
          sweep.TraceLines({line}, &ok);
          ASSERT_TRUE(ok);
          for (int j = 0; j < n; ++j) {
            ASSERT_EQ(slice_tri[size_t(j)], tri[size_t(first + j)]) << first << " " << j;
            if (tri[size_t(first + j)] == GridProfileSweep::kNoHit) continue;
            ASSERT_EQ(slice_depth[size_t(j)], depth[size_t(first + j)]) << first << " " << j;
            ++hits;
          }
        }
      }
    }
  }
  EXPECT_GT(hits, 20000);
}

// A line traced with its mask row painted on the way (LineRays::mask_row)
// gets the same hits, bit for bit, as without, and its painter the
// segments the mask phase's walk (ProfileLines) gives: the row painted both
// ways by ProfileMaskRule is the same. The warped rough grid above, both
// modes, two headings, lines every 37 m.
TEST(GridProfileSweepTest, AMaskRowPaintedOnTheWayIsTheProfileWalksRow) {
  const int w = kRoughWidth, h = kRoughHeight;
  std::mt19937 rng(7);
  const std::vector<Vector3f> posts = WarpedRoughPosts(rng);
  int64_t lit = 0, shadowed = 0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (double heading : {30.0, 250.0}) {
      const auto g = sensor::SarGeometry::Covering(Options(heading, 45.0, mode), Vector3d::Zero(), posts);
      const GridProfileSweep sweep(posts.data(), w, h, g);
      const ProfileMaskRule rule(sweep, g);
      const int count = 400;
      const auto [e0, de] = RaysAcrossTerrain(posts, g, count);
      std::vector<double> depth(count), painted_depth(count);
      std::vector<uint32_t> tri(count), painted_tri(count);
      for (double a = -420.0; a <= 420.0; a += 37.0) {
        ASSERT_TRUE(sweep.Trace(a, e0, de, count, depth.data(), tri.data()));
        std::vector<uint8_t> painted_row(size_t(g.width()), 0), walked_row(size_t(g.width()), 0);
        MaskRowPainter painter(rule, painted_row.data());
        GridProfileSweep::LineRays line{a, e0, de, 0, count, painted_depth.data(), painted_tri.data(), nullptr};
        line.mask_row = &painter;
        uint8_t ok = 0;
        sweep.TraceLines({line}, &ok);
        ASSERT_TRUE(ok);
        EXPECT_FALSE(painter.behind_sensor());
        for (int j = 0; j < count; ++j) {
          ASSERT_EQ(painted_tri[size_t(j)], tri[size_t(j)]) << j;
          if (tri[size_t(j)] != GridProfileSweep::kNoHit) {
            ASSERT_EQ(painted_depth[size_t(j)], depth[size_t(j)]) << j;
          }
        }
        sweep.ProfileLines(&a, 1, &ok, [&](size_t, const GridProfileSweep::ProfileSegment& s) {
          EXPECT_TRUE(rule.Paint(s, walked_row.data()));
        });
        ASSERT_TRUE(ok);
        ASSERT_EQ(painted_row, walked_row) << a;
        for (uint8_t f : walked_row) {
          lit += (f & kLitBit) != 0;
          shadowed += (f & kMaskShadow) != 0;
        }
      }
    }
  }
  EXPECT_GT(lit, 3000);  // the rows compared are lit and shadowed
  EXPECT_GT(shadowed, 100);
}

// The frontiers recorded by a coarse ray grid give the hit of a ray at any
// coordinate (the sub-rays between the grid's): on the warped rough grid
// above, both modes, all headings, 60 random coordinates per line across
// the terrain's extent against Embree's float rays: the same hits but for
// rays grazing an edge.
TEST(GridProfileSweepTest, FrontierHitsWhereEmbreeDoesBetweenTheRays) {
  const int w = kRoughWidth, h = kRoughHeight;
  std::mt19937 rng(11);
  const std::vector<Vector3f> posts = WarpedRoughPosts(rng);
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, w, h);
  const EmbreeScene embree(mesh);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int64_t rays = 0, hits = 0, lower_hits = 0, other_triangle = 0, disagree = 0;
  double worst_depth = 0.0;
  for (const auto mode : {sensor::ProjectionMode::kAffine, sensor::ProjectionMode::kExact}) {
    for (double heading : {0.0, 30.0, 135.0, 250.0}) {
      for (double depression : {20.0, 45.0, 70.0}) {
        const auto g = sensor::SarGeometry::Covering(Options(heading, depression, mode), Vector3d::Zero(), posts);
        const GridProfileSweep sweep(posts.data(), w, h, g);
        const bool affine = mode == sensor::ProjectionMode::kAffine;
        const auto [e_lo, e_hi] = RayCoordinateExtent(posts, g);
        // A coarse grid of 12 rays; the frontiers out to the terrain's extent.
        const int count = 12;
        const double de = (e_hi - e_lo) / (count - 1);
        std::vector<double> depth(count);
        std::vector<uint32_t> tri(count);
        GridProfileSweep::Frontier frontier;
        auto coordinate = [&](double e) { return affine ? e : std::tan(e); };
        for (double a = -420.0; a <= 420.0; a += 37.0) {
          GridProfileSweep::LineRays line{a, e_lo, de, 0, count, depth.data(), tri.data(), nullptr, nullptr,
                                             &frontier, coordinate(e_lo - de), coordinate(e_hi + de)};
          uint8_t ok = 0;
          sweep.TraceLines({line}, &ok);
          ASSERT_TRUE(ok);
          const Vector3d sensor_pos = g.SensorPosition(a);
          for (int k = 0; k < 60; ++k) {
            const double e = e_lo + (e_hi - e_lo) * unit(rng);
            Vector3d origin, dir;
            const double before = FloatRay(g, a, e, sensor_pos, &origin, &dir);  // depth of the origin
            const auto hit = embree.Intersect(origin.cast<float>(), dir.cast<float>(), 0.0f,
                                              std::numeric_limits<float>::infinity());
            double frontier_depth = 0.0;
            uint32_t frontier_triangle = 0;
            const bool found = sweep.FrontierHit(frontier, coordinate(e), &frontier_depth, &frontier_triangle);
            ++rays;
            if (hit.has_value() != found) {
              ++disagree;
              continue;
            }
            if (!hit) continue;
            ++hits;
            lower_hits += coordinate(e) < frontier.entry;
            if (hit->triangle != frontier_triangle) {
              ++other_triangle;
              continue;
            }
            worst_depth = std::max(worst_depth, std::abs(before + double(hit->t) - frontier_depth));
          }
        }
      }
    }
  }
  EXPECT_GT(hits, 15000);
  EXPECT_GT(lower_hits, 100);  // rays below the entry point: the lower frontier
  EXPECT_LE(disagree, rays / 2000) << disagree << " of " << rays;
  EXPECT_LE(other_triangle, hits / 1000) << other_triangle << " of " << hits;
  EXPECT_LT(worst_depth, 0.05);
  std::printf("rays %lld hits %lld (below the entry %lld) disagree %lld other triangle %lld worst depth %.2e m\n",
              (long long)rays, (long long)hits, (long long)lower_hits, (long long)disagree,
              (long long)other_triangle, worst_depth);
}

// A grid bent in plan into an arc (not convex): lines that cross its
// boundary four times are refused (the caller traces them), the others are
// swept and agree with Embree.
TEST(GridProfileSweepTest, RefusesLinesThatCrossTheGridTwice) {
  const int w = 80, h = 12;
  std::vector<Vector3f> posts;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      // Column c at angle 0..pi around the origin, rows at radius 300..410 m.
      const double angle = M_PI * c / (w - 1), radius = 300.0 + 10.0 * r;
      posts.emplace_back(float(radius * std::cos(angle)), float(radius * std::sin(angle)),
                         float(5.0 * std::sin(0.3 * c + 0.5 * r)));
    }
  }
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, w, h);
  const EmbreeScene embree(mesh);
  // Flight north, looking east from the right: lines run west-east (a = y).
  const auto g = sensor::SarGeometry::Covering(Options(0.0, 45.0, sensor::ProjectionMode::kAffine), Vector3d::Zero(),
                                               posts);
  const GridProfileSweep sweep(posts.data(), w, h, g);
  const int count = 400;
  std::vector<double> depth(count);
  std::vector<uint32_t> tri(count);
  int refused = 0, swept = 0;
  for (double a = -50.0; a <= 450.0; a += 5.0) {
    // 0 < y < 300: the line crosses both arms of the arc.
    const double y = a + g.scene_centre().y();
    const bool ok = sweep.Trace(a, -500.0, 2.5, count, depth.data(), tri.data());
    if (std::abs(y) < 5.0 || std::abs(y - 300.0) < 5.0) continue;  // at an arm's end or the inner edge's top
    const bool twice = y > 0.0 && y < 300.0;
    EXPECT_EQ(ok, !twice) << a;
    if (!ok) {
      ++refused;
      continue;
    }
    ++swept;
    for (int j = 0; j < count; ++j) {
      const Vector3d origin = g.scene_centre() + a * g.flight_direction() + (-500.0 + 2.5 * j) * g.range_plane_normal() -
                              3000.0 * g.look_direction();
      const auto hit = embree.Intersect(origin.cast<float>(), g.look_direction().cast<float>(), 0.0f,
                                        std::numeric_limits<float>::infinity());
      ASSERT_EQ(hit.has_value(), tri[j] != GridProfileSweep::kNoHit) << a << " " << j;
      if (hit) {
        EXPECT_NEAR(double(hit->t) - 3000.0, depth[j], 0.01);
      }
    }
  }
  EXPECT_GT(refused, 50);
  EXPECT_GT(swept, 30);  // above the hole, and beside the grid (every ray misses)
}

}  // namespace
}  // namespace gissar::render
