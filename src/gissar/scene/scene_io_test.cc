#include "gissar/scene/scene_io.h"

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <sstream>

#include "gissar/util/atomic_output.h"
#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar::scene {
namespace {
namespace fs = std::filesystem;

SceneFile Sample() {
  SceneFile s;
  s.mesh = MeshFromHeights({0, 1, 2, 3, 4, 5}, 3, 2, 10.0);
  s.mesh.classes[1] = 4;
  s.origin_lon_deg = 1.6;
  s.origin_lat_deg = 42.5;
  s.centre_enu = {1, 2, 3};
  s.class_names = {"default", "water", "forest", "urban", "road", "building"};
  s.materials = {{"water", {{"diffuse", 0.01}}}};
  return s;
}

TEST(SceneIoTest, RoundTrips) {
  const fs::path path = testing::MakeTempDir() / "s.gscene";
  WriteScene(path, Sample());
  const SceneFile back = ReadScene(path);
  EXPECT_EQ(back.mesh.vertices, Sample().mesh.vertices);
  EXPECT_EQ(back.mesh.triangles, Sample().mesh.triangles);
  EXPECT_EQ(back.mesh.classes, Sample().mesh.classes);
  EXPECT_EQ(back.origin_lat_deg, 42.5);
  EXPECT_EQ(back.centre_enu, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(back.class_names[4], "road");
  EXPECT_EQ(back.materials["water"]["diffuse"], 0.01);
}

// Stored reflectors survive the round trip (a scene without the key reads
// as none); a stored reflector of size 0 or without a type is a corrupt
// header naming the file.
TEST(SceneIoTest, ReflectorsRoundTripAndAreChecked) {
  const fs::path path = testing::MakeTempDir() / "r.gscene";
  WriteScene(path, Sample());
  EXPECT_TRUE(ReadScene(path).reflectors.empty());
  SceneFile s = Sample();
  StoredReflector r;
  r.type = "dihedral";
  r.lon_deg = 1.601;
  r.lat_deg = 42.499;
  r.apex_height_m = 0.5;
  r.size_m = 0.8;
  r.boresight_azimuth_deg = 285.0;
  r.boresight_elevation_deg = 35.0;
  r.roll_deg = 22.5;
  r.apex_enu = {81.9, -111.2, 2.5};
  r.source = "cr.csv";
  r.row = 3;
  s.reflectors = {r};
  WriteScene(path, s);
  const SceneFile back = ReadScene(path);
  ASSERT_EQ(back.reflectors.size(), 1u);
  const StoredReflector& b = back.reflectors[0];
  EXPECT_EQ(b.type, "dihedral");
  EXPECT_EQ(b.lon_deg, 1.601);
  EXPECT_EQ(b.size_m, 0.8);
  EXPECT_EQ(b.boresight_azimuth_deg, 285.0);
  EXPECT_EQ(b.roll_deg, 22.5);
  EXPECT_EQ(b.apex_enu, Eigen::Vector3d(81.9, -111.2, 2.5));
  EXPECT_EQ(b.source, "cr.csv");
  EXPECT_EQ(b.row, 3);
  for (int k = 0; k < 2; ++k) {
    SceneFile bad = s;
    if (k == 0) bad.reflectors[0].size_m = 0.0;
    else bad.reflectors[0].type = "";
    WriteScene(path, bad);
    try {
      ReadScene(path);
      FAIL() << k;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("reflector 1"), std::string::npos) << e.what();
      EXPECT_EQ(e.where(), path.string());
    }
  }
}

// Shading normals: the plane z = x / 10 + 3 y / 10 (posts 10 m apart)
// has the unit normal (-0.1, -0.3, 1) / |(-0.1, -0.3, 1)| at every vertex; they
// survive the round trip.
// A terrain grid at the start of the mesh round-trips; one the mesh does not
// start with is a corrupt file.
TEST(SceneIoTest, TerrainGridRoundTripsAndIsChecked) {
  const fs::path dir = testing::MakeTempDir();
  SceneFile scene = Sample();
  std::vector<float> heights(4 * 3, 5.0f);
  TriangleMesh grid = MeshFromHeights(heights, 4, 3, 10.0);
  scene.mesh.vertices = grid.vertices;
  scene.mesh.triangles.assign(grid.triangles.begin() + 2, grid.triangles.begin() + 6);  // cells 1 and 2
  scene.mesh.classes.assign(4, 1);
  scene.grid = GridPrefix{4, 3, 2};
  WriteScene(dir / "grid.gscene", scene);
  const SceneFile back = ReadScene(dir / "grid.gscene");
  EXPECT_EQ(back.grid.width, 4);
  EXPECT_EQ(back.grid.height, 3);
  EXPECT_EQ(back.grid.cells, 2);
  WriteScene(dir / "none.gscene", Sample());
  EXPECT_EQ(ReadScene(dir / "none.gscene").grid.cells, 0);
  scene.grid.cells = 3;  // more cells than the mesh starts with
  WriteScene(dir / "bad.gscene", scene);
  EXPECT_THROW(ReadScene(dir / "bad.gscene"), InputError);
}

TEST(SceneIoTest, ShadingNormalsRoundTrip) {
  SceneFile s = Sample();
  s.mesh.classes[1] = 0;
  s.mesh.SmoothShadingNormals(5);
  const Eigen::Vector3f expected = Eigen::Vector3f(-0.1f, -0.3f, 1.0f).normalized();
  ASSERT_EQ(s.mesh.shading_normals.size(), 6u);
  for (const auto& n : s.mesh.shading_normals) EXPECT_LT((n - expected).norm(), 1e-6f);
  const fs::path path = testing::MakeTempDir() / "n.gscene";
  WriteScene(path, s);
  const SceneFile back = ReadScene(path);
  EXPECT_EQ(back.mesh.shading_normals, s.mesh.shading_normals);
  // Without normals the flag is 0 and the mesh reads back without them.
  WriteScene(path, Sample());
  EXPECT_TRUE(ReadScene(path).mesh.shading_normals.empty());
}

TEST(SceneIoTest, TruncatedWrongVersionAndForeignFilesAreInputErrors) {
  const fs::path dir = testing::MakeTempDir();
  WriteScene(dir / "s.gscene", Sample());
  std::string bytes;
  {
    std::ifstream in(dir / "s.gscene", std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    bytes = ss.str();
  }
  auto expect = [&](const std::string& content, const std::string& needle) {
    std::ofstream(dir / "bad.gscene", std::ios::binary) << content;
    try {
      ReadScene(dir / "bad.gscene");
      FAIL() << needle;
    } catch (const InputError& e) {
      EXPECT_NE(e.message().find(needle), std::string::npos) << e.what();
    }
  };
  expect(bytes.substr(0, bytes.size() - 20), "truncated");
  expect(bytes.substr(0, 30), "truncated");
  std::string other_version = bytes;
  other_version[8] = 7;
  expect(other_version, "version 7 is not supported");
  std::string version_one = bytes;
  version_one[8] = 1;
  expect(version_one, "version 1 is not supported (this gissar reads 2); rebuild the scene");
  expect("solid cube\nfacet normal 0 0 1\n", "not a gissar scene");
  expect("", "too short");
  EXPECT_THROW(ReadScene(dir / "missing.gscene"), InputError);
}

TEST(SceneIoTest, PlyHasClassPerFace) {
  const fs::path path = testing::MakeTempDir() / "s.ply";
  const SceneFile s = Sample();
  WritePly(path, s.mesh, s.class_names);
  std::ifstream in(path, std::ios::binary);
  std::string header, line;
  while (std::getline(in, line) && line != "end_header") header += line + "\n";
  EXPECT_NE(header.find("element vertex 6"), std::string::npos);
  EXPECT_NE(header.find("element face 4"), std::string::npos);
  EXPECT_NE(header.find("property uchar class"), std::string::npos);
  EXPECT_NE(header.find("comment class 4 road"), std::string::npos);
  const auto body_bytes = fs::file_size(path) - header.size() - std::string("end_header\n").size();
  EXPECT_EQ(body_bytes, 6u * 12u + 4u * (1u + 12u + 1u));
}

TEST(SceneIoTest, ObjHasEveryVertexFaceAndClassMaterial) {
  const fs::path path = testing::MakeTempDir() / "s.obj";
  const SceneFile s = Sample();
  WriteObj(path, s.mesh, s.class_names, {{1, 2, 3}, {0, 0, 255}});
  std::ifstream in(path);
  int v = 0, f = 0, use = 0;
  for (std::string line; std::getline(in, line);) {
    v += line.rfind("v ", 0) == 0;
    f += line.rfind("f ", 0) == 0;
    use += line.rfind("usemtl ", 0) == 0;
  }
  EXPECT_EQ(v, 6);
  EXPECT_EQ(f, 4);
  EXPECT_EQ(use, 2);  // default and road
  std::ifstream mtl(fs::path(path).replace_extension(".mtl"));
  std::stringstream text;
  text << mtl.rdbuf();
  EXPECT_NE(text.str().find("newmtl water\nKd 0 0 1"), std::string::npos);
}

// A full disk is named as such, with the directory of the output, instead
// of "failed writing scene file" alone. /dev/full fails every write with
// ENOSPC, as a full file system does.
TEST(SceneIoTest, AFullDiskSaysNoSpaceLeft) {
  ASSERT_TRUE(fs::exists("/dev/full"));
  auto error_of = [](const std::function<void()>& write) -> std::string {
    try {
      write();
    } catch (const IoError& e) {
      EXPECT_EQ(e.where(), "/dev/full");
      return e.message();
    }
    return "no error";
  };
  const SceneFile s = Sample();
  const std::string expected = ": no space left on the device holding /dev";
  EXPECT_EQ(error_of([&] { WriteScene("/dev/full", s); }), "failed writing scene file" + expected);
  EXPECT_EQ(error_of([&] { WritePly("/dev/full", s.mesh, s.class_names); }), "failed writing PLY" + expected);
  const fs::path dir = testing::MakeTempDir();
  EXPECT_EQ(error_of([&] { WriteObj("/dev/full", dir / "s.mtl", "s.mtl", s.mesh, s.class_names, {}); }),
            "failed writing OBJ" + expected);
  // The MTL is short: its failure shows only when it is flushed.
  try {
    WriteObj(dir / "s.obj", "/dev/full", "full.mtl", s.mesh, s.class_names, {});
    ADD_FAILURE() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_EQ(e.message(), "failed writing MTL" + expected);
  }
}

// `scene build` writes PREFIX.gscene under a temporary name: on a full disk
// the error names PREFIX.gscene and its directory (the failure injected by
// making the temporary a link to /dev/full).
TEST(SceneIoTest, AFullDiskNamesTheSceneFileNotItsTemporary) {
  const fs::path dir = testing::MakeTempDir();
  AtomicOutputs outputs;
  const fs::path temp = outputs.Add(dir / "scene.gscene");
  fs::create_symlink("/dev/full", temp);
  try {
    WriteScene(temp, Sample());
    ADD_FAILURE() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_EQ(e.message(), "failed writing scene file: no space left on the device holding " + dir.string());
    EXPECT_EQ(e.where(), (dir / "scene.gscene").string());
  }
}

}  // namespace
}  // namespace gissar::scene
