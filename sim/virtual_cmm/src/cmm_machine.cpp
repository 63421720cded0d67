#include "cmm_machine.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace stampscan::sim::detail {

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

namespace {
// The head's part of the configuration: a bad one would divide by zero or trap the head.
const VirtualCmmConfig& checkedHead(const VirtualCmmConfig& c) {
  if (!(c.head_max_rate_deg_s > 0) || !(c.head_accel_deg_s2 > 0)) {
    throw std::invalid_argument("virtual CMM: head_max_rate_deg_s and head_accel_deg_s2 must be > 0");
  }
  if (c.head_kind == VirtualCmmConfig::HeadKind::Indexing && !(c.head_index_step_deg > 0)) {
    throw std::invalid_argument("virtual CMM: an indexing head needs head_index_step_deg > 0");
  }
  for (std::size_t i = 0; i < 3; ++i) {
    if (!(c.head_min_deg[i] <= c.head_power_on_deg[i] && c.head_power_on_deg[i] <= c.head_max_deg[i])) {
      throw std::invalid_argument("virtual CMM: head_power_on_deg[" + std::to_string(i) +
                                  "] is outside [head_min_deg, head_max_deg]");
    }
  }
  return c;
}
}  // namespace

CmmMachine::CmmMachine(VirtualCmmConfig config)
    : config_(checkedHead(config)),
      pose_{config_.power_on_position, config_.head_power_on_deg},
      tool_(config_.initial_tool),
      speed_(config_.default_speed),
      accel_(config_.default_accel) {}

MachinePose CmmMachine::Move::at(double elapsed) const {
  if (followed) {
    const std::array<double, 6> axes = followed->pose_at(std::clamp(elapsed, 0.0, followed->seconds));
    MachinePose p;
    for (std::size_t i = 0; i < 6; ++i) p.axis(i) = axes[i];
    return p;
  }
  if (progress.distance == 0) return from;
  const double fraction = progress.distanceAt(elapsed);
  MachinePose p;
  for (std::size_t i = 0; i < 6; ++i) p.axis(i) = from.axis(i) + (to.axis(i) - from.axis(i)) * fraction;
  return p;
}

MachinePose CmmMachine::poseLocked(Clock::time_point when) const {
  if (move_ && when >= move_->start) return move_->at(seconds(when - move_->start));
  // The latest ended move that had started by then: on it, or at rest after it.
  for (auto m = history_.rbegin(); m != history_.rend(); ++m) {
    if (when < m->start) continue;
    return when < *m->end ? m->at(seconds(when - m->start)) : m->rest;
  }
  // Before every move remembered: where the oldest started, or the machine's pose when none did.
  if (!history_.empty()) return history_.front().from;
  return move_ ? move_->from : pose_;
}

Vec3 CmmMachine::position(Clock::time_point now) const {
  std::lock_guard lock(mutex_);
  return poseLocked(now).xyz;
}

MachinePose CmmMachine::pose(Clock::time_point now) const {
  std::lock_guard lock(mutex_);
  return poseLocked(now);
}

MachinePose CmmMachine::destination(Clock::time_point when) const {
  std::lock_guard lock(mutex_);
  // A followed move's `to` is where the recording arrived.
  if (move_ && when >= move_->start) return move_->to;
  // Before the move under way: the target of the move under way then, or where it stood.
  for (auto m = history_.rbegin(); m != history_.rend(); ++m) {
    if (when < m->start) continue;
    return when < *m->end ? m->to : m->rest;
  }
  return poseLocked(when);
}

bool CmmMachine::homed() const {
  std::lock_guard lock(mutex_);
  return homed_;
}

bool CmmMachine::moving() const {
  std::lock_guard lock(mutex_);
  return move_.has_value();
}

void CmmMachine::setHomed() {
  std::lock_guard lock(mutex_);
  homed_ = true;
}

std::string CmmMachine::activeToolName() const {
  std::lock_guard lock(mutex_);
  return tool_;
}

bool CmmMachine::hasTool(const std::string& name) const {
  return std::find(config_.tools.begin(), config_.tools.end(), name) != config_.tools.end();
}

void CmmMachine::setActiveTool(const std::string& name) {
  std::lock_guard lock(mutex_);
  tool_ = name;
  speed_ = config_.default_speed;
  accel_ = config_.default_accel;
}

double CmmMachine::speed() const {
  std::lock_guard lock(mutex_);
  return speed_;
}

double CmmMachine::accel() const {
  std::lock_guard lock(mutex_);
  return accel_;
}

bool CmmMachine::setSpeed(double mm_per_s) {
  std::lock_guard lock(mutex_);
  speed_ = std::clamp(mm_per_s, config_.min_speed, config_.max_speed);
  return speed_ == mm_per_s;
}

bool CmmMachine::setAccel(double mm_per_s2) {
  std::lock_guard lock(mutex_);
  accel_ = std::clamp(mm_per_s2, config_.min_accel, config_.max_accel);
  return accel_ == mm_per_s2;
}

