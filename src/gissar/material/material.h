// Radar reflection properties per scene class. The foundation renderer uses
// the Lambertian diffuse term; the specular and mirror terms are added with
// the radiometry work.
#pragma once

#include <string>
#include <vector>

#include "gissar/scene/triangle_mesh.h"

namespace gissar::material {

struct Material {
  std::string name = "default";
  // Lambertian reflectivity rho in [0, 1]: a surface facing the radar at
  // local incidence theta returns rho * cos(theta) of the incident power.
  double diffuse = 1.0;

  // Throws ConfigError naming the material when a coefficient is negative,
  // above 1 or not finite.
  void Check() const;
};

// Materials indexed by scene::ClassId.
class MaterialTable {
 public:
  // One "default" Lambertian material with rho = 1 for class 0.
  MaterialTable();

  // Sets the material of class `id` (growing the table with defaults).
  void Set(scene::ClassId id, Material material);
  // The material of class `id`; the default material when unset.
  const Material& Get(scene::ClassId id) const;
  size_t size() const { return materials_.size(); }

 private:
  std::vector<Material> materials_;
};

}  // namespace gissar::material
