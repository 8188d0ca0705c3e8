#include "gissar/pipeline/image_probe_testing.h"
#include "gissar/pipeline/simulate_door.h"
#include "gissar/pipeline/scene_build.h"
#include "gissar/pipeline/scene_build_fields.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>

#include "gissar/pipeline/simulate.h"
#include "gissar/geo/dem.h"
#include "gissar/geo/local_frame.h"
#include "gissar/geo/raster_io.h"
#include "gissar/material/material.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

// Flat ground at 100 m, 1 km x 1 km, 10 m posts, in a local transverse
// Mercator CRS (map metres = ENU metres near the origin).
const char* kLocalTm =
    "+proj=tmerc +lat_0=42.5 +lon_0=1.6 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";

std::string FlatDem(const fs::path& dir) {
  const auto path = dir / "flat.tif";
  geo::WriteDemGeoTiff(path, std::vector<float>(101 * 101, 100.0f), 101, 101,
                       {-505.0, 10.0, 0.0, 505.0, 0.0, -10.0}, kLocalTm);
  return path.string();
}

// A GeoJSON file (WGS84) with one feature given in local TM metres.
std::string GeoJson(const fs::path& path, const std::string& type, std::vector<Eigen::Vector2d> pts,
                    const std::string& properties = "{}") {
  const geo::CrsTransform tm(kLocalTm);
  std::vector<double> x, y;
  for (const auto& p : pts) {
    x.push_back(p.x());
    y.push_back(p.y());
  }
  tm.ToLonLat(x, y);
  std::ostringstream coords;
  coords.precision(12);
  coords << "[";
  for (size_t i = 0; i < x.size(); ++i) coords << (i ? "," : "") << "[" << x[i] << "," << y[i] << "]";
  coords << "]";
  std::ofstream(path) << R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":)"
                      << properties << R"(,"geometry":{"type":")" << type << R"(","coordinates":)"
                      << (type == "Polygon" ? "[" + coords.str() + "]" : coords.str()) << "}}]}";
  return path.string();
}

SceneBuildRequest BuildOptions(const std::string& dem, const std::string& config, const fs::path& out) {
  SceneBuildRequest o;
  o.dem = dem;
  o.config = config;
  o.out_prefix = (out / "scene").string();
  o.vertical_datum = "ellipsoid";  // the flat DEM's CRS names none: no warning
  return o;
}

geo::FloatRaster Simulate(const std::string& scene, const fs::path& out, double spacing) {
  SimulateRequest o;
  o.scene = scene;
  o.geometry.heading_deg = 0.0;
  o.geometry.depression_deg = 40.0;
  o.geometry.range_spacing_m = spacing;
  o.geometry.azimuth_spacing_m = spacing;
  o.out_prefix = (out / "sim").string();
  RunSimulate(o, "test");
  return geo::ReadFloatRaster(out / "sim.tif");
}

// A flat scene with a water square: the water is darker than the ground by
// exactly the ratio of the materials' backscatter at 50 deg incidence.
TEST(SceneBuildTest, WaterIsDarkerByTheMaterialRatio) {
  const fs::path dir = testing::MakeTempDir();
  const std::string water = GeoJson(dir / "water.geojson", "Polygon",
                                    {{-150, -150}, {150, -150}, {150, 150}, {-150, 150}, {-150, -150}});
  std::ofstream(dir / "config.json") << R"({"layers": [{"path": "water.geojson", "class": "water"}]})";
  RunSceneBuild(BuildOptions(FlatDem(dir), (dir / "config.json").string(), dir), "test");
  const geo::FloatRaster image = Simulate((dir / "scene.gscene").string(), dir, 5.0);
  auto mean = [&](double x_m, double y_m) { return MeanAroundGroundPoint(image, x_m, y_m, 40.0, 5.0); };
  // The image is sigma0 (docs/radiometry.md): flat ground reads its class's
  // law at the incidence 50 deg, X band (0.031 m), VV.
  const double cos_inc = std::sin(40 * M_PI / 180);
  auto sigma0 = [&](scene::ClassId id) {
    return material::DefaultMaterial(id).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  };
  const double expected_ratio = sigma0(scene::kClassWater) / sigma0(scene::kClassDefault);
  const double ground = mean(-350, 0), water_level = mean(0, 0);
  EXPECT_NEAR(ground, sigma0(scene::kClassDefault), 0.01 * ground);
  EXPECT_NEAR(water_level / ground, expected_ratio, 0.02 * expected_ratio);
}

