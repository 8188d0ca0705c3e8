// One memory budget shared by the gissar runs of a machine (docs/robustness.md
// "Load: many runs at once").
//
// CheckMemoryBudget (memory_limit.h) compares one run's need with its
// --max-memory; fifty runs started at once would each pass it and together
// exhaust the machine. ReserveMemory also counts what the other live runs
// of this user have reserved, in a small ledger file every run shares:
//   - a run whose need fits beside the others' reservations is recorded and
//     goes on;
//   - a run whose need fits the budget alone but not beside them waits for
//     them to finish (polling; a run killed with SIGKILL stops counting at
//     once, its process being gone), up to `max_wait_s`, then is refused;
//   - a run whose need exceeds the budget alone is refused at once, as by
//     CheckMemoryBudget.
// Refusals are ConfigError (where "--max-memory") raised before the large
// allocations. A forced budget (>= kForcedMemoryLimitBytes, --force)
// reserves nothing and never waits.
//
// The ledger: $GISSAR_MEMORY_LEDGER when set (runs that name one file share a
// budget), else "gissar-memory.ledger" in $XDG_RUNTIME_DIR, else
// /dev/shm/gissar-memory-<uid>.ledger, else /tmp/gissar-memory-<uid>.ledger.
// One line per reservation: "<pid> <process start ticks> <id> <bytes>",
// rewritten under an exclusive flock; entries of processes that no longer
// exist (pid gone or reused: the start time differs) are dropped.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace gissar {

// A reservation held in the ledger until destruction (or Release()). Movable,
// not copyable; a default-constructed one holds nothing.
class MemoryReservation {
 public:
  MemoryReservation() = default;
  MemoryReservation(MemoryReservation&& other) noexcept;
  MemoryReservation& operator=(MemoryReservation&& other) noexcept;
  MemoryReservation(const MemoryReservation&) = delete;
  MemoryReservation& operator=(const MemoryReservation&) = delete;
  ~MemoryReservation();

  // Bytes reserved; 0 when nothing is held.
  double bytes() const { return bytes_; }
  // Seconds spent waiting for other runs before the reservation was made.
  double waited_s() const { return waited_s_; }
  // Removes the entry from the ledger now (idempotent, never throws).
  void Release() noexcept;

 private:
  friend MemoryReservation ReserveMemory(double, int64_t, const std::string&, const std::string&, double,
                                         const std::string&, const std::function<void(const std::string&)>&);
  std::string ledger_path_;
  uint64_t id_ = 0;
  double bytes_ = 0.0;
  double waited_s_ = 0.0;
};

// The ledger file this process uses (see above).
std::string DefaultMemoryLedgerPath();

// How long ReserveMemory waits for other runs by default, seconds.
inline constexpr double kDefaultMemoryWaitSeconds = 600.0;

// Reserves `needed_bytes` against `limit_bytes` shared with the other live
// reservations in `ledger_path` (rules above). Throws ConfigError
// ("--max-memory") when the need exceeds the limit alone ("<what> needs about
// N, over the memory limit of M; <how_to_reduce>, raise --max-memory, or run
// it anyway with --force") or when `max_wait_s` passed without room beside
// the other runs ("... other gissar runs on this machine hold H of the memory
// limit of M (K runs) ..."). Where the ledger cannot be opened (no writable
// directory), the run is checked alone, as by CheckMemoryBudget, and the
// returned reservation holds nothing. `waiting`, when given, is called once
// with a line saying what the run waits for when it starts waiting.
MemoryReservation ReserveMemory(double needed_bytes, int64_t limit_bytes, const std::string& what,
                                const std::string& how_to_reduce, double max_wait_s = kDefaultMemoryWaitSeconds,
                                const std::string& ledger_path = DefaultMemoryLedgerPath(),
                                const std::function<void(const std::string&)>& waiting = {});

// Bytes reserved by live runs in `ledger_path` and their number (tests, messages).
struct LedgerTotal {
  double bytes = 0.0;
  int entries = 0;
};
LedgerTotal ReadMemoryLedger(const std::string& ledger_path = DefaultMemoryLedgerPath());

}  // namespace gissar
