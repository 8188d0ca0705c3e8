// How closely two renderings of the same scene agree: the raster engine
// against the ray tracer, the height field against the BVH. A metric of the
// tests and `make bench` (bench/raster_agreement), in the gissar_render_testing
// library, not in gissar_render. Both images must have the same size and
// pixel grid.
#pragma once

#include <cstdint>
#include <vector>

namespace gissar::render {

struct IntensityAgreement {
  // Pearson correlation of 10 log10(I) over the pixels where both images
  // are positive (NaN when fewer than two such pixels or a constant image).
  double db_pearson = 0.0;
  int64_t compared_pixels = 0;  // pixels in the correlation
  // Mean of 10 log10(b / a) over the same pixels (NaN when there are none).
  double mean_db_difference = 0.0;
  int64_t one_sided_zero = 0;   // pixels where exactly one image is zero
};

// CHECKs that the images have the same size.
IntensityAgreement CompareIntensities(const std::vector<float>& a, const std::vector<float>& b);

struct MaskAgreement {
  int64_t flagged = 0;    // pixels with a non-zero code in either mask
  int64_t differing = 0;  // pixels whose codes differ
  // Differing pixels not explained by an edge: for some bit (layover,
  // shadow) set in one mask only, the other mask has that bit nowhere within
  // one pixel (3 x 3 neighbourhood). 0 means the masks are identical within
  // one pixel of their edges.
  int64_t away_from_edges = 0;
  // The first (row-major) of those pixels, at most kMaxListed: column, row,
  // code in a, code in b.
  static constexpr int kMaxListed = 64;
  struct Pixel {
    int col, row;
    uint8_t a, b;
  };
  std::vector<Pixel> unexplained;
};

// Compares two masks of kMask* codes, row-major width x height. CHECKs the
// sizes.
MaskAgreement CompareMasks(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b, int width,
                           int height);

}  // namespace gissar::render
