// The memory budget of a job (--max-memory): its default, parsing of sizes
// such as "8G", and the check made before large allocations, so that a job
// too big for the machine fails at once with a message saying how to shrink
// it instead of being killed (or swapping) half-way.
#pragma once

#include <cstdint>
#include <string>

namespace gissar {

// Physical memory available to this process, bytes: the smaller of the
// machine's RAM (sysconf) and the cgroup v1 or v2 limit when there is one
// (CgroupMemoryLimitBytes); 0 when neither can be read.
int64_t PhysicalMemoryBytes();

// The memory limit of the cgroup mounted at `cgroup_root` (normally
// /sys/fs/cgroup), bytes: the smaller of the v2 limit (memory.max) and the
// v1 limit (memory/memory.limit_in_bytes, where values of 2^60 and more mean
// none); 0 when there is neither.
int64_t CgroupMemoryLimitBytes(const std::string& cgroup_root);

// Default --max-memory: 3/4 of PhysicalMemoryBytes() (4 GiB when unknown).
int64_t DefaultMemoryLimitBytes();

// Parses a byte count: a positive number with an optional binary suffix K,
// M, G or T (optionally followed by "iB" or "B"), e.g. "512M", "1.5G",
// "8GiB", "1000000". Throws ConfigError naming `option` for anything else
// (negative, zero, NaN, unknown suffix, overflow).
int64_t ParseByteSize(const std::string& text, const std::string& option);

// "512 MiB", "1.5 GiB", "12 KiB", "100 B".
std::string FormatBytes(double bytes);

// Throws ConfigError(where = "--max-memory") when `needed_bytes` exceeds
// `limit_bytes`: "<what> needs about N, over the memory limit of M;
// <how_to_reduce>, raise --max-memory, or run it anyway with --force". Does nothing otherwise.
void CheckMemoryBudget(double needed_bytes, int64_t limit_bytes, const std::string& what,
                       const std::string& how_to_reduce);

// Most pixels of an image a job makes unless --force (CONVENTIONS, "Memory
// and size"): 2^28 (16384 x 16384).
inline constexpr int64_t kUnforcedImagePixels = int64_t{1} << 28;

// A memory budget at or above this is --force's (the CLI sets INT64_MAX,
// the Python corridor 2^62): it lifts both the budget and the image-size
// limit.
inline constexpr int64_t kForcedMemoryLimitBytes = int64_t{1} << 62;

// Throws ConfigError(where = `option`) when a `width` x `height` image is
// over kUnforcedImagePixels and `limit_bytes` is not forced: "<what> is
// over the 2^28-pixel limit (268435456 pixels); <how_to_reduce>, or run it
// anyway with --force". Does nothing otherwise.
void CheckImagePixels(double width, double height, int64_t limit_bytes, const std::string& what,
                      const std::string& how_to_reduce, const std::string& option);

}  // namespace gissar
