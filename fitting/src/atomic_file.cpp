#include "stampscan/fitting/atomic_file.hpp"

#include <pthread.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <system_error>

namespace stampscan::fitting {

namespace fs = std::filesystem;

namespace {

// The temporaries the signal handler removes. A signal handler may only touch lock-free atomics
// and call async-signal-safe functions (unlink, nanosleep, raise), so the paths live in a fixed
// table of plain character arrays, each guarded by its own state.
enum SlotState : int { kFree = 0, kBusy = 1, kArmed = 2 };
constexpr int kSlots = 256;
constexpr std::size_t kPathBytes = 4096;
struct PendingSlot {
  std::atomic<int> state{kFree};
  char path[kPathBytes] = {};
};
PendingSlot g_pending[kSlots];
// Set while commitTogether() renames: a signal arriving on another thread then waits for the
// renames to finish rather than removing half of a set.
std::atomic<int> g_committing{0};
static_assert(std::atomic<int>::is_always_lock_free);

int armSlot(const fs::path& temporary) {
  const std::string& text = temporary.native();
  if (text.size() >= kPathBytes) return -1;  // not tracked; the destructor still removes it
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (!g_pending[i].state.compare_exchange_strong(expected, kBusy)) continue;
    std::memcpy(g_pending[i].path, text.c_str(), text.size() + 1);
    g_pending[i].state.store(kArmed);
    return i;
  }
  return -1;  // more than kSlots outputs at once: the extra ones are not tracked
}

void releaseSlot(int slot) {
  if (slot < 0) return;
  g_pending[slot].state.store(kBusy);
  g_pending[slot].path[0] = '\0';
  g_pending[slot].state.store(kFree);
}

void onTerminatingSignal(int signal_number) {
  const timespec pause{0, 1'000'000};
  for (int waited = 0; g_committing.load() > 0 && waited < 2000; ++waited) nanosleep(&pause, nullptr);
  for (PendingSlot& slot : g_pending) {
    if (slot.state.load() == kArmed) ::unlink(slot.path);
  }
  ::signal(signal_number, SIG_DFL);
  ::raise(signal_number);
}

// A name beside `file` that no other writer, in this process or another, picks at the same time:
// "<file>.tmp-<pid>-<12 hex digits>". The writer's process id in it lets a later writer of the same
// file tell a temporary left by a killed process (SIGKILL, a power cut: no handler ran) from one
// still being written.
constexpr char kTemporaryMark[] = ".tmp-";
fs::path temporaryPathFor(const fs::path& file) {
  static std::atomic<std::uint64_t> counter{0};
  static const std::uint64_t processSalt = [] {
    std::random_device device;
    return (std::uint64_t{device()} << 32) ^ device() ^ static_cast<std::uint64_t>(::getpid());
  }();
  for (int attempt = 0;; ++attempt) {
    const auto tick = static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
    std::uint64_t mixed = processSalt ^ (tick * 0x9E3779B97F4A7C15ull) ^ (++counter << 48);
    std::string suffix = kTemporaryMark + std::to_string(::getpid()) + "-";
    for (int digit = 0; digit < 12; ++digit, mixed >>= 4) suffix += "0123456789abcdef"[mixed & 0xf];
    fs::path candidate = file;
    candidate += suffix;
    std::error_code error;
    if (!fs::exists(candidate, error) || attempt >= 16) return candidate;
  }
}

// Removes the temporaries of `file` whose writer no longer runs (temporaryPathFor's names with the
// process id of a process that does not exist). One whose process still runs, or whose name does
// not parse, is left alone.
void removeOrphanedTemporaries(const fs::path& file) {
  const std::string prefix = file.filename().string() + kTemporaryMark;
  std::error_code error;
  fs::directory_iterator it(file.parent_path().empty() ? fs::path(".") : file.parent_path(), error);
  if (error) return;
  for (const fs::directory_entry& entry : it) {
    const std::string name = entry.path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::size_t dash = name.find('-', prefix.size());
    if (dash == std::string::npos || dash == prefix.size()) continue;
    long pid = 0;
    try {
      std::size_t used = 0;
      pid = std::stol(name.substr(prefix.size(), dash - prefix.size()), &used);
      if (used != dash - prefix.size()) continue;
    } catch (const std::exception&) {
      continue;
    }
    if (pid <= 0 || pid == ::getpid()) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to ask)
    std::error_code ignored;
    fs::remove(entry.path(), ignored);
  }
}

