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

// A real file named `name` (e.g. "in.csv", for readers that go by the
// extension) holding `data`, in a per-process directory under $TMPDIR
// (/tmp), made once and reused; the file is removed on destruction.
class NamedFile {
 public:
  NamedFile(const uint8_t* data, size_t size, const std::string& name);
  ~NamedFile();
  NamedFile(const NamedFile&) = delete;
  NamedFile& operator=(const NamedFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace gissar::fuzz
