#include "gissar/util/provenance.h"

#include <gtest/gtest.h>

#include <fstream>

#include "gissar/util/error.h"
#include "gissar/util/testing.h"

namespace gissar {
namespace {

TEST(ProvenanceTest, Sha256MatchesKnownVector) {
  const auto dir = testing::MakeTempDir();
  std::ofstream(dir / "abc.txt") << "abc";
  // FIPS 180-2 test vector for "abc".
  EXPECT_EQ(Sha256OfFile(dir / "abc.txt"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  const auto record = InputFileRecord(dir / "abc.txt");
  EXPECT_EQ(record["bytes"], 3);
}

TEST(ProvenanceTest, InMemoryRasterIsRecordedWithoutBytesOrHash) {
  const auto record = InputFileRecord("/vsimem/gissar_dem.tif");
  EXPECT_EQ(record["path"], "/vsimem/gissar_dem.tif");
  EXPECT_EQ(record["in_memory"], true);
  EXPECT_FALSE(record.contains("sha256"));
}

TEST(ProvenanceTest, MissingFileIsAnIoError) {
  EXPECT_THROW(Sha256OfFile("/nonexistent/gissar/file"), IoError);
}

// A record started ahead gives InputFileRecord's record (the FIPS vector's
// checksum), and a missing file's IoError when asked for, not before.
TEST(ProvenanceTest, PendingRecordIsTheRecordOrItsError) {
  const auto dir = testing::MakeTempDir();
  std::ofstream(dir / "abc.txt") << "abc";
  const PendingInputRecord pending(dir / "abc.txt");
  const PendingInputRecord missing(dir / "missing.tif");
  const nlohmann::json record = pending.Get();
  EXPECT_EQ(record["sha256"], "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(record, InputFileRecord(dir / "abc.txt"));
  EXPECT_THROW(missing.Get(), IoError);
}

TEST(ProvenanceTest, VersionNamesTheProject) {
  EXPECT_EQ(VersionString().rfind("gissar 0.", 0), 0u);
}

}  // namespace
}  // namespace gissar
