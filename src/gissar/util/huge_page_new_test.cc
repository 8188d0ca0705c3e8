#include "gissar/util/huge_page_new.h"

#include <gtest/gtest.h>
#include <sys/mman.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace gissar {
namespace {

// The VmFlags line of the /proc/self/smaps mapping holding `address` ("" if none).
std::string VmFlagsOf(const void* address) {
  std::ifstream smaps("/proc/self/smaps");
  const auto at = reinterpret_cast<std::uintptr_t>(address);
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    unsigned long long begin = 0, end = 0;
    if (std::sscanf(line.c_str(), "%llx-%llx ", &begin, &end) == 2 && line.find(' ') > line.find('-')) {
      inside = at >= begin && at < end;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      return line.substr(8) + " ";
    }
  }
  return "";
}

bool Advised(const void* address) { return VmFlagsOf(address).find(" hg ") != std::string::npos; }

// A 16 MiB anonymous mapping advised for huge pages carries the kernel's
// "hg" flag; a 1 MiB one (under kHugePageAdviceBytes) is left alone.
TEST(HugePageNewTest, LargeRegionsAreAdvisedSmallOnesAreNot) {
  for (const std::size_t bytes : {std::size_t{16} << 20, std::size_t{1} << 20}) {
    void* region = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    ASSERT_NE(region, MAP_FAILED);
    ASSERT_FALSE(Advised(region)) << VmFlagsOf(region);
    AdviseHugePages(region, bytes);
    // The advice covers the whole huge pages inside the region: its last byte's page when the
    // region is large (a 16 MiB mapping holds at least seven aligned 2 MiB pages).
    const char* last = static_cast<const char*>(region) + bytes - 1;
    EXPECT_EQ(Advised(last) || Advised(static_cast<const char*>(region) + bytes / 2), bytes >= kHugePageAdviceBytes)
        << bytes << " bytes: " << VmFlagsOf(last);
    munmap(region, bytes);
  }
  AdviseHugePages(nullptr, std::size_t{64} << 20);  // nothing to advise, no fault
}

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
// In this executable (linked with gissar_huge_page_new) a 64 MiB vector's
// storage is advised, and its values are what was written.
TEST(HugePageNewTest, OperatorNewAdvisesLargeAllocations) {
  std::vector<float> plane(std::size_t{16} << 20, 1.5f);
  EXPECT_TRUE(Advised(plane.data() + plane.size() / 2)) << VmFlagsOf(plane.data() + plane.size() / 2);
  EXPECT_EQ(plane.front(), 1.5f);
  EXPECT_EQ(plane.back(), 1.5f);
  auto array = std::make_unique<double[]>(std::size_t{8} << 20);
  EXPECT_TRUE(Advised(array.get() + (std::size_t{4} << 20)));
  EXPECT_EQ(array[(std::size_t{8} << 20) - 1], 0.0);
}
#endif

}  // namespace
}  // namespace gissar
