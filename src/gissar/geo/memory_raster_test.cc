#include "gissar/geo/memory_raster.h"

#include <gtest/gtest.h>

#include <cmath>

#include "gissar/geo/dem.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace {

// A 3 x 2 UTM raster read back through the DEM reader: the same heights,
// post spacing and CRS as given.
TEST(MemoryRasterTest, ReadsBackAsADem) {
  const std::vector<float> heights = {100, 110, 120, 130, 140, 150};
  std::string path;
  {
    const MemoryRaster raster(heights, 3, 2, {500000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0}, "32631", NAN, "dem");
    path = raster.path();
    const Dem dem = ReadDem(path, DemReadOptions{});
    ASSERT_EQ(dem.width, 3);
    ASSERT_EQ(dem.height, 2);
    for (size_t i = 0; i < heights.size(); ++i) EXPECT_FLOAT_EQ(dem.heights_m[i], heights[i]);
    EXPECT_NE(dem.crs_wkt.find("UTM zone 31N"), std::string::npos);
  }
  // Gone with the object.
  EXPECT_THROW(ReadDem(path, DemReadOptions{}), InputError);
}

TEST(MemoryRasterTest, BadInputsNameTheArgument) {
  const std::vector<float> four = {1, 2, 3, 4};
  try {
    MemoryRaster bad(four, 2, 2, {0, 1, 0, 0, 0, -1}, "EPSG:999999", NAN, "dem");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.where(), "dem");
  }
  EXPECT_THROW(MemoryRaster(four, 4, 2, {0, 1, 0, 0, 0, -1}, "4326", NAN, "dem"), ConfigError);
  EXPECT_THROW(MemoryRaster(four, 2, 2, {0, 0, 0, 0, 0, 0}, "4326", NAN, "dem"), ConfigError);
}

}  // namespace
}  // namespace gissar::geo
