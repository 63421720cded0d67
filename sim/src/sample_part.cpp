#include "stampscan/sim/sample_part.hpp"

#include <Eigen/Dense>

#include <cmath>

namespace stampscan::sim {

namespace {
// C2 smoothstep on [0, 1].
double smoother(double t) {
  if (t <= 0) return 0;
  if (t >= 1) return 1;
  return t * t * t * (t * (6 * t - 15) + 10);
}
// Rounded-rectangle "radius": 1 on the pocket outline, smooth everywhere (superellipse of order 4).
double pocketRadius(double x, double y, double a, double b) {
  const double u = x / a, v = y / b;
  return std::pow(u * u * u * u + v * v * v * v, 0.25);
}
}  // namespace

PanPart::PanPart(const PanParams& params) : params_(params) {}

double PanPart::height(double x, double y) const {
  const PanParams& p = params_;
  // Wall: from the floor (inside) to the flange (outside) across wall_width around the outline.
  const double rho = pocketRadius(x, y, p.pocket_a, p.pocket_b);
  const double half_run = 0.5 * p.wall_width / std::min(p.pocket_a, p.pocket_b);
  const double t = (rho - (1.0 - half_run)) / (2.0 * half_run);
  double z = -p.depth * (1.0 - smoother(t));
  // Dome in the floor: a smooth cap.
  const double r = std::hypot(x, y) / p.dome_radius;
  if (r < 1.0) z += p.dome_height * (1.0 - smoother(r));
  return z;
}

Eigen::Vector2d PanPart::gradient(double x, double y) const {
  const double e = 1e-5;
  return {(height(x + e, y) - height(x - e, y)) / (2 * e), (height(x, y + e) - height(x, y - e)) / (2 * e)};
}

Vec3 PanPart::normal(double x, double y) const {
  const Eigen::Vector2d g = gradient(x, y);
  return Vec3(-g.x(), -g.y(), 1.0).normalized();
}

double PanPart::thicknessStrain(double x, double y) const {
  const Eigen::Vector2d g = gradient(x, y);
  const double slope_sq = g.squaredNorm();
  // Sheet stretched over a slope thins with the secant of the wall angle: eps3 ~ -ln(sqrt(1 + s^2)),
  // scaled to the requested maximum; the dome adds biaxial stretch at its pole.
  const double wall = -0.5 * std::log1p(slope_sq);
  const double r = std::hypot(x, y) / params_.dome_radius;
  const double dome = r < 1.0 ? -0.12 * (1.0 - smoother(r)) : 0.0;
  return params_.max_thinning_strain * wall / 1.2 + dome;
}

Vec3 PanPart::closestPoint(const Vec3& p) const {
  // Minimise E(u, v) = |p - (u, v, z(u, v))|^2 by Levenberg-Marquardt from the point below p. Plain
  // Gauss-Newton crawls near the tight radii of the wall; the damping keeps every step downhill.
  const auto energy = [&](double u, double v) { return (p - surfacePoint(u, v)).squaredNorm(); };
  double u = p.x(), v = p.y();
  double e = energy(u, v);
  double lambda = 1e-3;
  for (int it = 0; it < 200; ++it) {
    const double z = height(u, v);
    const Eigen::Vector2d g = gradient(u, v);
    const Vec3 r(u - p.x(), v - p.y(), z - p.z());
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
  return surfacePoint(u, v);
}

}  // namespace stampscan::sim