std::string CmmMachine::travelProblem(const Vec3& target) const {
  static constexpr std::array<char, 3> kAxis{'X', 'Y', 'Z'};
  for (std::size_t i = 0; i < 3; ++i) {
    if (target[i] < config_.travel_min[i] || target[i] > config_.travel_max[i]) {
      std::ostringstream why;
      why << kAxis[i] << "(" << target[i] << ") is outside the travel [" << config_.travel_min[i] << ", "
          << config_.travel_max[i] << "]";
      return why.str();
    }
  }
  return {};
}

std::string CmmMachine::headProblem(const Vec3& angles) const {
  for (std::size_t i = 0; i < 3; ++i) {
    std::ostringstream why;
    why << kAxisNames[i + 3] << "(" << angles[i] << ")";
    if (angles[i] < config_.head_min_deg[i] || angles[i] > config_.head_max_deg[i]) {
      why << " is outside the head's range [" << config_.head_min_deg[i] << ", " << config_.head_max_deg[i]
          << "] degrees";
      return why.str();
    }
    if (config_.head_kind == VirtualCmmConfig::HeadKind::Indexing) {
      const double steps = angles[i] / config_.head_index_step_deg;
      // A millionth of a degree: what the client's radian-degree round trip may add, far below any head.
      if (std::abs(steps - std::round(steps)) * config_.head_index_step_deg > 1e-6) {
        why << " is not an index position of this indexing head (every " << config_.head_index_step_deg
            << " degrees)";
        return why.str();
      }
    }
  }
  return {};
}

Vec3 CmmMachine::headTarget(const Vec3& angles) const {
  if (config_.head_kind != VirtualCmmConfig::HeadKind::Indexing) return angles;
  Vec3 grid{};
  for (std::size_t i = 0; i < 3; ++i) {
    grid[i] = std::round(angles[i] / config_.head_index_step_deg) * config_.head_index_step_deg;
  }
  return grid;
}

Clock::time_point CmmMachine::beginMove(const MachinePose& target, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  Move move;
  move.start = now;
  move.from = poseLocked(now);
  move.to = target;
  if (config_.follow) {
    std::array<double, 6> from{}, to{};
    for (std::size_t i = 0; i < 6; ++i) from[i] = move.from.axis(i), to[i] = target.axis(i);
    if (std::optional<FollowedMove> followed = config_.follow(from, to, now)) {
      // It arrives where the recording arrived, which is the target to the machine's resolution.
      move.followed = std::move(followed);
      const std::array<double, 6> end = move.followed->pose_at(move.followed->seconds);
      for (std::size_t i = 0; i < 6; ++i) move.to.axis(i) = end[i];
      move.progress = planTrapezoid(0.0, 1.0, 1.0);
      const double duration = move.followed->seconds;
      move_ = std::move(move);
      return now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(duration));
    }
  }
  // The progress p runs from 0 to 1. The ram moves length * p, each angle delta * p: its speed and
  // acceleration limits become limits on dp/dt of limit / length and limit / delta, and the tightest
  // of them all shapes the one trapezoid every axis follows. A move of the ram alone keeps the
  // timing of a plain trapezoid over its length.
  const double length = distance(move.from.xyz, target.xyz);
  double turn = 0;
  for (std::size_t i = 0; i < 3; ++i) turn = std::max(turn, std::abs(target.abc[i] - move.from.abc[i]));
  double rate = std::numeric_limits<double>::infinity();
  double accel = std::numeric_limits<double>::infinity();
  if (length > 0) {
    rate = std::min(speed_, config_.max_speed) / length;
    accel = accel_ / length;
  }
  if (turn > 0) {
    rate = std::min(rate, config_.head_max_rate_deg_s / turn);
    accel = std::min(accel, config_.head_accel_deg_s2 / turn);
  }
  move.progress = length > 0 || turn > 0 ? planTrapezoid(1.0, rate, accel) : planTrapezoid(0.0, 1.0, 1.0);
  move_ = move;
  return now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(move.progress.duration()));
}

void CmmMachine::endMove(bool reached, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  if (!move_) return;
  // Reached: exactly the commanded target, not the interpolation's rounding of it.
  pose_ = reached ? move_->to : poseLocked(now);
  move_->end = now;
  move_->rest = pose_;
  history_.push_back(std::move(*move_));
  while (!history_.empty() && *history_.front().end < now - kHistory) history_.pop_front();
  move_.reset();
  ++(reached ? completed_ : aborted_);
}

std::vector<Clock::time_point> CmmMachine::followedReportTimes() const {
  std::lock_guard lock(mutex_);
  std::vector<Clock::time_point> times;
  if (!move_ || !move_->followed) return times;
  for (const double t : move_->followed->report_at)
    times.push_back(move_->start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(t)));
  return times;
}

std::size_t CmmMachine::movesCompleted() const {
  std::lock_guard lock(mutex_);
  return completed_;
}

std::size_t CmmMachine::movesAborted() const {
  std::lock_guard lock(mutex_);
  return aborted_;
}

}  // namespace stampscan::sim::detail
