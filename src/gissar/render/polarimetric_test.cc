// Polarimetric passes of the tracer (RenderOptions::polarimetric): mirror
// chains carry a scattering matrix (rotated dihedral, trihedral), rough
// surfaces draw jointly distributed channels (covariance of an Oh plane),
// reciprocity HV = VH, and the reflectors' roll and channel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>

#include "gissar/material/scattering.h"
#include "gissar/render/sar_renderer.h"

namespace gissar::render {
namespace {

using cd = std::complex<double>;
using Eigen::Vector3d;
using Eigen::Vector3f;
using material::Polarization;
constexpr double kDeg = M_PI / 180.0;

double Db20(double amplitude) { return 20.0 * std::log10(amplitude); }
double Db10(double power) { return 10.0 * std::log10(power); }
double PhaseDeg(cd z) { return std::arg(z) / kDeg; }

void AddFacingQuad(scene::TriangleMesh& mesh, Vector3f a, Vector3f b, Vector3f c, Vector3f d, const Vector3f& facing,
                   scene::ClassId cls) {
  if ((b - a).cross(c - a).dot(facing) < 0) std::swap(b, d);
  mesh.AddQuad(a, b, c, d, cls);
}

sensor::SarGeometryOptions GeometryOptions(double heading_deg, double depression_deg, double spacing_m) {
  sensor::SarGeometryOptions o;
  o.heading_deg = heading_deg;
  o.depression_deg = depression_deg;
  o.range_spacing_m = spacing_m;
  o.azimuth_spacing_m = spacing_m;
  return o;
}

sensor::SarGeometry Covering(const sensor::SarGeometryOptions& o, const std::vector<Vector3f>& points) {
  return sensor::SarGeometry::Covering(o, Vector3d::Zero(), points);
}

// A nearly perfect conductor (Fresnel within 3e-5 of r_h = -1, r_v = +1 at
// 45 deg: 4e-4 dB, 0.002 deg), every mirror share 1, the bistatic return a
// specular cone only (diffuse + mirror <= 1).
material::Material Metal() {
  material::Material m{"metal", 0.0, 1.0, 1.0, 1.0};
  m.permittivity = {1e10, 0.0};
  return m;
}

RenderOptions PolarimetricOptions(Polarization pol, bool coherent = true) {
  RenderOptions o;
  o.rays_per_cell = 16.0;
  o.max_bounces = 3;
  o.coherent = coherent;
  o.polarimetric = true;
  o.polarization = pol;
  o.seed = 7;
  return o;
}

// Sum of the complex image of bounce layer `layer`.
cd LayerSum(const SarImage& image, int layer) {
  cd sum = 0.0;
  for (size_t k = 0; k < image.bounce_real[layer].size(); ++k) {
    sum += cd(image.bounce_real[layer][k], image.bounce_imag[layer][k]);
  }
  return sum;
}

// A dihedral of two 10 m x 6 m perpendicular metal plates, its fold
// through the origin perpendicular to the line of sight l and turned by psi
// from h towards v (HvBasis(l)), opening towards the radar: plate 0 along
// -(l + v') / sqrt 2 from the fold, plate 1 along (-l + v') / sqrt 2, v' =
// -sin psi h + cos psi v. A ray along l meets one plate at 45 deg, the other
// at 45 deg and leaves along -l: S = [[cos 2psi, sin 2psi], [sin 2psi,
// -cos 2psi]] (scattering.h), the same for both orders.
scene::TriangleMesh RotatedDihedral(const Vector3d& l, double psi) {
  const material::PolarizationBasis b = material::HvBasis(l);
  const Vector3d fold = std::cos(psi) * b.h + std::sin(psi) * b.v;
  const Vector3d v_turned = -std::sin(psi) * b.h + std::cos(psi) * b.v;
  const Vector3d w0 = -(l + v_turned) / std::sqrt(2.0), w1 = (-l + v_turned) / std::sqrt(2.0);
  const Vector3d n0 = (-l + v_turned) / std::sqrt(2.0), n1 = (-l - v_turned) / std::sqrt(2.0);
  const double half = 5.0, width = 6.0;
  scene::TriangleMesh mesh;
  auto plate = [&](const Vector3d& w, const Vector3d& n) {
    const Vector3d a = -half * fold, c = half * fold;
    AddFacingQuad(mesh, a.cast<float>(), c.cast<float>(), (c + width * w).cast<float>(), (a + width * w).cast<float>(),
                  n.cast<float>(), 0);
  };
  plate(w0, n0);
  plate(w1, n1);
  return mesh;
}

// The dihedral turned about the line of sight: the double-bounce layer's
// complex sums of the HH, HV and VV passes stand as cos 2psi : sin 2psi :
// -cos 2psi (every double-bounce path has the fold's length and the same
// matrix, and the passes trace the same rays: the sums are one common
// complex factor times S_c), within 0.1 dB and 1 deg; the plain dihedral's
// HH-VV phase is 180 deg; no HV at psi = 0, no co-pol at 45 deg.
TEST(PolarimetricRenderTest, RotatedDihedralGivesTheClosedFormMatrix) {
  material::MaterialTable metal;
  metal.Set(0, Metal());
  const sensor::SarGeometryOptions go = GeometryOptions(0.0, 40.0, 0.25);
  const std::vector<Vector3f> box = {{-9, -9, -9}, {9, 9, 9}};
  const Vector3d l = Covering(go, box).look_direction();
  for (const double psi_deg : {0.0, 22.5, 45.0}) {
    SCOPED_TRACE("psi " + std::to_string(psi_deg));
    const double psi = psi_deg * kDeg;
    const scene::TriangleMesh mesh = RotatedDihedral(l, psi);
    const sensor::SarGeometry g = Covering(go, mesh.vertices);
    ASSERT_NEAR((g.look_direction() - l).norm(), 0.0, 1e-12);
    const EmbreeScene embree(mesh);
    cd sum[3];
    const Polarization pols[3] = {Polarization::kHH, Polarization::kHV, Polarization::kVV};
    for (int c = 0; c < 3; ++c) sum[c] = LayerSum(RenderSar(embree, mesh, metal, g, PolarimetricOptions(pols[c])), 1);
    const double scale = std::max({std::abs(sum[0]), std::abs(sum[1]), std::abs(sum[2])});
    ASSERT_GT(scale, 0.0);
    const double want[3] = {std::cos(2 * psi), std::sin(2 * psi), -std::cos(2 * psi)};
    // The common factor: from the largest channel.
    const int ref = std::abs(want[0]) >= std::abs(want[1]) - 1e-12 ? 0 : 1;
    const cd common = sum[ref] / want[ref];
    for (int c = 0; c < 3; ++c) {
      const cd ratio = sum[c] / common;
      if (std::abs(want[c]) > 1e-6) {
        EXPECT_NEAR(Db20(std::abs(ratio) / std::abs(want[c])), 0.0, 0.1) << c;
        EXPECT_NEAR(std::remainder(PhaseDeg(ratio) - (want[c] > 0 ? 0.0 : 180.0), 360.0), 0.0, 1.0) << c;
      } else {
        EXPECT_LT(std::abs(sum[c]) / scale, 1e-4) << c;
      }
    }
    std::printf("dihedral psi %4.1f deg: |HH| %.4f |HV| %.4f |VV| %.4f (common scale); HH/VV %.4f dB %.3f deg, "
                "HV/HH %.4f dB %.3f deg (0: not defined)\n",
                psi_deg, std::abs(sum[0] / common), std::abs(sum[1] / common), std::abs(sum[2] / common),
                psi_deg == 45.0 ? 0.0 : Db20(std::abs(sum[0] / sum[2])),
                psi_deg == 45.0 ? 0.0 : PhaseDeg(sum[0] * std::conj(sum[2])),
                psi_deg == 22.5 ? Db20(std::abs(sum[1] / sum[0])) : 0.0,
                psi_deg == 22.5 ? PhaseDeg(sum[1] * std::conj(sum[0])) : 0.0);
    if (psi_deg == 0.0) {
      EXPECT_NEAR(Db20(std::abs(sum[0] / sum[2])), 0.0, 0.1);
      EXPECT_NEAR(std::abs(PhaseDeg(sum[0] * std::conj(sum[2]))), 180.0, 1.0);
    }
  }
}

// A trihedral of three perpendicular metal plates, the radar looking along
// its boresight: every triple-bounce path has S = I, so the triple layer's
// HH/VV is 0 dB, 0 deg and HV vanishes.
TEST(PolarimetricRenderTest, TrihedralTripleBounceHasEqualCoPolInPhase) {
  material::MaterialTable metal;
  metal.Set(0, Metal());
  const float x0 = 2, y0 = 3, L = 6;
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {x0 - L, y0 - L, 0}, {x0, y0 - L, 0}, {x0, y0, 0}, {x0 - L, y0, 0}, Vector3f::UnitZ(), 0);
  AddFacingQuad(mesh, {x0, y0 - L, 0}, {x0, y0, 0}, {x0, y0, L}, {x0, y0 - L, L}, -Vector3f::UnitX(), 0);
  AddFacingQuad(mesh, {x0 - L, y0, 0}, {x0, y0, 0}, {x0, y0, L}, {x0 - L, y0, L}, -Vector3f::UnitY(), 0);
  // Heading -45 deg, depression atan(1/sqrt 2): looking along (1, 1, -1).
  const sensor::SarGeometry g = Covering(GeometryOptions(-45.0, std::atan(1.0 / std::sqrt(2.0)) / kDeg, 0.2),
                                         mesh.vertices);
  const EmbreeScene embree(mesh);
  const cd hh = LayerSum(RenderSar(embree, mesh, metal, g, PolarimetricOptions(Polarization::kHH)), 2);
  const cd hv = LayerSum(RenderSar(embree, mesh, metal, g, PolarimetricOptions(Polarization::kHV)), 2);
  const cd vv = LayerSum(RenderSar(embree, mesh, metal, g, PolarimetricOptions(Polarization::kVV)), 2);
  ASSERT_GT(std::abs(hh), 0.0);
  std::printf("trihedral triple bounce: HH/VV %.5f dB %.4f deg, |HV/HH| %.2e\n", Db20(std::abs(hh / vv)),
              PhaseDeg(hh * std::conj(vv)), std::abs(hv / hh));
  EXPECT_NEAR(Db20(std::abs(hh / vv)), 0.0, 0.1);
  EXPECT_NEAR(PhaseDeg(hh * std::conj(vv)), 0.0, 1.0);
  EXPECT_LT(std::abs(hv / hh), 1e-4);
}

// A uniform plane, coherent polarimetric passes: the pixels are
// independent looks (every ray and pixel has its own seeded phases); over
// about 20 000 of them the mean |HH|^2, |VV|^2, |HV|^2 times sin(incidence)
// (beta0 -> sigma0) are the law's sigma0 within 0.2 dB (the standard error
// of a mean of 20 000 exponential looks is 0.7 %, 0.03 dB), the HH-VV
// correlation is the law's rho within 0.05 and HV is uncorrelated with HH.
// The default materials of bare soil (Oh: rho 0.7), forest (water cloud:
// canopy 1/3 and ground 0.7 mixed) and sea (Bragg: |rho| 1 with the SPM
// phase). The HH pass equals the single-channel coherent HH pass bit for
// bit.
TEST(PolarimetricRenderTest, UniformPlaneMultilookedCovarianceIsTheLaw) {
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-120, -120, 0}, {120, -120, 0}, {120, 120, 0}, {-120, 120, 0}, Vector3f::UnitZ(), 0);
  const double depression = 40.0;
  const sensor::SarGeometry g = Covering(GeometryOptions(0.0, depression, 1.0), mesh.vertices);
  const EmbreeScene embree(mesh);
  for (const scene::ClassId cls : {scene::kClassDefault, scene::kClassForest, scene::kClassSea}) {
    SCOPED_TRACE(scene::ClassNames()[cls]);
    material::MaterialTable materials;
    materials.Set(0, material::DefaultMaterial(cls));
    auto pass = [&](Polarization pol, bool polarimetric = true) {
      RenderOptions o = PolarimetricOptions(pol);
      o.polarimetric = polarimetric;
      o.rays_per_cell = 4.0;
      o.max_bounces = 1;
      return RenderSar(embree, mesh, materials, g, o);
    };
    const SarImage hh = pass(Polarization::kHH), hv = pass(Polarization::kHV), vv = pass(Polarization::kVV);
    double p_hh = 0, p_hv = 0, p_vv = 0;
    cd c_hh_vv = 0, c_hh_hv = 0;
    int n = 0;
    for (int r = int(g.v0()) - 75; r <= int(g.v0()) + 75; ++r) {
      for (int c = int(g.u0()) - 65; c <= int(g.u0()) + 65; ++c) {
        const size_t k = size_t(r) * hh.width + c;
        const cd a(hh.real[k], hh.imag[k]), x(hv.real[k], hv.imag[k]), b(vv.real[k], vv.imag[k]);
        p_hh += std::norm(a);
        p_hv += std::norm(x);
        p_vv += std::norm(b);
        c_hh_vv += a * std::conj(b);
        c_hh_hv += a * std::conj(x);
        ++n;
      }
    }
    const double cos_inc = std::sin(depression * kDeg);  // flat ground: incidence 90 deg - depression
    const material::PolarimetricSigma0 law = material::PolarimetricLaw(materials.Get(0), cos_inc, 0.031);
    const double to_sigma0 = std::cos(depression * kDeg) / n;  // beta0 -> sigma0: times sin(incidence)
    const cd rho = c_hh_vv / std::sqrt(p_hh * p_vv);
    std::printf("%s plane, %d looks: HH %.3f dB (law %.3f), HV %.3f dB (law %.3f), VV %.3f dB (law %.3f), "
                "rho %.4f%+.4fj (law %.4f%+.4fj), |rho HH-HV| %.4f\n",
                scene::ClassNames()[cls].c_str(), n, Db10(p_hh * to_sigma0), Db10(law.sigma0_hh),
                Db10(p_hv * to_sigma0), Db10(law.sigma0_hv), Db10(p_vv * to_sigma0), Db10(law.sigma0_vv),
                rho.real(), rho.imag(), law.rho_hh_vv.real(), law.rho_hh_vv.imag(),
                p_hv > 0 ? std::abs(c_hh_hv) / std::sqrt(p_hh * p_hv) : 0.0);
    EXPECT_GT(n, 19000);
    EXPECT_NEAR(Db10(p_hh * to_sigma0 / law.sigma0_hh), 0.0, 0.2);
    EXPECT_NEAR(Db10(p_vv * to_sigma0 / law.sigma0_vv), 0.0, 0.2);
    if (law.sigma0_hv > 0.0) {
      EXPECT_NEAR(Db10(p_hv * to_sigma0 / law.sigma0_hv), 0.0, 0.2);
      EXPECT_LT(std::abs(c_hh_hv) / std::sqrt(p_hh * p_hv), 0.05);
    } else {
      EXPECT_EQ(p_hv, 0.0);
    }
    EXPECT_NEAR(std::abs(rho - law.rho_hh_vv), 0.0, 0.05);
    // HH polarimetric == HH single-channel, bit for bit.
    const SarImage plain = pass(Polarization::kHH, false);
    EXPECT_EQ(plain.real, hh.real);
    EXPECT_EQ(plain.imag, hh.imag);
  }
}

