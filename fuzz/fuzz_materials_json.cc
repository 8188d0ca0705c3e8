// Fuzzes the materials file reader of `simulate --materials`
// (material::ReadMaterialsFile, then material::SceneMaterials as
// pipeline/simulate.cc applies it): any bytes must give a material table or
// a gissar::Error, never a crash, a hang or another exception.
// (fuzz_scene_config covers the same overrides inside a scene config.)
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "gissar/material/material.h"
#include "gissar/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const gissar::fuzz::MemoryFile file(data, size);
  try {
    const nlohmann::json overrides = gissar::material::ReadMaterialsFile(file.path());
    gissar::material::SceneMaterials(overrides, file.path());
  } catch (const gissar::Error&) {
  }
  return 0;
}
