#include "gissar/pipeline/mvg_commands.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <sstream>

#include "gissar/geo/raster_io.h"
#include "gissar/mvg/affine_camera.h"
#include "gissar/render/sar_renderer.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

// The mvg camera and the simulator's affine mode are the same model.
TEST(AffineCameraAgreementTest, MvgCameraEqualsSimulatorProjection) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> xy(-2000, 2000), z(-200, 900), angle(0, 360), dep(10, 80), res(0.3, 5);
  for (int trial = 0; trial < 50; ++trial) {
    sensor::SarGeometryOptions o;
    o.heading_deg = angle(rng);
    o.depression_deg = dep(rng);
    o.range_spacing_m = res(rng);
    o.azimuth_spacing_m = res(rng);
    o.look_side = trial % 2 ? sensor::LookSide::kLeft : sensor::LookSide::kRight;
    const Vector3d xc(xy(rng), xy(rng), z(rng));
    const sensor::SarGeometry g(o, xc, 512.5, 300.25, 1024, 600);
    mvg::SarPose pose;
    pose.heading_deg = o.heading_deg;
    pose.depression_deg = o.depression_deg;
    pose.look_side = trial % 2 ? mvg::LookSide::kLeft : mvg::LookSide::kRight;
    pose.range_spacing_m = o.range_spacing_m;
    pose.azimuth_spacing_m = o.azimuth_spacing_m;
    pose.scene_centre = xc;
    pose.u0 = 512.5;
    pose.v0 = 300.25;
    const mvg::AffineSarCamera camera(pose);
    for (int i = 0; i < 20; ++i) {
      const Vector3d p(xy(rng), xy(rng), z(rng));
      EXPECT_LT((camera.Project(p) - g.Project(p)).norm(), 0.01);
    }
    // Exact mode agrees within the far-field tolerance: R >= 100x the scene
    // size (here 100 m around Xc, R = 20 km, 1 m pixels: < 0.5 px).
    o.mode = sensor::ProjectionMode::kExact;
    o.slant_range_m = 20000;
    o.range_spacing_m = o.azimuth_spacing_m = 1.0;
    pose.range_spacing_m = pose.azimuth_spacing_m = 1.0;
    const sensor::SarGeometry exact(o, xc, 512.5, 300.25, 1024, 600);
    const mvg::AffineSarCamera unit(pose);
    std::uniform_real_distribution<double> near(-50, 50);
    const Vector3d p = xc + Vector3d(near(rng), near(rng), near(rng) * 0.5);
    EXPECT_LT((unit.Project(p) - exact.Project(p)).norm(), 0.5);
  }
}

void AddPlate(scene::TriangleMesh& mesh, const Vector3f& c, float s) {
  mesh.AddQuad(c + Vector3f(-s, -s, 0), c + Vector3f(s, -s, 0), c + Vector3f(s, s, 0), c + Vector3f(-s, s, 0));
}

// Centroids of the bright blobs of an image (4-connected, above a floor).
std::vector<Vector2d> DetectPeaks(const render::SarImage& image) {
  const float floor = 1e-3f * *std::max_element(image.intensity.begin(), image.intensity.end());
  std::vector<int> label(image.intensity.size(), -1);
  std::vector<Vector2d> peaks;
  for (size_t seed = 0; seed < image.intensity.size(); ++seed) {
    if (label[seed] >= 0 || image.intensity[seed] <= floor) continue;
    std::vector<size_t> stack{seed};
    label[seed] = static_cast<int>(peaks.size());
    double w = 0, wc = 0, wr = 0;
    while (!stack.empty()) {
      const size_t i = stack.back();
      stack.pop_back();
      const double v = image.intensity[i];
      w += v;
      wc += v * double(i % image.width);
      wr += v * double(i / image.width);
      const int c = int(i % image.width), r = int(i / image.width);
      for (auto [dc, dr] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        const int cc = c + dc, rr = r + dr;
        if (cc < 0 || rr < 0 || cc >= image.width || rr >= image.height) continue;
        const size_t j = size_t(rr) * image.width + cc;
        if (label[j] < 0 && image.intensity[j] > floor) {
          label[j] = label[seed];
          stack.push_back(j);
        }
      }
    }
    peaks.emplace_back(wc / w, wr / w);
  }
  return peaks;
}

