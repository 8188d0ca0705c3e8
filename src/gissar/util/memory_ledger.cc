#include "gissar/util/memory_ledger.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include "gissar/util/error.h"
#include "gissar/util/memory_limit.h"

namespace gissar {
namespace {

struct Entry {
  int64_t pid = 0;
  uint64_t start_ticks = 0;
  uint64_t id = 0;
  double bytes = 0.0;
};

// Field 22 of /proc/<pid>/stat (the process's start time in clock ticks since
// boot), 0 when it cannot be read. The command name (field 2) may hold spaces
// and parentheses, so the fields are counted after its last ')'.
uint64_t StartTicks(int64_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t close = text.rfind(')');
  if (close == std::string::npos) return 0;
  std::istringstream fields(text.substr(close + 1));
  std::string field;
  for (int index = 3; index <= 22 && fields >> field; ++index) {
    if (index == 22) return std::strtoull(field.c_str(), nullptr, 10);
  }
  return 0;
}

// The process that made the entry still runs (same pid, same start time).
bool Alive(const Entry& e) {
  if (e.pid <= 0) return false;
  if (kill(static_cast<pid_t>(e.pid), 0) != 0 && errno == ESRCH) return false;
  const uint64_t now = StartTicks(e.pid);
  return now == 0 || e.start_ticks == 0 || now == e.start_ticks;
}

// The ledger, open and exclusively locked for the lifetime of the object;
// fd() < 0 when it cannot be opened.
class LockedLedger {
 public:
  explicit LockedLedger(const std::string& path) {
    fd_ = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
    if (fd_ < 0) return;
    while (flock(fd_, LOCK_EX) != 0) {
      if (errno != EINTR) {
        close(fd_);
        fd_ = -1;
        return;
      }
    }
  }
  ~LockedLedger() {
    if (fd_ >= 0) close(fd_);  // also releases the flock
  }
  LockedLedger(const LockedLedger&) = delete;
  LockedLedger& operator=(const LockedLedger&) = delete;
  int fd() const { return fd_; }

  // The live entries (malformed lines and dead processes' entries dropped);
  // `pruned` tells whether anything was dropped.
  std::vector<Entry> Read(bool* pruned) const {
    std::string text;
    char buffer[4096];
    lseek(fd_, 0, SEEK_SET);
    for (ssize_t n; (n = read(fd_, buffer, sizeof(buffer))) != 0;) {
      if (n < 0) {
        if (errno == EINTR) continue;
        break;
      }
      text.append(buffer, static_cast<size_t>(n));
    }
    std::vector<Entry> live;
    std::istringstream lines(text);
    std::string line;
    *pruned = false;
    while (std::getline(lines, line)) {
      std::istringstream fields(line);
      Entry e;
      if (!(fields >> e.pid >> e.start_ticks >> e.id >> e.bytes) || !(e.bytes >= 0.0) || !Alive(e)) {
        *pruned = true;
        continue;
      }
      live.push_back(e);
    }
    return live;
  }

