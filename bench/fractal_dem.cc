// fractal_dem: writes a synthetic fractal DEM (scene::FractalHeights) as a
// GeoTIFF in a local transverse Mercator CRS centred on Andorra, for the
// benchmarks (scripts/bench.sh) and the POV-Ray comparison.
//
//   fractal_dem OUT.tif SIZE [SPACING_M=10] [RELIEF_M=800] [SEED=1] [PGM16]
//
// SIZE x SIZE posts, SPACING_M metres apart, heights in [500, 500 + RELIEF_M].
// With a fifth argument PGM16, the heights are rounded to 1/65535 of the
// relief first and also written to that path as a 16-bit binary PGM (the
// heightfield POV-Ray reads), so that both renderers see identical heights.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "gissar/geo/dem.h"
#include "gissar/scene/fractal_terrain.h"
#include "gissar/util/error.h"

int main(int argc, char** argv) {
  using namespace gissar;
  if (argc < 3) {
    std::fprintf(stderr, "usage: fractal_dem OUT.tif SIZE [SPACING_M] [RELIEF_M] [SEED] [PGM16]\n");
    return 2;
  }
  try {
    scene::FractalTerrainOptions o;
    o.width = o.height = std::stoi(argv[2]);
    const double spacing = argc > 3 ? std::stod(argv[3]) : 10.0;
    o.relief_m = argc > 4 ? std::stod(argv[4]) : 800.0;
    o.seed = argc > 5 ? std::stoull(argv[5]) : 1;
    o.base_m = 500.0;
    std::vector<float> heights = scene::FractalHeights(o);
    const int n = o.width;
    if (argc > 6) {
      // 16-bit quantisation shared by both renderers; PGM rows run north to
      // south like the GeoTIFF's.
      std::ofstream pgm(argv[6], std::ios::binary);
      pgm << "P5\n" << n << " " << n << "\n65535\n";
      for (float& h : heights) {
        const long q = std::lround((h - o.base_m) / o.relief_m * 65535.0);
        h = static_cast<float>(o.base_m + q * (o.relief_m / 65535.0));
        const unsigned char bytes[2] = {static_cast<unsigned char>(q >> 8), static_cast<unsigned char>(q & 255)};
        pgm.write(reinterpret_cast<const char*>(bytes), 2);
      }
      if (!pgm) throw IoError("cannot write the PGM heightfield", argv[6]);
    }
    const double half = n * spacing / 2;
    const std::string crs =
        "+proj=tmerc +lat_0=42.5 +lon_0=1.6 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs";
    geo::WriteDemGeoTiff(argv[1], heights, n, n, {-half, spacing, 0, half, 0, -spacing}, crs);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fractal_dem: %s\n", e.what());
    return 2;
  }
  return 0;
}
