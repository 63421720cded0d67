#include "sheet_arcs.hpp"

namespace stampscan::registration::detail {

Eigen::Vector2d chordToArc(const Eigen::Vector2d& u, const Eigen::Matrix2d& curvature) {
  const Eigen::Vector2d bend = curvature * u;
  return u + (u.dot(bend) / 6) * bend;
}


}  // namespace stampscan::registration::detail
