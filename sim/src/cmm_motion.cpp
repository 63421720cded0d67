#include "stampscan/sim/cmm_motion.hpp"

#include "stampscan/acquisition/trace/rigid_pose.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::sim {

Eigen::Isometry3d HeadState::pose() const { return trace::headPose(position, a, b); }

CmmTrajectory::CmmTrajectory(const CmmLimits& limits, HeadState start) : limits_(limits), end_(start) {}

std::size_t CmmTrajectory::moveTo(const Vec3& target, double a, double b, double speed, std::string label) {
  if ((target.array() < limits_.travel_min.array()).any() || (target.array() > limits_.travel_max.array()).any())
    throw std::invalid_argument("CMM move to (" + std::to_string(target.x()) + ", " + std::to_string(target.y()) +
                                ", " + std::to_string(target.z()) + ") is outside the machine's travel");
  Segment s;
  s.t0 = duration();
  s.from = end_;
  s.to.position = target;
  s.to.a = a;
  s.to.b = b;
  s.length = (target - end_.position).norm();
  s.label = std::move(label);
  const double v = std::clamp(speed, 1e-3, limits_.max_speed);
  const double acc = limits_.max_accel;
  // Trapezoid when there is room to reach the cruise speed, triangle otherwise.
  double t_acc = v / acc;
  if (acc * t_acc * t_acc > s.length) t_acc = std::sqrt(s.length / acc);
  s.accel = acc;
  s.accel_time = t_acc;
  s.cruise_speed = acc * t_acc;
  s.cruise_time = s.cruise_speed > 0 ? (s.length - acc * t_acc * t_acc) / s.cruise_speed : 0.0;
  double t_move = 2 * t_acc + s.cruise_time;
  // The head turns at its own rate; a move lasts at least as long as the turn.
  const double turn = std::max(std::abs(a - end_.a), std::abs(b - end_.b));
  t_move = std::max(t_move, turn / limits_.max_head_rate);
  s.t1 = s.t0 + t_move;
  segments_.push_back(s);
  end_ = s.to;
  return segments_.size() - 1;
}

void CmmTrajectory::dwell(double seconds, std::string label) {
  Segment s;
  s.t0 = duration();
  s.t1 = s.t0 + seconds;
  s.from = s.to = end_;
  s.label = std::move(label);
  segments_.push_back(s);
}

HeadState CmmTrajectory::at(double t) const {
  if (segments_.empty()) return end_;
  if (t <= 0) return segments_.front().from;
  if (t >= duration()) return end_;
  const auto it = std::upper_bound(segments_.begin(), segments_.end(), t,
                                   [](double value, const Segment& s) { return value < s.t1; });
  const Segment& s = *it;
  const double tau = t - s.t0;
  const double span = s.t1 - s.t0;
  HeadState h;
  // Distance travelled along the trapezoid.
  double dist = 0, speed = 0;
  const double ta = s.accel_time, tc = s.cruise_time;
  if (s.length > 0) {
    if (tau < ta) {
      dist = 0.5 * s.accel * tau * tau;
      speed = s.accel * tau;
    } else if (tau < ta + tc) {
      dist = 0.5 * s.accel * ta * ta + s.cruise_speed * (tau - ta);
      speed = s.cruise_speed;
    } else {
      const double tb = std::min(tau - ta - tc, ta);
      dist = 0.5 * s.accel * ta * ta + s.cruise_speed * tc + s.cruise_speed * tb - 0.5 * s.accel * tb * tb;
      speed = std::max(0.0, s.cruise_speed - s.accel * tb);
    }
    dist = std::min(dist, s.length);
  }
  const double along = s.length > 0 ? dist / s.length : 1.0;
  const double turn = span > 0 ? std::min(1.0, tau / span) : 1.0;
  h.position = s.from.position + along * (s.to.position - s.from.position);
  h.a = s.from.a + turn * (s.to.a - s.from.a);
  h.b = s.from.b + turn * (s.to.b - s.from.b);
  h.speed = speed;
  return h;
}

}  // namespace stampscan::sim