// A 20 m road running north (along track for heading 0) at x = 100 m
// appears as a dark strip of 20 cos(40 deg) / 2 = 7.7 columns at the
// predicted column.
TEST(SceneBuildTest, RoadStripAppearsWhereItsGeometryPredicts) {
  const fs::path dir = testing::MakeTempDir();
  GeoJson(dir / "road.geojson", "LineString", {{100, -400}, {100, 400}}, R"({"highway": "primary"})");
  std::ofstream(dir / "config.json")
      << R"({"layers": [{"path": "road.geojson", "class": "road", "geometry": "line", "width_m": 20}]})";
  RunSceneBuild(BuildOptions(FlatDem(dir), (dir / "config.json").string(), dir), "test");
  const double spacing = 2.0;
  const geo::FloatRaster image = Simulate((dir / "scene.gscene").string(), dir, spacing);
  const double u0 = std::stod(image.metadata.at("GISSAR_U0")), v0 = std::stod(image.metadata.at("GISSAR_V0"));
  const int row = int(v0);
  const double cos_inc = std::sin(40 * M_PI / 180);
  const double ground =
      material::DefaultMaterial(scene::kClassDefault).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  const double road = material::DefaultMaterial(scene::kClassRoad).Sigma0(cos_inc, 0.031, material::Polarization::kVV);
  const double threshold = 0.5 * (ground + road);
  int dark = 0;
  double first = -1, last = -1;
  const double predicted_centre = u0 + 100.0 * std::cos(40 * M_PI / 180) / spacing;
  // Search +-30 px around it (away from the scene's own edges).
  for (int c = int(predicted_centre) - 30; c <= int(predicted_centre) + 30; ++c) {
    const double v = image.bands[0][size_t(row) * image.width + c];
    if (v > 0 && v < threshold) {
      ++dark;
      if (first < 0) first = c;
      last = c;
    }
  }
  const double width_px = 20.0 * std::cos(40 * M_PI / 180) / spacing;
  EXPECT_NEAR(dark, width_px, 1.0);
  EXPECT_NEAR(0.5 * (first + last), predicted_centre, 0.75);
  EXPECT_NEAR(image.bands[0][size_t(row) * image.width + int(std::lround(predicted_centre))], road, 0.02 * road);
}

TEST(SceneBuildTest, AndorraSceneBuildsAndSimulates) {
  const fs::path dir = testing::MakeTempDir();
  SceneBuildRequest o;
  o.dem = testing::DataPath("andorra/andorra_srtm3_dem_filled.tif").string();
  o.vectors = {testing::DataPath("andorra/andorra_osm.gpkg").string()};
  o.out_prefix = (dir / "andorra").string();
  o.export_obj = true;
  const SceneBuildResult result = RunSceneBuild(o, "test");
  ASSERT_EQ(result.outputs.size(), 8u);  // .gscene .ply _classes.png _3d.png .json _mesh.json .obj .mtl
  for (const auto& p : result.outputs) EXPECT_GT(fs::file_size(p), 100u) << p;
  {
    // The OBJ names its MTL by the final name (not AtomicOutputs' temporary
    // one) and holds every triangle once.
    std::ifstream obj(o.out_prefix + ".obj");
    std::string line;
    int64_t faces = 0, vertices = 0;
    bool mtllib = false;
    while (std::getline(obj, line)) {
      mtllib = mtllib || line == "mtllib andorra.mtl";
      faces += line.rfind("f ", 0) == 0;
      vertices += line.rfind("v ", 0) == 0;
    }
    EXPECT_TRUE(mtllib);
    EXPECT_EQ(faces, result.summary["stats"]["triangles"].get<int64_t>());
    EXPECT_EQ(vertices, result.summary["stats"]["vertices"].get<int64_t>());
    std::ifstream mtl(o.out_prefix + ".mtl");
    std::stringstream text;
    text << mtl.rdbuf();
    EXPECT_NE(text.str().find("newmtl water\nKd"), std::string::npos);
    int w = 0, h = 0;
    geo::ReadByteRaster(o.out_prefix + "_3d.png", &w, &h);
    EXPECT_EQ(w, 960);
    EXPECT_EQ(h, 640);
  }
  const auto& classes = result.summary["stats"]["classes"];
  EXPECT_GT(classes["water"]["triangles"].get<int64_t>(), 100);
  EXPECT_GT(classes["road"]["triangles"].get<int64_t>(), 1000);
  EXPECT_GT(result.summary["peak_rss_bytes"].get<int64_t>(), 0);
  std::ostringstream info;
  PrintSceneInfo(o.out_prefix + ".gscene", info);
  EXPECT_NE(info.str().find("road"), std::string::npos);
  EXPECT_NE(info.str().find("triangles  " + std::to_string(result.summary["stats"]["triangles"].get<int64_t>())),
            std::string::npos) << info.str();
  const geo::FloatRaster image = Simulate(o.out_prefix + ".gscene", dir, 120.0);
  double sum = 0;
  for (float v : image.bands[0]) if (!std::isnan(v)) sum += v;  // NaN: outside the footprint
  EXPECT_GT(sum, 0);
}

