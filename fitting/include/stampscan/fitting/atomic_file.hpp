// Output files that appear whole or not at all.
//
// Every file the station writes (PLY clouds and meshes, traces made by the simulator, calibration
// files, run summaries) goes through AtomicFile: the content is written under a temporary name
// beside the target, unique across threads and processes, and renamed over the target once it is
// complete. A reader, another writer or a power cut never sees half a file; two commands writing
// one target leave one complete file, never a mixture. (It lives in fitting/ because the PLY
// writer, the lowest library that writes files, uses it; everything above may use it too.)
//
// Temporaries still pending when SIGINT, SIGTERM or SIGHUP arrives are removed by the handler
// that removeTemporariesOnSignals() installs, before the signal ends the process as it would have.
// A command that handles these signals itself (the scan's operator abort) ends its work normally
// and the destructors remove them.
//
// Several files that only make sense together (a calibration set) are replaced with
// commitTogether(): all are written first, then renamed in one step with the signals blocked, so
// an interrupted command leaves the old set or the new one.
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

namespace stampscan::fitting {

class AtomicFile {
 public:
  // Picks the temporary name (with this process's id); nothing is created until the caller writes
  // to temporaryPath(). Temporaries of the same target left by a process that no longer runs (killed
  // before any handler could remove them) are removed first.
  explicit AtomicFile(std::filesystem::path target);
  ~AtomicFile();  // removes the temporary unless committed
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::filesystem::path& target() const { return target_; }
  const std::filesystem::path& temporaryPath() const { return temporary_; }

  // Renames the temporary over the target. Throws std::runtime_error naming the target when the
  // temporary is missing or the rename fails (the temporary is then removed).
  void commit();
  bool committed() const { return committed_; }

 private:
  std::filesystem::path target_, temporary_;
  int slot_ = -1;  // in the signal handler's table of pending temporaries
  bool committed_ = false;
};

// Writes `contents` to `file` through an AtomicFile. Throws naming the file on failure.
void writeFileAtomically(const std::filesystem::path& file, std::string_view contents);

// Renames every temporary over its target, and removes the `stale` files of an older set that the
// new set does not replace, with SIGINT, SIGTERM and SIGHUP held back, so that an interrupted
// command leaves the whole old set or the whole new one.
void commitTogether(const std::vector<AtomicFile*>& files, const std::vector<std::filesystem::path>& stale = {});

// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove the pending temporaries and then
// end the process by the same signal. Call once at start-up; commands that install their own
// handlers replace these for as long as they run.
void removeTemporariesOnSignals();

}  // namespace stampscan::fitting
