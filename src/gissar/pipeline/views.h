// `gissar sequence` (heading sequences rendered from one scene build) and
// `gissar ortho` (orthographic views that explain a SAR image).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/util/reporter.h"
#include "gissar/pipeline/simulate.h"

namespace gissar::pipeline {

struct SequenceRequest {
  // Terrain, depression, range, spacings, sensor effects; its heading is
  // replaced by each frame's and its out_prefix names the sequence.
  SimulateRequest base;
  double heading_from_deg = 0.0;
  double heading_to_deg = 30.0;
  int frames = 7;           // >= 2, headings evenly spaced, both ends included
  int frame_delay_cs = 50;  // GIF frame time, 1/100 s

  // Throws ConfigError naming the option.
  void Check() const;
  nlohmann::json ToJson() const;
};

struct SequenceResult {
  std::vector<std::filesystem::path> outputs;
  std::vector<double> frame_seconds;  // render time per frame (one BVH for all)
  double bvh_seconds = 0.0;
};

// Renders every heading at the same depression and slant range (hence the
// same altitude: the sensor circles the scene centre), reusing one Embree
// scene, into frames of a common size centred on the scene centre. Writes
// PREFIX_fNN.tif (float32) and PREFIX_fNN.png per frame (one dB stretch:
// the first frame's), PREFIX_contact.png, PREFIX.gif and PREFIX.json.
SequenceResult RunSequence(const SequenceRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

struct OrthoRequest {
  SimulateRequest base;     // terrain, heading, depression, spacings
  std::string orthophoto;   // optional RGB raster draped instead of class colours

  void Check() const;
};

// Writes the thesis's trio: PREFIX_los.png (orthographic camera along the
// line of sight, from the sensor side), PREFIX_sar.png (the affine-model SAR
// quicklook), PREFIX_gperp.png (the virtual camera G_perp normal to the
// slant-range plane, on the SAR image's pixel grid), PREFIX_trio.png (side
// by side) and PREFIX.json. Throws the gissar::Error family.
std::vector<std::filesystem::path> RunOrtho(const OrthoRequest& options, const std::string& command_line, Reporter& reporter = NullReporter());

}  // namespace gissar::pipeline