// A reflectors CSV row at local TM (x, y) metres of kLocalTm.
std::string ReflectorRow(const std::string& type, double x_m, double y_m, double apex_height_m, double size_m,
                         double azimuth_deg, double elevation_deg) {
  std::vector<double> x{x_m}, y{y_m};
  geo::CrsTransform(kLocalTm).ToLonLat(x, y);
  std::ostringstream row;
  row.precision(12);
  row << type << "," << x[0] << "," << y[0] << "," << apex_height_m << "," << size_m << "," << azimuth_deg << ","
      << elevation_deg << "\n";
  return row.str();
}

constexpr const char* kReflectorHeader =
    "type,lon,lat,apex_height_m,size_m,boresight_azimuth_deg,boresight_elevation_deg\n";

// Issue 17: reflectors as scene objects. `scene build --reflectors` places a
// trihedral (a = 1 m) on the flat scene's ground (100 m) and stores it;
// `simulate --scene` renders it without the CSV at C band (5.55 cm): its
// response integrates to 4 pi a^4 / (3 lambda^2) = 1359.6 m2 (31.33 dB m2)
// within 1.5 dB (the ground a -80 dB table: negligible). A `--reflectors` on
// simulate adds a second one: the triple-bounce band then integrates to
// twice that. `scene info` lists the stored reflector.
TEST(SceneBuildTest, ReflectorsAreStoredInTheSceneAndRendered) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path csv = dir / "reflectors.csv";
  // Heading 0, looking right (east): the sensor lies west, 40 deg up.
  std::ofstream(csv) << kReflectorHeader << ReflectorRow("trihedral", -100.0, 50.0, 0.4, 1.0, 270.0, 40.0);
  SceneBuildRequest build = BuildOptions(FlatDem(dir), "", dir);
  build.reflectors = csv.string();
  const SceneBuildResult built = RunSceneBuild(build, "test");
  EXPECT_EQ(built.summary["stats"]["reflectors"], 1);
  const std::string scene_path = build.out_prefix + ".gscene";
  const scene::SceneFile file = scene::ReadScene(scene_path);
  ASSERT_EQ(file.reflectors.size(), 1u);
  EXPECT_EQ(file.reflectors[0].type, "trihedral");
  EXPECT_EQ(file.reflectors[0].row, 1);
  EXPECT_EQ(file.reflectors[0].source, "reflectors.csv");
  // On the ground (100 m, ENU z within the frame's curvature at 112 m from
  // the origin: 1 mm) plus the apex height.
  EXPECT_NEAR(file.reflectors[0].apex_enu.x(), -100.0, 0.05);
  EXPECT_NEAR(file.reflectors[0].apex_enu.y(), 50.0, 0.05);
  EXPECT_NEAR(file.reflectors[0].apex_enu.z(), 100.4, 0.01);
  std::ostringstream info;
  PrintSceneInfo(scene_path, info);
  EXPECT_NE(info.str().find("reflectors 1"), std::string::npos) << info.str();
  EXPECT_NE(info.str().find("trihedral"), std::string::npos) << info.str();
  EXPECT_NE(info.str().find("reflectors.csv row 1"), std::string::npos) << info.str();

  const fs::path materials = dir / "dark.json";
  std::ofstream(materials) << R"({"default": {"sigma0_db": [[0, -80], [90, -80]]}})";
  constexpr double kC = 0.0555;
  const double closed_form = 4.0 * M_PI / (3.0 * kC * kC);
  auto simulate = [&](const std::string& extra_csv, const std::string& name) {
    SimulateRequest o;
    o.scene = scene_path;
    o.materials = materials.string();
    o.reflectors = extra_csv;
    o.geometry.heading_deg = 0.0;
    o.geometry.depression_deg = 40.0;
    o.geometry.range_spacing_m = 2.0;
    o.geometry.azimuth_spacing_m = 2.0;
    o.wavelength_m = kC;
    o.radiometry = "beta0";
    o.range_resolution_m = 5.0;
    o.azimuth_resolution_m = 5.0;
    o.out_prefix = (dir / name).string();
    RunSimulate(o, "test");
    return geo::ReadFloatRaster(dir / (name + ".tif"));
  };
  // RCS (m2) of band `band` summed over `half` pixels around its peak (the
  // whole image for half < 0).
  auto integrated = [](const geo::FloatRaster& image, int band, int half) {
    const std::vector<float>& v = image.bands[size_t(band)];
    size_t peak = 0;
    for (size_t i = 0; i < v.size(); ++i) if (!std::isnan(v[i]) && (std::isnan(v[peak]) || v[i] > v[peak])) peak = i;
    const int pc = int(peak % image.width), pr = int(peak / image.width);
    double sum = 0.0;
    for (int r = 0; r < image.height; ++r) {
      for (int c = 0; c < image.width; ++c) {
        if (half >= 0 && (std::abs(r - pr) > half || std::abs(c - pc) > half)) continue;
        const float x = v[size_t(r) * image.width + c];
        if (!std::isnan(x)) sum += x;
      }
    }
    return sum * 2.0 * 2.0;
  };
  const geo::FloatRaster one = simulate("", "stored");
  const double stored_db = 10.0 * std::log10(integrated(one, 0, 40));
  std::printf("trihedral a = 1 m stored in the scene, C band: %.2f dB m2 (closed form %.2f)\n", stored_db,
              10.0 * std::log10(closed_form));
  EXPECT_NEAR(stored_db, 10.0 * std::log10(closed_form), 1.5);
  // Where the geometry puts it: column u0 + (x cos 40 + 0.4 sin 40... ) the
  // apex's slant-range offset, row v0 + y / 2.
  const double u0 = std::stod(one.metadata.at("GISSAR_U0")), v0 = std::stod(one.metadata.at("GISSAR_V0"));
  size_t peak = 0;
  for (size_t i = 0; i < one.bands[3].size(); ++i) {
    if (!std::isnan(one.bands[3][i]) && !(one.bands[3][i] <= one.bands[3][peak])) peak = i;
  }
  EXPECT_NEAR(double(peak % one.width), u0 + (-100.0 * std::cos(40 * M_PI / 180) - 0.4 * std::sin(40 * M_PI / 180)) / 2.0, 1.0);
  EXPECT_NEAR(double(peak / one.width), v0 + 50.0 / 2.0, 1.0);

  const fs::path extra = dir / "extra.csv";
  std::ofstream(extra) << kReflectorHeader << ReflectorRow("trihedral", 150.0, -120.0, 0.4, 1.0, 270.0, 40.0);
  const geo::FloatRaster two = simulate(extra.string(), "two");
  const double both_db = 10.0 * std::log10(integrated(two, 3, -1));
  std::printf("stored + simulate --reflectors: triple band %.2f dB m2 (twice the closed form %.2f)\n", both_db,
              10.0 * std::log10(2.0 * closed_form));
  EXPECT_NEAR(both_db, 10.0 * std::log10(2.0 * closed_form), 1.5);
  nlohmann::json sidecar;
  std::ifstream(dir / "two.json") >> sidecar;
  EXPECT_EQ(sidecar["radiometry"]["reflector_returns"], 2);
  EXPECT_EQ(sidecar["terrain"]["reflectors"], 1);
}

