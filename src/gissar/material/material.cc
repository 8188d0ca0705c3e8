#include "gissar/material/material.h"

#include <cmath>

#include "gissar/util/error.h"

namespace gissar::material {

void Material::Check() const {
  if (!std::isfinite(diffuse) || diffuse < 0.0 || diffuse > 1.0) {
    throw ConfigError("diffuse reflectivity must be in [0, 1], is " + std::to_string(diffuse),
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

}  // namespace gissar::material
