// Top view of a scene with one colour per radar class and a legend.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "gissar/scene/scene_config.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::image {

struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;  // interleaved, row-major, row 0 at the top
};

// The grey levels of `image` (width x height, row-major) when every pixel is
// neutral (R = G = B): the same picture in a third of the bytes, for a grey
// PNG. nullopt when any pixel has colour.
std::optional<std::vector<uint8_t>> NeutralGrey(const RgbImage& image);

// Colour of each class (index = ClassId): default tan, water blue, forest
// green, urban grey, road black, building red.
const std::array<std::array<uint8_t, 3>, scene::kClassCount>& ClassColours();

// Orthographic top view (east to the right, north up) of `mesh`: each
// triangle filled with its class colour, lightly hill-shaded (sun from the
// north-west) so relief stays readable, buildings drawn over the ground,
// and a legend with every class name. The longer side has `max_side_px`
// pixels. CHECKs that the mesh is not empty.
RgbImage RenderClassMap(const scene::TriangleMesh& mesh,
                        const std::vector<std::string>& class_names, int max_side_px = 1200);

}  // namespace gissar::image
