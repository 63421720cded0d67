// The trace's poses as Eigen transforms, and the one convention of the CMM head's angles: every
// stage that turns a recorded pose or a head position into a transform uses these.
#pragma once

#include "stampscan/acquisition/trace/session_description.hpp"

#include <Eigen/Geometry>

#include <cstddef>

namespace stampscan::trace {

inline Eigen::Isometry3d toIsometry(const RigidPose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = pose.rotation[static_cast<std::size_t>(3 * r + c)];
    T.translation()(r) = pose.translation[static_cast<std::size_t>(r)];
  }
  return T;
}

inline RigidPose toRigidPose(const Eigen::Isometry3d& T) {
  RigidPose pose;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) pose.rotation[static_cast<std::size_t>(3 * r + c)] = T.linear()(r, c);
    pose.translation[static_cast<std::size_t>(r)] = T.translation()(r);
  }
  return pose;
}

// The head frame in machine coordinates with the ram at `position` (mm), the head tilted by a about
// its x axis and turned by b about the machine's z axis (radians): translation(position) Rz(b) Rx(a).
// The CMM reports its head in these angles (HeadSample, the plan's head poses).
inline Eigen::Isometry3d headPose(const Eigen::Vector3d& position, double a, double b) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translate(position);
  T.rotate(Eigen::AngleAxisd(b, Eigen::Vector3d::UnitZ()));
  T.rotate(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()));
  return T;
}

}  // namespace stampscan::trace
