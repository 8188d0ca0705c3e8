#include "gissar/pipeline/reference_database.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "gissar/util/error.h"
#include "gissar/util/provenance.h"

namespace gissar::pipeline {
namespace {
namespace fs = std::filesystem;

// A catalogue of one done pose (the keys gissar.distributed writes) whose
// terrain hash is `sha256`.
nlohmann::json Catalogue(const std::string& sha256) {
  nlohmann::json reference = {
      {"image", "db_p0000_h090.tif"}, {"band", 1}, {"mask", "db_p0000_h090_mask.tif"},
      {"sidecar", "db_p0000_h090.json"}, {"heading_deg", 90.0}, {"depression_deg", 40.0},
      {"slant_range_m", 10000.0}, {"look_side", "right"}, {"projection_mode", "affine"}, {"db", false},
      {"frame_origin_lon_lat_h", {1.5, 42.5, 0.0}}, {"centre_enu_m", {0.0, 0.0, 1000.0}},
      {"look_direction_enu", {0.0, -0.766044443118978, -0.642787609686539}},
      {"flight_direction_enu", {1.0, 0.0, 0.0}}, {"u0", 47.5}, {"v0", 47.5}, {"width", 96}, {"height", 96},
      {"range_spacing_m", 60.0}, {"azimuth_spacing_m", 60.0}};
  return {{"type", "Collection"},
          {"gissar:database", {{"format", 1}, {"terrain", "dem"}, {"terrain_sha256", sha256}, {"vertical_datum", ""}}},
          {"gissar:poses", {{{"id", "p0000_h090"}, {"status", "done"}, {"reference", reference}},
                            {{"id", "p0001_h090"}, {"status", "skipped"}}}}};
}

class ReferenceDatabaseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("gissar_refdb_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                                        "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    dem_ = (dir_ / "dem.tif").string();
    std::ofstream(dem_) << "not really a DEM, but bytes to hash";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& text) {
    const std::string path = (dir_ / "db_catalog.json").string();
    std::ofstream(path) << text;
    return path;
  }
  // The message of the error `f` throws (empty if none).
  template <class E, class F>
  std::string ErrorOf(F f) {
    try {
      f();
    } catch (const E& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
  std::string dem_;
};

TEST_F(ReferenceDatabaseTest, ReadsItemsAndResolvesPathsAgainstTheCatalogue) {
  const std::string path = Write(Catalogue(Sha256OfFile(dem_)).dump());
  const ReferenceDatabase db = ReadReferenceDatabase(path);
  EXPECT_EQ(db.terrain, "dem");
  EXPECT_EQ(db.poses, 2);
  ASSERT_EQ(db.items.size(), 1u);
  EXPECT_EQ(db.items[0].id, "p0000_h090");
  EXPECT_EQ(db.items[0].image, (fs::absolute(dir_) / "db_p0000_h090.tif").lexically_normal().string());
  EXPECT_EQ(db.items[0].width, 96);
  EXPECT_NO_THROW(CheckDatabaseTerrain(db, "", dem_, ""));
}

TEST_F(ReferenceDatabaseTest, AnotherDemIsRefusedNamingBothHashes) {
  const std::string other(64, 'a');
  const ReferenceDatabase db = ReadReferenceDatabase(Write(Catalogue(other).dump()));
  const std::string message = ErrorOf<InputError>([&] { CheckDatabaseTerrain(db, "", dem_, ""); });
  EXPECT_NE(message.find("another DEM"), std::string::npos) << message;
  EXPECT_NE(message.find(other), std::string::npos) << message;
  EXPECT_NE(message.find(Sha256OfFile(dem_)), std::string::npos) << message;
  // A DEM database given a scene.
  EXPECT_NE(ErrorOf<InputError>([&] { CheckDatabaseTerrain(db, dem_, "", ""); }).find("give --dem"), std::string::npos);
}

TEST_F(ReferenceDatabaseTest, CorruptedCataloguesNameTheFileAndTheKey) {
  const std::string good = Sha256OfFile(dem_);
  std::string message = ErrorOf<InputError>([&] { ReadReferenceDatabase(Write("{\"type\": \"Collection\", ")); });
  EXPECT_NE(message.find("not JSON"), std::string::npos) << message;
  EXPECT_NE(message.find("db_catalog.json"), std::string::npos) << message;

  nlohmann::json c = Catalogue(good);
  c["gissar:poses"][0]["reference"].erase("u0");
  message = ErrorOf<InputError>([&] { ReadReferenceDatabase(Write(c.dump())); });
  EXPECT_NE(message.find("gissar:poses[0].reference.u0"), std::string::npos) << message;
  EXPECT_NE(message.find("db_catalog.json"), std::string::npos) << message;

  c = Catalogue(good);
  c["gissar:poses"][0]["reference"]["width"] = "wide";
  message = ErrorOf<InputError>([&] { ReadReferenceDatabase(Write(c.dump())); });
  EXPECT_NE(message.find("gissar:poses[0].reference.width"), std::string::npos) << message;

  c = Catalogue("xyz");
  message = ErrorOf<InputError>([&] { ReadReferenceDatabase(Write(c.dump())); });
  EXPECT_NE(message.find("gissar:database.terrain_sha256"), std::string::npos) << message;

  c = Catalogue(good);
  c.erase("gissar:database");
  message = ErrorOf<InputError>([&] { ReadReferenceDatabase(Write(c.dump())); });
  EXPECT_NE(message.find("not a reference database"), std::string::npos) << message;

  c = Catalogue(good);
  c["gissar:poses"][0]["status"] = "failed";
  message = ErrorOf<InputError>([&] { ReadReferenceDatabase(Write(c.dump())); });
  EXPECT_NE(message.find("no stored reference"), std::string::npos) << message;

  message = ErrorOf<InputError>([&] { ReadReferenceDatabase((dir_ / "missing_catalog.json").string()); });
  EXPECT_NE(message.find("does not exist"), std::string::npos) << message;
}

TEST_F(ReferenceDatabaseTest, CoveringReferenceIsTheNearestWithinHeadingTolerance) {
  const ReferenceDatabase db = ReadReferenceDatabase(Write(Catalogue(Sha256OfFile(dem_)).dump()));
  const geo::LocalFrame frame(1.5, 42.5, 0.0);
  const std::vector<sensor::SarGeometry> cameras = {ItemGeometryInFrame(db.items[0], frame)};
  // Same frame: the camera is the stored one.
  EXPECT_NEAR(cameras[0].options().heading_deg, 90.0, 1e-6);
  EXPECT_NEAR(cameras[0].options().depression_deg, 40.0, 1e-6);
  EXPECT_NEAR(cameras[0].scene_centre().z(), 1000.0, 1e-3);
  nav::SensorModel model;
  model.range_spacing_m = model.azimuth_spacing_m = 60.0;
  model.width = model.height = 96;
  nav::NavPose prior{93.0, 40.0, 10000.0, Eigen::Vector3d(300.0, -200.0, 1000.0)};
  std::string reason;
  auto choices = CoveringReferences(db, cameras, prior, model, 10.0, 2, &reason);
  ASSERT_EQ(choices.size(), 1u);
  EXPECT_NEAR(choices[0].distance_m, std::hypot(300.0, 200.0), 1e-6);
  EXPECT_NEAR(choices[0].heading_difference_deg, 3.0, 1e-9);
  // Heading beyond the tolerance.
  prior.heading_deg = 110.0;
  EXPECT_TRUE(CoveringReferences(db, cameras, prior, model, 10.0, 2, &reason).empty());
  EXPECT_NE(reason.find("no stored reference covers the prior"), std::string::npos) << reason;
  EXPECT_NE(reason.find("p0000_h090"), std::string::npos) << reason;
  // Outside the central half of the footprint (40 km away).
  prior.heading_deg = 90.0;
  prior.centre_enu = Eigen::Vector3d(40000.0, 0.0, 1000.0);
  EXPECT_TRUE(CoveringReferences(db, cameras, prior, model, 10.0, 2, &reason).empty());
  // Another sensor (pixel spacing twice as large).
  prior.centre_enu = Eigen::Vector3d(0.0, 0.0, 1000.0);
  model.range_spacing_m = model.azimuth_spacing_m = 120.0;
  EXPECT_TRUE(CoveringReferences(db, cameras, prior, model, 10.0, 2, &reason).empty());
  EXPECT_NE(reason.find("sensor"), std::string::npos) << reason;
}

}  // namespace
}  // namespace gissar::pipeline
