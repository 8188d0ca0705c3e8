// The product renderer's coherent mode (render/product_renderer.h): phasors
// formed on a real radar grid from the re-projected returns.
#include "gissar/render/product_renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>

#include "gissar/material/scattering.h"
#include "gissar/scene/scene_config.h"

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


// ------------------------------------------------ polarimetric passes

using material::Polarization;
using cd = std::complex<double>;

RenderOptions PolarimetricPass(Polarization pol, int bounces) {
  RenderOptions o = Options(true, 7);
  o.polarimetric = true;
  o.polarization = pol;
  o.max_bounces = bounces;
  return o;
}

// A uniform rough plane (the default class: Oh at C band) on the product
// grid, one polarimetric pass per channel: the multilooked single-look
// covariance is the law's, as in the tracer's own polarimetric passes
// (PolarimetricRenderTest.UniformPlaneMultilookedCovarianceIsTheLaw):
// |HH|^2, |HV|^2, |VV|^2 within 0.2 dB of sigma0 (beta0 -> sigma0 by each
// pixel's incidence on the flat ground), |rho_HH,VV - rho_law| < 0.05, HV
// uncorrelated with HH, the HV pass equal to the VH pass, and the detected
// bands (incoherent sums) those of the incoherent polarimetric passes.
TEST(ProductRendererTest, PolarimetricPassesHaveTheLawsCovariance) {
  const Track track = MakeTrack();
  const scene::TriangleMesh mesh = Ground();
  const EmbreeScene embree(mesh);
  material::MaterialTable materials;
  materials.Set(0, material::DefaultMaterial(scene::kClassDefault));
  auto pass = [&](Polarization pol, bool coherent = true) {
    RenderOptions o = PolarimetricPass(pol, 1);
    o.coherent = coherent;
    return RenderProduct(embree, mesh, materials, track.frame, track.orbit, track.grid, o);
  };
  const ProductImage hh = pass(Polarization::kHH), hv = pass(Polarization::kHV), vv = pass(Polarization::kVV);
  const ProductImage vh = pass(Polarization::kVH);
  EXPECT_EQ(hv.image.real, vh.image.real);
  EXPECT_EQ(hv.image.imag, vh.image.imag);
  EXPECT_EQ(pass(Polarization::kVV, false).image.bounce_layers[0], vv.image.bounce_layers[0]);
  const SarImage& a = hh.image;
  double r_hh = 0, r_hv = 0, r_vv = 0, p_hh = 0, p_vv = 0, p_hv = 0;
  cd c_hh_vv = 0, c_hh_hv = 0;
  int n = 0;
  const material::Material& m = materials.Get(0);
  for (int r = 10; r < a.height - 10; ++r) {
    for (int c = 10; c < a.width - 10; ++c) {
      const size_t k = size_t(r) * a.width + c;
      ASSERT_TRUE(std::isfinite(hh.height_m[k]));
      // The pixel's ground point and its incidence from the track (x = -8 km, z = 6 km, abeam).
      const Vector3d p = track.frame.EnuFromGeodetic(hh.lon_deg_exact[k], hh.lat_deg_exact[k], hh.height_m[k]);
      const double cos_inc = (Vector3d(-8000.0, p.y(), 6000.0) - p).normalized().z();
      const double sin_inc = std::sqrt(1.0 - cos_inc * cos_inc);
      const material::PolarimetricSigma0 law = material::PolarimetricLaw(m, cos_inc, 0.056);
      const cd x(a.real[k], a.imag[k]), y(hv.image.real[k], hv.image.imag[k]), z(vv.image.real[k], vv.image.imag[k]);
      r_hh += std::norm(x) * sin_inc / law.sigma0_hh;
      r_hv += std::norm(y) * sin_inc / law.sigma0_hv;
      r_vv += std::norm(z) * sin_inc / law.sigma0_vv;
      p_hh += std::norm(x);
      p_hv += std::norm(y);
      p_vv += std::norm(z);
      c_hh_vv += x * std::conj(z);
      c_hh_hv += x * std::conj(y);
      ++n;
    }
  }
  const double cos_centre = 0.6;  // the scene centre: 6 km up, 10 km away
  const cd rho_law = material::PolarimetricLaw(m, cos_centre, 0.056).rho_hh_vv;
  const cd rho = c_hh_vv / std::sqrt(p_hh * p_vv);
  const double rho_hv = std::abs(c_hh_hv) / std::sqrt(p_hh * p_hv);
  auto db = [](double x) { return 10.0 * std::log10(x); };
  std::printf("[ measured ] Oh plane on a product grid, %d looks: HH %+.3f dB, HV %+.3f dB, VV %+.3f dB from the "
              "law; rho %.4f%+.4fj (law %.4f%+.4fj); |rho HH-HV| %.4f\n",
              n, db(r_hh / n), db(r_hv / n), db(r_vv / n), rho.real(), rho.imag(), rho_law.real(), rho_law.imag(),
              rho_hv);
  EXPECT_GT(n, 7000);
  EXPECT_NEAR(db(r_hh / n), 0.0, 0.2);
  EXPECT_NEAR(db(r_hv / n), 0.0, 0.2);
  EXPECT_NEAR(db(r_vv / n), 0.0, 0.2);
  EXPECT_LT(std::abs(rho - rho_law), 0.05);
  EXPECT_LT(rho_hv, 0.05);
}

