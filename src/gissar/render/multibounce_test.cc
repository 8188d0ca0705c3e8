// Multi-bounce radiometry: dihedral and trihedral phase centres, specular
// planes, a building by water, coherent speckle statistics, contributions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numeric>

#include "gissar/render/sar_renderer.h"

namespace gissar::render {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;
constexpr double kDeg = M_PI / 180.0;

void AddFacingQuad(scene::TriangleMesh& mesh, Vector3f a, Vector3f b, Vector3f c, Vector3f d,
                   const Vector3f& facing, scene::ClassId cls) {
  if ((b - a).cross(c - a).dot(facing) < 0) std::swap(b, d);
  mesh.AddQuad(a, b, c, d, cls);
}

// Class 1: rough reflective ground; class 2: smooth metal (walls).
material::MaterialTable Materials() {
  material::MaterialTable t;
  t.Set(0, {"ground", 0.5, 0.0, 1.0, 0.0});
  t.Set(1, {"mirror_ground", 0.2, 0.0, 1.0, 0.8});
  t.Set(2, {"metal", 0.05, 0.9, 0.05, 0.9});
  return t;
}

sensor::SarGeometry Geometry(double heading, double depression, double spacing,
                             const scene::TriangleMesh& mesh) {
  sensor::SarGeometryOptions o;
  o.heading_deg = heading;
  o.depression_deg = depression;
  o.range_spacing_m = spacing;
  o.azimuth_spacing_m = spacing;
  return sensor::SarGeometry::Covering(o, Vector3d::Zero(), mesh.vertices);
}

SarImage Render(const scene::TriangleMesh& mesh, const sensor::SarGeometry& g, int bounces = 3,
                bool contributions = false, double rays = 16.0) {
  const EmbreeScene embree(mesh);
  RenderOptions o;
  o.rays_per_cell = rays;
  o.max_bounces = bounces;
  o.record_contributions = contributions;
  return RenderSar(embree, mesh, Materials(), g, o);
}

// Intensity-weighted mean column and row of a band (0 when empty).
Eigen::Vector2d Centroid(const std::vector<float>& band, int width, double* total = nullptr) {
  double w = 0, wc = 0, wr = 0;
  for (size_t i = 0; i < band.size(); ++i) {
    w += band[i];
    wc += band[i] * double(i % width);
    wr += band[i] * double(i / width);
  }
  if (total != nullptr) *total = w;
  return w > 0 ? Eigen::Vector2d(wc / w, wr / w) : Eigen::Vector2d::Zero();
}

// A vertical metal wall facing the radar on reflective ground: every
// ground-wall (and wall-ground) path has the length of the path to the
// corner, so the double-bounce band is a line at the corner's slant range.
TEST(MultiBounceTest, DihedralReturnsAtTheCornerRange) {
  for (double depression : {30.0, 45.0, 60.0}) {
    for (float H : {5.0f, 12.0f}) {
      const float xw = 20.0f;
      scene::TriangleMesh mesh;
      AddFacingQuad(mesh, {-80, -40, 0}, {xw, -40, 0}, {xw, 40, 0}, {-80, 40, 0}, Vector3f::UnitZ(), 1);
      AddFacingQuad(mesh, {xw, -40, 0}, {xw, 40, 0}, {xw, 40, H}, {xw, -40, H}, -Vector3f::UnitX(), 2);
      const auto g = Geometry(0.0, depression, 0.5, mesh);
      const SarImage image = Render(mesh, g);
      double power = 0;
      const Eigen::Vector2d c = Centroid(image.bounce_layers[1], image.width, &power);
      const Eigen::Vector2d corner = g.Project(Vector3d(xw, 0, 0));
      SCOPED_TRACE("depression " + std::to_string(depression) + " H " + std::to_string(H));
      EXPECT_GT(power, 0.0);
      EXPECT_NEAR(c.x(), corner.x(), 0.5);
      // The line is one pixel wide: all double-bounce power within +-1 px.
      double near = 0;
      for (size_t i = 0; i < image.bounce_layers[1].size(); ++i) {
        if (std::abs(double(i % image.width) - corner.x()) <= 1.0) near += image.bounce_layers[1][i];
      }
      EXPECT_NEAR(near / power, 1.0, 1e-6);
      // Total = sum of the bounce layers.
      double sum_layers = 0, total = 0;
      for (const auto& layer : image.bounce_layers) sum_layers += std::accumulate(layer.begin(), layer.end(), 0.0);
      total = std::accumulate(image.intensity.begin(), image.intensity.end(), 0.0);
      EXPECT_NEAR(total, sum_layers, 1e-6 * total);
    }
  }
}

// A trihedral corner reflector opening towards the radar: the triple-bounce
// return lands on the apex pixel (range and azimuth).
TEST(MultiBounceTest, TrihedralReturnsAtTheApex) {
  const float x0 = 10, y0 = 15, L = 12;
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {x0 - L, y0 - L, 0}, {x0, y0 - L, 0}, {x0, y0, 0}, {x0 - L, y0, 0}, Vector3f::UnitZ(), 2);
  AddFacingQuad(mesh, {x0, y0 - L, 0}, {x0, y0, 0}, {x0, y0, L}, {x0, y0 - L, L}, -Vector3f::UnitX(), 2);
  AddFacingQuad(mesh, {x0 - L, y0, 0}, {x0, y0, 0}, {x0, y0, L}, {x0 - L, y0, L}, -Vector3f::UnitY(), 2);
  // Heading -45 deg: the radar looks north-east, into the corner.
  for (double depression : {30.0, 35.26}) {
    const auto g = Geometry(-45.0, depression, 0.25, mesh);
    const SarImage image = Render(mesh, g, 3);
    double power = 0;
    const Eigen::Vector2d c = Centroid(image.bounce_layers[2], image.width, &power);
    const Eigen::Vector2d apex = g.Project(Vector3d(x0, y0, 0));
    EXPECT_GT(power, 0.0);
    EXPECT_NEAR(c.x(), apex.x(), 0.5) << depression;
    EXPECT_NEAR(c.y(), apex.y(), 0.5) << depression;
  }
}

