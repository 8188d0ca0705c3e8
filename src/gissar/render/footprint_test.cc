// Footprint-aware sampling (issue 16, item 5): every pixel of a surface's
// illuminated footprint receives returns, evenly, whatever the incidence,
// the slope and the ratio of pixel to DEM cell.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>

#include "gissar/render/embree_scene.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::render {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Largest amplitude (dB) of a sinusoid in the 2-D discrete Fourier
// transform of `x` (rows x cols, mean removed): 2 |X(u, v)| / (rows cols)
// over every frequency but (0, 0).
double PeriodogramPeakDb(const std::vector<double>& x, int rows, int cols) {
  using C = std::complex<double>;
  std::vector<C> a(x.begin(), x.end());
  std::vector<C> b(a.size());
  for (int r = 0; r < rows; ++r) {  // along columns of each row
    for (int v = 0; v < cols; ++v) {
      C s = 0;
      for (int c = 0; c < cols; ++c) s += a[size_t(r) * cols + c] * std::polar(1.0, -2.0 * M_PI * v * c / cols);
      b[size_t(r) * cols + v] = s;
    }
  }
  double peak = 0.0;
  for (int v = 0; v < cols; ++v) {
    for (int u = 0; u < rows; ++u) {
      if (u == 0 && v == 0) continue;
      C s = 0;
      for (int r = 0; r < rows; ++r) s += b[size_t(r) * cols + v] * std::polar(1.0, -2.0 * M_PI * u * r / rows);
      peak = std::max(peak, 2.0 * std::abs(s) / (double(rows) * cols));
    }
  }
  return peak;
}

struct Measure {
  double spread_db = 0.0;   // standard deviation of the pixels in dB
  double peak_db = 0.0;     // largest periodogram amplitude
  int empty = 0;            // interior pixels without a return
  int pixels = 0;
};

// A plane of DEM posts `cell_m` apart, tilted by `tilt_deg` towards the radar
// (negative: away), seen at incidence `incidence_deg` (affine, heading 0,
// looking east) with pixels `ratio` x cell_m; the interior 80 % of its image.
Measure TiltedPlane(double incidence_deg, double tilt_deg, double ratio, double rays) {
  const double pixel = 5.0, cell = pixel / ratio;
  const double side = 80.0 * pixel;  // ground extent, metres
  const int n = static_cast<int>(std::lround(side / cell)) + 1;
  std::vector<Eigen::Vector3f> posts;
  const double slope = std::tan(tilt_deg * kDeg);  // rises away from the radar: faces it
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const double x = -0.5 * side + c * cell, y = -0.5 * side + r * cell;
      posts.emplace_back(float(x), float(y), float(x * slope));
    }
  }
  const scene::TriangleMesh mesh = scene::MeshFromGrid(posts, n, n);
  sensor::SarGeometryOptions o;
  o.heading_deg = 0.0;
  o.depression_deg = 90.0 - incidence_deg;
  o.range_spacing_m = pixel;
  o.azimuth_spacing_m = pixel;
  const auto g = sensor::SarGeometry::Covering(o, Eigen::Vector3d::Zero(), mesh.vertices);
  const EmbreeScene embree(mesh);
  RenderOptions ro;
  ro.rays_per_cell = rays;
  ro.max_bounces = 1;
  const SarImage image = RenderSar(embree, mesh, material::MaterialTable(), g, ro);
  // Interior: the image of the plane's central 80 % (range is monotonic in x
  // on a lit plane, azimuth is y).
  const double m = 0.4 * side;
  auto at = [&](double x, double y) { return g.Project(Eigen::Vector3d(x, y, x * slope)); };
  const Eigen::Vector2d lo = at(-m, -m), hi = at(m, m);
  const int c0 = int(std::ceil(std::min(lo.x(), hi.x()))), c1 = int(std::floor(std::max(lo.x(), hi.x())));
  const int r0 = int(std::ceil(std::min(lo.y(), hi.y()))), r1 = int(std::floor(std::max(lo.y(), hi.y())));
  Measure out;
  std::vector<double> db;
  double sum = 0.0, sum2 = 0.0;
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      const double v = image.intensity[size_t(r) * image.width + c];
      ++out.pixels;
      if (!(v > 0.0)) {
        ++out.empty;
        db.push_back(0.0);
        continue;
      }
      db.push_back(10.0 * std::log10(v));
      sum += db.back();
      sum2 += db.back() * db.back();
    }
  }
  const double mean = sum / out.pixels;
  out.spread_db = std::sqrt(std::max(0.0, sum2 / out.pixels - mean * mean));
  for (double& v : db) v -= mean;
  out.peak_db = PeriodogramPeakDb(db, r1 - r0 + 1, c1 - c0 + 1);
  return out;
}

// Incidence 20-70 deg, planes flat and tilted 20 deg towards and away from
// the radar, pixel/DEM-cell ratio 0.25-4, 1 and 4 rays per cell: no empty
// pixel, spread <= 0.1 dB, no periodogram peak above 0.05 dB. Local
// incidence runs from 5 to 85 deg: at 20 deg incidence the towards-tilt is
// taken at 25 deg (at 20 deg the plane would be normal to the beam and image
// into a single range line) and at 70 deg the away-tilt at 65 deg (at 70 deg
// it is edge-on: no return at all).
TEST(FootprintTest, TiltedPlanesFillEveryPixelEvenly) {
  double worst_spread = 0.0, worst_peak = 0.0;
  int empty = 0;
  for (double incidence : {20.0, 45.0, 70.0}) {
    for (double tilt : {-20.0, 0.0, 20.0}) {
      double inc = incidence;
      if (tilt > 0 && incidence < 25.0) inc = 25.0;
      if (tilt < 0 && incidence > 65.0) inc = 65.0;
      for (double ratio : {0.25, 1.0, 4.0}) {
        for (double rays : {1.0, 4.0}) {
          const Measure m = TiltedPlane(inc, tilt, ratio, rays);
          const std::string what = "incidence " + std::to_string(inc) + " tilt " + std::to_string(tilt) +
                                   " ratio " + std::to_string(ratio) + " rays " + std::to_string(rays);
          ASSERT_GT(m.pixels, 100) << what;
          EXPECT_EQ(m.empty, 0) << what;
          EXPECT_LE(m.spread_db, 0.1) << what;
          EXPECT_LE(m.peak_db, 0.05) << what;
          worst_spread = std::max(worst_spread, m.spread_db);
          worst_peak = std::max(worst_peak, m.peak_db);
          empty += m.empty;
        }
      }
    }
  }
  std::printf("footprint: %d empty pixels, worst spread %.4f dB, worst periodogram peak %.4f dB\n", empty,
              worst_spread, worst_peak);
}

}  // namespace
}  // namespace gissar::render
