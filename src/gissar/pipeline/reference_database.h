// Reference databases for pose fixes (`gissar locate --database
// PREFIX_catalog.json`, `gissar evaluate --database`; docs/navigation.md
// "Fixes from a reference database"): the reader of the STAC catalogue a
// corridor writes (docs/distributed.md "Reference database keys"), the check
// that it was built from the same terrain, the choice of the stored
// reference that covers a prior pose, and the stored reference as a
// nav::StoredReference in the locate's frame.
//
// Errors: a catalogue that is not JSON, lacks a key or holds a wrong value
// is an InputError naming the file and the key (gissar:poses[3].reference.u0);
// a database built from another DEM or scene is an InputError naming both
// SHA-256 hashes.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "gissar/geo/local_frame.h"
#include "gissar/nav/locate.h"

namespace gissar::pipeline {

// One done pose of the catalogue with its stored reference.
struct StoredReferenceItem {
  std::string id;
  std::string image;  // absolute path (the catalogue's relative path resolved against its directory)
  std::string mask;   // absolute path, or empty: no mask stored
  int band = 1;
  bool db = false;    // the stored values are dB (else linear)
  double heading_deg = 0.0, depression_deg = 0.0, slant_range_m = 0.0;
  sensor::LookSide look_side = sensor::LookSide::kRight;
  // The affine camera in the ENU tangent frame of the simulation (origin
  // frame_origin: lon, lat, height).
  Eigen::Vector3d frame_origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d centre_enu = Eigen::Vector3d::Zero();
  Eigen::Vector3d look_direction = Eigen::Vector3d::Zero();
  Eigen::Vector3d flight_direction = Eigen::Vector3d::Zero();
  double u0 = 0.0, v0 = 0.0;
  int width = 0, height = 0;
  double range_spacing_m = 0.0, azimuth_spacing_m = 0.0;
  nlohmann::json ToJson() const;  // id and the image path (for result records)
};

struct ReferenceDatabase {
  std::string path;            // the catalogue
  std::string terrain;         // "dem" or "scene"
  std::string terrain_sha256;  // lowercase hex
  std::string vertical_datum;  // as the corridor was given it ("" = from the file)
  std::vector<StoredReferenceItem> items;  // done poses with a reference, catalogue order
  int poses = 0;               // every pose of the catalogue (done or not)
};

// Reads a corridor catalogue (gissar:database and every done pose's
// `reference`). InputError naming the file and the key for anything missing
// or malformed; a catalogue with no usable reference is an InputError too.
ReferenceDatabase ReadReferenceDatabase(const std::string& path);

// Refuses a database built from another terrain than --scene/--dem (kind or
// SHA-256 of the file's bytes; InputError naming both hashes) or with
// another explicit vertical datum (ConfigError).
void CheckDatabaseTerrain(const ReferenceDatabase& database, const std::string& scene, const std::string& dem,
                          const std::string& vertical_datum);

// A stored reference's camera in `frame` (the locate's terrain frame): the
// look and flight directions and the centre carried through WGS84.
sensor::SarGeometry ItemGeometryInFrame(const StoredReferenceItem& item, const geo::LocalFrame& frame);

// A stored reference that covers a prior: the prior's image centre lies in
// the central half of the stored image (at least a quarter of the image
// from every edge) and the headings differ by at most the tolerance.
struct ReferenceChoice {
  size_t item = 0;                // index into ReferenceDatabase::items
  double distance_m = 0.0;        // horizontal distance between the image centres
  double heading_difference_deg = 0.0;
};
// The covering references, nearest centre first (at most `max_choices`);
// when none covers, an empty list and `reason` says why (the nearest
// reference by centre distance, its heading difference and where the prior
// falls in it).
std::vector<ReferenceChoice> CoveringReferences(const ReferenceDatabase& database,
                                                const std::vector<sensor::SarGeometry>& cameras,
                                                const nav::NavPose& prior, const nav::SensorModel& model,
                                                double heading_tolerance_deg, size_t max_choices,
                                                std::string* reason);

// Reads the item's image (band; dB converted to linear) and mask and makes
// the stored reference with the camera `geometry` (ItemGeometryInFrame).
nav::StoredReference LoadStoredReference(const StoredReferenceItem& item, const sensor::SarGeometry& geometry,
                                         const nav::NavScene& scene);

}  // namespace gissar::pipeline
