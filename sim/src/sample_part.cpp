#include "stampscan/sim/sample_part.hpp"

#include "stampscan/sim/height_field.hpp"

#include <Eigen/Dense>

#include <algorithm>

#include <cmath>

namespace stampscan::sim {

namespace {
// C2 smoothstep on [0, 1].
double smoother(double t) {
  if (t <= 0) return 0;
  if (t >= 1) return 1;
  return t * t * t * (t * (6 * t - 15) + 10);
}
}  // namespace

PanPart::PanPart(const PanParams& params) : params_(params) {}

double PanPart::pocketRadius(double x, double y) const {
  const double u = x / params_.pocket_a, v = y / params_.pocket_b;
  return std::sqrt(std::sqrt(u * u * u * u + v * v * v * v));
}

double PanPart::wallHeight(double s) const {
  // Wall: from the floor (inside) to the flange (outside) across wall_width around the outline.
  const double half_run = 0.5 * params_.wall_width / std::min(params_.pocket_a, params_.pocket_b);
  const double t = (s - (1.0 - half_run)) / (2.0 * half_run);
  return -params_.depth * (1.0 - smoother(t));
}

double PanPart::height(double x, double y) const {
  double z = wallHeight(pocketRadius(x, y));
  // Dome in the floor: a smooth cap.
  const double r = std::sqrt(x * x + y * y) / params_.dome_radius;
  if (r < 1.0) z += params_.dome_height * (1.0 - smoother(r));
  return z;
}

Eigen::Vector2d PanPart::gradient(double x, double y) const {
  return heightGradient([this](double u, double v) { return height(u, v); }, x, y);
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
  return closestPointOnHeightField([this](double u, double v) { return height(u, v); }, p);
}

}  // namespace stampscan::sim
