// Pictures of two-view geometry: an image pair side by side with matches
// and epipolar lines.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "gissar/image/class_map.h"

namespace gissar::image {

struct EpipolarPlotInput {
  std::vector<uint8_t> image1, image2;  // grey, row-major
  int width1 = 0, height1 = 0, width2 = 0, height2 = 0;
  std::vector<std::array<Eigen::Vector2d, 2>> matches;  // pixel in image 1, pixel in image 2
  std::vector<bool> inlier;                             // per match
  // Epipolar lines a x + b y + c = 0: in image 2 of each image-1 point, and
  // in image 1 of each image-2 point.
  std::vector<Eigen::Vector3d> lines_in_2, lines_in_1;
};

// Image 1 left, image 2 right; inliers green with their epipolar lines in
// yellow, outliers red crosses; a match's two points joined by a thin line.
RgbImage DrawEpipolarPair(const EpipolarPlotInput& input);

}  // namespace gissar::image