// End to end: point targets (raised plates) simulated at headings 0 and 30
// deg (affine mode), found by peak detection, give the heading change with
// `fmatrix` and the pose of view 1 with `resect`.
TEST(MvgEndToEndTest, SimulatedTargetsGiveHeadingChangeAndPose) {
  const fs::path dir = testing::MakeTempDir();
  std::vector<Vector3d> targets;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> height(0.0, 80.0);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 4; ++j) targets.emplace_back(-240.0 + 120.0 * i, -180.0 + 120.0 * j, height(rng));
  scene::TriangleMesh mesh;
  for (const Vector3d& t : targets) AddPlate(mesh, t.cast<float>(), 1.0f);
  const render::EmbreeScene embree(mesh);
  render::RenderOptions ro;
  ro.rays_per_cell = 16;
  ro.max_bounces = 1;
  std::vector<sensor::SarGeometry> views;
  std::vector<std::vector<Vector2d>> detected(2);  // per view, per target
  for (double heading : {0.0, 30.0}) {
    sensor::SarGeometryOptions o;
    o.heading_deg = heading;
    o.depression_deg = 40.0;
    o.range_spacing_m = 1.0;
    o.azimuth_spacing_m = 1.0;
    views.push_back(sensor::SarGeometry(o, Vector3d::Zero(), 400, 400, 800, 800));
    const render::SarImage image = render::RenderSar(embree, mesh, material::MaterialTable(), views.back(), ro);
    const std::vector<Vector2d> peaks = DetectPeaks(image);
    ASSERT_EQ(peaks.size(), targets.size());
    std::vector<Vector2d>& labelled = detected[views.size() - 1];
    for (const Vector3d& t : targets) {
      const Vector2d predicted = views.back().Project(t);
      const auto nearest = std::min_element(peaks.begin(), peaks.end(), [&](const Vector2d& a, const Vector2d& b) {
        return (a - predicted).norm() < (b - predicted).norm();
      });
      EXPECT_LT((*nearest - predicted).norm(), 0.5);
      labelled.push_back(*nearest);
    }
  }
  {
    std::ofstream csv(dir / "matches.csv");
    csv.precision(10);
    csv << "id,x1,y1,x2,y2\n";
    for (size_t i = 0; i < targets.size(); ++i) {
      csv << i << "," << detected[0][i].x() << "," << detected[0][i].y() << "," << detected[1][i].x() << ","
          << detected[1][i].y() << "\n";
    }
    std::ofstream pts(dir / "points.csv");
    pts.precision(10);
    pts << "X,Y,Z,x,y\n";
    for (size_t i = 0; i < targets.size(); ++i) {
      pts << targets[i].x() << "," << targets[i].y() << "," << targets[i].z() << "," << detected[0][i].x() << ","
          << detected[0][i].y() << "\n";
    }
  }
  FmatrixRequest f;
  f.matches = (dir / "matches.csv").string();
  f.range_spacing_m = Vector2d(1, 1);
  f.azimuth_spacing_m = Vector2d(1, 1);
  f.depressions = Vector2d(40, 40);
  f.json_out = (dir / "f.json").string();
  const nlohmann::json fj = RunFmatrix(f, "test");
  EXPECT_NEAR(fj["heading_change_deg"].get<double>(), 30.0, 0.1);
  EXPECT_EQ(fj["inliers"].size(), targets.size());
  ResectRequest r;
  r.points = (dir / "points.csv").string();
  r.json_out = (dir / "r.json").string();
  const nlohmann::json rj = RunResect(r, "test");
  EXPECT_NEAR(rj["heading_deg"].get<double>(), 0.0, 0.05);
  EXPECT_NEAR(rj["depression_deg"].get<double>(), 40.0, 0.05);
  EXPECT_NEAR(rj["range_spacing_m"].get<double>(), 1.0, 0.005);
}

