#include "stampscan/sim/formed_part.hpp"

#include "stampscan/sim/height_field.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stampscan::sim {

namespace {

// Jacobian of the in-plane inverse map (x, y) -> (u, v) by central differences.
Eigen::Matrix2d materialJacobian(const FormedPart& part, double x, double y) {
  const double e = 1e-5;
  Eigen::Matrix2d J;
  J.col(0) = (part.materialAt(x + e, y) - part.materialAt(x - e, y)) / (2 * e);
  J.col(1) = (part.materialAt(x, y + e) - part.materialAt(x, y - e)) / (2 * e);
  return J;
}

double smoother(double t) {
  if (t <= 0) return 0;
  if (t >= 1) return 1;
  return t * t * t * (t * (6 * t - 15) + 10);
}
double smootherSlope(double t) {
  if (t <= 0 || t >= 1) return 0;
  return 30 * t * t * (1 - t) * (1 - t);
}

}  // namespace

Vec3 FormedPart::normal(double x, double y) const {
  const Vec2 g = heightGradient([this](double u, double v) { return height(u, v); }, x, y);
  return Vec3(-g.x(), -g.y(), 1.0).normalized();
}

Vec3 FormedPart::position(const Vec2& m) const {
  // Newton on materialAt(x) = m. The in-plane map is smooth, monotone and close to the identity,
  // so a few damped steps from x = m converge to machine precision.
  Vec2 x = m;
  Vec2 r = materialAt(x.x(), x.y()) - m;
  for (int it = 0; it < 50 && r.norm() > 1e-11; ++it) {
    const Vec2 step = materialJacobian(*this, x.x(), x.y()).lu().solve(-r);
    double scale = 1.0;
    for (int tries = 0; tries < 30; ++tries, scale *= 0.5) {
      const Vec2 trial = x + scale * step;
      const Vec2 r_trial = materialAt(trial.x(), trial.y()) - m;
      if (r_trial.norm() < r.norm()) {
        x = trial;
        r = r_trial;
        break;
      }
    }
  }
  if (r.norm() > 1e-6) throw std::runtime_error("FormedPart::position: forming map did not invert");
  return surfacePoint(x.x(), x.y());
}

Deformation FormedPart::deformationAt(double x, double y) const {
  Deformation d;
  d.point = surfacePoint(x, y);
  d.normal = normal(x, y);
  d.material = materialAt(x, y);
  // X(m) = (phi(m), h(phi(m))) with phi the inverse of materialAt, so
  // F = [I; grad h] * dphi/dm = [I; grad h] * (dm/dx)^-1.
  const Eigen::Matrix2d dphi = materialJacobian(*this, x, y).inverse();
  const Vec2 g = heightGradient([this](double u, double v) { return height(u, v); }, x, y);
  Eigen::Matrix<double, 3, 2> lift;
  lift << 1, 0, 0, 1, g.x(), g.y();
  d.gradient = lift * dphi;
  // Right Cauchy-Green tensor C = F^T F: its eigenvalues are the squared principal stretches and its
  // eigenvectors the material directions that become the ellipse axes.
  const Eigen::Matrix2d C = d.gradient.transpose() * d.gradient;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(C);
  d.minor_stretch = std::sqrt(eig.eigenvalues()(0));
  d.major_stretch = std::sqrt(eig.eigenvalues()(1));
  d.major_direction_material = eig.eigenvectors().col(1).normalized();
  d.major_direction = (d.gradient * d.major_direction_material).normalized();
  d.major_strain = std::log(d.major_stretch);
  d.minor_strain = std::log(d.minor_stretch);
  d.thickness_strain = -(d.major_strain + d.minor_strain);
  return d;
}

Vec3 FormedPart::closestPoint(const Vec3& p) const {
  return closestPointOnHeightField([this](double u, double v) { return height(u, v); }, p);
}

// ---- Dome -------------------------------------------------------------------------------------

DomePart::DomePart(const DomeParams& params) : params_(params) {
  if (params.die_radius <= 0 || params.blank_half_size < params.die_radius || params.pole_strain < 0 ||
      params.pole_strain > 0.5)
    throw std::invalid_argument("DomePart: need 0 < die radius <= blank half size and 0 <= pole strain <= 0.5");
}

double DomePart::height(double x, double y) const {
  // sqrt rather than hypot: this runs for every ray step of the renderer, and the extra range
  // protection of hypot is not needed at millimetre scales.
  const double s = std::sqrt(x * x + y * y) / params_.die_radius;
  if (s >= 1) return 0;
  const double w = 1 - s * s;
  return params_.depth * w * w;
}

Vec2 DomePart::materialAt(double x, double y) const {
  // A formed point at radius r came from radius rho = r / k(r), k = 1 + beta (1 - s^2)^2: k is the
  // hoop stretch, exp(pole_strain) at the pole and 1 at the die. d(rho)/dr > 0 for every beta >= 0,
  // so the map is one to one.
  const double s = std::sqrt(x * x + y * y) / params_.die_radius;
  if (s >= 1) return {x, y};
  const double beta = std::expm1(params_.pole_strain);
  const double w = 1 - s * s;
  return Vec2(x, y) / (1 + beta * w * w);
}