// A smooth specular plate returns (almost) nothing unless its normal points
// at the radar.
TEST(MultiBounceTest, SpecularPlaneIsDarkUnlessFacingTheRadar) {
  material::MaterialTable table;
  table.Set(0, {"smooth", 0.0, 1.0, 0.02, 0.0});
  const double depression = 40.0;
  auto total_power = [&](const Vector3f& normal) {
    scene::TriangleMesh mesh;
    const Vector3f u = normal.cross(Vector3f::UnitY()).normalized(), v = normal.cross(u).normalized();
    AddFacingQuad(mesh, -20 * u - 20 * v, 20 * u - 20 * v, 20 * u + 20 * v, -20 * u + 20 * v, normal, 0);
    const auto g = Geometry(0.0, depression, 0.5, mesh);
    const EmbreeScene embree(mesh);
    RenderOptions o;
    const SarImage image = RenderSar(embree, mesh, table, g, o);
    return std::accumulate(image.intensity.begin(), image.intensity.end(), 0.0);
  };
  const Vector3f facing = Vector3f(-std::cos(depression * kDeg), 0, std::sin(depression * kDeg));
  const double flat = total_power(Vector3f::UnitZ());
  const double tilted_5 = total_power(Eigen::AngleAxisf(5 * kDeg, Vector3f::UnitY()) * facing);
  const double tilted_20 = total_power(Eigen::AngleAxisf(20 * kDeg, Vector3f::UnitY()) * facing);
  const double at_radar = total_power(facing);
  EXPECT_EQ(flat, 0.0);
  EXPECT_GT(at_radar, 1.0);
  // 5 deg off: cos(10 deg)^(1/0.02) = 0.47 of the head-on return (the cone's
  // width); 20 deg off: cos(40 deg)^50 = 1.6e-6.
  EXPECT_NEAR(tilted_5 / at_radar, std::pow(std::cos(10 * kDeg), 50.0), 0.03);
  EXPECT_LT(tilted_20, 1e-4 * at_radar);
}

