// The speed profile of one straight CMM move: accelerate at the limit, cruise at the top speed,
// brake at the limit (a triangle when the move is too short to reach the top speed). Used by the
// virtual CMM to execute GoTo and Home in simulated real time.
#pragma once

namespace stampscan::sim {

struct TrapezoidMove {
  double distance = 0;     // mm along the path
  double peak_speed = 0;   // mm/s reached: the speed limit, or less on a short move
  double accel = 0;        // mm/s^2, accelerating and braking alike
  double accel_time = 0;   // s to reach peak_speed; braking takes as long
  double cruise_time = 0;  // s at peak_speed

  double duration() const { return 2 * accel_time + cruise_time; }
  // Distance travelled `t` seconds after the start, clamped to [0, duration()].
  double distanceAt(double t) const;
  double speedAt(double t) const;
};

// Throws std::invalid_argument unless distance >= 0 and max_speed, accel > 0 (all finite).
TrapezoidMove planTrapezoid(double distance, double max_speed, double accel);

}  // namespace stampscan::sim