BlankRect DomePart::blank() const {
  const double h = params_.blank_half_size;
  return {Vec2(-h, -h), Vec2(h, h)};
}

// ---- Stamped pan ------------------------------------------------------------------------------

namespace {
PanParams shapeOf(const StampedPanParams& p) {
  PanParams q;
  q.half_length = p.half_length;
  q.half_width = p.half_width;
  q.pocket_a = p.pocket_a;
  q.pocket_b = p.pocket_b;
  q.depth = p.depth;
  q.wall_width = p.wall_width;
  q.dome_radius = p.dome_radius;
  q.dome_height = p.dome_height;
  return q;
}
}  // namespace

StampedPanPart::StampedPanPart(const StampedPanParams& params) : params_(params), shape_(shapeOf(params)) {
  if (params.pocket_a <= 0 || params.pocket_b <= 0 || params.wall_width <= 0 || params.depth <= 0)
    throw std::invalid_argument("StampedPanPart: pocket sizes, wall width and depth must be positive");
  // Tabulate sigma(s) = int_0^s sqrt(1 + (dz/ds / L)^2) / lambda_m(s) ds, with L the wall's length
  // scale (mm per unit of s across the narrow side). Where the wall is long and steep, more
  // material than its flat projection is needed: it is drawn in from the flange. lambda_m, the
  // meridional stretch, is 1 on floor and flange, rises to 1.05 over the wall and peaks at
  // exp(peak_strain) in a band just above the punch radius.
  const double L = std::min(params.pocket_a, params.pocket_b);
  const double half_run = 0.5 * params.wall_width / L;
  const double s_max = 1.5 * std::hypot(params.half_length / params.pocket_a, params.half_width / params.pocket_b) + 1;
  const int n = 16000;
  table_step_ = s_max / n;
  stretch_.resize(n + 1);
  sigma_.resize(n + 1);
  for (int i = 0; i <= n; ++i) {
    const double s = i * table_step_;
    const double t = (s - (1.0 - half_run)) / (2.0 * half_run);
    const double slope = params.depth * smootherSlope(t) / (2.0 * half_run) / L;
    const double band = std::exp(-std::pow((t - 0.3) / 0.25, 2));
    const double wall = smoother(t * 8) * smoother((1 - t) * 8);
    const double lambda = 1.0 + 0.05 * wall + std::expm1(params.peak_strain) * band;
    stretch_[i] = std::sqrt(1 + slope * slope) / lambda;
    sigma_[i] = i == 0 ? 0 : sigma_[i - 1] + 0.5 * (stretch_[i - 1] + stretch_[i]) * table_step_;
  }
  // The blank: the material that reaches the formed footprint's edge along the axes.
  const Vec2 edge_x = materialAt(params.half_length, 0), edge_y = materialAt(0, params.half_width);
  blank_ = {Vec2(-edge_x.x(), -edge_y.y()), Vec2(edge_x.x(), edge_y.y())};
}

double StampedPanPart::materialRadius(double s) const {
  // Exact integral of the piecewise-linear integrand: sigma is C1 in s.
  const double pos = std::min(s / table_step_, static_cast<double>(stretch_.size() - 2));
  const std::size_t i = static_cast<std::size_t>(pos);
  const double d = (pos - static_cast<double>(i)) * table_step_;
  const double slope = (stretch_[i + 1] - stretch_[i]) / table_step_;
  const double extra = s - static_cast<double>(stretch_.size() - 1) * table_step_;  // beyond the table
  return sigma_[i] + stretch_[i] * d + 0.5 * slope * d * d + std::max(0.0, extra) * stretch_.back();
}

double StampedPanPart::height(double x, double y) const { return shape_.height(x, y); }

Vec2 StampedPanPart::materialAt(double x, double y) const {
  // The pocket's level sets are scaled copies of one rounded rectangle, so moving a point along its
  // ray from the centre by sigma(s) / s maps level set s onto level set sigma(s).
  const double s = shape_.pocketRadius(x, y);
  if (s < 1e-9) return {x, y};
  return Vec2(x, y) * (materialRadius(s) / s);
}

BlankRect StampedPanPart::footprint() const {
  // The corners draw in less than the sides: the footprint is the box around the formed blank.
  Vec2 lo(0, 0), hi(0, 0);
  const BlankRect b = blank();
  for (int i = 0; i <= 64; ++i) {
    const double t = i / 64.0;
    for (const Vec2& m : {Vec2(b.min.x() + t * (b.max.x() - b.min.x()), b.min.y()),
                          Vec2(b.min.x() + t * (b.max.x() - b.min.x()), b.max.y()),
                          Vec2(b.min.x(), b.min.y() + t * (b.max.y() - b.min.y())),
                          Vec2(b.max.x(), b.min.y() + t * (b.max.y() - b.min.y()))}) {
      const Vec3 p = position(m);
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
  }
  return {lo, hi};
}

std::unique_ptr<FormedPart> makePart(PartKind kind) {
  if (kind == PartKind::Dome) return std::make_unique<DomePart>();
  return std::make_unique<StampedPanPart>();
}

}  // namespace stampscan::sim
