#include "gissar/util/atomic_output.h"

#include <fcntl.h>
#include <sched.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "gissar/util/error.h"

namespace gissar {
namespace fs = std::filesystem;
namespace {

// What the signal handler does with a record (docs/robustness.md):
enum Stage : int {
  kFree = 0,      // unused (reusable)
  kWriting = 1,   // being filled in: skipped
  kUnlink = 2,    // a temporary or the lock file: unlink(temp)
  kBackup = 3,    // final had an old version, saved as backup: unlink(temp);
                  // before the commit point rename(backup, final), after it unlink(backup)
  kNoBackup = 4,  // final had no old version: unlink(temp); before the commit point unlink(final)
};

constexpr size_t kPathBytes = 4096;

// One record per live temporary. Records form an append-only linked list that
// is never freed (records are reused), so the handler can walk it at any time
// without locks or allocation: there is no fixed limit on their number.
struct Node {
  std::atomic<int> stage{kFree};
  std::atomic<int> committed{0};         // used on a transaction's first record
  std::atomic<std::atomic<int>*> commit_flag{nullptr};
  Node* next = nullptr;
  char temp[kPathBytes] = {};
  char final_path[kPathBytes] = {};
  char backup[kPathBytes] = {};
};

std::atomic<Node*> g_head{nullptr};

void CopyPath(char* dst, const std::string& s) {
  const size_t n = std::min(s.size(), kPathBytes - 1);
  std::memcpy(dst, s.data(), n);
  dst[n] = '\0';
}

Node* AcquireNode(const std::string& temp, const std::string& final_path, const std::string& backup) {
  Node* node = nullptr;
  for (Node* n = g_head.load(); n != nullptr; n = n->next) {
    int expected = kFree;
    if (n->stage.compare_exchange_strong(expected, kWriting)) {
      node = n;
      break;
    }
  }
  if (node == nullptr) {
    node = new Node;  // never freed: the handler may read it at any time
    node->stage.store(kWriting);
    Node* head = g_head.load();
    do {
      node->next = head;
    } while (!g_head.compare_exchange_weak(head, node));
  }
  CopyPath(node->temp, temp);
  CopyPath(node->final_path, final_path);
  CopyPath(node->backup, backup);
  node->committed.store(0);
  node->commit_flag.store(&node->committed);
  node->stage.store(kUnlink);
  return node;
}

void ReleaseNode(Node* node) {
  if (node != nullptr) node->stage.store(kFree);
}

// Commit steps and the handler exclude each other: a handler running on
// another thread waits for the step in progress to end, and the committing
// thread takes no further step once the handler has started.
std::atomic<bool> g_exiting{false};
std::atomic<int> g_step_busy{0};
std::atomic<long> g_commit_tid{0};

long ThreadId() { return static_cast<long>(syscall(SYS_gettid)); }

void EnterStep() {
  g_step_busy.store(1);
  if (g_exiting.load()) {
    g_step_busy.store(0);
    for (;;) pause();  // the handler is about to _exit
  }
}
void LeaveStep() { g_step_busy.store(0); }

struct StepGuard {
  StepGuard() { EnterStep(); }
  ~StepGuard() { LeaveStep(); }
};

extern "C" void CleanupOnSignal(int sig) {
  g_exiting.store(true);
  if (ThreadId() != g_commit_tid.load()) {
    while (g_step_busy.load() != 0) sched_yield();
  }
  for (Node* n = g_head.load(); n != nullptr; n = n->next) {
    const int stage = n->stage.load();
    if (stage < kUnlink) continue;
    unlink(n->temp);
    const std::atomic<int>* flag = n->commit_flag.load();
    const bool committed = flag != nullptr && flag->load() != 0;
    if (stage == kBackup) {
      if (committed) {
        unlink(n->backup);
      } else {
        rename(n->backup, n->final_path);
        unlink(n->backup);  // rename is a no-op when both name the same file
      }
    } else if (stage == kNoBackup && !committed) {
      unlink(n->final_path);
    }
  }
  _exit(128 + sig);
}

std::string Hex(uint64_t value, int digits) {
  static const char* kDigits = "0123456789abcdef";
  std::string s(static_cast<size_t>(digits), '0');
  for (int i = digits - 1; i >= 0; --i, value >>= 4) s[static_cast<size_t>(i)] = kDigits[value & 15];
  return s;
}

uint64_t Fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::string UniqueSuffix() {
  static std::atomic<uint64_t> counter{0};
  const uint64_t pid = static_cast<uint64_t>(getpid());
  return Hex(pid, 6) + Hex(counter++, 6);
}

fs::path DirectoryOf(const fs::path& path) {
  fs::path dir = path.parent_path();
  return dir.empty() ? fs::path(".") : dir;
}

// The absolute, normalised spelling of `path` (symbolic links in the existing
// part resolved), for comparing outputs before they exist.
fs::path Resolved(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) p = fs::absolute(path, ec).lexically_normal();
  return p;
}

void CheckDirectory(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw IoError("output directory does not exist", dir.string());
  if (access(dir.c_str(), W_OK) != 0) throw IoError("output directory is not writable", dir.string());
}

// Test hook: GISSAR_TEST_COMMIT_PAUSE="<stage>:<marker>".
void MaybePause(const char* stage) {
  const char* env = std::getenv("GISSAR_TEST_COMMIT_PAUSE");
  if (env == nullptr) return;
  const std::string value = env;
  const size_t colon = value.find(':');
  if (colon == std::string::npos || value.substr(0, colon) != stage) return;
  const std::string marker = value.substr(colon + 1);
  const int fd = open(marker.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd >= 0) close(fd);
  for (int i = 0; i < 1200; ++i) usleep(100000);
}

void TestHookCheck(const char* stage) { MaybePause(stage); }

}  // namespace