// A metal dihedral (two 10 m x 6 m plates, fold horizontal and
// perpendicular to the line of sight) on the product grid, two bounces:
// the double-bounce layer's complex sums have HH = -VV (0 dB, 180 deg) and
// no HV, as the tracer's own passes give them.
TEST(ProductRendererTest, PolarimetricDihedralHasHhAndVvOpposite) {
  const Track track = MakeTrack();
  const Vector3d l = Vector3d(8000.0, 0.0, -6000.0).normalized();  // line of sight to the scene centre
  const material::PolarizationBasis b = material::HvBasis(l);
  const Vector3d fold = b.h;
  const Vector3d w0 = -(l + b.v) / std::sqrt(2.0), w1 = (-l + b.v) / std::sqrt(2.0);
  const Vector3d n0 = (-l + b.v) / std::sqrt(2.0), n1 = (-l - b.v) / std::sqrt(2.0);
  scene::TriangleMesh mesh;
  auto plate = [&](const Vector3d& w, const Vector3d& n) {
    const Vector3d p0 = -5.0 * fold, p1 = 5.0 * fold;
    Vector3f q[4] = {p0.cast<float>(), p1.cast<float>(), (p1 + 6.0 * w).cast<float>(), (p0 + 6.0 * w).cast<float>()};
    if ((q[1] - q[0]).cross(q[2] - q[0]).dot(n.cast<float>()) < 0) std::swap(q[1], q[3]);
    mesh.AddQuad(q[0], q[1], q[2], q[3], 0);
  };
  plate(w0, n0);
  plate(w1, n1);
  const EmbreeScene embree(mesh);
  material::MaterialTable materials;
  material::Material metal{"metal", 0.0, 1.0, 1.0, 1.0};
  metal.permittivity = {1e10, 0.0};
  materials.Set(0, metal);
  auto layer_sum = [&](Polarization pol) {
    RenderOptions o = PolarimetricPass(pol, 2);
    o.rays_per_cell = 16.0;
    const ProductImage image = RenderProduct(embree, mesh, materials, track.frame, track.orbit, track.grid, o);
    cd sum = 0.0;
    for (size_t k = 0; k < image.image.bounce_real[1].size(); ++k) {
      sum += cd(image.image.bounce_real[1][k], image.image.bounce_imag[1][k]);
    }
    return sum;
  };
  const cd hh = layer_sum(Polarization::kHH), hv = layer_sum(Polarization::kHV), vv = layer_sum(Polarization::kVV);
  const double ratio_db = 20.0 * std::log10(std::abs(hh) / std::abs(vv));
  const double phase_deg = std::arg(hh * std::conj(vv)) * 180.0 / M_PI;
  std::printf("[ measured ] dihedral on a product grid, double bounce: |HH| %.4g, HH/VV %.4f dB, %.3f deg, "
              "|HV/HH| %.2g\n",
              std::abs(hh), ratio_db, phase_deg, std::abs(hv) / std::abs(hh));
  ASSERT_GT(std::abs(hh), 0.0);
  EXPECT_NEAR(ratio_db, 0.0, 0.1);
  EXPECT_NEAR(std::abs(phase_deg), 180.0, 1.0);
  EXPECT_LT(std::abs(hv) / std::abs(hh), 1e-3);
}

}  // namespace
}  // namespace gissar::render
