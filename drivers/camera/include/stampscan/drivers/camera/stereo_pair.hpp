// Pairs the frames of the left and right cameras. With software triggers (trigger()), a pair is the
// two frames of the same trigger id, accepted when their station times differ by at most the
// tolerance; in free-run, each frame is paired with the other camera's nearest frame within the
// tolerance. Frames that find no partner are dropped and counted, never paired wrongly.
//
// Thread safety: add() may be called from both cameras' stream threads at once (one mutex); the
// pair callback runs on whichever stream thread completed the pair.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>

#include "stampscan/drivers/camera/gige_camera.hpp"

namespace stampscan::drivers::camera {

struct StereoFrame {
  Frame left, right;
  std::uint64_t trigger_id = 0;  // 0 in free-run
  std::int64_t skew_ns = 0;      // right.station_time_ns - left.station_time_ns
};

struct StereoPairOptions {
  std::chrono::nanoseconds tolerance = std::chrono::milliseconds(5);
  std::size_t max_pending = 8;  // per side: older unmatched frames are dropped
};

struct StereoStats {
  std::uint64_t pairs = 0;
  std::uint64_t unmatched_left = 0, unmatched_right = 0;  // dropped: no partner
  std::uint64_t out_of_tolerance = 0;  // same trigger id, but too far apart in time: both dropped
  std::int64_t last_rejected_skew_ns = 0;  // the skew of the last out-of-tolerance pair
};

class StereoPair {
 public:
  enum class Side { Left, Right };
  using PairCallback = std::function<void(const StereoFrame&)>;

  // Borrows both cameras (they must outlive this object); on_pair receives each pair.
  StereoPair(GigECamera& left, GigECamera& right, PairCallback on_pair, StereoPairOptions options = {});
  ~StereoPair();
  StereoPair(const StereoPair&) = delete;
  StereoPair& operator=(const StereoPair&) = delete;

  void start();  // startStreaming() on both, feeding add()
  void stop() noexcept;
  // Software-triggers left then right; returns the trigger id (the same on both when no trigger
  // was lost; throws DeviceError "trigger" when they disagree).
  std::uint64_t trigger();

  // The pairing itself, usable without cameras (tests, trace replay).
  void add(Side side, const FrameView& frame);
  StereoStats stats() const;

 private:
  void addLocked(Side side, Frame frame);
  GigECamera& left_;
  GigECamera& right_;
  PairCallback on_pair_;
  StereoPairOptions options_;
  mutable std::mutex mutex_;
  std::deque<Frame> pending_[2];
  StereoStats stats_;
};

}  // namespace stampscan::drivers::camera