// A building standing in water: the water mirrors the beam into the facade
// and the facade sends it back, so the building's mirror return lies on the
// water line (the facade's foot), beyond its direct (laid-over) return.
TEST(MultiBounceTest, BuildingByWaterShowsItsMirrorReturnOnTheWaterLine) {
  const float x0 = 10, x1 = 30, H = 20;
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-100, -30, 0}, {x0, -30, 0}, {x0, 30, 0}, {-100, 30, 0}, Vector3f::UnitZ(), 1);  // water
  AddFacingQuad(mesh, {x0, -30, 0}, {x0, 30, 0}, {x0, 30, H}, {x0, -30, H}, -Vector3f::UnitX(), 2);
  AddFacingQuad(mesh, {x0, -30, H}, {x1, -30, H}, {x1, 30, H}, {x0, 30, H}, Vector3f::UnitZ(), 2);
  const auto g = Geometry(0.0, 40.0, 0.5, mesh);
  const SarImage image = Render(mesh, g);
  const Eigen::Vector2d foot = g.Project(Vector3d(x0, 0, 0));
  const Eigen::Vector2d top = g.Project(Vector3d(x0, 0, H));
  // Direct (single-bounce) facade return: laid over between the top's and
  // the foot's range. Mirror (double-bounce) return: at the foot's range.
  const Eigen::Vector2d mirror = Centroid(image.bounce_layers[1], image.width);
  EXPECT_NEAR(mirror.x(), foot.x(), 0.5);
  const int row = int(g.v0());
  double facade = 0;
  for (int c = int(std::ceil(top.x())); c < int(foot.x()); ++c) facade += image.bounce_layers[0][size_t(row) * image.width + c];
  EXPECT_GT(facade, 0.0);
  EXPECT_GT(foot.x() - top.x(), 10.0);
}

TEST(MultiBounceTest, ContributionsMatchTheImage) {
  const float xw = 20.0f;
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-40, -20, 0}, {xw, -20, 0}, {xw, 20, 0}, {-40, 20, 0}, Vector3f::UnitZ(), 1);
  AddFacingQuad(mesh, {xw, -20, 0}, {xw, 20, 0}, {xw, 20, 8}, {xw, -20, 8}, -Vector3f::UnitX(), 2);
  const auto g = Geometry(0.0, 40.0, 1.0, mesh);
  const SarImage image = Render(mesh, g, 3, true, 4.0);
  ASSERT_FALSE(image.contributions.empty());
  double per_bounce[3] = {0, 0, 0};
  for (const Contribution& c : image.contributions) {
    per_bounce[std::min<int>(c.bounces, 3) - 1] += c.intensity;
    if (c.bounces == 2) {
      EXPECT_NEAR(c.range_m, g.SlantRange(Vector3d(xw, 0, 0)), 1e-3);
    }
  }
  for (int b = 0; b < 2; ++b) {
    const double image_sum = std::accumulate(image.bounce_layers[b].begin(), image.bounce_layers[b].end(), 0.0);
    EXPECT_NEAR(image_sum, per_bounce[b], 1e-3 * per_bounce[b] + 1e-6) << b;
  }
}

// Coherent mode over a flat uniform area: single-look intensity / mean is
// exponentially distributed (Kolmogorov-Smirnov at 1 %), mean preserved.
TEST(MultiBounceTest, CoherentSingleLookIntensityIsExponential) {
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-150, -150, 0}, {150, -150, 0}, {150, 150, 0}, {-150, 150, 0}, Vector3f::UnitZ(), 0);
  const auto g = Geometry(0.0, 40.0, 1.0, mesh);
  const EmbreeScene embree(mesh);
  RenderOptions o;
  o.rays_per_cell = 16.0;
  o.coherent = true;
  o.seed = 11;
  material::MaterialTable lambert;
  lambert.Set(0, material::Material{"default", 1.0});
  const SarImage image = RenderSar(embree, mesh, lambert, g, o);
  // beta0 of a unit Lambertian plane: 4 sin^2(d) / cos(d).
  const double expected_mean = 4.0 * std::sin(40 * kDeg) * std::tan(40 * kDeg);
  std::vector<double> samples;
  // Every other pixel (neighbours share splatted scatterers), away from edges.
  for (int r = int(g.v0()) - 120; r <= int(g.v0()) + 120; r += 2)
    for (int c = int(g.u0()) - 100; c <= int(g.u0()) + 100; c += 2)
      samples.push_back(image.intensity[size_t(r) * image.width + c]);
  const double mean = std::accumulate(samples.begin(), samples.end(), 0.0) / samples.size();
  EXPECT_NEAR(mean / expected_mean, 1.0, 0.03);
  std::sort(samples.begin(), samples.end());
  double d = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    const double cdf = 1.0 - std::exp(-samples[i] / mean);
    d = std::max({d, std::abs(cdf - double(i) / samples.size()), std::abs(cdf - double(i + 1) / samples.size())});
  }
  const double critical = 1.628 / std::sqrt(double(samples.size()));  // 1 % level
  EXPECT_LT(d, critical) << "KS statistic over " << samples.size() << " pixels";
}

