// The machine behind the virtual CMM's I++ DME server: where the ram is, whether it is homed, the
// active tool and its GoToPar (§6.3.6), and the move in progress. It outlives connections, like a
// real controller. Thread-safe: the session's executor moves it while the reader thread queries it.
#pragma once

#include "stampscan/sim/trapezoid_move.hpp"
#include "stampscan/sim/virtual_cmm.hpp"

#include <array>
#include <chrono>
#include <mutex>
#include <optional>
#include <string>

namespace stampscan::sim::detail {

using Clock = std::chrono::steady_clock;
using Vec3 = std::array<double, 3>;

double seconds(Clock::duration d);
double distance(const Vec3& a, const Vec3& b);

class CmmMachine {
 public:
  explicit CmmMachine(VirtualCmmConfig config);
  const VirtualCmmConfig& config() const { return config_; }

  Vec3 position(Clock::time_point now) const;  // interpolated along the move in progress
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

  // Starts a straight move to `target` at the actual speed and acceleration (the speed never above
  // the machine's maximum); returns the time it will arrive.
  Clock::time_point beginMove(const Vec3& target, Clock::time_point now);
  // Ends the move: at the target when `reached`, else where the ram is at `now` (an abort).
  void endMove(bool reached, Clock::time_point now);

  std::size_t movesCompleted() const;
  std::size_t movesAborted() const;

 private:
  struct Move {
    Clock::time_point start;
    Vec3 from, to;
    double length = 0;
    TrapezoidMove profile;
  };
  Vec3 positionLocked(Clock::time_point now) const;

  const VirtualCmmConfig config_;
  mutable std::mutex mutex_;
  Vec3 position_;
  bool homed_ = false;
  std::string tool_;
  double speed_, accel_;
  std::optional<Move> move_;
  std::size_t completed_ = 0, aborted_ = 0;
};

}  // namespace stampscan::sim::detail
