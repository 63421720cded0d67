#include "stampscan/sim/trapezoid_move.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::sim {

TrapezoidMove planTrapezoid(double distance, double max_speed, double accel) {
  if (!(std::isfinite(distance) && distance >= 0)) throw std::invalid_argument("move distance must be >= 0");
  if (!(std::isfinite(max_speed) && max_speed > 0)) throw std::invalid_argument("move speed must be > 0");
  if (!(std::isfinite(accel) && accel > 0)) throw std::invalid_argument("move acceleration must be > 0");
  TrapezoidMove move;
  move.distance = distance;
  move.accel = accel;
  // Accelerating to v and braking from it covers v^2 / a; a shorter move peaks at sqrt(d a).
  move.peak_speed = std::min(max_speed, std::sqrt(distance * accel));
  move.accel_time = move.peak_speed / accel;
  const double ramps = move.peak_speed * move.accel_time;  // both ramps: 2 * v^2 / (2a)
  move.cruise_time = move.peak_speed > 0 ? std::max(0.0, distance - ramps) / move.peak_speed : 0.0;
  return move;
}

double TrapezoidMove::distanceAt(double t) const {
  const double total = duration();
  if (t <= 0) return 0;
  if (t >= total) return distance;
  if (t < accel_time) return 0.5 * accel * t * t;
  if (t < accel_time + cruise_time) return 0.5 * peak_speed * accel_time + peak_speed * (t - accel_time);
  const double left = total - t;  // braking mirrors accelerating
  return std::clamp(distance - 0.5 * accel * left * left, 0.0, distance);
}

double TrapezoidMove::speedAt(double t) const {
  const double total = duration();
  if (t <= 0 || t >= total) return 0;
  if (t < accel_time) return accel * t;
  if (t < accel_time + cruise_time) return peak_speed;
  return accel * (total - t);
}

}  // namespace stampscan::sim