AtomicOutputs::~AtomicOutputs() {
  if (!committed_) {
    for (size_t i = 0; i < temp_paths_.size(); ++i) {
      std::error_code ec;
      fs::remove(temp_paths_[i], ec);
    }
  }
  for (void* node : nodes_) ReleaseNode(static_cast<Node*>(node));
  Release();
}

void AtomicOutputs::LockPrefix(const fs::path& prefix) {
  if (lock_fd_ >= 0) return;
  Lock(prefix);
}

void AtomicOutputs::Lock(const fs::path& prefix) {
  const fs::path dir = DirectoryOf(prefix);
  CheckDirectory(dir);
  const fs::path resolved = Resolved(dir) / prefix.filename();
  hash_ = Hex(Fnv1a(resolved.string()), 16);
  const fs::path lock_path = dir / (".gs-" + hash_ + ".lock");
  for (int attempt = 0; attempt < 20; ++attempt) {
    const int fd = open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd < 0) {
      throw IoError(std::string("cannot create the output lock file: ") + std::strerror(errno), lock_path.string());
    }
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
      close(fd);
      throw IoError("another gissar run is writing outputs with this prefix (lock " +
                        lock_path.filename().string() + ")",
                    prefix.string());
    }
    // The holder before us may have removed the file after we opened it:
    // the lock only counts on the file that is still there.
    struct stat held {}, current {};
    if (fstat(fd, &held) == 0 && stat(lock_path.c_str(), &current) == 0 && held.st_ino == current.st_ino &&
        held.st_dev == current.st_dev) {
      lock_fd_ = fd;
      lock_path_ = lock_path.string();
      lock_node_ = AcquireNode(lock_path_, "", "");
      break;
    }
    close(fd);
  }
  if (lock_fd_ < 0) throw IoError("cannot take the output lock", lock_path.string());
  // Leftovers of a run on this prefix that was killed (SIGKILL): nothing else
  // can be writing them while we hold the lock.
  const std::string stem = ".gs-" + hash_ + "-";
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(stem, 0) == 0 && name.size() > 4 &&
        (name.compare(name.size() - 4, 4, ".tmp") == 0 || name.compare(name.size() - 4, 4, ".bak") == 0)) {
      std::error_code rm;
      fs::remove(it->path(), rm);
    }
  }
}

void AtomicOutputs::Release() noexcept {
  if (lock_fd_ < 0) return;
  unlink(lock_path_.c_str());  // while still holding the lock (see Lock)
  ReleaseNode(static_cast<Node*>(lock_node_));
  lock_node_ = nullptr;
  close(lock_fd_);
  lock_fd_ = -1;
}