// The shared reference case through the command: F equals F_true.
TEST(FmatrixCommandTest, ReferenceCase2) {
  const fs::path dir = testing::MakeTempDir();
  FmatrixRequest f;
  f.matches = testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree_points.csv").string();
  f.depressions = Vector2d(40, 40);
  f.range_spacing_m = f.azimuth_spacing_m = Vector2d(1, 1);
  f.json_out = (dir / "f.json").string();
  const nlohmann::json out = RunFmatrix(f, "test");
  nlohmann::json ref;
  std::ifstream(testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree.json")) >> ref;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out["F"][r][c].get<double>(), ref["F_true"][r][c].get<double>(), 1e-10);
  EXPECT_NEAR(out["heading_change_deg"].get<double>(), 30.0, 1e-6);
  EXPECT_NEAR(out["kvd"]["theta_deg"].get<double>(), 23.198952052312735, 1e-7);
  EXPECT_FALSE(fs::exists(dir / "f_kvd.png"));  // pictures only with --plot
}

// --plot: the KvD diagram, and with the images the epipolar picture.
TEST(FmatrixCommandTest, PlotsTheKvdDiagramAndTheEpipolarPair) {
  const fs::path dir = testing::MakeTempDir();
  const int w = 1024, h = 1024;
  std::vector<float> image(size_t(w) * h);
  for (size_t i = 0; i < image.size(); ++i) image[i] = 1.0f + float(i % 37) * 0.1f;
  geo::WriteFloatGeoTiff(dir / "a.tif", {w, h, {image}, {}, {}});
  FmatrixRequest f;
  f.matches = testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree_points.csv").string();
  f.depressions = Vector2d(40, 40);
  f.range_spacing_m = f.azimuth_spacing_m = Vector2d(1, 1);
  f.json_out = (dir / "f.json").string();
  f.plot_prefix = (dir / "f").string();
  f.image1 = f.image2 = (dir / "a.tif").string();
  const nlohmann::json out = RunFmatrix(f, "test");
  ASSERT_EQ(out["pictures"].size(), 2u);
  int pw = 0, ph = 0;
  geo::ReadByteRaster(dir / "f_kvd.png", &pw, &ph);
  EXPECT_EQ(pw, 420);  // image/annotated.cc: 420 x 460 canvas
  EXPECT_EQ(ph, 460);
  geo::ReadByteRaster(dir / "f_epipolar.png", &pw, &ph);
  EXPECT_EQ(pw, 2 * w + 10);
  EXPECT_EQ(ph, h);
  // An image without --plot is a configuration error.
  f.plot_prefix.clear();
  EXPECT_THROW(RunFmatrix(f, "test"), ConfigError);
}

// Two outputs resolving to one file (the JSON named like the plot's
// PREFIX_kvd.png or PREFIX_epipolar.png, also through a link or another
// spelling) are a ConfigError naming both flags, and nothing is written.
TEST(FmatrixCommandTest, OutputsNamingTheSameFileAreAConfigErrorNamingBothFlags) {
  const fs::path dir = testing::MakeTempDir();
  const int w = 64, h = 64;
  geo::WriteFloatGeoTiff(dir / "a.tif", {w, h, {std::vector<float>(size_t(w) * h, 1.0f)}, {}, {}});
  FmatrixRequest f;
  f.matches = testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree_points.csv").string();
  f.plot_prefix = (dir / "OUT").string();
  auto expect_collision = [&](const std::string& json_out, const std::string& what) {
    f.json_out = json_out;
    try {
      RunFmatrix(f, "test");
      ADD_FAILURE() << what << ": expected ConfigError";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.where(), "--out/--plot") << what;
      EXPECT_NE(e.message().find("--out and --plot name the same file"), std::string::npos) << e.message();
    }
  };
  expect_collision((dir / "OUT_kvd.png").string(), "JSON over the KvD diagram");
  expect_collision((dir / "sub" / ".." / "OUT_kvd.png").string(), "another spelling");
  f.image1 = f.image2 = (dir / "a.tif").string();
  expect_collision((dir / "OUT_epipolar.png").string(), "JSON over the epipolar picture");
  f.image1 = f.image2 = "";
  // A link to the KvD diagram of an earlier run: the same file too.
  std::ofstream(dir / "OUT_kvd.png") << "earlier";
  fs::create_symlink(dir / "OUT_kvd.png", dir / "link.json");
  expect_collision((dir / "link.json").string(), "a link");
  std::ifstream earlier(dir / "OUT_kvd.png");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(earlier), {}), "earlier");
  size_t entries = 0;
  for (auto it = fs::directory_iterator(dir); it != fs::directory_iterator(); ++it) ++entries;
  EXPECT_EQ(entries, 3u);  // a.tif, OUT_kvd.png, link.json: nothing new
  // Distinct names are fine.
  f.json_out = (dir / "OUT.json").string();
  EXPECT_TRUE(RunFmatrix(f, "test")["converged"].get<bool>());
}