// Bad reflector rows on `scene build`: exit-2 errors naming the file and the
// row (an unknown type before the DEM is read; a row off the DEM once the
// scene is built), and nothing is written.
TEST(SceneBuildTest, BadReflectorRowsAreErrorsNamingTheRow) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  const fs::path out = dir / "out";
  fs::create_directory(out);
  const fs::path csv = dir / "bad.csv";
  SceneBuildRequest build = BuildOptions(dem, "", out);
  build.reflectors = csv.string();
  std::ofstream(csv) << kReflectorHeader << ReflectorRow("trihedral", 0, 0, 0, 1, 270, 40)
                     << ReflectorRow("cone", 0, 0, 0, 1, 270, 40);
  try {
    RunSceneBuild(build, "test");
    FAIL() << "an unknown type";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown reflector type 'cone'"), std::string::npos) << e.what();
    EXPECT_NE(e.where().find("bad.csv row 2"), std::string::npos) << e.where();
  }
  std::ofstream(csv) << kReflectorHeader << ReflectorRow("trihedral", 0, 0, 0, 1, 270, 40)
                     << ReflectorRow("plate", 5000, 0, 0, 1, 270, 40);
  try {
    RunSceneBuild(build, "test");
    FAIL() << "a reflector off the DEM";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("outside the terrain"), std::string::npos) << e.what();
    EXPECT_NE(e.where().find("bad.csv row 2"), std::string::npos) << e.where();
  }
  EXPECT_TRUE(fs::is_empty(out));
}

