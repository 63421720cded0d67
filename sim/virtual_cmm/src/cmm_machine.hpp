// The machine behind the virtual CMM's I++ DME server: where the ram is, the head's angles, whether
// it is homed, the active tool and its GoToPar (§6.3.6), and the move in progress. It outlives
// connections, like a real controller. Thread-safe: the session's executor moves it while the reader
// thread queries it.
#pragma once

#include "stampscan/sim/trapezoid_move.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <array>
#include <chrono>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace stampscan::sim::detail {

using Clock = std::chrono::steady_clock;
using Vec3 = std::array<double, 3>;

double seconds(Clock::duration d);
double distance(const Vec3& a, const Vec3& b);

// Six axes in the order of the wire names X, Y, Z, Tool.A, Tool.B, Tool.C: mm and degrees (§6.1.2).
struct MachinePose {
  Vec3 xyz{};
  Vec3 abc{};  // degrees
  double axis(std::size_t i) const { return i < 3 ? xyz[i] : abc[i - 3]; }
  double& axis(std::size_t i) { return i < 3 ? xyz[i] : abc[i - 3]; }
  bool operator==(const MachinePose&) const = default;
};
inline constexpr std::array<const char*, 6> kAxisNames{"X", "Y", "Z", "Tool.A", "Tool.B", "Tool.C"};

class CmmMachine {
 public:
  explicit CmmMachine(VirtualCmmConfig config);
  const VirtualCmmConfig& config() const { return config_; }

  Vec3 position(Clock::time_point now) const;  // interpolated along the move in progress
  MachinePose pose(Clock::time_point now) const;  // position and angles at the same instant
  // Where the move in progress at `when` ends (pose(when) at rest then).
  MachinePose destination(Clock::time_point when) const;
  bool homed() const;
  bool moving() const;
  void setHomed();

  std::string activeToolName() const;
  bool hasTool(const std::string& name) const;
  // Makes `name` the active tool; its GoToPar actual values start at the defaults (§6.3.6).
  void setActiveTool(const std::string& name);

  double speed() const;
  double accel() const;
  // Sets the actual value clamped to [min, max] (§6.3.6); false when it had to clamp.
  bool setSpeed(double mm_per_s);
  bool setAccel(double mm_per_s2);

  // Empty when `target` is inside the travel, otherwise which axis is out and by how much.
  std::string travelProblem(const Vec3& target) const;
  // Empty when the head can take `angles` (degrees): inside each axis' range and, for an indexing
  // head, on the index grid. Otherwise which angle and why.
  std::string headProblem(const Vec3& angles) const;
  // The angles the head takes for `angles`: an indexing head's grid values exactly, so that rounding
  // in the client's degree conversion does not accumulate.
  Vec3 headTarget(const Vec3& angles) const;

  // Starts a move to `target`: the ram on a straight line at the actual speed and acceleration (the
  // speed never above the machine's maximum), the head at its own rate limits, all six axes on one
  // trapezoidal progress from 0 to 1 so that they start and finish together (§6.3.2.12). Returns the
  // time it will arrive.
  Clock::time_point beginMove(const MachinePose& target, Clock::time_point now);
  // Ends the move: at the target when `reached`, else where the ram is at `now` (an abort).
  void endMove(bool reached, Clock::time_point now);

  // The report instants of the move in progress when it is followed (FollowedMove::report_at), as
  // absolute times; empty otherwise.
  std::vector<Clock::time_point> followedReportTimes() const;

  std::size_t movesCompleted() const;
  std::size_t movesAborted() const;

 private:
  struct Move {
    Clock::time_point start;
    MachinePose from, to;
    TrapezoidMove progress;  // "distance" 0..1 along the move; 0 long when nothing moves
    std::optional<FollowedMove> followed;  // a replayed move, followed instead of `progress`
    // Once ended: when, and where the machine stood from then on (the target, or where it stopped).
    std::optional<Clock::time_point> end;
    MachinePose rest;
    // The pose `elapsed` seconds after the start, the move still running.
    MachinePose at(double elapsed) const;
  };
  // The pose at any time: a time before the current move (a sensor whose data are built late, on a
  // loaded host, asks for the pose at its exposure) is looked up in the moves that ended.
  MachinePose poseLocked(Clock::time_point when) const;
  // The ended moves, oldest first, kept for kHistory.
  static constexpr std::chrono::seconds kHistory{120};
  std::deque<Move> history_;

  const VirtualCmmConfig config_;
  mutable std::mutex mutex_;
  MachinePose pose_;
  bool homed_ = false;
  std::string tool_;
  double speed_, accel_;
  std::optional<Move> move_;
  std::size_t completed_ = 0, aborted_ = 0;
};

}  // namespace stampscan::sim::detail
