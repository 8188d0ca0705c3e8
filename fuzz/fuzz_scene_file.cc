// Fuzzes the binary scene reader (scene::ReadScene): any bytes must give a
// valid scene (indices in range, finite vertices, one class per triangle) or
// a gissar::Error.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz_support.h"
#include "gissar/scene/scene_io.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  try {
    const gissar::scene::SceneFile scene = gissar::scene::ReadScene(file.path());
    const auto& mesh = scene.mesh;
    if (mesh.classes.size() != mesh.triangles.size()) std::abort();
    for (const Eigen::Vector3i& t : mesh.triangles) {
      if ((t.array() < 0).any() || (t.array() >= static_cast<int>(mesh.vertices.size())).any()) {
        std::abort();
      }
    }
    mesh.Bounds();
  } catch (const gissar::Error&) {
  }
  return 0;
}
