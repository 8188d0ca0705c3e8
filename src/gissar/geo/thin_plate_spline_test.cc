#include "gissar/geo/thin_plate_spline.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gissar/geo/raster_io.h"
#include "gissar/geo/thin_plate_spline_kernels.h"
#include "gissar/geo/warp.h"

namespace gissar::geo {
namespace {

// The unit square's corners with values 0, 0, 0, 1. By symmetry the kernel
// coefficients are c (1, -1, -1, 1); at the corners the kernel sums are
// +-2 ln 2, so the four interpolation conditions give c = 1 / (8 ln 2),
// a0 = -1/4, a1 = a2 = 1/2. Hence f(1/2, 1/2) = 1/4 and f(1/2, 0) = 0 (the
// kernel terms cancel in pairs), and at (2, 2), with squared distances 8, 5,
// 5, 2: f = 7/4 + (8 ln 8 - 10 ln 5 + 2 ln 2) / (8 ln 2).
// The nodes are moved and scaled (the interpolant does not change), and the
// second value is the first times -3 plus 7.
TEST(ThinPlateSplineTest, SquareCornersGiveTheClosedForm) {
  const Eigen::Vector2d origin(1000.0, 2000.0);
  const double side = 300.0;
  auto at = [&](double u, double v) { return Eigen::Vector2d(origin + side * Eigen::Vector2d(u, v)); };
  const std::vector<Eigen::Vector2d> nodes{at(0, 0), at(1, 0), at(0, 1), at(1, 1)};
  std::vector<Eigen::Vector2d> values;
  for (double f : {0.0, 0.0, 0.0, 1.0}) values.emplace_back(f, -3.0 * f + 7.0);
  const auto spline = ThinPlateSpline::Fit(nodes, values);
  ASSERT_TRUE(spline.has_value());
  EXPECT_EQ(spline->node_count(), 4);
  const double ln2 = std::log(2.0);
  const double far = 1.75 + (8.0 * std::log(8.0) - 10.0 * std::log(5.0) + 2.0 * ln2) / (8.0 * ln2);
  const std::vector<std::pair<Eigen::Vector2d, double>> expected{
      {at(0.5, 0.5), 0.25}, {at(0.5, 0.0), 0.0}, {at(2.0, 2.0), far}, {at(1.0, 1.0), 1.0}, {at(0.0, 1.0), 0.0}};
  for (const auto& [p, f] : expected) {
    const Eigen::Vector2d got = (*spline)(p);
    EXPECT_NEAR(got.x(), f, 1e-12) << p.transpose();
    EXPECT_NEAR(got.y(), -3.0 * f + 7.0, 1e-11) << p.transpose();
  }
}

// Values that are an affine function of the nodes are reproduced exactly
// everywhere (the kernel part vanishes).
TEST(ThinPlateSplineTest, ReproducesAnAffineFunction) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 800.0);
  auto truth = [](const Eigen::Vector2d& p) {
    return Eigen::Vector2d(1.5 + 2e-5 * p.x() - 1e-6 * p.y(), 42.5 - 3e-6 * p.x() - 1.8e-5 * p.y());
  };
  std::vector<Eigen::Vector2d> nodes, values;
  for (int i = 0; i < 200; ++i) {
    nodes.emplace_back(u(rng), u(rng));
    values.push_back(truth(nodes.back()));
  }
  const auto spline = ThinPlateSpline::Fit(nodes, values);
  ASSERT_TRUE(spline.has_value());
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector2d p(u(rng) * 1.5 - 200.0, u(rng));
    EXPECT_LT(((*spline)(p) - truth(p)).cwiseAbs().maxCoeff(), 1e-12) << p.transpose();
  }
}

