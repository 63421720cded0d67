#include "stampscan/drivers/camera/stereo_pair.hpp"

#include <cstdlib>

namespace stampscan::drivers::camera {

StereoPair::StereoPair(GigECamera& left, GigECamera& right, PairCallback on_pair, StereoPairOptions options)
    : left_(left), right_(right), on_pair_(std::move(on_pair)), options_(options) {}

StereoPair::~StereoPair() { stop(); }

void StereoPair::start() {
  left_.startStreaming([this](const FrameView& f) { add(Side::Left, f); });
  try {
    right_.startStreaming([this](const FrameView& f) { add(Side::Right, f); });
  } catch (...) {
    left_.stopStreaming();
    throw;
  }
}

void StereoPair::stop() noexcept {
  left_.stopStreaming();
  right_.stopStreaming();
}

std::uint64_t StereoPair::trigger() {
  const std::uint64_t l = left_.softwareTrigger();
  const std::uint64_t r = right_.softwareTrigger();
  if (l != r) {
    throw DeviceError(left_.name() + "+" + right_.name(), "trigger",
                      "trigger ids disagree: left " + std::to_string(l) + ", right " + std::to_string(r));
  }
  return l;
}

void StereoPair::add(Side side, const FrameView& frame) {
  // Copy outside the lock: the bytes are only valid during the camera's callback.
  Frame owned = Frame::copyOf(frame);
  std::unique_lock lock(mutex_);
  addLocked(side, std::move(owned));
}

void StereoPair::addLocked(Side side, Frame frame) {
  const int me = side == Side::Left ? 0 : 1;
  std::deque<Frame>& others = pending_[1 - me];
  const std::int64_t tol = options_.tolerance.count();
  auto dropped = [&](int which, std::uint64_t n) {
    (which == 0 ? stats_.unmatched_left : stats_.unmatched_right) += n;
  };
  // Find the partner: same trigger id, else (free-run) the nearest station time within tolerance.
  std::size_t match = others.size();
  if (frame.info.trigger_id != 0) {
    for (std::size_t i = 0; i < others.size(); ++i) {
      if (others[i].info.trigger_id == frame.info.trigger_id) match = i;
    }
  } else {
    std::int64_t best = tol + 1;
    for (std::size_t i = 0; i < others.size(); ++i) {
      const std::int64_t d = std::llabs(others[i].info.station_time_ns - frame.info.station_time_ns);
      if (d < best) {
        best = d;
        match = i;
      }
    }
  }
  if (match == others.size()) {
    pending_[me].push_back(std::move(frame));
    while (pending_[me].size() > options_.max_pending) {
      pending_[me].pop_front();
      dropped(me, 1);
    }
    return;
  }
  // Frames older than the partner on its side will never be paired (ids and times increase).
  dropped(1 - me, match);
  Frame partner = std::move(others[match]);
  others.erase(others.begin(), others.begin() + static_cast<std::ptrdiff_t>(match) + 1);
  StereoFrame pair;
  pair.left = me == 0 ? std::move(frame) : std::move(partner);
  pair.right = me == 0 ? std::move(partner) : std::move(frame);
  pair.trigger_id = pair.left.info.trigger_id;
  pair.skew_ns = pair.right.info.station_time_ns - pair.left.info.station_time_ns;
  if (std::llabs(pair.skew_ns) > tol) {
    ++stats_.out_of_tolerance;
    stats_.last_rejected_skew_ns = pair.skew_ns;
    return;
  }
  ++stats_.pairs;
  if (on_pair_) on_pair_(pair);
}

StereoStats StereoPair::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace stampscan::drivers::camera