// A wall (height H, length L, facing the radar broadside) on smooth ground,
// single-bounce laws constant tables, later bounces diffuse only. Every
// ground-wall and wall-ground path has the corner's length, so the double
// bounce is a line at the corner's slant range; its RCS by hand, at
// depression d (wall incidence d, ground incidence 90 deg - d), rays
// crossing the wall's cross-section H L cos d:
//   wall mirror -> ground: R_w(d) * 4 d_g sin^2 d / sin d per m^2 of beam,
//   ground mirror -> wall: R_g(90 - d) * 4 d_w cos^2 d / cos d,
// each counted twice (the reversed path has the same length and power):
//   D = 8 H L cos d [R_w(d) d_g sin d + R_g(90 - d) d_w cos d].
// R: Fresnel |Gamma_v|^2 times the mirror share. Both mirror chains then
// leave towards the radar: no triple bounce.
TEST(MultiBounceTest, WallOnSmoothGroundDihedralLevelByHand) {
  material::Material ground{"ground", 0.3, 0.0, 1.0, 0.6};
  ground.model = material::ScatteringModel::kTable;
  ground.sigma0_db = {{0.0, -20.0}, {90.0, -20.0}};
  ground.permittivity = {5.0, -0.5};
  material::Material wall{"wall", 0.2, 0.0, 1.0, 0.8};
  wall.model = material::ScatteringModel::kTable;
  wall.sigma0_db = {{0.0, -15.0}, {90.0, -15.0}};
  wall.permittivity = {7.0, -1.0};
  material::MaterialTable table;
  table.Set(0, ground);
  table.Set(1, wall);
  auto fresnel_v = [](std::complex<double> eps, double c) {
    const std::complex<double> root = std::sqrt(eps - (1.0 - c * c));
    return std::norm((eps * c - root) / (eps * c + root));
  };
  const float xw = 20.0f, H = 12.0f, L = 80.0f;
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-100, -L / 2, 0}, {xw, -L / 2, 0}, {xw, L / 2, 0}, {-100, L / 2, 0}, Vector3f::UnitZ(), 0);
  AddFacingQuad(mesh, {xw, -L / 2, 0}, {xw, L / 2, 0}, {xw, L / 2, H}, {xw, -L / 2, H}, -Vector3f::UnitX(), 1);
  for (double depression : {30.0, 45.0, 60.0}) {
    SCOPED_TRACE("depression " + std::to_string(depression));
    const double d = depression * kDeg;
    const auto g = Geometry(0.0, depression, 0.5, mesh);
    const EmbreeScene embree(mesh);
    RenderOptions o;
    o.rays_per_cell = 16.0;
    o.max_bounces = 3;
    const SarImage image = RenderSar(embree, mesh, table, g, o);
    const double r_wall = 0.8 * fresnel_v({7.0, -1.0}, std::cos(d));
    const double r_ground = 0.6 * fresnel_v({5.0, -0.5}, std::sin(d));
    const double expected =
        8.0 * H * L * std::cos(d) * (r_wall * 0.3 * std::sin(d) + r_ground * 0.2 * std::cos(d));
    double power = 0;
    const Eigen::Vector2d c = Centroid(image.bounce_layers[1], image.width, &power);
    const double pixel_area = g.range_spacing_m() * g.azimuth_spacing_m();
    // Tolerance: the wall's cross-section (6 m at 60 deg) is crossed by a
    // whole number of rays about 0.15 m apart, one row ~2.5 %.
    EXPECT_NEAR(power * pixel_area / expected, 1.0, 0.03);
    EXPECT_NEAR(c.x(), g.Project(Vector3d(xw, 0, 0)).x(), 0.5);
    const double triple =
        std::accumulate(image.bounce_layers[2].begin(), image.bounce_layers[2].end(), 0.0);
    EXPECT_EQ(triple, 0.0);
    // Relative level: the line (one slant-range pixel wide, L long) against
    // the ground's beta0 = sigma0 / sin(theta_i) = 0.01 / cos(d).
    const double line_beta0 = expected / (L * g.range_spacing_m());
    std::printf("depression %.0f: double bounce %.4f m^2 (by hand %.4f), line %.1f dB above the ground\n",
                depression, power * pixel_area, expected, 10 * std::log10(line_beta0 / (0.01 / std::cos(d))));
  }
}

}  // namespace
}  // namespace gissar::render
