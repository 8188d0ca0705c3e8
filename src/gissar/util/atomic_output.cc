#include "gissar/util/atomic_output.h"

#include <unistd.h>

#include <array>
#include <atomic>
#include <csignal>
#include <cstring>
#include <random>
#include <system_error>

#include "gissar/util/error.h"

namespace gissar {
namespace fs = std::filesystem;
namespace {

// Files to delete on a signal: live temporaries, and the outputs already
// renamed by a Commit() in progress. Kept in fixed storage so the signal
// handler can unlink them without allocating. A slot is kFree, kWriting
// (its path being copied: the handler skips it) or kReady.
constexpr int kMaxLiveTemporaries = 256;
constexpr int kMaxPathBytes = 4096;
enum SlotState : int { kFree = 0, kWriting = 1, kReady = 2 };
std::array<std::atomic<int>, kMaxLiveTemporaries> g_slot_state{};
char g_slot_path[kMaxLiveTemporaries][kMaxPathBytes];

void RegisterTemporary(const fs::path& path) {
  const std::string s = path.string();
  if (s.size() + 1 > static_cast<size_t>(kMaxPathBytes)) return;
  for (int i = 0; i < kMaxLiveTemporaries; ++i) {
    int expected = kFree;
    if (g_slot_state[i].compare_exchange_strong(expected, kWriting)) {
      std::memcpy(g_slot_path[i], s.c_str(), s.size() + 1);
      g_slot_state[i].store(kReady);
      return;
    }
  }
}

void UnregisterTemporary(const fs::path& path) {
  const std::string s = path.string();
  for (int i = 0; i < kMaxLiveTemporaries; ++i) {
    if (g_slot_state[i].load() == kReady && s == g_slot_path[i]) {
      g_slot_state[i].store(kFree);
      return;
    }
  }
}

extern "C" void CleanupOnSignal(int sig) {
  for (int i = 0; i < kMaxLiveTemporaries; ++i) {
    if (g_slot_state[i].load() == kReady) unlink(g_slot_path[i]);
  }
  _exit(128 + sig);
}

std::string RandomSuffix() {
  static std::atomic<unsigned> counter{0};
  std::random_device rd;
  return std::to_string(getpid()) + "-" + std::to_string(counter++) + "-" +
         std::to_string(rd() % 100000);
}

}  // namespace

AtomicOutputs::~AtomicOutputs() {
  if (!committed_) RemoveTemporaries();
}

fs::path AtomicOutputs::Add(const fs::path& final_path) {
  fs::path dir = final_path.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw IoError("output directory does not exist", dir.string());
  }
  if (access(dir.c_str(), W_OK) != 0) {
    throw IoError("output directory is not writable", dir.string());
  }
  if (fs::is_directory(final_path, ec)) {
    throw IoError("output path is a directory", final_path.string());
  }
  fs::path temp = dir / ("." + final_path.filename().string() + ".tmp-" + RandomSuffix());
  RegisterTemporary(temp);
  final_paths_.push_back(final_path);
  temp_paths_.push_back(temp);
  return temp;
}

void AtomicOutputs::Commit() {
  for (size_t i = 0; i < temp_paths_.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(temp_paths_[i], ec)) {
      RemoveTemporaries();
      throw IoError("output was never written", final_paths_[i].string());
    }
  }
  // Until every rename is done, a signal also removes the outputs already
  // renamed: an interrupted run leaves no partial set of outputs.
  for (const fs::path& final_path : final_paths_) RegisterTemporary(final_path);
  for (size_t i = 0; i < temp_paths_.size(); ++i) {
    std::error_code ec;
    fs::rename(temp_paths_[i], final_paths_[i], ec);
    if (ec) {
      const std::string reason = ec.message();
      RemoveTemporaries();
      for (size_t k = 0; k < i; ++k) fs::remove(final_paths_[k], ec);
      for (const fs::path& final_path : final_paths_) UnregisterTemporary(final_path);
      throw IoError("cannot rename output into place: " + reason, final_paths_[i].string());
    }
    UnregisterTemporary(temp_paths_[i]);
  }
  for (const fs::path& final_path : final_paths_) UnregisterTemporary(final_path);
  committed_ = true;
}

void AtomicOutputs::RemoveTemporaries() noexcept {
  for (const fs::path& temp : temp_paths_) {
    std::error_code ec;
    fs::remove(temp, ec);
    UnregisterTemporary(temp);
  }
}

void CheckOutputsAreNotInputs(const std::vector<fs::path>& outputs,
                              const std::vector<std::string>& inputs) {
  for (const fs::path& out : outputs) {
    for (const std::string& input : inputs) {
      std::error_code ec;
      if (!out.empty() && !input.empty() && fs::exists(input, ec) && fs::exists(out, ec) &&
          fs::equivalent(out, input, ec)) {
        throw ConfigError("output would overwrite the input " + input, out.string());
      }
    }
  }
}

void InstallSignalCleanup() {
  static std::atomic<bool> installed{false};
  if (installed.exchange(true)) return;
  struct sigaction action;
  std::memset(&action, 0, sizeof(action));
  action.sa_handler = CleanupOnSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

}  // namespace gissar
