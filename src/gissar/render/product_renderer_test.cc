// The product renderer's coherent mode (render/product_renderer.h): phasors
// formed on a real radar grid from the re-projected returns.
#include "gissar/render/product_renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>

#include "gissar/material/scattering.h"

namespace gissar::render {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

// A straight, level track 6 km up and 8 km west of the scene centre, flying
// north at 200 m/s (right-looking: the radar looks east), as state vectors
// in ECEF; and the zero-Doppler grid of 1 m x 1 m pixels (0.005 s lines)
// centred on the scene.
struct Track {
  geo::LocalFrame frame{10.0, 45.0};
  sensor::Orbit orbit;
  sensor::RadarGrid grid;
};

Vector3d Ecef(const geo::LocalFrame& frame, const Vector3d& enu) {
  const Vector3d llh = frame.GeodeticFromEnu(enu);
  return geo::LocalFrame::EcefFromGeodetic(llh.x(), llh.y(), llh.z());
}

Track MakeTrack() {
  const geo::LocalFrame frame(10.0, 45.0);
  const double speed = 200.0;
  std::vector<double> t;
  std::vector<Vector3d> p, v;
  for (int i = -10; i <= 10; ++i) {
    const Vector3d enu(-8000.0, speed * i, 6000.0);
    t.push_back(i);
    p.push_back(Ecef(frame, enu));
    v.push_back(Ecef(frame, enu + Vector3d(0, speed, 0)) - p.back());  // the ENU frame is affine to ECEF
  }
  Track track{frame, sensor::Orbit(t, p, v), {}};
  sensor::RadarGrid& g = track.grid;
  g.cols = 120;
  g.rows = 100;
  g.dr_m = 1.0;
  g.dt_s = 1.0 / speed;
  g.r0_m = 10000.0 - 0.5 * (g.cols - 1) * g.dr_m;  // 10 km: the range of the scene centre
  g.t0_s = -0.5 * (g.rows - 1) * g.dt_s;
  g.look_side = sensor::LookSide::kRight;
  g.wavelength_m = 0.056;
  return track;
}

// Flat rough ground (single bounce only), 300 m x 300 m.
scene::TriangleMesh Ground() {
  scene::TriangleMesh mesh;
  mesh.AddQuad(Vector3f(-150, -150, 0), Vector3f(150, -150, 0), Vector3f(150, 150, 0), Vector3f(-150, 150, 0), 0);
  return mesh;
}

material::MaterialTable Materials() {
  material::MaterialTable t;
  t.Set(0, {"ground", 0.5, 0.0, 1.0, 0.0});
  return t;
}

RenderOptions Options(bool coherent, uint64_t seed = 1) {
  RenderOptions o;
  o.rays_per_cell = 4.0;
  o.max_bounces = 1;
  o.coherent = coherent;
  o.wavelength_m = 0.056;
  o.seed = seed;
  return o;
}

// Coherent mode: the same returns as the incoherent render (bounce layers
// identical), phasors whose power averages to the incoherent image (random
// micro-phase per return and pixel), complex bounce layers adding up to the
// complex total, the total's power = the detected total.
TEST(ProductRendererTest, CoherentSpeckleAveragesToTheIncoherentImage) {
  const Track track = MakeTrack();
  const scene::TriangleMesh mesh = Ground();
  const EmbreeScene embree(mesh);
  const ProductImage incoherent =
      RenderProduct(embree, mesh, Materials(), track.frame, track.orbit, track.grid, Options(false));
  const ProductImage coherent =
      RenderProduct(embree, mesh, Materials(), track.frame, track.orbit, track.grid, Options(true));
  const SarImage& a = incoherent.image;
  const SarImage& b = coherent.image;
  ASSERT_EQ(b.real.size(), b.intensity.size());
  ASSERT_EQ(b.bounce_real[0].size(), b.real.size());
  EXPECT_TRUE(a.real.empty());
  EXPECT_EQ(a.bounce_layers[0], b.bounce_layers[0]);  // the same returns, landed at the same places
  EXPECT_EQ(incoherent.contributions, coherent.contributions);
  double sum_a = 0, sum_b = 0, worst_split = 0, worst_detect = 0;
  int64_t pixels = 0;
  // Interior pixels (away from the footprint's edges).
  for (int r = 10; r < b.height - 10; ++r) {
    for (int c = 10; c < b.width - 10; ++c) {
      const size_t k = size_t(r) * b.width + c;
      sum_a += a.intensity[k];
      sum_b += b.intensity[k];
      ++pixels;
      worst_split = std::max(worst_split, double(std::abs(b.bounce_real[0][k] - b.real[k]) +
                                                 std::abs(b.bounce_imag[0][k] - b.imag[k])));
      const double power = double(b.real[k]) * b.real[k] + double(b.imag[k]) * b.imag[k];
      worst_detect = std::max(worst_detect, std::abs(power - b.intensity[k]) / std::max(power, 1e-30));
    }
  }
  ASSERT_GT(pixels, 5000);
  ASSERT_GT(sum_a, 0.0);
  const double ratio = sum_b / sum_a;
  std::printf("[ measured ] coherent / incoherent mean intensity over %lld pixels: %.4f\n",
              static_cast<long long>(pixels), ratio);
  // Single-look speckle (exponential, std = mean per independent sample):
  // ~7000 pixels, 4 rays per pixel -> about 1 % standard deviation.
  EXPECT_NEAR(ratio, 1.0, 0.05);
  EXPECT_EQ(worst_split, 0.0);  // one bounce: the single layer is the total
  EXPECT_LT(worst_detect, 1e-5);
  // The intensity statistics are those of speckle: std / mean near 1.
  double s = 0, s2 = 0;
  for (int r = 10; r < b.height - 10; ++r) {
    for (int c = 10; c < b.width - 10; ++c) {
      const double x = b.intensity[size_t(r) * b.width + c] / (a.intensity[size_t(r) * b.width + c] + 1e-30);
      s += x;
      s2 += x * x;
    }
  }
  const double mean = s / pixels, contrast = std::sqrt(s2 / pixels - mean * mean) / mean;
  std::printf("[ measured ] speckle contrast (std/mean of coherent/incoherent): %.3f\n", contrast);
  EXPECT_GT(contrast, 0.6);
  EXPECT_LT(contrast, 1.2);
  // Deterministic for a seed; another seed draws other micro-phases.
  const ProductImage again =
      RenderProduct(embree, mesh, Materials(), track.frame, track.orbit, track.grid, Options(true));
  EXPECT_EQ(again.image.real, b.real);
  const ProductImage other =
      RenderProduct(embree, mesh, Materials(), track.frame, track.orbit, track.grid, Options(true, 2));
  EXPECT_NE(other.image.real, b.real);
  EXPECT_EQ(other.image.bounce_layers[0], b.bounce_layers[0]);
}

// A reflector's phase centre on the product grid: pixel and range_m from
// zero-Doppler geo2rdr on the orbit (the exact distance to the sensor at
// the time the line of sight is perpendicular to the velocity), not the
// straight tracing line's.
TEST(ProductRendererTest, ReflectorRangeIsTheTrueZeroDopplerRange) {
  const Track track = MakeTrack();
  const scene::TriangleMesh mesh = Ground();
  const EmbreeScene embree(mesh);
  RenderOptions o = Options(true);
  SceneReflector r;
  r.type = material::ReflectorType::kTrihedral;
  r.size_m = 1.0;
  r.apex_enu = Vector3d(20.0, -10.0, 0.5);
  r.boresight_enu = (Vector3d(-8000.0, -10.0, 6000.0) - r.apex_enu).normalized();
  o.reflectors = {r};
  const ProductImage image = RenderProduct(embree, mesh, Materials(), track.frame, track.orbit, track.grid, o);
  ASSERT_EQ(image.image.points.size(), 1u);
  const PointReturn& p = image.image.points[0];
  // The zero-Doppler point of the straight track is abeam: y = -10 m.
  const Vector3d sensor = Ecef(track.frame, Vector3d(-8000.0, -10.0, 6000.0));
  const double range = (Ecef(track.frame, r.apex_enu) - sensor).norm();
  EXPECT_NEAR(p.range_m, range, 1e-6);
  EXPECT_NEAR(p.col, track.grid.ColOfRange(range), 1e-6);
  EXPECT_NEAR(p.row, track.grid.RowOfTime(-10.0 / 200.0), 1e-6);
  EXPECT_EQ(p.layer, 2);  // triple bounce
  // Its phasor's phase at this wavelength (what the sensor stage adds).
  const std::complex<double> phase = material::PathPhase(2.0 * p.range_m, o.wavelength_m);
  EXPECT_NEAR(std::arg(phase), -std::remainder(4.0 * M_PI * range / o.wavelength_m, 2.0 * M_PI), 1e-6);
}

}  // namespace
}  // namespace gissar::render
