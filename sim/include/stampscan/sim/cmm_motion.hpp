// The CMM's motion: straight moves of the probe head with trapezoidal speed profiles under speed and
// acceleration limits, inside the machine's travel, and the indexing head's angles. A trajectory is
// built move by move and then sampled at any time.
#pragma once

#include "stampscan/fitting/cloud.hpp"

#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace stampscan::sim {

using fitting::Vec3;

struct CmmLimits {
  double max_speed = 250;     // mm/s
  double max_accel = 800;     // mm/s^2
  double max_head_rate = 1.5; // rad/s for the indexing head
  Vec3 travel_min{-400, -300, -100};
  Vec3 travel_max{400, 300, 600};
};

// Where the probe head is: the ram's reference point and the head's angles a (tilt about x) and b
// (turn about z, applied after a).
struct HeadState {
  Vec3 position = Vec3::Zero();
  double a = 0, b = 0;
  // The head frame in machine coordinates: translation(position) * Rz(b) * Rx(a).
  Eigen::Isometry3d pose() const;
  double speed = 0;  // mm/s along the path at this instant
};

class CmmTrajectory {
 public:
  explicit CmmTrajectory(const CmmLimits& limits = {}, HeadState start = {});

  // A straight move to `target` at up to `speed` mm/s (clamped to the limit), accelerating and
  // braking at the limit; the head turns to (a, b) during the move. Returns the move's index.
  // Throws std::invalid_argument when the target is outside the travel.
  std::size_t moveTo(const Vec3& target, double a, double b, double speed, std::string label = {});
  void dwell(double seconds, std::string label = {});

  struct Segment {
    double t0 = 0, t1 = 0;  // seconds from the start of the trajectory
    HeadState from, to;
    double cruise_speed = 0, accel = 0;
    double accel_time = 0, cruise_time = 0;  // braking takes accel_time too
    double length = 0;
    std::string label;
  };
  const std::vector<Segment>& segments() const { return segments_; }
  double duration() const { return segments_.empty() ? 0.0 : segments_.back().t1; }
  HeadState at(double t) const;
  const HeadState& end() const { return end_; }
  const CmmLimits& limits() const { return limits_; }

 private:
  CmmLimits limits_;
  HeadState end_;
  std::vector<Segment> segments_;
};

}  // namespace stampscan::sim