  void Write(const std::vector<Entry>& entries) const {
    std::string text;
    for (const Entry& e : entries) {
      text += std::to_string(e.pid) + " " + std::to_string(e.start_ticks) + " " + std::to_string(e.id) + " " +
              std::to_string(static_cast<int64_t>(e.bytes)) + "\n";
    }
    if (ftruncate(fd_, 0) != 0) return;
    lseek(fd_, 0, SEEK_SET);
    for (size_t done = 0; done < text.size();) {
      const ssize_t n = write(fd_, text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return;  // a full /dev/shm: the entries not written do not count (checked alone)
      done += static_cast<size_t>(n);
    }
  }

 private:
  int fd_ = -1;
};

std::atomic<uint64_t> next_id{1};

std::string UserLedgerName() { return "gissar-memory-" + std::to_string(getuid()) + ".ledger"; }

bool IsDirectory(const char* path) {
  struct stat s {};
  return path != nullptr && *path != '\0' && stat(path, &s) == 0 && S_ISDIR(s.st_mode) && access(path, W_OK) == 0;
}

}  // namespace

MemoryReservation::MemoryReservation(MemoryReservation&& other) noexcept
    : ledger_path_(std::move(other.ledger_path_)), id_(std::exchange(other.id_, 0)),
      bytes_(std::exchange(other.bytes_, 0.0)), waited_s_(other.waited_s_) {}

MemoryReservation& MemoryReservation::operator=(MemoryReservation&& other) noexcept {
  if (this != &other) {
    Release();
    ledger_path_ = std::move(other.ledger_path_);
    id_ = std::exchange(other.id_, 0);
    bytes_ = std::exchange(other.bytes_, 0.0);
    waited_s_ = other.waited_s_;
  }
  return *this;
}

MemoryReservation::~MemoryReservation() { Release(); }

void MemoryReservation::Release() noexcept {
  if (id_ == 0) return;
  try {
    const LockedLedger ledger(ledger_path_);
    if (ledger.fd() >= 0) {
      bool pruned = false;
      std::vector<Entry> entries = ledger.Read(&pruned);
      const int64_t pid = getpid();
      std::erase_if(entries, [&](const Entry& e) { return e.pid == pid && e.id == id_; });
      ledger.Write(entries);
    }
  } catch (...) {  // NOLINT(bugprone-empty-catch): releasing never throws; a dead process's entry is dropped anyway
  }
  id_ = 0;
  bytes_ = 0.0;
}

std::string DefaultMemoryLedgerPath() {
  if (const char* path = std::getenv("GISSAR_MEMORY_LEDGER"); path != nullptr && *path != '\0') return path;
  if (const char* runtime = std::getenv("XDG_RUNTIME_DIR"); IsDirectory(runtime)) {
    return std::string(runtime) + "/gissar-memory.ledger";
  }
  if (IsDirectory("/dev/shm")) return "/dev/shm/" + UserLedgerName();
  return "/tmp/" + UserLedgerName();
}

LedgerTotal ReadMemoryLedger(const std::string& ledger_path) {
  LedgerTotal total;
  const LockedLedger ledger(ledger_path);
  if (ledger.fd() < 0) return total;
  bool pruned = false;
  for (const Entry& e : ledger.Read(&pruned)) {
    total.bytes += e.bytes;
    ++total.entries;
  }
  return total;
}

MemoryReservation ReserveMemory(double needed_bytes, int64_t limit_bytes, const std::string& what,
                                const std::string& how_to_reduce, double max_wait_s, const std::string& ledger_path,
                                const std::function<void(const std::string&)>& waiting) {
  CheckMemoryBudget(needed_bytes, limit_bytes, what, how_to_reduce);
  MemoryReservation reservation;
  if (limit_bytes >= kForcedMemoryLimitBytes || !(needed_bytes > 0.0)) return reservation;
  const auto started = std::chrono::steady_clock::now();
  auto pause = std::chrono::milliseconds(20);
  const int64_t pid = getpid();
  const uint64_t start_ticks = StartTicks(pid);
  bool told = false;
  while (true) {
    LedgerTotal others;
    {
      const LockedLedger ledger(ledger_path);
      if (ledger.fd() < 0) return reservation;  // no ledger: checked alone (above)
      bool pruned = false;
      std::vector<Entry> entries = ledger.Read(&pruned);
      for (const Entry& e : entries) {
        others.bytes += e.bytes;
        ++others.entries;
      }
      if (others.bytes + needed_bytes <= static_cast<double>(limit_bytes)) {
        reservation.ledger_path_ = ledger_path;
        reservation.id_ = next_id.fetch_add(1);
        reservation.bytes_ = needed_bytes;
        entries.push_back(Entry{pid, start_ticks, reservation.id_, needed_bytes});
        ledger.Write(entries);
        break;
      }
      if (pruned) ledger.Write(entries);
    }
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    if (waited >= max_wait_s) {
      throw ConfigError(what + " needs about " + FormatBytes(needed_bytes) + ", and other gissar runs on this " +
                            "machine hold " + FormatBytes(others.bytes) + " of the memory limit of " +
                            FormatBytes(static_cast<double>(limit_bytes)) + " (" + std::to_string(others.entries) +
                            (others.entries == 1 ? " run" : " runs") + ", ledger " + ledger_path + "; waited " +
                            std::to_string(static_cast<int>(waited)) + " s); run it when they have finished, " +
                            how_to_reduce + ", raise --max-memory, or run it anyway with --force",
                        "--max-memory");
    }
    if (waiting && !told) {
      told = true;
      waiting(what + " needs about " + FormatBytes(needed_bytes) + "; waiting for other gissar runs on this machine, " +
              "which hold " + FormatBytes(others.bytes) + " of the memory limit of " +
              FormatBytes(static_cast<double>(limit_bytes)) + " (" + std::to_string(others.entries) +
              (others.entries == 1 ? " run" : " runs") + "), at most " + std::to_string(static_cast<int>(max_wait_s)) +
              " s");
    }
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::milliseconds(250));
  }
  reservation.waited_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return reservation;
}

}  // namespace gissar