fs::path AtomicOutputs::Add(const fs::path& final_path) {
  const fs::path dir = DirectoryOf(final_path);
  CheckDirectory(dir);
  std::error_code ec;
  const fs::file_status status = fs::status(final_path, ec);
  if (fs::is_directory(status)) throw IoError("output path is a directory", final_path.string());
  if (fs::exists(status) && !fs::is_regular_file(status)) {
    throw IoError("output exists and is not a regular file", final_path.string());
  }
  if (final_path.string().size() + 1 > kPathBytes) throw IoError("output path is too long", final_path.string());
  if (final_path.filename().string().size() > 255) {
    throw IoError("output file name is longer than 255 bytes", final_path.string());
  }
  const fs::path resolved = Resolved(final_path);
  for (size_t i = 0; i < final_paths_.size(); ++i) {
    std::error_code eq;
    if (resolved_[i] == resolved || (fs::exists(status) && fs::equivalent(final_paths_[i], final_path, eq))) {
      throw ConfigError("two outputs name the same file " + final_paths_[i].string(), final_path.string());
    }
  }
  if (lock_fd_ < 0) {
    fs::path prefix = final_path;
    prefix.replace_extension();
    Lock(prefix);
  }
  const fs::path temp = dir / (".gs-" + hash_ + "-" + UniqueSuffix() + ".tmp");
  nodes_.push_back(AcquireNode(temp.string(), final_path.string(), ""));
  final_paths_.push_back(final_path);
  resolved_.push_back(resolved);
  temp_paths_.push_back(temp);
  return temp;
}

void AtomicOutputs::Commit() {
  for (size_t i = 0; i < temp_paths_.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(temp_paths_[i], ec)) {
      for (const fs::path& t : temp_paths_) fs::remove(t, ec);
      throw IoError("output was never written", final_paths_[i].string());
    }
  }
  g_commit_tid.store(ThreadId());
  const size_t n = nodes_.size();
  std::vector<Node*> nodes(n);
  for (size_t i = 0; i < n; ++i) nodes[i] = static_cast<Node*>(nodes_[i]);
  std::atomic<int>* flag = n > 0 ? &nodes[0]->committed : nullptr;
  if (flag != nullptr) {
    flag->store(0);
    for (Node* node : nodes) node->commit_flag.store(flag);
  }
  std::vector<fs::path> backups(n);
  std::vector<bool> has_backup(n, false);
  // Undoes every step taken so far (a failed rename): the previous set back.
  auto roll_back = [&](size_t renamed) {
    StepGuard step;
    for (size_t k = 0; k < n; ++k) {
      std::error_code ec;
      fs::remove(temp_paths_[k], ec);
      if (has_backup[k]) {
        rename(backups[k].c_str(), final_paths_[k].c_str());
        unlink(backups[k].c_str());
      } else if (k < renamed) {
        fs::remove(final_paths_[k], ec);
      }
      nodes[k]->stage.store(kUnlink);
    }
  };
  // Backups of the previous outputs (hard links; a rename where links fail).
  for (size_t i = 0; i < n; ++i) {
    struct stat st {};
    if (lstat(final_paths_[i].c_str(), &st) != 0) continue;
    backups[i] = DirectoryOf(final_paths_[i]) / (".gs-" + hash_ + "-" + UniqueSuffix() + ".bak");
    StepGuard step;
    CopyPath(nodes[i]->backup, backups[i].string());
    nodes[i]->stage.store(kBackup);
    if (link(final_paths_[i].c_str(), backups[i].c_str()) != 0 &&
        rename(final_paths_[i].c_str(), backups[i].c_str()) != 0) {
      const std::string reason = std::strerror(errno);
      nodes[i]->stage.store(kUnlink);
      LeaveStep();
      roll_back(0);
      throw IoError("cannot keep the previous output while replacing it: " + reason, final_paths_[i].string());
    }
    has_backup[i] = true;
  }
  TestHookCheck("written");
  for (size_t i = 0; i < n; ++i) {
    {
      StepGuard step;
      if (!has_backup[i]) nodes[i]->stage.store(kNoBackup);
      if (rename(temp_paths_[i].c_str(), final_paths_[i].c_str()) != 0) {
        const std::string reason = std::strerror(errno);
        LeaveStep();
        roll_back(i);
        throw IoError("cannot rename output into place: " + reason, final_paths_[i].string());
      }
    }
    if (i == 0) TestHookCheck("renamed");
  }
  {
    StepGuard step;
    if (flag != nullptr) flag->store(1);  // the commit point
    committed_ = true;
  }
  for (size_t i = 0; i < n; ++i) {
    StepGuard step;
    if (has_backup[i]) unlink(backups[i].c_str());
    nodes[i]->stage.store(kUnlink);
  }
}

