#include "fuzz_support.h"

#include <sys/mman.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>

namespace gissar::fuzz {

MemoryFile::MemoryFile(const uint8_t* data, size_t size) {
  fd_ = memfd_create("gissar-fuzz", 0);
  if (fd_ < 0) std::abort();
  size_t written = 0;
  while (written < size) {
    const ssize_t n = write(fd_, data + written, size - written);
    if (n <= 0) std::abort();
    written += static_cast<size_t>(n);
  }
  path_ = "/proc/self/fd/" + std::to_string(fd_);
}

MemoryFile::~MemoryFile() { close(fd_); }

namespace {

// The per-process directory of NamedFile, removed at exit when empty.
const std::string& TempDirectory() {
  static const std::string dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern = std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/gissar-fuzz-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) std::abort();
    std::atexit([] { rmdir(TempDirectory().c_str()); });
    return pattern;
  }();
  return dir;
}

}  // namespace

NamedFile::NamedFile(const uint8_t* data, size_t size, const std::string& name) {
  path_ = TempDirectory() + "/" + name;
  FILE* f = std::fopen(path_.c_str(), "wb");
  if (f == nullptr) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  if (std::fclose(f) != 0) std::abort();
}

NamedFile::~NamedFile() { std::remove(path_.c_str()); }

}  // namespace gissar::fuzz
