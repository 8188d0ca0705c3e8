// A 3-D picture of a scene mesh: perspective view from an oblique direction,
// triangles in their class colours, Lambertian shading from a fixed sun,
// hidden surfaces removed with a z-buffer (a small software rasteriser, no
// GPU). For people to see what the simulator sees: relief, lakes, roads,
// buildings.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "gissar/image/class_map.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::image {

struct MeshViewOptions {
  // Where the camera stands, seen from the scene centre: compass azimuth
  // (degrees clockwise from north) and elevation above the horizon (degrees,
  // (0, 90]). The camera looks at the centre of the mesh's bounding box from
  // the distance at which the box's bounding sphere fits the field of view;
  // the picture is then zoomed and centred so that the projected box fills
  // 95 % of its limiting side.
  double view_azimuth_deg = 200.0;
  double view_elevation_deg = 35.0;
  double vertical_exaggeration = 1.5;  // heights scaled about the mean height, > 0
  double field_of_view_deg = 30.0;     // perspective strength (camera distance), (1, 120)
  // Sun direction (compass azimuth, elevation, degrees): diffuse shading
  // 0.35 + 0.65 max(0, n . sun); ground smooth-shaded with area-weighted
  // vertex normals (upward), buildings flat-shaded with the face normal
  // facing the camera.
  double sun_azimuth_deg = 315.0;
  double sun_elevation_deg = 45.0;
  int width = 960;
  int height = 640;
  // Throws ConfigError naming the field when a value is out of range.
  void Check() const;
};

// Renders `mesh` (ENU metres) with `class_colours[class]` (classes past the
// end are light grey) on a pale sky-blue background. Supersampled 2 x 2 and
// averaged (anti-aliased edges). CHECKs that the mesh is not empty; throws
// ConfigError for bad options.
RgbImage RenderMeshView(const scene::TriangleMesh& mesh,
                        const std::vector<std::array<uint8_t, 3>>& class_colours,
                        const MeshViewOptions& options = MeshViewOptions());

// The class colours of the class map (ClassColours()) as a vector.
std::vector<std::array<uint8_t, 3>> ClassColourList();

}  // namespace gissar::image