// Holds back the terminating signals on this thread and tells handlers on other threads to wait.
class CommitWindow {
 public:
  CommitWindow() {
    sigset_t held;
    sigemptyset(&held);
    for (const int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&held, s);
    pthread_sigmask(SIG_BLOCK, &held, &previous_);
    ++g_committing;
  }
  ~CommitWindow() {
    --g_committing;
    pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
  }
  CommitWindow(const CommitWindow&) = delete;
  CommitWindow& operator=(const CommitWindow&) = delete;

 private:
  sigset_t previous_{};
};

// The finished temporary's bytes written into a target that is not a regular file.
void copyInto(const fs::path& temporary, const fs::path& target) {
  std::ifstream in(temporary, std::ios::binary);
  std::ofstream out(target, std::ios::binary);
  if (!in || !out) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error(target.string() + ": cannot be written (" + std::generic_category().message(errno) + ")");
  }
  if (in.peek() != std::ifstream::traits_type::eof()) out << in.rdbuf();
  out.flush();
  if (!out) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw std::runtime_error(target.string() + ": cannot be written (writing into it failed)");
  }
}

}  // namespace

AtomicFile::AtomicFile(fs::path target) : target_(std::move(target)), temporary_(temporaryPathFor(target_)) {
  removeOrphanedTemporaries(target_);
  slot_ = armSlot(temporary_);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ignored;
    fs::remove(temporary_, ignored);
  }
  releaseSlot(slot_);
}

void AtomicFile::commit() {
  if (committed_) return;
  std::error_code error;
  // A device or a pipe named as the output (/dev/null, /dev/stdout, a FIFO) is written to, never
  // replaced: renaming over it would put a plain file where the device was.
  if (const fs::file_status target = fs::status(target_, error);
      !error && fs::exists(target) && !fs::is_regular_file(target) && !fs::is_directory(target)) {
    copyInto(temporary_, target_);
    fs::remove(temporary_, error);
    committed_ = true;
    releaseSlot(slot_);
    slot_ = -1;
    return;
  }
  error.clear();
  // Atomic on POSIX file systems: readers see the old file or the complete new one, never a part.
  fs::rename(temporary_, target_, error);
  if (error) {
    fs::remove(temporary_, error);
    throw std::runtime_error(target_.string() + ": cannot be written (renaming the finished temporary file over it failed: " +
                             error.message() + ")");
  }
  committed_ = true;
  releaseSlot(slot_);
  slot_ = -1;
}

void writeFileAtomically(const fs::path& file, std::string_view contents) {
  AtomicFile output(file);
  {
    std::ofstream out(output.temporaryPath(), std::ios::binary | std::ios::trunc);
    if (!out) {
      throw std::runtime_error(file.string() + ": cannot be written (cannot create " + output.temporaryPath().string() +
                               ": " + std::generic_category().message(errno) + ")");
    }
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.close();
    if (!out) throw std::runtime_error(file.string() + ": cannot be written (disk full?)");
  }
  output.commit();
}

void commitTogether(const std::vector<AtomicFile*>& files, const std::vector<fs::path>& stale) {
  // Every temporary must exist before the first rename, so that a missing one cannot leave the
  // set half replaced.
  for (const AtomicFile* file : files) {
    std::error_code error;
    if (!file->committed() && !fs::is_regular_file(file->temporaryPath(), error)) {
      throw std::runtime_error(file->target().string() + ": cannot be written (its temporary file is missing)");
    }
  }
  const CommitWindow window;
  for (AtomicFile* file : files) file->commit();
  for (const fs::path& old : stale) {
    std::error_code error;
    fs::remove(old, error);
    if (error) throw std::runtime_error(old.string() + ": cannot be removed (" + error.message() + ")");
  }
}

void removeTemporariesOnSignals() {
  struct sigaction action {};
  action.sa_handler = onTerminatingSignal;
  sigemptyset(&action.sa_mask);
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) ::sigaction(s, &action, nullptr);
}

}  // namespace stampscan::fitting
