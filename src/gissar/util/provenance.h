// Provenance records for output sidecars: every output carries a JSON file
// with the options, the input files (path, size, SHA-256) and the version.
#pragma once

#include <filesystem>
#include <future>
#include <string>

#include <nlohmann/json.hpp>

namespace gissar {

// "gissar <semver> (<git describe>)".
std::string VersionString();

// SHA-256 of a file's bytes as lowercase hex. Throws IoError when the file
// cannot be read.
std::string Sha256OfFile(const std::filesystem::path& path);

// {"path": absolute path, "bytes": size, "sha256": hex}. Throws IoError when
// the file cannot be read. A GDAL in-memory raster (/vsimem/..., the Python
// door's arrays, geo/memory_raster.h) has no file: {"path", "in_memory": true}.
nlohmann::json InputFileRecord(const std::filesystem::path& path);

// InputFileRecord of `path`, computed on a thread of its own from the
// moment it is made (its checksum reads the whole file: a job's own work
// overlaps it). Get() waits for the record and throws what InputFileRecord
// threw; a default-made one has no record (Get() fails a GISSAR_CHECK).
// Destroying it waits for the thread.
class PendingInputRecord {
 public:
  PendingInputRecord() = default;
  explicit PendingInputRecord(const std::filesystem::path& path);
  nlohmann::json Get() const;

 private:
  std::shared_future<nlohmann::json> record_;
};

// Writes `value` pretty-printed to `path` (a plain write: callers route it
// through AtomicOutputs). Throws IoError on failure (WriteError of
// atomic_output.h: a full disk says "no space left", naming the output).
void WriteJsonFile(const nlohmann::json& value, const std::filesystem::path& path);

// Current UTC time as ISO 8601 ("2026-11-23T10:00:00Z").
std::string UtcTimestamp();

// The fields every provenance record starts with: {"command", "command_line",
// "version", "created_utc" (now), "options"}. Callers add inputs and results.
nlohmann::json ProvenanceHeader(const std::string& command, const std::string& command_line,
                                const nlohmann::json& options);

}  // namespace gissar