// Reciprocity: the HV and VH passes of a scene with rough ground, a wall on
// it (dielectric double bounces seen obliquely) and a turned metal dihedral
// are the same image (complex and detected, every bounce layer) to 1e-6
// of the largest pixel, and so are their reflector returns.
TEST(PolarimetricRenderTest, HvPassEqualsVhPass) {
  material::MaterialTable table;
  material::Material ground = material::DefaultMaterial(scene::kClassDefault);
  ground.mirror = 0.5;
  ground.diffuse = 0.3;
  table.Set(0, ground);
  material::Material wall{"wall", 0.2, 0.3, 0.3, 0.7};
  wall.permittivity = {6.0, -1.0};
  table.Set(1, wall);
  table.Set(2, Metal());
  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-40, -40, 0}, {40, -40, 0}, {40, 40, 0}, {-40, 40, 0}, Vector3f::UnitZ(), 0);
  // A wall turned 30 deg from broadside.
  const Vector3f a(10, -15, 0), b(25, 11, 0);
  AddFacingQuad(mesh, a, b, b + Vector3f(0, 0, 8), a + Vector3f(0, 0, 8), -Vector3f::UnitX(), 1);
  const sensor::SarGeometryOptions go = GeometryOptions(0.0, 35.0, 0.5);
  const Vector3d l = Covering(go, mesh.vertices).look_direction();
  scene::TriangleMesh dihedral = RotatedDihedral(l, 30 * kDeg);
  for (Vector3f& v : dihedral.vertices) v += Vector3f(-15, 10, 8);
  for (size_t t = 0; t < dihedral.triangle_count(); ++t) {
    const Eigen::Vector3i tri = dihedral.Triangle(t);
    mesh.AddTriangle(dihedral.vertices[tri[0]], dihedral.vertices[tri[1]], dihedral.vertices[tri[2]], 2);
  }
  const sensor::SarGeometry g = Covering(go, mesh.vertices);
  const EmbreeScene embree(mesh);
  SceneReflector reflector;
  reflector.type = material::ReflectorType::kDihedral;
  reflector.size_m = 0.5;
  reflector.apex_enu = Vector3d(-30, -20, 0.5);
  reflector.boresight_enu = -l;
  reflector.roll_rad = 20 * kDeg;
  for (const bool coherent : {true, false}) {
    RenderOptions o = PolarimetricOptions(Polarization::kHV, coherent);
    o.rays_per_cell = 9.0;
    o.reflectors = {reflector};
    const SarImage hv = RenderSar(embree, mesh, table, g, o);
    o.polarization = Polarization::kVH;
    const SarImage vh = RenderSar(embree, mesh, table, g, o);
    auto max_abs = [](const std::vector<float>& x) {
      double m = 0;
      for (float v : x) m = std::max(m, double(std::abs(v)));
      return m;
    };
    auto max_diff = [](const std::vector<float>& x, const std::vector<float>& y) {
      EXPECT_EQ(x.size(), y.size());
      double m = 0;
      for (size_t k = 0; k < std::min(x.size(), y.size()); ++k) m = std::max(m, double(std::abs(x[k] - y[k])));
      return m;
    };
    const double scale = max_abs(hv.intensity);
    ASSERT_GT(scale, 0.0);
    EXPECT_LE(max_diff(hv.intensity, vh.intensity), 1e-6 * scale);
    for (int layer = 0; layer < 3; ++layer) {
      EXPECT_LE(max_diff(hv.bounce_layers[layer], vh.bounce_layers[layer]), 1e-6 * scale) << layer;
      if (coherent) {
        const double amp = std::sqrt(scale);
        EXPECT_LE(max_diff(hv.bounce_real[layer], vh.bounce_real[layer]), 1e-6 * amp) << layer;
        EXPECT_LE(max_diff(hv.bounce_imag[layer], vh.bounce_imag[layer]), 1e-6 * amp) << layer;
      }
    }
    const double double_bounce = std::accumulate(hv.bounce_layers[1].begin(), hv.bounce_layers[1].end(), 0.0);
    EXPECT_GT(double_bounce, 0.0);  // the cross-polarised double bounce is there
    ASSERT_EQ(hv.points.size(), 1u);
    ASSERT_EQ(vh.points.size(), 1u);
    EXPECT_EQ(hv.points[0].beta0_sum, vh.points[0].beta0_sum);
    EXPECT_EQ(hv.points[0].phase_offset_rad, vh.points[0].phase_offset_rad);
    std::printf("HV vs VH (%s): worst |HV - VH| / max %.2e, double-bounce HV %.4g\n",
                coherent ? "coherent" : "incoherent", max_diff(hv.intensity, vh.intensity) / scale, double_bounce);
  }
}