TEST(SceneBuildTest, BadVectorInputGivesClearErrorsOrCountedWarnings) {
  const fs::path dir = testing::MakeTempDir();
  const std::string dem = FlatDem(dir);
  const std::string gpkg = testing::DataPath("andorra/andorra_osm.gpkg").string();
  auto config = [&](const std::string& text) {
    std::ofstream(dir / "c.json") << text;
    return (dir / "c.json").string();
  };
  // Missing layer: names file and the layers there are.
  try {
    RunSceneBuild(BuildOptions(dem, config(R"({"layers": [{"path": ")" + gpkg + R"(", "layer": "lakes", "class": "water"}]})"), dir), "t");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(e.message().find("no layer 'lakes'"), std::string::npos) << e.what();
    EXPECT_EQ(e.where(), gpkg);
  }
  // Unknown class: names key and file.
  try {
    RunSceneBuild(BuildOptions(dem, config(R"({"layers": [{"path": "x.gpkg", "class": "glacier"}]})"), dir), "t");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(e.message().find("unknown class 'glacier' at 'layers[0].class'"), std::string::npos) << e.what();
    EXPECT_EQ(e.where(), (dir / "c.json").string());
  }
  // Andorra polygons lie entirely outside this synthetic DEM: counted
  // warnings, and the scene is still written.
  const auto result = RunSceneBuild(
      BuildOptions(dem, config(R"({"layers": [{"path": ")" + gpkg + R"(", "layer": "water", "class": "water"}]})"), dir), "t");
  ASSERT_EQ(result.summary["warnings"].size(), 1u);
  EXPECT_NE(result.summary["warnings"][0].get<std::string>().find("89 features outside the DEM"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "scene.gscene"));
}

