// All-or-nothing output sets (docs/robustness.md, "Commit protocol").
//
// Each output is written under a short temporary name in its final directory
// (".gs-<prefix hash>-<unique>.tmp", at most 40 bytes, so an output name of
// 255 bytes still works); Commit() then moves the whole set into place:
//   1. every temporary must exist (else IoError, and nothing changes);
//   2. every existing final output gets a hard-link backup (".gs-...bak");
//   3. each temporary is renamed over its final name;
//   4. the commit point: the set is complete; the backups are removed.
// An interrupt (SIGINT, SIGTERM, SIGHUP: see InstallSignalCleanup) before the
// commit point restores every backup over its final name and removes the new
// outputs that had none, so the previous set is left exactly as it was; an
// interrupt after it leaves the complete new set. Either way no temporary is
// left. Nothing is kept in a fixed-size table: any number of outputs, any
// number of live AtomicOutputs objects.
//
// Each object takes an advisory lock (flock) on its output prefix — by default
// the first output's directory and file name without extension, or the one
// given with LockPrefix() — held until destruction: a second concurrent run on
// the same prefix fails at once (IoError "another gissar run is writing ...").
// The lock file (".gs-<hash>.lock") exists only while the lock is held. Once
// the lock is taken, temporaries and backups that a killed run (SIGKILL) left
// on the same prefix are removed.
//
// Test hook (tests only): GISSAR_TEST_COMMIT_PAUSE="<stage>:<marker file>"
// makes Commit() create the marker file and sleep (until a signal, at most 120
// s) at <stage>: "written" (temporaries complete, nothing renamed yet) or
// "renamed" (after the first rename, before the commit point).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "gissar/util/error.h"

namespace gissar {

class AtomicOutputs {
 public:
  AtomicOutputs() = default;
  AtomicOutputs(const AtomicOutputs&) = delete;
  AtomicOutputs& operator=(const AtomicOutputs&) = delete;
  ~AtomicOutputs();

  // Sets the output prefix to lock (e.g. "--out" as given: dir/stem). Must be
  // called before the first Add(); takes the lock at once. Throws IoError when
  // another run holds it or the directory is missing / not writable.
  void LockPrefix(const std::filesystem::path& prefix);

  // Registers `final_path` and returns the temporary path to write instead
  // (same directory, short hidden name). Throws IoError when the directory
  // does not exist or is not writable, when `final_path` exists and is not a
  // regular file (a directory, a device, a FIFO), or when another run holds
  // the prefix lock; ConfigError when `final_path` names the same file as an
  // output registered earlier.
  std::filesystem::path Add(const std::filesystem::path& final_path);

  // Moves every output into place (protocol above). Throws IoError if a
  // temporary is missing (it was never written) or a rename fails; the
  // previous outputs are then restored and no temporary is left.
  void Commit();

  const std::vector<std::filesystem::path>& final_paths() const { return final_paths_; }

 private:
  void Lock(const std::filesystem::path& prefix);
  void Release() noexcept;

  std::vector<std::filesystem::path> final_paths_;
  std::vector<std::filesystem::path> resolved_;  // absolute, normalised final paths
  std::vector<std::filesystem::path> temp_paths_;
  std::vector<void*> nodes_;  // signal-handler records, one per output
  void* lock_node_ = nullptr;
  int lock_fd_ = -1;
  std::string lock_path_;
  std::string hash_;
  bool committed_ = false;
};

// Throws ConfigError("output would overwrite the input X", output) when one
// of `outputs` names the same existing file as one of `inputs` (compared with
// std::filesystem::equivalent, so links and different spellings count), and
// ConfigError("two outputs name the same file X", output) when two outputs do
// (also before they exist); InputError when an input is a FIFO, a device or a
// socket (GDAL "/vsi..." paths are not checked); empty entries are ignored. Commands call it before
// reading anything.
void CheckOutputsAreNotInputs(const std::vector<std::filesystem::path>& outputs,
                              const std::vector<std::string>& inputs);

// The output a file being written stands for: the final path when `path` is
// the temporary of an output registered with a live AtomicOutputs (Add()),
// else `path` itself. Write errors name it, never the ".gs-...tmp" name.
std::filesystem::path OutputPathOf(const std::filesystem::path& path);

// A full disk: `error` (errno right after the failed write or close) is
// ENOSPC or EDQUOT (also /dev/full), or the file system holding `path` has no
// block left for this user (statvfs: GDAL's and giflib's errors carry no
// errno).
bool OutOfSpace(int error, const std::filesystem::path& path);
// "no space left on the device holding DIR" (DIR: the directory of `path`).
std::string NoSpaceMessage(const std::filesystem::path& path);

// The error of a failed write or close of `path` (any file, or the temporary
// of an AtomicOutputs output), `error` being errno right after it (0 when
// unknown): IoError("<what>: no space left on the device holding DIR", OUT)
// on a full disk (OutOfSpace), else IoError("<what>", OUT); OUT =
// OutputPathOf(path). Every writer of outputs reports through it.
IoError WriteError(const std::string& what, const std::filesystem::path& path, int error);

// Installs SIGINT/SIGTERM/SIGHUP handlers that finish or undo the commit in
// progress as described above, remove every live temporary and lock file, and
// exit with status 128 + signal (130/143/129). Idempotent.
void InstallSignalCleanup();

}  // namespace gissar
