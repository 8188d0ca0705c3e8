// Vector input through OGR: polygon and line layers from GeoPackage,
// Shapefile, GeoJSON, OSM (PBF and XML, also .osm.gz) and anything else OGR
// reads, with attribute filters, reprojected to a target CRS (the DEM's).
// Geometry validity is not checked here: the scene module repairs it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace gissar::geo {

using Ring = std::vector<Eigen::Vector2d>;      // closed: first point repeated at the end
using PolygonRings = std::vector<Ring>;        // outer ring first, then holes
using LinePoints = std::vector<Eigen::Vector2d>;

struct VectorFeature {
  int64_t fid = -1;
  // Non-null attributes as text. OSM `other_tags` (key=>value lists) are
  // expanded into their own entries (e.g. "height", "building:levels",
  // "width") unless a field of that name exists.
  std::map<std::string, std::string> fields;
  std::vector<PolygonRings> polygons;  // from (multi)polygons
  std::vector<LinePoints> lines;       // from (multi)linestrings
};

struct VectorLayerRequest {
  std::string path;   // file (".osm.gz" is read through /vsigzip/)
  std::string layer;  // layer name; empty = the only layer of a one-layer source
  std::string where;  // OGR SQL attribute filter, empty = all features
};

// Names of the layers of a vector source. Throws InputError when the file is
// missing or not a vector source OGR reads.
std::vector<std::string> ListVectorLayers(const std::string& path);

// Reads the features of one layer, coordinates transformed to
// `target_crs_wkt` (x = easting/longitude, y = northing/latitude). Throws
// InputError naming file and layer when: the file is missing or not vector
// data, the layer does not exist (the message lists the layers), the
// attribute filter is invalid, the layer has no CRS (a file without CRS
// cannot be placed), or a feature has a non-finite coordinate (before or
// after reprojection). Features without geometry, or with point geometry, are
// skipped; curves are linearised.
std::vector<VectorFeature> ReadVectorLayer(const VectorLayerRequest& request,
                                           const std::string& target_crs_wkt);

// Parses OSM "other_tags" text ("k"=>"v","k2"=>"v2") into key/value pairs.
std::map<std::string, std::string> ParseOsmOtherTags(const std::string& text);

}  // namespace gissar::geo
