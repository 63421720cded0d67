#include "stampscan/fitting/quadric_patch.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <limits>

namespace stampscan::fitting {

QuadricPatch::Sums::Sums(const LocalSurface& plane, const Vec3& origin, double scale)
    : origin_(origin), inv_scale_(1.0 / scale), frame_(frameAround(plane.normal(origin))) {}

QuadricPatch::Sums::Sums(const Eigen::Matrix3d& frame, const Vec3& origin, double scale, int order,
                         std::vector<double>* variance_rows)
    : origin_(origin), inv_scale_(1.0 / scale), frame_(frame), order_(order == 3 ? 3 : 2), variance_rows_(variance_rows) {
  if (variance_rows_) variance_rows_->clear();
}

void QuadricPatch::Sums::add(const Vec3& p, double w) {
  if (order_ == 3) {  // a point is a cell without spread
    addCell(p, Eigen::Matrix3d::Zero(), w, w * w);
    return;
  }
  const Vec3 d = (p - origin_) * inv_scale_;
  const double u = frame_.col(0).dot(d), v = frame_.col(1).dot(d), h = frame_.col(2).dot(d);
  const double uu = u * u, uv = u * v, vv = v * v;
  const double wu = w * u, wv = w * v, wuu = w * uu, wuv = w * uv, wvv = w * vv;
  // Lower triangle of phi phi^T for phi = (1, u, v, uu, uv, vv), row by row.
  ata_[0] += w;
  ata_[1] += wu;
  ata_[2] += wu * u;
  ata_[3] += wv;
  ata_[4] += wv * u;
  ata_[5] += wv * v;
  ata_[6] += wuu;
  ata_[7] += wuu * u;
  ata_[8] += wuu * v;
  ata_[9] += wuu * uu;
  ata_[10] += wuv;
  ata_[11] += wuv * u;
  ata_[12] += wuv * v;
  ata_[13] += wuv * uu;
  ata_[14] += wuv * uv;
  ata_[15] += wvv;
  ata_[16] += wvv * u;
  ata_[17] += wvv * v;
  ata_[18] += wvv * uu;
  ata_[19] += wvv * uv;
  ata_[20] += wvv * vv;
  atb_[0] += w * h;
  atb_[1] += wu * h;
  atb_[2] += wv * h;
  atb_[3] += wuu * h;
  atb_[4] += wuv * h;
  atb_[5] += wvv * h;
  ++count_;
}

void QuadricPatch::Sums::addCell(const Vec3& mean, const Eigen::Matrix3d& covariance, double w,
                                 double variance_weight) {
  const Vec3 d = (mean - origin_) * inv_scale_;
  const Vec3 t1 = frame_.col(0), t2 = frame_.col(1);
  const double u = t1.dot(d), v = t2.dot(d), h = frame_.col(2).dot(d);
  const double s2 = inv_scale_ * inv_scale_;
  const double cuu = t1.dot(covariance * t1) * s2, cuv = t1.dot(covariance * t2) * s2, cvv = t2.dot(covariance * t2) * s2;
  // E[phi] over the cell's points: the means of u^2, uv, v^2 carry the in-plane covariance (and
  // those of the cubic terms the covariance times the mean).
  const double phi[10] = {1.0,
                          u,
                          v,
                          u * u + cuu,
                          u * v + cuv,
                          v * v + cvv,
                          u * u * u + 3 * u * cuu,
                          u * u * v + v * cuu + 2 * u * cuv,
                          u * v * v + u * cvv + 2 * v * cuv,
                          v * v * v + 3 * v * cvv};
  if (order_ == 3)
    accumulate<10>(phi, w, h);
  else
    accumulate<6>(phi, w, h);
  if (variance_rows_) {
    variance_rows_->insert(variance_rows_->end(), phi, phi + terms());
    variance_rows_->push_back(variance_weight);
  }
  ++count_;
}

namespace {
using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 10, 10>;
using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 10, 1>;
Matrix unpack(const double (&lower)[55], int n) {
  Matrix a(n, n);
  int k = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) a(i, j) = a(j, i) = lower[k++];
  return a;
}
// Ridge on the curvature (and cubic) terms only: where the neighbours do not span two directions (a
// row of repeats, an edge) the patch stays close to the plane instead of curling at random. `a` is
// normalised by its total weight.
void addRidge(Matrix& a) {
  const double ridge = 1e-4 * (a(3, 3) + a(5, 5)) + 1e-12;
  for (int i = 3; i < 6; ++i) a(i, i) += ridge;
  // The cubic terms' own scale is their diagonal; the ridge keeps them determined at an edge.
  for (int i = 6; i < a.rows(); ++i) a(i, i) += 1e-4 * a(i, i) + 1e-12;
  a(1, 1) += 1e-12;
  a(2, 2) += 1e-12;
}
}  // namespace