// Matches of two unrelated point sets: RANSAC finds an F with a few
// inliers, but no more than chance gives, so there is no result: the JSON
// says converged false and why, with the consensus figures; no F, no
// heading change, no pictures.
TEST(FmatrixCommandTest, UnrelatedMatchesAreNoResult) {
  const fs::path dir = testing::MakeTempDir();
  {
    std::mt19937 rng(40);
    std::uniform_real_distribution<double> coordinate(0.0, 1000.0);
    std::ofstream csv(dir / "random.csv");
    csv.precision(10);
    csv << "x1,y1,x2,y2\n";
    for (int i = 0; i < 40; ++i) {
      const double x1 = coordinate(rng), y1 = coordinate(rng), x2 = coordinate(rng), y2 = coordinate(rng);
      csv << x1 << "," << y1 << "," << x2 << "," << y2 << "\n";
    }
  }
  FmatrixRequest f;
  f.matches = (dir / "random.csv").string();
  f.range_spacing_m = f.azimuth_spacing_m = Vector2d(1, 1);
  f.depressions = Vector2d(40, 40);
  f.json_out = (dir / "f.json").string();
  f.plot_prefix = (dir / "f").string();
  const nlohmann::json out = RunFmatrix(f, "test");
  EXPECT_FALSE(out["converged"].get<bool>());
  EXPECT_NE(out["reason"].get<std::string>().find("no consensus better than chance"), std::string::npos)
      << out["reason"];
  const nlohmann::json& c = out["consensus"];
  EXPECT_GE(c["inliers"].get<int>(), 5);  // what RANSAC alone accepted
  EXPECT_FALSE(c["significant"].get<bool>());
  EXPECT_GT(c["p_value"].get<double>(), c["alpha"].get<double>() / c["hypotheses"].get<double>());
  EXPECT_TRUE(c["required"].is_null() || c["required"].get<int>() > c["inliers"].get<int>());
  EXPECT_GT(c["expected_by_chance"].get<double>(), 4.0);
  EXPECT_FALSE(out.contains("F"));
  EXPECT_FALSE(out.contains("heading_change_deg"));
  nlohmann::json written;
  std::ifstream(dir / "f.json") >> written;
  EXPECT_EQ(written, out);
  EXPECT_FALSE(fs::exists(dir / "f_kvd.png"));
}

// The reference cases (50 noise-free matches; 200 with noise and 30
// outliers) are far beyond chance.
TEST(FmatrixCommandTest, ReferenceCasesHaveASignificantConsensus) {
  const fs::path dir = testing::MakeTempDir();
  for (const char* name : {"affine/case2_thesis_dpsi30_dep40_noisefree_points.csv",
                           "affine/case3_dpsi30_dep40_45_res1_0.75_points.csv"}) {
    FmatrixRequest f;
    f.matches = testing::TestDataPath(name).string();
    f.json_out = (dir / "f.json").string();
    const nlohmann::json out = RunFmatrix(f, "test");
    EXPECT_TRUE(out["converged"].get<bool>()) << name;
    EXPECT_TRUE(out["reason"].is_null()) << name;
    const nlohmann::json& c = out["consensus"];
    EXPECT_TRUE(c["significant"].get<bool>()) << name;
    EXPECT_EQ(c["inliers"].get<size_t>(), out["inliers"].size()) << name;
    EXPECT_LT(c["p_value"].get<double>(), 1e-30) << name;
    EXPECT_LT(c["required"].get<int>(), 20) << name;
  }
  // One fit to all matches tests no hypothesis.
  FmatrixRequest f;
  f.matches = testing::TestDataPath("affine/case2_thesis_dpsi30_dep40_noisefree_points.csv").string();
  f.json_out = (dir / "g.json").string();
  f.robust = false;
  const nlohmann::json out = RunFmatrix(f, "test");
  EXPECT_TRUE(out["converged"].get<bool>());
  EXPECT_TRUE(out["consensus"].is_null());
}

