#include "gissar/image/radiometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <optional>

#include "gissar/material/reflector.h"

#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/triangle_mesh.h"
#include "gissar/util/error.h"

namespace gissar::image {
namespace {

constexpr double kDeg = M_PI / 180.0;

// A class-0 material of constant sigma0 (dB) at every incidence.
material::MaterialTable ConstantSigma0(double db) {
  material::Material m;
  m.name = "default";
  m.model = material::ScatteringModel::kTable;
  m.sigma0_db = {{0.0, db}, {90.0, db}};
  material::MaterialTable table;
  table.Set(0, m);
  return table;
}

struct Rendered {
  render::SarImage image;
  std::optional<sensor::SarGeometry> geometry;
};

// Flat ground z = 0, 1600 m square, seen at `depression` with square pixels
// of `spacing_m`, rendered with `rays` rays per cell and converted to
// `radiometry`.
Rendered RenderFlat(double depression, double spacing_m, double rays, Radiometry radiometry, double sigma0_db,
                    double heading = 30.0, double nesz_db = std::nan("")) {
  scene::TriangleMesh mesh;
  const float X = 800;
  mesh.AddQuad({-X, -X, 0}, {X, -X, 0}, {X, X, 0}, {-X, X, 0});
  sensor::SarGeometryOptions o;
  o.heading_deg = heading;
  o.depression_deg = depression;
  o.range_spacing_m = spacing_m;
  o.azimuth_spacing_m = spacing_m;
  Rendered out;
  out.geometry = sensor::SarGeometry::Covering(o, Eigen::Vector3d::Zero(), mesh.vertices);
  const render::EmbreeScene embree(mesh);
  render::RenderOptions ro;
  ro.rays_per_cell = rays;
  out.image = render::RenderSar(embree, mesh, ConstantSigma0(sigma0_db), *out.geometry, ro);
  SensorEffects effects;
  effects.radiometry = radiometry;
  effects.nesz_db = nesz_db;
  std::vector<double> incidence(out.image.width);
  for (int c = 0; c < out.image.width; ++c) incidence[c] = out.geometry->IncidenceDeg(c);
  ApplySensorEffects(out.image, effects, incidence);
  return out;
}

// Mean (dB of the linear mean) and per-pixel spread (dB) over the pixels
// within 300 m (ground) of the scene centre: well inside the square.
std::pair<double, double> CentreStats(const Rendered& r) {
  const auto& g = *r.geometry;
  const int half_rows = static_cast<int>(300.0 / g.azimuth_spacing_m());
  const int half_cols = static_cast<int>(300.0 * std::cos(g.options().depression_deg * kDeg) / g.range_spacing_m());
  double sum = 0.0, sum_db = 0.0, sum_db2 = 0.0;
  int n = 0;
  for (int row = int(g.v0()) - half_rows; row <= int(g.v0()) + half_rows; ++row) {
    for (int col = int(g.u0()) - half_cols; col <= int(g.u0()) + half_cols; ++col) {
      const double v = r.image.intensity[size_t(row) * r.image.width + col];
      sum += v;
      sum_db += 10.0 * std::log10(v);
      sum_db2 += 100.0 * std::log10(v) * std::log10(v);
      ++n;
    }
  }
  const double mean_db = sum_db / n;
  return {10.0 * std::log10(sum / n), std::sqrt(std::max(0.0, sum_db2 / n - mean_db * mean_db))};
}

// Issue 17's acceptance: a flat plane of constant sigma0 = -10 dB reads
// -10 dB whatever the depression, ray count and pixel spacing.
// The coherent sensor stage adds each point's phase offset (arg S_c of a
// polarimetric pass's reflector matrix) to its path phase: two points of
// equal power and range, offsets 0 and pi, cancel; offsets 0 and 0 add to
// twice the amplitude.
TEST(RadiometryTest, PointPhaseOffsetTurnsThePhasor) {
  auto sum_of = [](double offset_rad) {
    render::SarImage image;
    image.width = image.height = 32;
    const size_t n = 32 * 32;
    image.intensity.assign(n, 0.0f);
    image.real.assign(n, 0.0f);
    image.imag.assign(n, 0.0f);
    for (const double offset : {0.0, offset_rad}) {
      render::PointReturn p;
      p.col = 15.3;
      p.row = 16.7;
      p.beta0_sum = 4.0;
      p.range_m = 1234.5;
      p.layer = 1;
      p.phase_offset_rad = offset;
      image.points.push_back(p);
    }
    SensorEffects effects;
    effects.wavelength_m = 0.031;
    effects.range_resolution_px = 1.0;
    effects.azimuth_resolution_px = 1.0;
    ApplySensorEffects(image, effects, std::vector<double>(32, 55.0));
    std::complex<double> sum = 0.0;
    double power = 0.0;
    for (size_t k = 0; k < n; ++k) {
      sum += std::complex<double>(image.real[k], image.imag[k]);
      power += double(image.real[k]) * image.real[k] + double(image.imag[k]) * image.imag[k];
    }
    return std::make_pair(std::abs(sum), power);
  };
  const auto [opposite_amplitude, opposite_power] = sum_of(M_PI);
  const auto [equal_amplitude, equal_power] = sum_of(0.0);
  EXPECT_GT(equal_power, 0.0);
  EXPECT_LT(opposite_power, 1e-9 * equal_power);
  EXPECT_LT(opposite_amplitude, 1e-5 * equal_amplitude);
}

TEST(RadiometryTest, FlatPlaneSigma0IsIndependentOfRaysAndPixels) {
  for (double depression : {30.0, 45.0, 60.0}) {
    for (double rays : {1.0, 16.0}) {
      for (double spacing : {5.0, 20.0}) {
        const Rendered r = RenderFlat(depression, spacing, rays, Radiometry::kSigma0, -10.0);
        const auto [mean_db, spread_db] = CentreStats(r);
        EXPECT_NEAR(mean_db, -10.0, 0.1) << depression << " deg, " << rays << " rays, " << spacing << " m";
        std::printf("flat sigma0: depression %.0f, %.0f rays, %.0f m: mean %.3f dB, spread %.3f dB\n", depression,
                    rays, spacing, mean_db, spread_db);
        EXPECT_LT(spread_db, 0.1) << depression << " deg, " << rays << " rays, " << spacing << " m";
      }
    }
  }
}

// beta0 = sigma0 / sin(theta_i), gamma0 = sigma0 / cos(theta_i): at 30 deg
// depression (theta_i = 60 deg) -10 dB sigma0 is -9.375 dB beta0 and
// -6.990 dB gamma0.
TEST(RadiometryTest, Beta0AndGamma0FollowTheIncidence) {
  const double beta0 = -10.0 - 10.0 * std::log10(std::sin(60.0 * kDeg));
  const double gamma0 = -10.0 - 10.0 * std::log10(std::cos(60.0 * kDeg));
  EXPECT_NEAR(beta0, -9.375, 1e-3);
  EXPECT_NEAR(gamma0, -6.990, 1e-3);
  for (double rays : {1.0, 16.0}) {
    EXPECT_NEAR(CentreStats(RenderFlat(30.0, 10.0, rays, Radiometry::kBeta0, -10.0)).first, beta0, 0.1);
    EXPECT_NEAR(CentreStats(RenderFlat(30.0, 10.0, rays, Radiometry::kGamma0, -10.0)).first, gamma0, 0.1);
  }
}

// Thermal noise is in sigma0: a -40 dB plane with NESZ -20 dB reads
// 10 log10(1e-4 + 1e-2) = -19.957 dB on average.
TEST(RadiometryTest, NoiseIsAddedInSigma0) {
  const Rendered r = RenderFlat(40.0, 5.0, 4.0, Radiometry::kSigma0, -40.0, 0.0, -20.0);
  EXPECT_NEAR(CentreStats(r).first, 10.0 * std::log10(1e-4 + 1e-2), 0.1);
}

TEST(RadiometryTest, ConversionsAndParsing) {
  EXPECT_NEAR(FactorFromBeta0(Radiometry::kSigma0, 30.0), 0.5, 1e-12);
  EXPECT_NEAR(FactorFromBeta0(Radiometry::kGamma0, 45.0), 1.0, 1e-12);
  EXPECT_EQ(FactorFromBeta0(Radiometry::kBeta0, 10.0), 1.0);
  EXPECT_EQ(ParseRadiometry("gamma0", "--radiometry"), Radiometry::kGamma0);
  EXPECT_THROW(ParseRadiometry("sigma_0", "--radiometry"), ConfigError);
  std::vector<float> v = {100.0f, 0.01f, 0.0f};
  ToDecibels(v);
  EXPECT_NEAR(v[0], 20.0f, 1e-5);
  EXPECT_NEAR(v[1], -20.0f, 1e-5);
  EXPECT_TRUE(std::isnan(v[2]));
  std::vector<float> img = {1, 2, 3, 4, 5, 6};
  ScaleColumns(img, 3, 2, {1.0, 0.5, 2.0});
  EXPECT_EQ(img, (std::vector<float>{1, 1, 6, 4, 2.5, 12}));
}

// The bounce bands are converted with the total: they still add up.
// Sum of the bounce layers at pixel k; a layer the render left empty (more
// bounces than it traced) returned nothing.
double LayerSum(const render::SarImage& image, size_t k) {
  double sum = 0.0;
  for (const auto& layer : image.bounce_layers) {
    if (!layer.empty()) sum += layer[k];
  }
  return sum;
}

TEST(RadiometryTest, BandsStayConsistent) {
  const Rendered r = RenderFlat(45.0, 20.0, 4.0, Radiometry::kGamma0, -10.0);
  for (size_t k = 0; k < r.image.intensity.size(); ++k) {
    const double sum = LayerSum(r.image, k);
    ASSERT_NEAR(sum, r.image.intensity[k], 1e-5 * (1.0 + std::abs(sum)));
  }
}

}  // namespace
}  // namespace gissar::image