std::optional<QuadricPatch::FitWithVariance> QuadricPatch::fitWithOffsetVariance(const Sums& s) {
  const int n = s.terms();
  Matrix a = unpack(s.ata_, n);
  Vector b(n);
  for (int i = 0; i < n; ++i) b(i) = s.atb_[i];
  const double total = a(0, 0);
  if (!(total > 0)) return std::nullopt;
  a /= total;
  b /= total;
  addRidge(a);
  FitWithVariance result;
  QuadricPatch& patch = result.patch;
  patch.origin_ = s.origin_;
  patch.scale_ = 1.0 / s.inv_scale_;
  patch.frame_ = s.frame_;
  const Eigen::LDLT<Matrix> ldlt(a);
  const Vector c = ldlt.solve(b);
  if (!c.allFinite()) return std::nullopt;
  patch.c_.head(n) = c;
  result.offset_variance_factor = std::numeric_limits<double>::infinity();
  if (s.variance_rows_) {
    // The height at the origin is e_0^T M^-1 A^T W y: its variance per unit residual variance is
    // sum_k v_k (phi_k . r)^2 with r = M^-1 e_0 (M normalised by the total weight, hence total^2).
    const Vector r = ldlt.solve(Vector::Unit(n, 0));
    const std::vector<double>& rows = *s.variance_rows_;
    double factor = 0;
    for (std::size_t k = 0; k + static_cast<std::size_t>(n) < rows.size(); k += static_cast<std::size_t>(n) + 1) {
      double dot = 0;
      for (int i = 0; i < n; ++i) dot += rows[k + static_cast<std::size_t>(i)] * r(i);
      factor += rows[k + static_cast<std::size_t>(n)] * dot * dot;
    }
    factor /= total * total;
    if (std::isfinite(factor) && factor >= 0) result.offset_variance_factor = factor;
  }
  return result;
}

std::optional<QuadricPatch> QuadricPatch::fit(const Sums& s) {
  auto result = fitWithOffsetVariance(s);
  if (!result) return std::nullopt;
  return result->patch;
}

Vec3 QuadricPatch::project(const Vec3& x) const {
  const Vec3 q = toLocal(x);
  double u = q.x(), v = q.y();
  // Minimise (u - u0)^2 + (v - v0)^2 + (f(u, v) - w0)^2 by Gauss-Newton from the foot below x. Two
  // steps leave an error far below the noise for points within a bandwidth of a patch that is not
  // steep in its own frame (its frame is the local tangent plane); callers that move far iterate.
  for (int it = 0; it < 2; ++it) {
    const double r = height(u, v) - q.z();
    const Eigen::Vector2d g = slope(u, v);
    // Solve (I + g g^T) step = J^T r in closed form: (I + g g^T)^-1 = I - g g^T / (1 + |g|^2).
    const Eigen::Vector2d jtr(u - q.x() + g.x() * r, v - q.y() + g.y() * r);
    const Eigen::Vector2d step = jtr - g * (g.dot(jtr) / (1.0 + g.squaredNorm()));
    u -= step.x();
    v -= step.y();
    // The error left after a step is about the step squared times the curvature in patch units
    // (well under one where a patch is read): after a step below 1e-3 of the scale, under 1e-6.
    if (step.squaredNorm() < 1e-6) break;
  }
  return origin_ + scale_ * (frame_ * Vec3(u, v, height(u, v)));
}

Vec3 QuadricPatch::normal(const Vec3& x) const {
  const Vec3 q = toLocal(x);
  const Eigen::Vector2d g = slope(q.x(), q.y());
  return (frame_ * Vec3(-g.x(), -g.y(), 1.0)).normalized();
}

double QuadricPatch::signedDistance(const Vec3& x) const {
  const Vec3 q = toLocal(x);
  const Eigen::Vector2d g = slope(q.x(), q.y());
  return (q.z() - height(q.x(), q.y())) / std::sqrt(1.0 + g.squaredNorm()) * scale_;
}

void QuadricPatch::flip() {
  // w -> -w with the same (u, v): the frame normal turns round and every height changes sign.
  frame_.col(2) = -frame_.col(2);
  c_ = -c_;
}

Eigen::Matrix2d QuadricPatch::hessianAtOrigin() const {
  Eigen::Matrix2d hessian;
  hessian << 2 * c_(3), c_(4), c_(4), 2 * c_(5);
  return hessian / scale_;
}

double QuadricPatch::maxCurvatureAtOrigin() const {
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(hessianAtOrigin()).eigenvalues().cwiseAbs().maxCoeff();
}

}  // namespace stampscan::fitting