// GCPs with relief-like longitude/latitude offsets: a jittered 12 x 16
// lattice 80 pixels apart, then a dense 24 x 24 cluster 3 pixels apart (as the
// GCP refinement places them).
std::vector<GroundControlPoint> ReliefGcps(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> relief(0.0, 2e-4);  // about 20 m
  std::vector<GroundControlPoint> gcps;
  for (int r = 0; r < 16; ++r) {
    for (int c = 0; c < 12; ++c) {
      GroundControlPoint g;
      g.pixel = 80.0 * c + 10.0 * unit(rng);
      g.line = 80.0 * r + 10.0 * unit(rng);
      gcps.push_back(g);
    }
  }
  for (int r = 0; r < 24; ++r) {
    for (int c = 0; c < 24; ++c) {
      GroundControlPoint g;
      g.pixel = 400.0 + 3.0 * c + 0.5 * unit(rng);
      g.line = 600.0 + 3.0 * r + 0.5 * unit(rng);
      gcps.push_back(g);
    }
  }
  for (auto& g : gcps) {
    g.lon_deg = 1.5 + 1e-4 * g.pixel + 2e-6 * g.line + relief(rng);
    g.lat_deg = 42.5 - 1e-6 * g.pixel - 1e-4 * g.line + relief(rng);
  }
  return gcps;
}

// Points between the nodes and beyond them, and in the dense cluster.
std::vector<Eigen::Vector2d> ProbePoints(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < 3000; ++i) points.emplace_back(1100.0 * unit(rng) - 50.0, 1400.0 * unit(rng) - 50.0);
  for (int i = 0; i < 500; ++i) points.emplace_back(395.0 + 80.0 * unit(rng), 595.0 + 80.0 * unit(rng));
  return points;
}

// Against GDAL's own transformer (the one gdalwarp -tps builds), evaluated
// between the nodes and beyond them.
TEST(ThinPlateSplineTest, AgreesWithGdalsTransformer) {
  std::mt19937 rng(11);
  const std::vector<GroundControlPoint> gcps = ReliefGcps(rng);
  std::vector<Eigen::Vector2d> nodes, values;
  for (const auto& g : gcps) {
    nodes.emplace_back(g.pixel, g.line);
    values.emplace_back(g.lon_deg, g.lat_deg);
  }
  ASSERT_EQ(gcps.size(), 768u);
  const auto spline = ThinPlateSpline::Fit(nodes, values);
  ASSERT_TRUE(spline.has_value());
  const std::vector<Eigen::Vector2d> points = ProbePoints(rng);
  const std::vector<Eigen::Vector2d> ours = spline->Evaluate(points);
  const std::vector<Eigen::Vector2d> gdal = TpsLonLat(gcps, points);
  double worst = 0.0;
  for (size_t i = 0; i < points.size(); ++i) {
    ASSERT_TRUE(gdal[i].allFinite()) << i;
    EXPECT_EQ(ours[i], (*spline)(points[i]));  // parallel evaluation = one point at a time
    worst = std::max(worst, (ours[i] - gdal[i]).cwiseAbs().maxCoeff());
  }
  // 1e-9 deg is about 0.1 mm on the ground.
  std::printf("[ measured ] largest difference from GDAL's spline: %.3g deg\n", worst);
  EXPECT_LT(worst, 1e-9);
  // The spline passes through its nodes.
  for (size_t i = 0; i < nodes.size(); i += 7) {
    EXPECT_LT(((*spline)(nodes[i]) - values[i]).cwiseAbs().maxCoeff(), 1e-10) << i;
  }
}