void CheckOutputsAreNotInputs(const std::vector<fs::path>& outputs, const std::vector<std::string>& inputs) {
  // Inputs that would never end (a FIFO, a device, a socket) are refused
  // before anything opens them; GDAL virtual paths (/vsizip/...) are not local.
  for (const std::string& input : inputs) {
    if (input.empty() || input.rfind("/vsi", 0) == 0) continue;
    struct stat st {};
    if (stat(input.c_str(), &st) != 0) continue;  // missing: the reader says so
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) || S_ISSOCK(st.st_mode)) {
      throw InputError("input is not a regular file (a FIFO, device or socket)", input);
    }
  }
  for (const fs::path& out : outputs) {
    for (const std::string& input : inputs) {
      std::error_code ec;
      if (!out.empty() && !input.empty() && fs::exists(input, ec) && fs::exists(out, ec) &&
          fs::equivalent(out, input, ec)) {
        throw ConfigError("output would overwrite the input " + input, out.string());
      }
    }
  }
  for (size_t i = 0; i < outputs.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (outputs[i].empty() || outputs[j].empty()) continue;
      std::error_code ec;
      if (Resolved(outputs[i]) == Resolved(outputs[j]) || fs::equivalent(outputs[i], outputs[j], ec)) {
        throw ConfigError("two outputs name the same file " + outputs[j].string(), outputs[i].string());
      }
    }
  }
}

fs::path OutputPathOf(const fs::path& path) {
  const std::string text = path.string();
  if (text.empty()) return path;
  for (Node* n = g_head.load(); n != nullptr; n = n->next) {
    // Output records only (the lock file's has no final path); a record
    // being filled in or free is skipped, and one reused meanwhile is not
    // trusted (its stage is read again after its paths).
    if (n->stage.load() < kUnlink || n->final_path[0] == '\0' || text != n->temp) continue;
    const std::string final_path = n->final_path;
    if (n->stage.load() >= kUnlink && text == n->temp) return final_path;
  }
  return path;
}

bool OutOfSpace(int error, const fs::path& path) {
  if (error == ENOSPC || error == EDQUOT) return true;
  std::error_code ec;
  fs::path dir = fs::absolute(path, ec).lexically_normal().parent_path();
  if (ec || dir.empty()) dir = ".";
  struct statvfs st {};
  // Blocks free to unprivileged users; root may still use the reserved
  // ones (f_bfree), and a write fails for it only when those are gone too.
  // No block accounting (e.g. /proc), or read-only (squashfs reports no free block).
  if (statvfs(dir.c_str(), &st) != 0 || st.f_blocks == 0 || (st.f_flag & ST_RDONLY) != 0) return false;
  return (geteuid() == 0 ? st.f_bfree : st.f_bavail) == 0;
}

std::string NoSpaceMessage(const fs::path& path) {
  std::error_code ec;
  fs::path dir = fs::absolute(path, ec).lexically_normal().parent_path();
  if (ec || dir.empty()) dir = fs::current_path(ec);
  return "no space left on the device holding " + dir.string();
}

IoError WriteError(const std::string& what, const fs::path& path, int error) {
  const std::string output = OutputPathOf(path).string();
  if (OutOfSpace(error, path)) return IoError(what + ": " + NoSpaceMessage(path), output);
  return IoError(what, output);
}

void InstallSignalCleanup() {
  static std::atomic<bool> installed{false};
  if (installed.exchange(true)) return;
  struct sigaction action;
  std::memset(&action, 0, sizeof(action));
  action.sa_handler = CleanupOnSignal;
  sigemptyset(&action.sa_mask);
  sigaddset(&action.sa_mask, SIGINT);
  sigaddset(&action.sa_mask, SIGTERM);
  sigaddset(&action.sa_mask, SIGHUP);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  sigaction(SIGHUP, &action, nullptr);
}

}  // namespace gissar
