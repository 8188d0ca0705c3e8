// Test helper shared by the pipeline tests: reading a simulated image at the
// projection of a ground point.
#pragma once

#include <cmath>
#include <cstddef>
#include <string>

#include "gissar/geo/raster_io.h"

namespace gissar::pipeline {

// Mean of band 1 over the 5 x 5 pixels around the projection of ground point
// (x_m, y_m) (ENU metres from the scene centre) in an affine image at heading
// 0 (range along x, azimuth along y) with the given depression and square
// pixel spacing; the centre's pixel is the image's GISSAR_U0/GISSAR_V0.
inline double MeanAroundGroundPoint(const geo::FloatRaster& image, double x_m, double y_m, double depression_deg,
                                    double spacing_m) {
  const double u0 = std::stod(image.metadata.at("GISSAR_U0")), v0 = std::stod(image.metadata.at("GISSAR_V0"));
  const int c = int(std::lround(u0 + x_m * std::cos(depression_deg * M_PI / 180) / spacing_m));
  const int r = int(std::lround(v0 + y_m / spacing_m));
  double sum = 0;
  for (int dr = -2; dr <= 2; ++dr)
    for (int dc = -2; dc <= 2; ++dc) sum += image.bands[0][size_t(r + dr) * image.width + c + dc];
  return sum / 25;
}

}  // namespace gissar::pipeline