// The PLY/OBJ meshes say where they are: header comments and
// PREFIX_mesh.json give the ENU frame's origin and a PROJ pipeline that takes
// mesh coordinates to WGS84; applied by PROJ, it puts the mesh's vertices
// back on the DEM posts they came from (map position and height).
TEST(SceneBuildTest, MeshExportsCarryOriginAndCrs) {
  const fs::path dir = testing::MakeTempDir();
  std::ofstream(dir / "config.json") << R"({"layers": []})";
  SceneBuildRequest o = BuildOptions(FlatDem(dir), (dir / "config.json").string(), dir);
  o.export_obj = true;
  RunSceneBuild(o, "test");
  nlohmann::json crs;
  std::ifstream(o.out_prefix + "_mesh.json") >> crs;
  const std::string pipeline = crs.at("proj_pipeline_to_wgs84").get<std::string>();
  // The DEM's centre (map 0, 0) is the frame origin: lon_0 = 1.6, lat_0 = 42.5.
  EXPECT_NEAR(crs.at("origin_lon_deg").get<double>(), 1.6, 1e-9);
  EXPECT_NEAR(crs.at("origin_lat_deg").get<double>(), 42.5, 1e-9);
  for (const char* suffix : {".ply", ".obj"}) {
    std::ifstream file(o.out_prefix + suffix, std::ios::binary);
    std::string header((std::istreambuf_iterator<char>(file)), {});
    header = header.substr(0, 2000);
    EXPECT_NE(header.find("origin_lon_deg 1.6"), std::string::npos) << suffix;
    EXPECT_NE(header.find(pipeline), std::string::npos) << suffix;
  }
  const scene::SceneFile scene = scene::ReadScene(o.out_prefix + ".gscene");
  // Vertices at the DEM's corner and centre posts: map (-500, 500), (0, 0), (500, -500), height 100.
  std::vector<Eigen::Vector3d> enu;
  std::vector<Eigen::Vector2d> want;
  for (const Eigen::Vector2d& m : {Eigen::Vector2d(-500, 500), Eigen::Vector2d(0, 0), Eigen::Vector2d(500, -500)}) {
    double best = 1e9;
    Eigen::Vector3d pick;
    for (const auto& v : scene.mesh.vertices) {
      // ENU ~ local TM near the origin (within 0.1 m over 1 km): find the post.
      const double d = (v.head<2>().cast<double>() - m).norm();
      if (d < best) best = d, pick = v.cast<double>();
    }
    ASSERT_LT(best, 1.0);
    enu.push_back(pick);
    want.push_back(m);
  }
  const std::vector<Eigen::Vector3d> geodetic = geo::ApplyProjPipeline(pipeline, enu);
  const geo::CrsTransform tm(kLocalTm);
  std::vector<double> x, y;
  for (const auto& g : geodetic) x.push_back(g.x()), y.push_back(g.y());
  tm.FromLonLat(x, y);
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_NEAR(x[i], want[i].x(), 0.01) << i;
    EXPECT_NEAR(y[i], want[i].y(), 0.01) << i;
    EXPECT_NEAR(geodetic[i].z(), 100.0, 0.01) << i;  // the DEM's height, ellipsoidal
  }
}

// Records the warnings of a run.
struct WarningRecorder : Reporter {
  std::vector<std::string> warnings;
  void Warn(const std::string& line) override { warnings.push_back(line); }
};

// 21 x 21 posts of 0.0005 deg centred on (1.6 E, 42.5 N): heights 100 m, the
// five western columns -5 m (below the 0 m sea level, on the border).
std::string CoastDem(const fs::path& path, const std::string& crs) {
  std::vector<float> h(21 * 21, 100.0f);
  for (int r = 0; r < 21; ++r) {
    for (int c = 0; c < 5; ++c) h[size_t(r) * 21 + c] = -5.0f;
  }
  geo::WriteDemGeoTiff(path, h, 21, 21, {1.6 - 10.5 * 0.0005, 0.0005, 0.0, 42.5 + 10.5 * 0.0005, 0.0, -0.0005}, crs);
  return path.string();
}

// EGM96 undulation at (1.6 E, 42.5 N): PROJ's `cct +proj=vgridshift
// +grids=egm96_15.gtx` gives 52.7906 m.
constexpr double kN = 52.7906;

