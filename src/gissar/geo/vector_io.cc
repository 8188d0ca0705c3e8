#include "gissar/geo/vector_io.h"

#include <gdal_priv.h>
#include <ogr_geometry.h>
#include <ogrsf_frmts.h>

#include <memory>

#include "gissar/geo/gdal_env.h"
#include "gissar/util/error.h"

namespace gissar::geo {
namespace fs = std::filesystem;
namespace {

std::string GdalPath(const std::string& path) {
  if (path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0) return "/vsigzip/" + path;
  return path;
}

DatasetPtr OpenVector(const std::string& path) {
  EnsureGdal();
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError("vector file does not exist", path);
  if (fs::is_directory(path, ec) && fs::is_empty(path, ec)) {
    throw InputError("vector path is an empty directory", path);
  }
  DatasetPtr ds(GDALDataset::Open(GdalPath(path).c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) throw InputError("not vector data OGR can read", path);
  return ds;
}

Ring ToRing(const OGRLinearRing* ring) {
  Ring out;
  out.reserve(ring->getNumPoints());
  for (int i = 0; i < ring->getNumPoints(); ++i) out.emplace_back(ring->getX(i), ring->getY(i));
  return out;
}

void Collect(const OGRGeometry* geometry, VectorFeature& feature) {
  if (geometry == nullptr) return;
  switch (wkbFlatten(geometry->getGeometryType())) {
    case wkbPolygon: {
      const auto* polygon = geometry->toPolygon();
      if (polygon->getExteriorRing() == nullptr) return;
      PolygonRings rings{ToRing(polygon->getExteriorRing())};
      for (int i = 0; i < polygon->getNumInteriorRings(); ++i) {
        rings.push_back(ToRing(polygon->getInteriorRing(i)));
      }
      feature.polygons.push_back(std::move(rings));
      return;
    }
    case wkbLineString: {
      const auto* line = geometry->toLineString();
      LinePoints points;
      for (int i = 0; i < line->getNumPoints(); ++i) points.emplace_back(line->getX(i), line->getY(i));
      feature.lines.push_back(std::move(points));
      return;
    }
    case wkbMultiPolygon:
    case wkbMultiLineString:
    case wkbGeometryCollection: {
      const auto* collection = geometry->toGeometryCollection();
      for (int i = 0; i < collection->getNumGeometries(); ++i) {
        Collect(collection->getGeometryRef(i), feature);
      }
      return;
    }
    default:
      if (geometry->hasCurveGeometry()) {
        std::unique_ptr<OGRGeometry> linear(geometry->getLinearGeometry());
        Collect(linear.get(), feature);
      }
      return;
  }
}

bool AllFinite(const VectorFeature& feature) {
  for (const PolygonRings& polygon : feature.polygons) {
    for (const Ring& ring : polygon) {
      for (const Eigen::Vector2d& p : ring) {
        if (!p.allFinite()) return false;
      }
    }
  }
  for (const LinePoints& line : feature.lines) {
    for (const Eigen::Vector2d& p : line) {
      if (!p.allFinite()) return false;
    }
  }
  return true;
}

}  // namespace

std::map<std::string, std::string> ParseOsmOtherTags(const std::string& text) {
  std::map<std::string, std::string> tags;
  size_t i = 0;
  auto read_quoted = [&](std::string* out) {
    while (i < text.size() && text[i] != '"') ++i;
    if (i >= text.size()) return false;
    ++i;
    out->clear();
    while (i < text.size() && text[i] != '"') {
      if (text[i] == '\\' && i + 1 < text.size()) ++i;
      out->push_back(text[i++]);
    }
    if (i >= text.size()) return false;
    ++i;
    return true;
  };
  std::string key, value;
  while (read_quoted(&key)) {
    if (text.compare(i, 2, "=>") != 0) break;
    i += 2;
    if (!read_quoted(&value)) break;
    tags[key] = value;
  }
  return tags;
}

std::vector<std::string> ListVectorLayers(const std::string& path) {
  DatasetPtr ds = OpenVector(path);
  std::vector<std::string> names;
  for (int i = 0; i < ds->GetLayerCount(); ++i) names.emplace_back(ds->GetLayer(i)->GetName());
  return names;
}

std::vector<VectorFeature> ReadVectorLayer(const VectorLayerRequest& request,
                                           const std::string& target_crs_wkt) {
  DatasetPtr ds = OpenVector(request.path);
  OGRLayer* layer = nullptr;
  if (request.layer.empty()) {
    if (ds->GetLayerCount() != 1) {
      throw InputError("source has " + std::to_string(ds->GetLayerCount()) +
                           " layers: name the one to read",
                       request.path);
    }
    layer = ds->GetLayer(0);
  } else {
    layer = ds->GetLayerByName(request.layer.c_str());
  }
  if (layer == nullptr) {
    std::string names;
    for (int i = 0; i < ds->GetLayerCount(); ++i) {
      names += (i ? ", " : "") + std::string(ds->GetLayer(i)->GetName());
    }
    throw InputError("no layer '" + request.layer + "' (layers: " + names + ")", request.path);
  }
  const std::string where = request.path + ", layer " + layer->GetName();
  if (!request.where.empty() && layer->SetAttributeFilter(request.where.c_str()) != OGRERR_NONE) {
    throw InputError("invalid attribute filter '" + request.where + "': " + LastGdalMessage(), where);
  }
  const OGRSpatialReference* source_srs = layer->GetSpatialRef();
  if (source_srs == nullptr) throw InputError("layer has no coordinate reference system", where);
  OGRSpatialReference target;
  if (target.SetFromUserInput(target_crs_wkt.c_str()) != OGRERR_NONE) {
    throw InputError("cannot parse the target CRS", where);
  }
  // Features are placed horizontally (their heights come from the DEM): the
  // horizontal part of a compound DEM CRS (e.g. EPSG:4326+5773).
  if (target.IsCompound()) target.StripVertical();
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRSpatialReference source(*source_srs);
  source.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> transform(
      OGRCreateCoordinateTransformation(&source, &target));
  if (!transform) throw InputError("no transformation to the DEM's CRS: " + LastGdalMessage(), where);

  std::vector<VectorFeature> features;
  layer->ResetReading();
  const bool osm = std::string(ds->GetDriverName()) == "OSM";
  if (osm) ds->ResetReading();
  for (auto& ogr_feature : *layer) {
    OGRGeometry* geometry = ogr_feature->GetGeometryRef();
    if (geometry == nullptr) continue;
    if (geometry->transform(transform.get()) != OGRERR_NONE) {
      throw InputError("cannot reproject feature " + std::to_string(ogr_feature->GetFID()), where);
    }
    VectorFeature feature;
    feature.fid = ogr_feature->GetFID();
    Collect(geometry, feature);
    if (feature.polygons.empty() && feature.lines.empty()) continue;
    if (!AllFinite(feature)) {
      throw InputError("feature " + std::to_string(feature.fid) +
                           " has a non-finite coordinate (NaN or infinity)",
                       where);
    }
    std::string other_tags;
    for (int i = 0; i < ogr_feature->GetFieldCount(); ++i) {
      if (!ogr_feature->IsFieldSetAndNotNull(i)) continue;
      const std::string name = ogr_feature->GetFieldDefnRef(i)->GetNameRef();
      const std::string value = ogr_feature->GetFieldAsString(i);
      if (name == "other_tags") other_tags = value;
      feature.fields[name] = value;
    }
    if (!other_tags.empty()) {
      for (const auto& [k, v] : ParseOsmOtherTags(other_tags)) feature.fields.emplace(k, v);
    }
    features.push_back(std::move(feature));
  }
  return features;
}

}  // namespace gissar::geo
