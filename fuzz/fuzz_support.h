// Helpers shared by the libFuzzer harnesses.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace gissar::fuzz {

// An in-memory file (memfd) holding `data`, readable by path as
// "/proc/self/fd/N" through std::ifstream, fopen or GDAL. Closed on
// destruction.
class MemoryFile {
 public:
  MemoryFile(const uint8_t* data, size_t size);
  ~MemoryFile();
  MemoryFile(const MemoryFile&) = delete;
  MemoryFile& operator=(const MemoryFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  int fd_ = -1;
  std::string path_;
};

}  // namespace gissar::fuzz