// A DEM tagged EPSG:4326+5773 is egm96 by default: the scene is raised by N,
// the sea rule still sees the orthometric heights (-5 m is sea), and the
// scene keeps the datum; an untagged DEM is ellipsoid with one warning.
TEST(SceneBuildTest, VerticalDatumFromTheFileRaisesTheSceneAndIsKept) {
  const fs::path dir = testing::MakeTempDir();
  SceneBuildRequest o;
  o.dem = CoastDem(dir / "egm96.tif", "EPSG:4326+5773");
  o.out_prefix = (dir / "egm96").string();
  WarningRecorder quiet;
  const SceneBuildResult built = RunSceneBuild(o, "test", quiet);
  EXPECT_TRUE(quiet.warnings.empty());
  EXPECT_EQ(built.summary["vertical_datum"]["datum"], "egm96");
  EXPECT_EQ(built.summary["vertical_datum"]["source"], "file");
  EXPECT_EQ(built.summary["stats"]["sea_from_dem"], true);
  const scene::SceneFile file = scene::ReadScene(dir / "egm96.gscene");
  EXPECT_EQ(file.provenance["vertical_datum"], "egm96");
  EXPECT_NEAR(file.centre_height_m, 100.0 + kN, 0.01);
  // Every vertex lies at its orthometric height + N: 100 + N on land, and
  // the sea (the -5 m posts, whose surface is flattened to the 0 m sea
  // level) at 0 + N.
  const geo::LocalFrame frame(file.origin_lon_deg, file.origin_lat_deg, 0.0);
  int sea_level = 0, land = 0;
  for (const Eigen::Vector3f& v : file.mesh.vertices) {
    const double h = frame.GeodeticFromEnu(v.cast<double>()).z();
    if (std::abs(h - (0.0 + kN)) < 0.05) ++sea_level;
    else if (std::abs(h - (100.0 + kN)) < 0.05) ++land;
  }
  EXPECT_EQ(sea_level, 5 * 21);
  EXPECT_EQ(sea_level + land, int(file.mesh.vertices.size()));
  int sea_triangles = 0;
  for (scene::ClassId c : file.mesh.classes) sea_triangles += c == scene::kClassSea;
  EXPECT_GT(sea_triangles, 0);

  // The scene keeps its datum: the same explicitly (EPSG:5773 = egm96) is
  // fine, another one is a ConfigError naming the flag.
  SimulateRequest s;
  s.scene = (dir / "egm96.gscene").string();
  s.vertical_datum = "EPSG:5773";
  EXPECT_EQ(LoadTerrain(s).vertical_datum, "egm96");
  s.vertical_datum = "ellipsoid";
  try {
    LoadTerrain(s);
    ADD_FAILURE() << "a scene built on egm96 accepted --vertical-datum ellipsoid";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--vertical-datum"), std::string::npos) << e.what();
  }

  // Untagged: ellipsoid, assumed, one warning naming the file and the flag.
  o.dem = CoastDem(dir / "plain.tif", "EPSG:4326");
  o.out_prefix = (dir / "plain").string();
  WarningRecorder recorder;
  const SceneBuildResult plain = RunSceneBuild(o, "test", recorder);
  EXPECT_EQ(plain.summary["vertical_datum"]["datum"], "ellipsoid");
  EXPECT_EQ(plain.summary["vertical_datum"]["source"], "assumed");
  ASSERT_EQ(recorder.warnings.size(), 1u);
  EXPECT_NE(recorder.warnings[0].find("plain.tif"), std::string::npos) << recorder.warnings[0];
  EXPECT_NE(recorder.warnings[0].find("--vertical-datum"), std::string::npos) << recorder.warnings[0];
  EXPECT_NEAR(scene::ReadScene(dir / "plain.gscene").centre_height_m, 100.0, 1e-3);
}

// simulate's DEM path: the file's datum by default, the flag over it, the
// sea from the orthometric heights, and a missing EGM2008 grid an InputError.
TEST(SceneBuildTest, SimulateDemTakesTheDatumFromTheFileOrTheFlag) {
  const fs::path dir = testing::MakeTempDir();
  SimulateRequest s;
  s.dem = CoastDem(dir / "egm96.tif", "EPSG:4326+5773");
  s.center_lonlat = Eigen::Vector2d(1.6, 42.5);
  Terrain t = LoadTerrain(s);
  EXPECT_EQ(t.vertical_datum, "egm96");
  EXPECT_EQ(t.vertical_datum_source, "file");
  EXPECT_NEAR(t.centre.height_m, 100.0 + kN, 0.01);
  EXPECT_EQ(t.description["vertical_datum"], "egm96");
  int sea_triangles = 0;
  for (scene::ClassId c : t.mesh.classes) sea_triangles += c == scene::kClassSea;
  EXPECT_EQ(sea_triangles, 2 * 4 * 20);  // the 4 x 20 cells between the sea posts
  s.vertical_datum = "ellipsoid";
  t = LoadTerrain(s);
  EXPECT_EQ(t.vertical_datum_source, "flag");
  EXPECT_NEAR(t.centre.height_m, 100.0, 1e-3);
  s.vertical_datum = "egm2008";
  try {
    LoadTerrain(s);
    GTEST_SKIP() << "PROJ found the EGM2008 grid here";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("us_nga_egm08_25.tif"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("egm96.tif"), std::string::npos) << e.what();
  }
}

