#include "cmm_machine.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace stampscan::sim::detail {

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

CmmMachine::CmmMachine(VirtualCmmConfig config)
    : config_(std::move(config)),
      position_(config_.power_on_position),
      tool_(config_.initial_tool),
      speed_(config_.default_speed),
      accel_(config_.default_accel) {}

Vec3 CmmMachine::positionLocked(Clock::time_point now) const {
  if (!move_ || move_->length == 0) return position_;
  const double fraction = move_->profile.distanceAt(seconds(now - move_->start)) / move_->length;
  Vec3 p{};
  for (std::size_t i = 0; i < 3; ++i) p[i] = move_->from[i] + (move_->to[i] - move_->from[i]) * fraction;
  return p;
}

Vec3 CmmMachine::position(Clock::time_point now) const {
  std::lock_guard lock(mutex_);
  return positionLocked(now);
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

Clock::time_point CmmMachine::beginMove(const Vec3& target, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  Move move;
  move.start = now;
  move.from = positionLocked(now);
  move.to = target;
  move.length = distance(move.from, target);
  move.profile = planTrapezoid(move.length, std::min(speed_, config_.max_speed), accel_);
  move_ = move;
  return now + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(move.profile.duration()));
}

void CmmMachine::endMove(bool reached, Clock::time_point now) {
  std::lock_guard lock(mutex_);
  if (!move_) return;
  // Reached: exactly the commanded target, not the interpolation's rounding of it.
  position_ = reached ? move_->to : positionLocked(now);
  move_.reset();
  ++(reached ? completed_ : aborted_);
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