// A ground-wall dihedral of dielectrics (the default materials: ground
// `default`, eps 6-1j, mirror 0, and `building`, eps 6-0.5j, mirror 0.7),
// coherent polarimetric passes: every double-bounce path is radar -> wall
// (mirror) -> ground (bistatic law back to the radar). Below the wall's
// pseudo-Brewster angle (atan sqrt 6 = 67.8 deg) r_h and r_v have opposite
// signs and so do HH and VV (material::TraceSpecularChain of the specular
// chain: about -174 deg at depression 40 deg), whether the wall faces the
// radar or is turned 25 deg in azimuth (the ground's diffuse part scatters
// in the ground's own frame; the facet bisecting the incoming and radar
// directions, a rotated dihedral with the wall, only carries the specular
// cone). At depression 75 deg the wall facing the radar is met at 75 deg
// incidence, beyond that angle: r_v has changed sign, and HH and VV are in
// phase, as from a single bounce (the reason a dielectric dihedral is not
// red in a Pauli image everywhere: scripts/monaco_polarimetry.sh). Checked on
// the complex sum of the double-bounce layer and pixel by pixel (the pixels
// holding 99 % of its HH power); HH double power above VV's (|r_h| > |r_v|
// on both faces).
TEST(PolarimetricRenderTest, DielectricGroundWallDoubleBounceOppositeBelowTheWallsBrewsterAngleInPhaseBeyond) {
  material::MaterialTable table;
  table.Set(0, material::DefaultMaterial(scene::kClassDefault));
  table.Set(1, material::DefaultMaterial(scene::kClassBuilding));
  ASSERT_EQ(table.Get(0).mirror, 0.0);
  struct Case {
    double depression_deg, turn_deg;
    bool opposite;  // wall incidence below its pseudo-Brewster angle
  };
  for (const Case& c : {Case{40.0, 0.0, true}, Case{40.0, 25.0, true}, Case{75.0, 0.0, false}}) {
    const double depression = c.depression_deg, turn_deg = c.turn_deg;
    SCOPED_TRACE("depression " + std::to_string(depression) + " deg, wall turned " + std::to_string(turn_deg) +
                 " deg");
    scene::TriangleMesh mesh;
    AddFacingQuad(mesh, {-40, -40, 0}, {40, -40, 0}, {40, 40, 0}, {-40, 40, 0}, Vector3f::UnitZ(), 0);
    // The radar looks east (+x): the wall faces west, turned by turn_deg.
    const float t = static_cast<float>(turn_deg * kDeg);
    const Vector3f along(std::sin(t), std::cos(t), 0), facing(-std::cos(t), std::sin(t), 0);
    const Vector3f a = Vector3f(10, 0, 0) - 15.0f * along, b = Vector3f(10, 0, 0) + 15.0f * along;
    AddFacingQuad(mesh, a, b, b + Vector3f(0, 0, 10), a + Vector3f(0, 0, 10), facing, 1);
    const sensor::SarGeometry g = Covering(GeometryOptions(0.0, depression, 0.5), mesh.vertices);
    const EmbreeScene embree(mesh);
    auto pass = [&](Polarization pol) {
      RenderOptions o = PolarimetricOptions(pol);
      o.rays_per_cell = 9.0;
      o.max_bounces = 2;
      return RenderSar(embree, mesh, table, g, o);
    };
    const SarImage hh = pass(Polarization::kHH), vv = pass(Polarization::kVV), hv = pass(Polarization::kHV);
    const std::vector<float>&hr = hh.bounce_real[1], &hi = hh.bounce_imag[1], &vr = vv.bounce_real[1],
                           &vi = vv.bounce_imag[1];
    ASSERT_FALSE(hr.empty());
    cd sum = 0;
    double p_hh = 0, p_vv = 0, p_hv = 0;
    std::vector<std::pair<double, double>> pixels;  // (|HH|^2, phase deg)
    for (size_t k = 0; k < hr.size(); ++k) {
      const cd x(hr[k], hi[k]), y(vr[k], vi[k]), z(hv.bounce_real[1][k], hv.bounce_imag[1][k]);
      sum += x * std::conj(y);
      p_hh += std::norm(x);
      p_vv += std::norm(y);
      p_hv += std::norm(z);
      if (std::norm(x) > 0.0) pixels.push_back({std::norm(x), PhaseDeg(x * std::conj(y))});
    }
    ASSERT_GT(p_hh, 0.0);
    std::sort(pixels.begin(), pixels.end(), [](auto& u, auto& w) { return u.first > w.first; });
    double held = 0, expected_power = 0;
    int bright = 0, expected = 0;  // pixels whose phase is the expected one
    for (const auto& [power, phase] : pixels) {
      if (held >= 0.99 * p_hh) break;
      held += power;
      ++bright;
      if ((std::abs(phase) > 90.0) == c.opposite) {
        ++expected;
        expected_power += power;
      }
    }
    std::printf("dielectric ground-wall, depression %.0f deg, wall turned %.0f deg: arg <HH VV*> %.1f deg, HH/VV "
                "%.2f dB, HV/HH %.2f dB, %d bright pixels, %.3f %s (%.3f of the power)\n",
                depression, turn_deg, PhaseDeg(sum), Db10(p_hh / p_vv), Db10(p_hv / p_hh), bright,
                double(expected) / bright, c.opposite ? "opposite" : "in phase", expected_power / held);
    if (c.opposite) {
      EXPECT_GT(std::abs(PhaseDeg(sum)), 160.0);
    } else {
      EXPECT_LT(std::abs(PhaseDeg(sum)), 20.0);
    }
    EXPECT_GT(p_hh, p_vv);
    EXPECT_GT(bright, 20);
    EXPECT_GE(double(expected) / bright, 0.95);
  }
}