TEST(RegisterCommandTest, RecoversAKnownAffineWarp) {
  const fs::path dir = testing::MakeTempDir();
  // A synthetic image pair: moving = fixed warped by a known affine map.
  const int w = 120, h = 100;
  std::vector<float> fixed(size_t(w) * h), moving(size_t(w) * h);
  auto pattern = [](double x, double y) { return float(1.0 + 0.5 * std::sin(x * 0.21) * std::cos(y * 0.17)); };
  Eigen::Matrix2d A;
  A << 0.98, 0.05, -0.04, 1.02;
  const Vector2d t(3.5, -2.0);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      fixed[size_t(r) * w + c] = pattern(c, r);
      const Vector2d f = A.inverse() * (Vector2d(c, r) - t);  // moving pixel -> fixed pixel
      moving[size_t(r) * w + c] = pattern(f.x(), f.y());
    }
  geo::WriteFloatGeoTiff(dir / "fixed.tif", {w, h, {fixed}, {}, {}});
  geo::WriteFloatGeoTiff(dir / "moving.tif", {w, h, {moving}, {}, {}});
  {
    std::ofstream csv(dir / "cp.csv");
    csv << "x1,y1,x2,y2\n";
    for (const Vector2d& p : {Vector2d(10, 10), Vector2d(100, 15), Vector2d(20, 90), Vector2d(95, 85), Vector2d(60, 50),
                             Vector2d(30, 60)}) {
      const Vector2d m = A * p + t;
      csv << p.x() << "," << p.y() << "," << m.x() << "," << m.y() << "\n";
    }
  }
  RegisterRequest o;
  o.fixed = (dir / "fixed.tif").string();
  o.moving = (dir / "moving.tif").string();
  o.points = (dir / "cp.csv").string();
  o.out_prefix = (dir / "reg").string();
  const nlohmann::json out = RunRegister(o, "test");
  EXPECT_LT(out["rms_px"].get<double>(), 1e-6);
  const auto reg = geo::ReadFloatRaster(dir / "reg.tif");
  double err = 0;
  int n = 0;
  for (int r = 20; r < 80; ++r)
    for (int c = 20; c < 100; ++c) {
      err += std::abs(reg.bands[0][size_t(r) * w + c] - fixed[size_t(r) * w + c]);
      ++n;
    }
  EXPECT_LT(err / n, 0.01);
  EXPECT_TRUE(fs::exists(dir / "reg_composite.png"));
}

}  // namespace
}  // namespace gissar::pipeline

namespace gissar::pipeline {
namespace {

TEST(EpipolarCommandTest, DrawsThePair) {
  const fs::path dir = testing::MakeTempDir();
  const int w = 1024, h = 1024;
  std::vector<float> image(size_t(w) * h);
  for (size_t i = 0; i < image.size(); ++i) image[i] = 1.0f + float(i % 37) * 0.1f;
  geo::WriteFloatGeoTiff(dir / "a.tif", {w, h, {image}, {}, {}});
  EpipolarRequest o;
  o.matches = testing::TestDataPath("affine/case3_dpsi30_dep40_45_res1_0.75_points.csv").string();
  o.image1 = o.image2 = (dir / "a.tif").string();
  o.out_png = (dir / "epi.png").string();
  RunEpipolar(o);
  int pw = 0, ph = 0;
  geo::ReadByteRaster(dir / "epi.png", &pw, &ph);
  EXPECT_EQ(pw, 2 * w + 10);
  EXPECT_EQ(ph, h);
}

}  // namespace
}  // namespace gissar::pipeline