// The incremental fit, with the same GCPs added as the refinement adds them
// (the lattice, then the cluster in rounds of 144), is GDAL's spline after
// the last round and Fit's spline after every round.
TEST(ThinPlateSplineTest, IncrementalFitIsGdalsSplineAfterEveryRound) {
  std::mt19937 rng(11);
  const std::vector<GroundControlPoint> gcps = ReliefGcps(rng);
  const std::vector<Eigen::Vector2d> points = ProbePoints(rng);
  IncrementalThinPlateSpline incremental;
  EXPECT_FALSE(incremental.Spline().has_value());
  std::vector<Eigen::Vector2d> all_nodes, all_values;
  for (size_t begin = 0; begin < gcps.size();) {
    const size_t end = begin == 0 ? 192 : std::min(gcps.size(), begin + 144);
    std::vector<Eigen::Vector2d> nodes, values;
    for (size_t i = begin; i < end; ++i) {
      nodes.emplace_back(gcps[i].pixel, gcps[i].line);
      values.emplace_back(gcps[i].lon_deg, gcps[i].lat_deg);
    }
    all_nodes.insert(all_nodes.end(), nodes.begin(), nodes.end());
    all_values.insert(all_values.end(), values.begin(), values.end());
    ASSERT_TRUE(incremental.Add(nodes, values)) << begin;
    EXPECT_EQ(incremental.node_count(), int(end));
    const auto spline = incremental.Spline();
    const auto direct = ThinPlateSpline::Fit(all_nodes, all_values);
    ASSERT_TRUE(spline && direct) << begin;
    EXPECT_EQ(spline->node_count(), int(end));
    const std::vector<Eigen::Vector2d> a = spline->Evaluate(points), b = direct->Evaluate(points);
    double worst = 0.0;
    for (size_t i = 0; i < points.size(); ++i) worst = std::max(worst, (a[i] - b[i]).cwiseAbs().maxCoeff());
    EXPECT_LT(worst, 1e-10) << "after " << end << " nodes";
    begin = end;
  }
  const std::vector<Eigen::Vector2d> ours = incremental.Spline()->Evaluate(points);
  const std::vector<Eigen::Vector2d> gdal = TpsLonLat(gcps, points);
  double worst = 0.0;
  for (size_t i = 0; i < points.size(); ++i) worst = std::max(worst, (ours[i] - gdal[i]).cwiseAbs().maxCoeff());
  std::printf("[ measured ] incremental fit, largest difference from GDAL's spline: %.3g deg\n", worst);
  EXPECT_LT(worst, 1e-9);
}

// The square's closed form (SquareCornersGiveTheClosedForm) with the fourth
// corner added in a second batch.
TEST(ThinPlateSplineTest, IncrementalFitOfTheSquareGivesTheClosedForm) {
  IncrementalThinPlateSpline spline;
  ASSERT_TRUE(spline.Add({{0, 0}, {1, 0}, {0, 1}}, {{0, 7}, {0, 7}, {0, 7}}));
  // Three nodes: the affine plane through them.
  EXPECT_NEAR((*spline.Spline())(Eigen::Vector2d(5, -2)).x(), 0.0, 1e-15);
  ASSERT_TRUE(spline.Add({{1, 1}}, {{1, 4}}));
  const double ln2 = std::log(2.0);
  const double far = 1.75 + (8.0 * std::log(8.0) - 10.0 * std::log(5.0) + 2.0 * ln2) / (8.0 * ln2);
  const auto s = spline.Spline();
  ASSERT_TRUE(s.has_value());
  for (const auto& [p, f] : std::vector<std::pair<Eigen::Vector2d, double>>{
           {{0.5, 0.5}, 0.25}, {{0.5, 0.0}, 0.0}, {{2.0, 2.0}, far}, {{1.0, 1.0}, 1.0}}) {
    EXPECT_NEAR((*s)(p).x(), f, 1e-12) << p.transpose();
    EXPECT_NEAR((*s)(p).y(), -3.0 * f + 7.0, 1e-11) << p.transpose();
  }
}

TEST(ThinPlateSplineTest, IncrementalFitRefusesAndKeepsItsSpline) {
  IncrementalThinPlateSpline spline;
  EXPECT_FALSE(spline.Add({{0, 0}, {1, 1}}, {{0, 0}, {1, 1}}));  // too few
  std::vector<Eigen::Vector2d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(3.0 * i, 2.0 * i + 1.0);
  EXPECT_FALSE(spline.Add(line, line));  // collinear
  EXPECT_EQ(spline.node_count(), 0);
  ASSERT_TRUE(spline.Add({{0, 0}, {10, 0}, {0, 10}, {10, 10}}, {{0, 0}, {1, 0}, {0, 1}, {1, 1}}));
  const Eigen::Vector2d probe(3.0, 7.0);
  const Eigen::Vector2d before = (*spline.Spline())(probe);
  // A node already there makes the system singular; a non-finite one is refused.
  EXPECT_FALSE(spline.Add({{5, 5}, {10, 10}}, {{0.5, 0.5}, {2, 2}}));
  EXPECT_FALSE(spline.Add({{5, std::nan("")}}, {{0, 0}}));
  EXPECT_EQ(spline.node_count(), 4);
  EXPECT_EQ((*spline.Spline())(probe), before);
}