// Reflectors CSV with roll_deg to the channels: a dihedral rolled 45 deg
// returns its whole RCS in HV and none co-polarised; without the column
// (roll 0) the co-pol channels keep the scalar RCS, HV none, VV 180 deg
// from HH; a trihedral's HH and VV are equal and in phase (the coherent
// sensor stage's use of the phase offset: image/radiometry_test.cc).
TEST(PolarimetricRenderTest, ReflectorRollAndChannel) {
  const auto dir = std::filesystem::temp_directory_path() / "gissar_polarimetric_reflectors";
  std::filesystem::create_directories(dir);
  const std::string seven = "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg";
  std::ofstream(dir / "rolled.csv") << seven << ",roll_deg\ndihedral,0,0,0,0.5,270,35,45\ntrihedral,0,0,0,0.5,270,35,0\n";
  std::ofstream(dir / "plain.csv") << seven << "\ndihedral,0,0,0,0.5,270,35\n";
  const auto rolled = material::ReadReflectorsCsv((dir / "rolled.csv").string());
  const auto plain = material::ReadReflectorsCsv((dir / "plain.csv").string());
  std::filesystem::remove_all(dir);
  ASSERT_EQ(rolled.size(), 2u);
  ASSERT_EQ(plain.size(), 1u);
  EXPECT_EQ(plain[0].roll_deg, 0.0);

  scene::TriangleMesh mesh;
  AddFacingQuad(mesh, {-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}, Vector3f::UnitZ(), 0);
  const sensor::SarGeometry g = Covering(GeometryOptions(0.0, 35.0, 0.5), mesh.vertices);
  const EmbreeScene embree(mesh);
  auto place = [&](const material::ReflectorSpec& spec, const Vector3d& at) {
    SceneReflector r;
    r.type = spec.type;
    r.size_m = spec.size_m;
    r.apex_enu = at;
    r.boresight_enu = -g.look_direction();  // at boresight
    r.roll_rad = spec.roll_deg * kDeg;
    return r;
  };
  const std::vector<SceneReflector> reflectors = {place(rolled[0], {-5, -5, 1}), place(rolled[1], {5, 5, 1}),
                                                  place(plain[0], {5, -5, 1})};
  const double lambda = 0.031;
  const std::vector<PointReturn> scalar = ReflectorReturns(embree, reflectors, g, lambda);
  ASSERT_EQ(scalar.size(), 3u);
  const double full = material::PeakRcs(material::ReflectorType::kDihedral, 0.5, lambda) /
                      (g.range_spacing_m() * g.azimuth_spacing_m());
  EXPECT_NEAR(scalar[0].beta0_sum / full, 1.0, 1e-9);  // at boresight: the peak
  std::map<Polarization, std::vector<PointReturn>> by;
  for (const Polarization pol : {Polarization::kHH, Polarization::kHV, Polarization::kVH, Polarization::kVV}) {
    by[pol] = ReflectorReturns(embree, reflectors, g, lambda, pol);
    ASSERT_EQ(by[pol].size(), 3u);
  }
  // Rolled dihedral.
  EXPECT_LT(by[Polarization::kHH][0].beta0_sum, 1e-12 * full);
  EXPECT_LT(by[Polarization::kVV][0].beta0_sum, 1e-12 * full);
  EXPECT_NEAR(by[Polarization::kHV][0].beta0_sum / scalar[0].beta0_sum, 1.0, 1e-12);
  EXPECT_EQ(by[Polarization::kHV][0].beta0_sum, by[Polarization::kVH][0].beta0_sum);
  // Trihedral: co-pol the scalar RCS, in phase; no HV.
  EXPECT_EQ(by[Polarization::kHH][1].beta0_sum, scalar[1].beta0_sum);
  EXPECT_EQ(by[Polarization::kVV][1].beta0_sum, scalar[1].beta0_sum);
  EXPECT_EQ(by[Polarization::kHH][1].phase_offset_rad, 0.0);
  EXPECT_EQ(by[Polarization::kVV][1].phase_offset_rad, 0.0);
  EXPECT_EQ(by[Polarization::kHV][1].beta0_sum, 0.0);
  // Plain dihedral (no roll column): HH = VV = the scalar RCS, 180 deg apart.
  EXPECT_EQ(by[Polarization::kHH][2].beta0_sum, scalar[2].beta0_sum);
  EXPECT_EQ(by[Polarization::kVV][2].beta0_sum, scalar[2].beta0_sum);
  EXPECT_NEAR(std::abs(by[Polarization::kVV][2].phase_offset_rad - by[Polarization::kHH][2].phase_offset_rad), M_PI,
              1e-12);
  EXPECT_EQ(by[Polarization::kHV][2].beta0_sum, 0.0);

}

}  // namespace
}  // namespace gissar::render
