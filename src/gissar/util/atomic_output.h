// All-or-nothing output files. Each output is written under a temporary name
// in its final directory; Commit() renames every one of them to its final
// name. If the object is destroyed without Commit() (an exception, an early
// return) the temporaries are deleted, so a failure never leaves a partial or
// half-written output behind. Temporaries are also deleted when the process
// receives SIGINT or SIGTERM (see InstallSignalCleanup).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace gissar {

class AtomicOutputs {
 public:
  AtomicOutputs() = default;
  AtomicOutputs(const AtomicOutputs&) = delete;
  AtomicOutputs& operator=(const AtomicOutputs&) = delete;
  ~AtomicOutputs();

  // Registers `final_path` and returns the temporary path to write instead
  // (same directory, hidden name). Throws IoError when the directory does not
  // exist or is not writable, or when `final_path` is a directory.
  std::filesystem::path Add(const std::filesystem::path& final_path);

  // Renames every temporary to its final path. Throws IoError if a temporary
  // is missing (it was never written) or a rename fails; the temporaries left
  // and the outputs already renamed are then removed.
  void Commit();

  const std::vector<std::filesystem::path>& final_paths() const { return final_paths_; }

 private:
  void RemoveTemporaries() noexcept;

  std::vector<std::filesystem::path> final_paths_;
  std::vector<std::filesystem::path> temp_paths_;
  bool committed_ = false;
};

// Throws ConfigError("output would overwrite the input X", output) when one
// of `outputs` names the same existing file as one of `inputs` (compared with
// std::filesystem::equivalent, so links and different spellings count);
// empty entries are ignored. Commands call it before reading anything.
void CheckOutputsAreNotInputs(const std::vector<std::filesystem::path>& outputs,
                              const std::vector<std::string>& inputs);

// Installs SIGINT/SIGTERM handlers that delete every live temporary output
// (and, during a Commit(), the outputs it already renamed, so an interrupted
// run leaves none of its outputs) and exit with status 128 + signal
// (130/143). Idempotent.
void InstallSignalCleanup();

}  // namespace gissar