// Both vector widths of the kernel sums against a long-double sum of
// d ln d: nodes at squared distances from 0 (phi(0) = 0) through 1e-12 to
// 2e4, with coefficients of both signs. The eight-lane build runs only where
// the CPU has AVX-512.
TEST(ThinPlateSplineTest, BothKernelWidthsSumDLnD) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-50.0, 50.0), c(-1.0, 1.0);
  constexpr size_t kCount = 200;  // a multiple of 8
  std::vector<double> xs(kCount), ys(kCount), c0(kCount), c1(kCount);
  for (size_t j = 0; j < kCount; ++j) {
    xs[j] = u(rng);
    ys[j] = u(rng);
    c0[j] = c(rng);
    c1[j] = c(rng);
  }
  const double qx = xs[7], qy = ys[7];  // on a node: phi(0) = 0
  xs[11] = qx;                          // squared distance 1e-12
  ys[11] = qy + 1e-6;
  long double reference[2] = {0.0L, 0.0L}, magnitude = 0.0L;
  for (size_t j = 0; j < kCount; ++j) {
    const long double dx = (long double)xs[j] - qx, dy = (long double)ys[j] - qy;
    const long double d = dx * dx + dy * dy;
    const long double phi = d > 0.0L ? d * std::log(d) : 0.0L;
    reference[0] += c0[j] * phi;
    reference[1] += c1[j] * phi;
    magnitude += std::fabs(phi);
  }
  auto check = [&](const char* name, auto&& sums_of) {
    double sums[2];
    sums_of(xs.data(), ys.data(), c0.data(), c1.data(), kCount, qx, qy, sums);
    for (int v = 0; v < 2; ++v) {
      EXPECT_NEAR(sums[v], double(reference[v]), 1e-14 * double(magnitude)) << name << " value " << v;
    }
  };
  check("four lanes", internal::KernelSums4);
  if (internal::HasAvx512()) check("eight lanes", internal::KernelSums8);
  std::printf("[ measured ] kernel widths checked: 4%s\n", internal::HasAvx512() ? " and 8 (AVX-512)" : "");
}

TEST(ThinPlateSplineTest, RefusesTooFewOrCollinearNodes) {
  const std::vector<Eigen::Vector2d> two{{0.0, 0.0}, {1.0, 1.0}};
  EXPECT_FALSE(ThinPlateSpline::Fit(two, two).has_value());
  std::vector<Eigen::Vector2d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(3.0 * i, 2.0 * i + 1.0);
  EXPECT_FALSE(ThinPlateSpline::Fit(line, line).has_value());
  std::vector<Eigen::Vector2d> same(5, Eigen::Vector2d(4.0, 4.0));
  EXPECT_FALSE(ThinPlateSpline::Fit(same, same).has_value());
  // Two coincident nodes make the system singular.
  std::vector<Eigen::Vector2d> dup{{0, 0}, {10, 0}, {0, 10}, {10, 10}, {10, 10}};
  std::vector<Eigen::Vector2d> vals{{0, 0}, {1, 0}, {0, 1}, {1, 1}, {2, 2}};
  EXPECT_FALSE(ThinPlateSpline::Fit(dup, vals).has_value());
  // A non-finite node.
  std::vector<Eigen::Vector2d> bad{{0, 0}, {10, 0}, {0, std::nan("")}};
  EXPECT_FALSE(ThinPlateSpline::Fit(bad, bad).has_value());
}

}  // namespace
}  // namespace gissar::geo
