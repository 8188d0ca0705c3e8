#include "gissar/material/material.h"

#include <cmath>

#include "gissar/util/error.h"

namespace gissar::material {

double Material::Backscatter(double cos_incidence) const {
  if (cos_incidence <= 0.0) return 0.0;
  double value = diffuse * cos_incidence;
  if (specular > 0.0) {
    const double cos_mirror = 2.0 * cos_incidence * cos_incidence - 1.0;  // cos(2 theta)
    if (cos_mirror > 0.0) value += specular * std::pow(cos_mirror, 1.0 / roughness);
  }
  return value;
}

void Material::Check() const {
  const std::pair<const char*, double> coefficients[] = {
      {"diffuse", diffuse}, {"specular", specular}, {"mirror", mirror}};
  for (const auto& [key, value] : coefficients) {
    if (!std::isfinite(value) || value < 0.0 || value > 1.0) {
      throw ConfigError(std::string(key) + " must be in [0, 1], is " + std::to_string(value),
                        "material " + name);
    }
  }
  if (!std::isfinite(roughness) || roughness <= 0.0 || roughness > 1.0) {
    throw ConfigError("roughness must be in (0, 1], is " + std::to_string(roughness),
                      "material " + name);
  }
}

MaterialTable::MaterialTable() : materials_(1) {}

void MaterialTable::Set(scene::ClassId id, Material material) {
  material.Check();
  if (id >= materials_.size()) materials_.resize(size_t(id) + 1);
  materials_[id] = std::move(material);
}

const Material& MaterialTable::Get(scene::ClassId id) const {
  return id < materials_.size() ? materials_[id] : materials_[0];
}

nlohmann::json MaterialTable::ToJson() const {
  nlohmann::json j = nlohmann::json::object();
  for (const Material& m : materials_) {
    j[m.name] = {{"diffuse", m.diffuse}, {"specular", m.specular}, {"roughness", m.roughness},
                 {"mirror", m.mirror}};
  }
  return j;
}

Material DefaultMaterial(scene::ClassId id) {
  switch (id) {
    case scene::kClassWater:
      return {"water", 0.03, 0.9, 0.05, 0.9};
    case scene::kClassForest:
      return {"forest", 0.85, 0.05, 1.0, 0.0};
    case scene::kClassUrban:
      return {"urban", 0.6, 0.3, 0.3, 0.3};
    case scene::kClassRoad:
      return {"road", 0.12, 0.6, 0.1, 0.5};
    case scene::kClassBuilding:
      return {"building", 0.4, 0.6, 0.15, 0.7};
    case scene::kClassSea:  // water's until the sea gets its own model
      return {"sea", 0.03, 0.9, 0.05, 0.9};
    default:
      return {"default", 0.5, 0.1, 0.6, 0.0};
  }
}

MaterialTable SceneMaterials(const nlohmann::json& overrides, const std::string& source) {
  MaterialTable table;
  for (int c = 0; c < scene::kClassCount; ++c) table.Set(c, DefaultMaterial(c));
  if (overrides.is_null()) return table;
  if (!overrides.is_object()) throw ConfigError("'materials' must be an object", source);
  for (const auto& [name, fields] : overrides.items()) {
    const auto id = scene::ClassIdFromName(name);
    if (!id) throw ConfigError("unknown key 'materials." + name + "' (not a class)", source);
    if (!fields.is_object()) throw ConfigError("'materials." + name + "' must be an object", source);
    Material m = table.Get(*id);
    for (const auto& [key, value] : fields.items()) {
      const std::string where = "materials." + name + "." + key;
      if (!value.is_number()) throw ConfigError("'" + where + "' must be a number", source);
      const double v = value.get<double>();
      if (key == "diffuse") {
        m.diffuse = v;
      } else if (key == "specular") {
        m.specular = v;
      } else if (key == "roughness") {
        m.roughness = v;
      } else if (key == "mirror") {
        m.mirror = v;
      } else {
        throw ConfigError("unknown key '" + where + "'", source);
      }
    }
    try {
      m.Check();
    } catch (const ConfigError& e) {
      throw ConfigError("'materials." + name + "': " + e.message(), source);
    }
    table.Set(*id, m);
  }
  return table;
}

}  // namespace gissar::material
