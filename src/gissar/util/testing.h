// Test helpers: the one place tests find their data, so no test depends on
// the working directory.
#pragma once

#include <filesystem>
#include <string_view>

namespace gissar::testing {

// Path of a file under the project's bundled data/ folder
// (e.g. DataPath("andorra/andorra_srtm3_dem_raw.tif")). The root is the
// source tree, or $GISSAR_DATA_DIR when set.
std::filesystem::path DataPath(std::string_view relative);

// Path of a file under the repository's tests/data/ folder (reference
// results computed by independent code, see tests/data/README.md), or under
// $GISSAR_TEST_DATA_DIR when set.
std::filesystem::path TestDataPath(std::string_view relative);

// A fresh, empty directory unique to the calling test; removed at exit.
std::filesystem::path MakeTempDir();

}  // namespace gissar::testing