// The scene build table (scene_build_fields.cc) writes the sidecar's keys and
// reads them back: the window and centre as lists (null: not set), the
// vector files as a list of strings; null keeps a plain field's default; an
// unknown key is a ConfigError naming it and the source.
TEST(SceneBuildFields, RoundTripWindowCentreAndVectors) {
  SceneBuildRequest o;
  o.dem = "dem.tif";
  o.fill_nodata = true;
  o.window = std::array<int, 4>{10, 20, 300, 400};
  o.vectors = {"water.gpkg", "roads.geojson"};
  o.center_lonlat = Eigen::Vector2d(1.55, 42.51);
  o.out_prefix = "s";
  o.export_obj = true;
  o.sea = "off";
  o.sea_level_m = -1.5;
  o.dem_oversample = 3;
  o.vertical_units = "ft";
  o.vertical_datum = "egm96";
  o.flat_shading = true;
  o.reflectors = "cr.csv";
  o.max_memory_bytes = 123456789;
  const nlohmann::json j = o.ToJson();
  EXPECT_EQ(j.size(), 17u);
  EXPECT_EQ(j.at("window"), nlohmann::json({10, 20, 300, 400}));
  EXPECT_EQ(j.at("center_lonlat"), nlohmann::json({1.55, 42.51}));
  EXPECT_EQ(j.at("vectors"), nlohmann::json({"water.gpkg", "roads.geojson"}));
  EXPECT_EQ(j.at("export_obj"), true);
  EXPECT_EQ(j.at("max_memory_bytes"), 123456789);
  SceneBuildRequest round;
  round.ApplyJson(j, "test");
  EXPECT_EQ(round.ToJson(), j);
  EXPECT_EQ(round.vectors, o.vectors);
  EXPECT_EQ(*round.window, (std::array<int, 4>{10, 20, 300, 400}));
  EXPECT_EQ(round.center_lonlat->y(), 42.51);
  round.ApplyJson({{"window", nullptr}, {"center_lonlat", nullptr}, {"sea", nullptr}, {"dem_oversample", nullptr}},
                  "test");
  EXPECT_FALSE(round.window.has_value());
  EXPECT_FALSE(round.center_lonlat.has_value());
  EXPECT_EQ(round.sea, "off");
  EXPECT_EQ(round.dem_oversample, 3);
  EXPECT_EQ(SceneBuildRequest().ToJson().at("window"), nullptr);
  try {
    round.ApplyJson({{"vector", {"a.gpkg"}}}, "gissar.Scene.build keyword");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "unknown key 'vector'; did you mean vectors?");
    EXPECT_EQ(e.where(), "gissar.Scene.build keyword");
  }
  EXPECT_THROW(round.ApplyJson({{"window", {1, 2, 3}}}, "test"), ConfigError);
  EXPECT_THROW(round.ApplyJson({{"vectors", "a.gpkg"}}, "test"), ConfigError);
  const RequestField<SceneBuildRequest>& window = SceneBuildFields().at("window");
  EXPECT_EQ(window.from_text("1,2,3,4", window.Flag()), nlohmann::json({1, 2, 3, 4}));
  EXPECT_THROW(window.from_text("1,2,3", window.Flag()), ConfigError);
  EXPECT_EQ(SceneBuildFields().at("export_obj").Flag(), "--obj");
  EXPECT_EQ(SceneBuildFields().at("center_lonlat").Flag(), "--center");
  EXPECT_EQ(SceneBuildFields().at("max_memory_bytes").help, "");
}

}  // namespace
}  // namespace gissar::pipeline
