// Fuzzes the JSON scene config reader and the material overrides it carries
// (scene::LoadSceneConfig, material::SceneMaterials): any bytes must give a
// config or a gissar::Error, never a crash, a hang or another exception.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "gissar/material/material.h"
#include "gissar/scene/scene_config.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  try {
    const gissar::scene::SceneConfig config = gissar::scene::LoadSceneConfig(file.path());
    gissar::material::SceneMaterials(config.materials, config.source);
    config.ToJson().dump();
  } catch (const gissar::Error&) {
  }
  return 0;
}
