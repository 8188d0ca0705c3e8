// Radar reflection properties per scene class, RaySAR-style: a Lambertian
// diffuse term, a specular highlight in a cone whose width follows the
// surface roughness, and a mirror reflectivity that continues a ray (used by
// the multi-bounce renderer).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gissar/scene/scene_config.h"
#include "gissar/scene/triangle_mesh.h"

namespace gissar::material {

struct Material {
  std::string name = "default";
  // Lambertian reflectivity: returns diffuse * cos(theta) of the incident
  // power at local incidence theta.
  double diffuse = 1.0;
  // Specular highlight strength: returns specular * cos(2 theta)^(1/roughness)
  // towards the radar (the mirror direction's cosine with the view
  // direction is cos(2 theta) in backscatter), zero beyond theta = 45 deg.
  double specular = 0.0;
  // In (0, 1]: small values give a narrow cone (smooth surface).
  double roughness = 1.0;
  // Share of the power that continues as a mirror-reflected ray.
  double mirror = 0.0;

  // Single-bounce backscatter for cos(local incidence) `cos_incidence`
  // (values <= 0: back face, returns 0).
  double Backscatter(double cos_incidence) const;

  // Throws ConfigError naming the material when a coefficient is negative,
  // above 1, not finite, or roughness is not in (0, 1].
  void Check() const;
};

// Materials indexed by scene::ClassId.
class MaterialTable {
 public:
  // One "default" Lambertian material with diffuse = 1 for class 0.
  MaterialTable();

  // Sets the material of class `id` (growing the table with defaults).
  void Set(scene::ClassId id, Material material);
  // The material of class `id`; the class-0 material when unset.
  const Material& Get(scene::ClassId id) const;
  size_t size() const { return materials_.size(); }

  nlohmann::json ToJson() const;

 private:
  std::vector<Material> materials_;
};

// The default material of each GIS scene class, following the thesis's
// approximations (docs/scene.md): water strongly specular and dark in
// diffuse backscatter, forest strongly diffuse, roads specular, buildings
// reflective.
Material DefaultMaterial(scene::ClassId id);

// The table of every scene class: defaults, overridden by `overrides`
// ({"water": {"diffuse": 0.02, ...}}, keys diffuse/specular/roughness/mirror).
// Throws ConfigError naming the key and `source` for unknown classes or
// keys, non-numbers and out-of-range values.
MaterialTable SceneMaterials(const nlohmann::json& overrides, const std::string& source);

}  // namespace gissar::material
