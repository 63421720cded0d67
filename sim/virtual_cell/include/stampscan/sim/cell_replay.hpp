// Replay: the virtual cell fed from a recorded trace instead of the simulator. A scan recorded on a
// real cell (or on the virtual one) runs again through the drivers, the ScanRunner and the
// measurement:
//   - the virtual CMM follows the recorded head track: each move it is sent on is found in the
//     recording (the next one, after the last followed, that leaves from where the machine stands
//     and arrives at the target) and played with its recorded timing;
//   - the digitizer serves, at each tick, the recorded profile exposed nearest to the matching
//     instant of the recording, stamped with that profile's own exposure;
//   - the cameras serve the recorded frame nearest to the matching instant.
// "The matching instant": each followed move fixes the offset between the replay's clock and the
// recording's station clock (recorded = replay + offset) until the next one, so the profiles of a
// sweep meet the head poses they met when recorded, however long the runner took in between.
//
// The recording's station times: profiles are stamped by the digitizer, whose clock pairs put them
// on the station clock with the median offset, as the measurement does; frames count from when they
// reached the station.
//
// Thread safety: every member may be called from any thread (the CMM's executor, the digitizer's
// and the cameras' threads).
#pragma once

#include "stampscan/acquisition/scan_plan.hpp"

#include "stampscan/acquisition/trace/mcap_reader.hpp"
#include "stampscan/acquisition/trace/session_description.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::sim {

struct RecordedPose {
  std::int64_t station_time_ns = 0;
  std::array<double, 3> xyz{};  // mm
  double head_a = 0, head_b = 0;  // rad
};

struct RecordedProfile {
  std::int64_t station_time_ns = 0;  // its stamp on the recording's station clock
  std::uint32_t status = 0;
  std::vector<float> range;
  std::vector<std::uint16_t> intensity;
};

struct RecordedFrame {
  std::int64_t station_time_ns = 0;
  std::uint32_t width = 0, height = 0, bytes_per_pixel = 1;
  std::vector<std::uint8_t> data;  // rows without padding
};

struct RecordedSession {
  trace::SessionDescription session;
  std::vector<RecordedPose> head;          // by time
  std::vector<RecordedProfile> profiles;   // by time
  std::vector<RecordedFrame> frames[2];    // left, right; by time
  trace::TraceHealth health;
};

// Reads what a replay needs from a trace. Throws std::runtime_error naming the file when it is not
// a trace, has no session description, no CMM positions, or (with profiles) no digitizer clock pairs.
RecordedSession loadRecordedSession(const std::filesystem::path& trace);

struct ReplayStats {
  std::size_t moves_followed = 0, moves_not_recorded = 0;
  std::size_t profiles_served = 0, profiles_missing = 0, frames_served = 0;
};

class CellReplay {
 public:
  explicit CellReplay(RecordedSession session);
  CellReplay(const CellReplay&) = delete;
  CellReplay& operator=(const CellReplay&) = delete;

  const RecordedSession& recording() const { return recording_; }

  // For VirtualCmmConfig::follow (six axes: mm and degrees).
  std::optional<FollowedMove> followMove(const std::array<double, 6>& from, const std::array<double, 6>& to,
                                         std::chrono::steady_clock::time_point now);
  // The recording's station time at a replay instant.
  std::int64_t recordedTime(std::chrono::steady_clock::time_point t) const;
  // The recorded profile stamped nearest to `recorded_ns`, when one is within `tolerance_ns`.
  const RecordedProfile* profileNear(std::int64_t recorded_ns, std::int64_t tolerance_ns);
  // The recorded frame of camera 0 (left) or 1 (right) nearest to `recorded_ns`, within `tolerance_ns`.
  const RecordedFrame* frameNear(int camera, std::int64_t recorded_ns, std::int64_t tolerance_ns);

  ReplayStats stats() const;

  // Keeps the time map in `offset_ns` and `known` (lock-free atomics, e.g. in memory shared between
  // processes) instead of in this object: the process that follows the moves writes it, the others
  // (`station sim serve` runs the cameras apart from the CMM) read it. Call before any other member.
  void shareTimeMap(std::atomic<std::int64_t>* offset_ns, std::atomic<bool>* known);

 private:
  RecordedSession recording_;
  double report_interval_s_ = 0.01;  // the recording's usual spacing of position reports in a move
  mutable std::mutex mutex_;
  std::size_t cursor_ = 0;  // head samples before it belong to moves already followed
  std::int64_t offset_ns_ = 0;  // recorded station time minus replay steady time
  bool offset_known_ = false;
  std::atomic<std::int64_t>* shared_offset_ns_ = nullptr;  // see shareTimeMap()
  std::atomic<bool>* shared_known_ = nullptr;
  ReplayStats stats_;
};

// A recording made ready to run again (`station scan --replay`): the replay that serves it, the
// plan to play (the one the trace carries, or `plan_file` when given) and the session it records.
struct PreparedReplay {
  std::shared_ptr<CellReplay> replay;
  acquisition::ScanPlan plan;
  trace::SessionDescription session;
};
// Throws std::runtime_error naming the trace when it is damaged (unless `accept_damaged`: what
// remains is replayed) or carries no plan and none is given.
PreparedReplay prepareReplay(const std::filesystem::path& trace, bool accept_damaged,
                             const std::filesystem::path& plan_file = {});

}  // namespace stampscan::sim
