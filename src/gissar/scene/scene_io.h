// Scene files: a compact binary format that loads fast (".gscene"), and PLY
// export with a per-face class property for MeshLab/Blender.
//
// .gscene layout (little-endian): magic "GISSARSC", uint32 version (2),
// uint64 JSON byte count + JSON (frame origin, scene centre, class names,
// materials, provenance), uint64 vertex count, uint64 triangle count,
// float32[3 n] ENU vertices, int32[3 m] triangles, uint8[m] classes,
// uint8 shading-normal flag (0/1) and, when 1, float32[3 n] per-vertex unit
// shading normals (zero = flat), magic "GSCNEND1". Version 1 (no normals)
// is refused with a message to rebuild the scene. The header's optional key
// "reflectors" (absent in scenes built before it: none) lists the canonical
// reflectors placed by `scene build --reflectors` (StoredReflector).
// The optional key "terrain_grid" ({"width", "height", "cells"}) says that
// the mesh starts with a terrain grid (GridPrefix).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/scene/triangle_mesh.h"

namespace gissar::scene {

inline constexpr uint32_t kSceneFileVersion = 2;

// A canonical reflector stored in a scene (docs/scene.md): its CSV row as
// read (material/reflector.h: the scene module keeps the type as its name)
// and its phase centre placed on the scene's surface, ENU metres.
struct StoredReflector {
  std::string type;  // a name of material::kReflectorTypes (checked by the reader of the scene)
  double lon_deg = 0.0, lat_deg = 0.0;
  double apex_height_m = 0.0;
  double size_m = 1.0;
  double boresight_azimuth_deg = 0.0;
  double boresight_elevation_deg = 0.0;
  double roll_deg = 0.0;  // about the boresight (material/scattering.h); absent in older scenes: 0
  Eigen::Vector3d apex_enu = Eigen::Vector3d::Zero();  // surface below (lon, lat) + apex_height_m
  std::string source;  // the CSV it came from (file name)
  int row = 0;         // its data row there
};

struct SceneFile {
  TriangleMesh mesh;              // ENU metres
  double origin_lon_deg = 0.0;    // ENU frame origin (WGS84, height 0)
  double origin_lat_deg = 0.0;
  Eigen::Vector3d centre_enu = Eigen::Vector3d::Zero();  // default scene centre
  double centre_lon_deg = 0.0, centre_lat_deg = 0.0, centre_height_m = 0.0;
  std::vector<std::string> class_names;  // index = ClassId
  nlohmann::json materials = nlohmann::json::object();  // overrides from the config
  nlohmann::json provenance = nlohmann::json::object();
  std::vector<StoredReflector> reflectors;
  // The mesh's terrain grid (GridPrefix; header key "terrain_grid", absent in
  // scenes built before it and when cells == 0): traced as a height field.
  GridPrefix grid;
};

// Writes the binary scene. Throws IoError on failure.
void WriteScene(const std::filesystem::path& path, const SceneFile& scene);

// Reads a binary scene. Throws InputError naming the file when it is
// missing, not a gissar scene, of another version, truncated (sizes are
// checked against the file's length before anything is allocated), or
// corrupt: a header that is not the expected JSON, a non-finite or invalid
// frame origin or centre, no class names, out-of-range vertex indices or
// class ids, non-finite vertices or shading normals, a bad end marker, a
// reflector with a non-finite field, size <= 0 or no type name, a
// terrain_grid that is not the mesh's first triangles.
SceneFile ReadScene(const std::filesystem::path& path);

// Binary little-endian PLY with vertex x,y,z (float, ENU metres) and faces
// with vertex_indices and a uchar `class` property; class names in comments,
// then `header_comments` (one line each, e.g. the frame's origin and CRS).
void WritePly(const std::filesystem::path& path, const TriangleMesh& mesh,
              const std::vector<std::string>& class_names,
              const std::vector<std::string>& header_comments = {});

// Wavefront OBJ (+ MTL beside it, same stem) with one material per class
// coloured like the class map, for any 3-D viewer. `class_colours[i]` is the
// RGB of class i. Writes `path` and `path` with extension ".mtl".
void WriteObj(const std::filesystem::path& path, const TriangleMesh& mesh,
              const std::vector<std::string>& class_names,
              const std::vector<std::array<uint8_t, 3>>& class_colours);

// The same with the MTL written to `mtl_path` and referenced from the OBJ as
// `mtllib_name` (for writers that go through temporary names, e.g.
// AtomicOutputs: the OBJ must name the MTL's final file name).
// `header_comments` are written as "# ..." lines after the first.
void WriteObj(const std::filesystem::path& path, const std::filesystem::path& mtl_path,
              const std::string& mtllib_name, const TriangleMesh& mesh,
              const std::vector<std::string>& class_names,
              const std::vector<std::array<uint8_t, 3>>& class_colours,
              const std::vector<std::string>& header_comments = {});

}  // namespace gissar::scene
