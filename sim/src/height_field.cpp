#include "stampscan/sim/height_field.hpp"

#include <Eigen/Dense>

#include <algorithm>

namespace stampscan::sim {

Eigen::Vector2d heightGradient(const HeightFunction& height, double x, double y) {
  const double e = 1e-5;
  return {(height(x + e, y) - height(x - e, y)) / (2 * e), (height(x, y + e) - height(x, y - e)) / (2 * e)};
}

Eigen::Vector3d closestPointOnHeightField(const HeightFunction& height, const Eigen::Vector3d& p) {
  // Minimise E(u, v) = |p - (u, v, h(u, v))|^2. Plain Gauss-Newton crawls near tight radii; the
  // Levenberg-Marquardt damping keeps every step downhill.
  const auto at = [&](double u, double v) { return Eigen::Vector3d(u, v, height(u, v)); };
  const auto energy = [&](double u, double v) { return (p - at(u, v)).squaredNorm(); };
  double u = p.x(), v = p.y();
  double e = energy(u, v);
  double lambda = 1e-3;
  for (int it = 0; it < 200; ++it) {
    const Eigen::Vector2d g = heightGradient(height, u, v);
    const Eigen::Vector3d r = at(u, v) - p;
    Eigen::Matrix<double, 3, 2> J;
    J << 1, 0, 0, 1, g.x(), g.y();
    const Eigen::Matrix2d jtj = J.transpose() * J;
    const Eigen::Vector2d jtr = J.transpose() * r;
    bool improved = false;
    for (int tries = 0; tries < 30 && !improved; ++tries) {
      const Eigen::Vector2d step = (jtj + lambda * Eigen::Matrix2d::Identity()).ldlt().solve(-jtr);
      const double e_new = energy(u + step.x(), v + step.y());
      if (e_new < e) {
        u += step.x();
        v += step.y();
        improved = step.norm() > 1e-13;
        e = e_new;
        lambda = std::max(lambda * 0.3, 1e-9);
        if (!improved) break;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved || jtr.norm() < 1e-14) break;
  }
  return at(u, v);
}

}  // namespace stampscan::sim
