// Transparent huge pages for large C++ allocations.
//
// Linking the object library gissar_huge_page_new into an executable
// replaces the global operator new/delete (and their array forms) with ones
// that allocate with malloc, as the standard library does, and then advise
// the kernel (madvise MADV_HUGEPAGE) to back every whole 2 MiB page of an
// allocation of kHugePageAdviceBytes or more with a transparent huge page.
// The first touch of a fresh DEM, mesh or image plane then takes one page
// fault per 2 MiB instead of one per 4 KiB: on the 2-core virtual machines
// gissar is measured on (THP in "madvise" mode), page faults were about a
// fifth of a 4000 x 4000 exact simulation (docs/performance.md). Resident
// memory is unchanged for the dense arrays gissar allocates.
//
// It is what glibc's GLIBC_TUNABLES=glibc.malloc.hugetlb=1 does for every
// malloc, without an environment variable read at process start. Sanitized
// builds keep the sanitizer's own operator new (the file then defines
// nothing), so new/delete mismatches are still reported. Only executables
// link it (the gissar CLI, the benchmarks, util_test); a library never
// replaces its host's allocator (the Python module does not).
#pragma once

#include <cstddef>

namespace gissar {

// Allocations of at least this many bytes are advised (two huge pages: a
// smaller one may hold no whole aligned huge page).
inline constexpr std::size_t kHugePageAdviceBytes = std::size_t{4} << 20;

// Advises MADV_HUGEPAGE for the whole 2 MiB pages inside [data, data +
// bytes) when bytes >= kHugePageAdviceBytes; does nothing otherwise, or
// where the kernel refuses (the advice is a hint: failures are ignored).
void AdviseHugePages(void* data, std::size_t bytes) noexcept;

}  // namespace gissar