namespace gissar::image {
namespace {

constexpr double kC = 0.0555, kX = 0.031;

struct PointScene {
  scene::TriangleMesh mesh;
  std::optional<sensor::SarGeometry> geometry;
};

// A very dark flat square (sigma0 -80 dB) 400 m wide, seen at 40 deg
// depression, heading 0, pixels `spacing` m.
PointScene DarkGround(double spacing) {
  PointScene s;
  const float X = 200;
  s.mesh.AddQuad({-X, -X, 0}, {X, -X, 0}, {X, X, 0}, {-X, X, 0});
  sensor::SarGeometryOptions o;
  o.heading_deg = 0.0;
  o.depression_deg = 40.0;
  o.range_spacing_m = spacing;
  o.azimuth_spacing_m = spacing;
  s.geometry = sensor::SarGeometry::Covering(o, Eigen::Vector3d::Zero(), s.mesh.vertices);
  return s;
}

render::SarImage RenderPoints(const PointScene& s, const std::vector<render::SceneReflector>& reflectors,
                              double wavelength, bool coherent, double resolution_m) {
  const render::EmbreeScene embree(s.mesh);
  render::RenderOptions ro;
  ro.coherent = coherent;
  ro.wavelength_m = wavelength;
  ro.reflectors = reflectors;
  render::SarImage image = render::RenderSar(embree, s.mesh, ConstantSigma0(-80.0), *s.geometry, ro);
  SensorEffects e;
  e.radiometry = Radiometry::kBeta0;
  e.wavelength_m = wavelength;
  e.range_resolution_px = resolution_m / s.geometry->range_spacing_m();
  e.azimuth_resolution_px = resolution_m / s.geometry->azimuth_spacing_m();
  std::vector<double> incidence(image.width, 50.0);
  ApplySensorEffects(image, e, incidence);
  return image;
}

// Integrated RCS (m^2): sum of beta0 * pixel area within `half` pixels of
// the scene centre.
double IntegratedRcs(const render::SarImage& image, const sensor::SarGeometry& g, int half) {
  double sum = 0.0;
  for (int r = int(g.v0()) - half; r <= int(g.v0()) + half; ++r) {
    for (int c = int(g.u0()) - half; c <= int(g.u0()) + half; ++c) sum += image.intensity[size_t(r) * image.width + c];
  }
  return sum * g.range_spacing_m() * g.azimuth_spacing_m();
}

render::SceneReflector Trihedral(double a, const Eigen::Vector3d& apex, const sensor::SarGeometry& g) {
  render::SceneReflector r;
  r.type = material::ReflectorType::kTrihedral;
  r.size_m = a;
  r.apex_enu = apex;
  r.boresight_enu = -g.look_direction();  // pointed at the sensor
  return r;
}

// Issue 17: a trihedral of a = 1 m integrates to 4 pi a^4 / (3 lambda^2)
// within 1.5 dB at C and X band, in both modes, and X - C follows
// 20 log10(lambda_C / lambda_X).
TEST(ReflectorTest, TrihedralRcsFollowsPhysicalOptics) {
  const PointScene s = DarkGround(2.0);
  for (bool coherent : {false, true}) {
    double db[2];
    int k = 0;
    for (double lambda : {kC, kX}) {
      const auto image = RenderPoints(s, {Trihedral(1.0, Eigen::Vector3d(0.3, 0.7, 0.0), *s.geometry)}, lambda,
                                      coherent, 5.0);
      const double expected = 4.0 * M_PI / (3.0 * lambda * lambda);
      db[k] = 10.0 * std::log10(IntegratedRcs(image, *s.geometry, 40));
      std::printf("trihedral a = 1 m, lambda %.4f m%s: %.2f dB m2 (closed form %.2f)\n", lambda,
                  coherent ? " coherent" : "", db[k], 10.0 * std::log10(expected));
      EXPECT_NEAR(db[k], 10.0 * std::log10(expected), 1.5) << lambda << (coherent ? " coherent" : "");
      ++k;
    }
    EXPECT_NEAR(db[1] - db[0], 20.0 * std::log10(kC / kX), 1.0);
  }
}

// Issue 17: two trihedrals (a = 0.3 m) 0.5 m apart along track in one
// 10 m resolution cell: with slant ranges lambda/4 apart (two-way phase pi)
// they cancel, >= 20 dB below the pair lambda/2 apart (in phase).
TEST(ReflectorTest, QuarterWavelengthPairCancelsInCoherentMode) {
  const PointScene s = DarkGround(2.0);
  const sensor::SarGeometry& g = *s.geometry;
  auto pair_rcs = [&](double range_offset) {
    const Eigen::Vector3d a(0.0, 0.0, 0.0);
    const Eigen::Vector3d b = a + 0.5 * g.flight_direction() + range_offset * g.look_direction();
    const auto image = RenderPoints(s, {Trihedral(0.3, a, g), Trihedral(0.3, b, g)}, kC, true, 10.0);
    return IntegratedRcs(image, g, 40);
  };
  const double in_phase = pair_rcs(kC / 2.0), cancelled = pair_rcs(kC / 4.0);
  std::printf("trihedral pair: lambda/2 %.2f dB m2, lambda/4 %.2f dB m2, ratio %.1f dB\n",
              10.0 * std::log10(in_phase), 10.0 * std::log10(cancelled), 10.0 * std::log10(in_phase / cancelled));
  EXPECT_GT(10.0 * std::log10(in_phase / cancelled), 20.0);
  // In phase: twice the amplitude, four times one trihedral's RCS (0.5 m is
  // 1/20 of the resolution: within 0.5 dB).
  EXPECT_NEAR(10.0 * std::log10(in_phase / (4.0 * material::PeakRcs(material::ReflectorType::kTrihedral, 0.3, kC))),
              0.0, 0.5);
}

// A hidden reflector (behind a wall, seen from the sensor) returns nothing.
TEST(ReflectorTest, OccludedReflectorIsDark) {
  PointScene s = DarkGround(2.0);
  // A 20 m wall between the reflector (at x = 0) and the sensor (west).
  s.mesh.AddQuad({-10, -50, 0}, {-10, 50, 0}, {-10, 50, 20}, {-10, -50, 20});
  s.geometry = sensor::SarGeometry::Covering(s.geometry->options(), Eigen::Vector3d::Zero(), s.mesh.vertices);
  const render::EmbreeScene embree(s.mesh);
  EXPECT_TRUE(render::ReflectorReturns(embree, {Trihedral(1.0, Eigen::Vector3d::Zero(), *s.geometry)}, *s.geometry, kC)
                  .empty());
  EXPECT_EQ(render::ReflectorReturns(embree, {Trihedral(1.0, Eigen::Vector3d(20, 0, 0), *s.geometry)}, *s.geometry, kC)
                .size(),
            1u);
}

// Coherent speckle over a homogeneous rough plane: single-look intensity is
// exponential (ENL 1), its mean is the incoherent mean, and neighbouring
// pixels correlate as the PSF says: |rho_amplitude(1 px)|^2 with the
// unwindowed amplitude response sin(pi B x) / (pi B x), B = 0.8859 / res.
TEST(CoherentTest, SpeckleIsFullyDevelopedAndFollowsThePsf) {
  for (double resolution_px : {0.0, 2.0}) {
    Rendered r[2];
    for (int mode = 0; mode < 2; ++mode) {
      scene::TriangleMesh mesh;
      const float X = 800;
      mesh.AddQuad({-X, -X, 0}, {X, -X, 0}, {X, X, 0}, {-X, X, 0});
      sensor::SarGeometryOptions o;
      o.heading_deg = 0.0;
      o.depression_deg = 45.0;
      o.range_spacing_m = 5.0;
      o.azimuth_spacing_m = 5.0;
      r[mode].geometry = sensor::SarGeometry::Covering(o, Eigen::Vector3d::Zero(), mesh.vertices);
      const render::EmbreeScene embree(mesh);
      render::RenderOptions ro;
      ro.rays_per_cell = 16.0;
      ro.coherent = mode == 1;
      ro.seed = 7;
      r[mode].image = render::RenderSar(embree, mesh, ConstantSigma0(-10.0), *r[mode].geometry, ro);
      SensorEffects e;
      e.range_resolution_px = e.azimuth_resolution_px = resolution_px;
      std::vector<double> inc(r[mode].image.width);
      for (int c = 0; c < r[mode].image.width; ++c) inc[c] = r[mode].geometry->IncidenceDeg(c);
      ApplySensorEffects(r[mode].image, e, inc);
    }
    EXPECT_NEAR(CentreStats(r[1]).first, CentreStats(r[0]).first, 0.2) << resolution_px;
    // ENL and lag-1 range correlation of the coherent intensity.
    const auto& g = *r[1].geometry;
    const auto& v = r[1].image.intensity;
    const int w = r[1].image.width;
    double s1 = 0, s2 = 0, s12 = 0;
    int n = 0;
    for (int row = int(g.v0()) - 50; row <= int(g.v0()) + 50; ++row) {
      for (int c = int(g.u0()) - 50; c <= int(g.u0()) + 50; ++c) {
        const double a = v[size_t(row) * w + c], b = v[size_t(row) * w + c + 1];
        s1 += a;
        s2 += a * a;
        s12 += a * b;
        ++n;
      }
    }
    const double mean = s1 / n, var = s2 / n - mean * mean;
    EXPECT_NEAR(mean * mean / var, 1.0, 0.1) << resolution_px;
    std::printf("coherent, resolution %.0f px: mean %.3f dB (incoherent %.3f), ENL %.3f, lag-1 corr %.3f\n",
                resolution_px, CentreStats(r[1]).first, CentreStats(r[0]).first, mean * mean / var,
                (s12 / n - mean * mean) / var);
    if (resolution_px > 0) {
      const double bw = 0.8859 / resolution_px;
      auto h = [&](double x) { return std::abs(x) < 1e-12 ? 1.0 : std::sin(M_PI * bw * x) / (M_PI * bw * x); };
      double num = 0, den = 0;
      for (int k = -60; k <= 60; ++k) {
        num += h(k) * h(k + 1);
        den += h(k) * h(k);
      }
      const double expected = (num / den) * (num / den);
      EXPECT_NEAR((s12 / n - mean * mean) / var, expected, 0.05);
    }
  }
}

// Incoherent speckle with an impulse response is correlated over the
// resolution cell: single look ENL 1, lag-1 correlation |rho(1)|^2 of the
// unwindowed amplitude response, mean unchanged, bands still add up.
TEST(SpeckleTest, CorrelatedOverTheResolutionCell) {
  scene::TriangleMesh mesh;
  const float X = 800;
  mesh.AddQuad({-X, -X, 0}, {X, -X, 0}, {X, X, 0}, {-X, X, 0});
  sensor::SarGeometryOptions o;
  o.heading_deg = 0.0;
  o.depression_deg = 45.0;
  o.range_spacing_m = 5.0;
  o.azimuth_spacing_m = 5.0;
  const auto g = sensor::SarGeometry::Covering(o, Eigen::Vector3d::Zero(), mesh.vertices);
  const render::EmbreeScene embree(mesh);
  render::RenderOptions ro;
  render::SarImage image = render::RenderSar(embree, mesh, ConstantSigma0(-10.0), g, ro);
  SensorEffects e;
  const double res = 2.0;
  e.range_resolution_px = e.azimuth_resolution_px = res;
  e.speckle_looks = 1.0;
  std::vector<double> inc(image.width);
  for (int c = 0; c < image.width; ++c) inc[c] = g.IncidenceDeg(c);
  ApplySensorEffects(image, e, inc);
  const auto& v = image.intensity;
  const int w = image.width;
  double s1 = 0, s2 = 0, s12 = 0;
  int n = 0;
  for (int row = int(g.v0()) - 80; row <= int(g.v0()) + 80; ++row) {
    for (int c = int(g.u0()) - 80; c <= int(g.u0()) + 80; ++c) {
      const size_t k = size_t(row) * w + c;
      const double a = v[k], b = v[k + 1];
      s1 += a;
      s2 += a * a;
      s12 += a * b;
      ++n;
      ASSERT_NEAR(LayerSum(image, k), a, 1e-5 * a + 1e-12);
    }
  }
  const double mean = s1 / n, var = s2 / n - mean * mean;
  EXPECT_NEAR(10.0 * std::log10(mean), -10.0, 0.2);
  EXPECT_NEAR(mean * mean / var, 1.0, 0.1);
  std::printf("correlated speckle, 1 look, 2 px resolution: mean %.3f dB, ENL %.3f, lag-1 corr %.3f\n",
              10.0 * std::log10(mean), mean * mean / var, (s12 / n - mean * mean) / var);
  const double bw = 0.8859 / res;
  auto h = [&](double x) { return std::abs(x) < 1e-12 ? 1.0 : std::sin(M_PI * bw * x) / (M_PI * bw * x); };
  double num = 0, den = 0;
  for (int k = -60; k <= 60; ++k) {
    num += h(k) * h(k + 1);
    den += h(k) * h(k);
  }
  EXPECT_NEAR((s12 / n - mean * mean) / var, (num / den) * (num / den), 0.05);
}

// Coherent mode: every return goes into the complex total and into the
// complex image of its bounce count (reflectors too), the impulse response
// and the radiometric scaling treat them alike, so the complex bands add up
// to the complex total and each detected bounce band is |z_b|^2.
TEST(CoherentTest, ComplexBounceBandsAddUpToTheComplexTotal) {
  PointScene s = DarkGround(1.0);
  // A wall facing the radar (looking east) on the ground: double bounce.
  Eigen::Vector3f a(30, -60, 0), b(30, 60, 0), c(30, 60, 15), d(30, -60, 15);
  if ((b - a).cross(c - a).dot(-Eigen::Vector3f::UnitX()) < 0) std::swap(b, d);
  s.mesh.AddQuad(a, b, c, d, 1);
  material::MaterialTable table;
  material::Material ground{"ground", 0.3, 0.2, 0.3, 0.6};
  ground.model = material::ScatteringModel::kTable;
  ground.sigma0_db = {{0.0, -12.0}, {90.0, -12.0}};
  material::Material wall = ground;
  wall.name = "wall";
  wall.mirror = 0.7;
  table.Set(0, ground);
  table.Set(1, wall);
  const render::EmbreeScene embree(s.mesh);
  render::RenderOptions ro;
  ro.coherent = true;
  ro.wavelength_m = kX;
  ro.seed = 5;
  ro.reflectors = {Trihedral(0.5, Eigen::Vector3d(-40.3, 10.2, 0.0), *s.geometry)};
  render::SarImage image = render::RenderSar(embree, s.mesh, table, *s.geometry, ro);
  SensorEffects e;
  e.radiometry = Radiometry::kGamma0;
  e.wavelength_m = kX;
  e.range_resolution_px = 2.0;
  e.azimuth_resolution_px = 2.0;
  std::vector<double> incidence(image.width, 50.0);
  ApplySensorEffects(image, e, incidence);
  double power[4] = {0, 0, 0, 0}, worst = 0;
  for (size_t k = 0; k < image.real.size(); ++k) {
    double re = 0, im = 0;
    for (int l = 0; l < 4; ++l) {
      // Layers beyond max_bounces are empty: no return of that order.
      if (l >= ro.max_bounces) {
        ASSERT_TRUE(image.bounce_real[l].empty() && image.bounce_imag[l].empty() && image.bounce_layers[l].empty());
        continue;
      }
      ASSERT_EQ(image.bounce_real[l].size(), image.real.size());
      re += image.bounce_real[l][k];
      im += image.bounce_imag[l][k];
      const double p = double(image.bounce_real[l][k]) * image.bounce_real[l][k] +
                       double(image.bounce_imag[l][k]) * image.bounce_imag[l][k];
      EXPECT_NEAR(image.bounce_layers[l][k], p, 1e-6 * (1.0 + p));
      power[l] += p;
    }
    const double scale = 1.0 + std::hypot(image.real[k], image.imag[k]);
    worst = std::max(worst, std::hypot(re - image.real[k], im - image.imag[k]) / scale);
  }
  EXPECT_LT(worst, 1e-5);
  EXPECT_GT(power[0], 0.0);
  EXPECT_GT(power[1], 0.0);  // ground-wall dihedral
  EXPECT_GT(power[2], 0.0);  // the trihedral
}

}  // namespace
}  // namespace gissar::image
