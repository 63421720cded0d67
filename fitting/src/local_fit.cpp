#include "stampscan/fitting/local_fit.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>

namespace stampscan::fitting {

void WeightedSums::add(const Vec3& p, double w) {
  const Vec3 q = (p - origin_) * inv_scale_;
  ++count_;
  w_ += w;
  wp_ += w * q;
  wpp_.noalias() += w * q * q.transpose();
}

void WeightedSums::addCell(const Vec3& mean, const Eigen::Matrix3d& covariance, double w) {
  const Vec3 q = (mean - origin_) * inv_scale_;
  ++count_;
  w_ += w;
  wp_ += w * q;
  wpp_.noalias() += w * (q * q.transpose() + covariance * (inv_scale_ * inv_scale_));
}

std::optional<LocalSurface> LocalSurface::fitPlane(const WeightedSums& s) {
  if (!(s.w_ > 0)) return std::nullopt;
  LocalSurface surface;
  surface.origin_ = s.origin_;
  surface.scale_ = s.scale();
  surface.kind_ = Kind::Plane;
  const Vec3 mean_local = s.wp_ / s.w_;  // Eq. (2)
  // Eq. (7): centred weighted covariance B = sum w (q - a)(q - a)^T.
  const Eigen::Matrix3d cov = s.wpp_ / s.w_ - mean_local * mean_local.transpose();
  // Coincident points only (repeated observations of one spot): no plane is defined.
  if (!(cov.trace() > 1e-14)) return std::nullopt;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(cov);
  // Eq. (6): the normal minimises the weighted squared distances: smallest eigenvector.
  Vec3 n = eig.eigenvectors().col(0);
  if (!n.allFinite() || n.squaredNorm() < 0.5) n = Vec3::UnitZ();
  n.normalize();
  const double trace = eig.eigenvalues().sum();
  surface.variation_ = trace > 0 ? std::max(0.0, eig.eigenvalues()(0)) / trace : 0.0;
  surface.spread_ = std::max(0.0, eig.eigenvalues()(1));
  surface.ul_ = n;
  surface.u0_ = -n.dot(mean_local);
  surface.uq_ = 0;
  surface.mean_ = s.origin_ + mean_local * surface.scale_;
  return surface;
}

void AlgebraicMoments::add(const Vec3& p, double w) {
  const double x = (p.x() - origin_.x()) * inv_scale_, y = (p.y() - origin_.y()) * inv_scale_,
               z = (p.z() - origin_.z()) * inv_scale_;
  const double r = x * x + y * y + z * z;
  const double wx = w * x, wy = w * y, wz = w * z, wr = w * r;
  ++count_;
  s_[0] += w;
  s_[1] += wx;
  s_[2] += wy;
  s_[3] += wz;
  s_[4] += wr;
  s_[5] += wx * x;
  s_[6] += wx * y;
  s_[7] += wx * z;
  s_[8] += wx * r;
  s_[9] += wy * y;
  s_[10] += wy * z;
  s_[11] += wy * r;
  s_[12] += wz * z;
  s_[13] += wz * r;
  s_[14] += wr * r;
}

Eigen::Matrix<double, 5, 5> AlgebraicMoments::matrix() const {
  Eigen::Matrix<double, 5, 5> m;
  m << s_[0], s_[1], s_[2], s_[3], s_[4],  //
      s_[1], s_[5], s_[6], s_[7], s_[8],   //
      s_[2], s_[6], s_[9], s_[10], s_[11],  //
      s_[3], s_[7], s_[10], s_[12], s_[13],  //
      s_[4], s_[8], s_[11], s_[13], s_[14];
  return m;
}

std::optional<LocalSurface> LocalSurface::fitPrattSphere(const AlgebraicMoments& moments) {
  if (!(moments.weightSum() > 0) || moments.count() < 5) return std::nullopt;
  Eigen::Matrix<double, 5, 5> m = moments.matrix();
  // Normalise by the weight sum, and regularise slightly so that exactly co-spherical or
  // co-planar data (where M is singular) still give the obvious answer.
  m /= m(0, 0);
  m.diagonal().array() += 1e-10 * (1.0 + m.trace());
  // Pratt's constraint u^T N u = |ul|^2 - 4 u0 uq.
  Eigen::Matrix<double, 5, 5> n = Eigen::Matrix<double, 5, 5>::Zero();
  n(1, 1) = n(2, 2) = n(3, 3) = 1.0;
  n(0, 4) = n(4, 0) = -2.0;
  // min u^T M u subject to u^T N u = 1  <=>  N u = mu M u with the largest mu (mu = 1 / lambda).
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix<double, 5, 5>> solver(n, m, Eigen::ComputeEigenvectors | Eigen::Ax_lBx);
  if (solver.info() != Eigen::Success) return std::nullopt;
  const double mu = solver.eigenvalues()(4);
  if (!(mu > 0)) return std::nullopt;
  Eigen::Matrix<double, 5, 1> u = solver.eigenvectors().col(4);
  const double pratt = u(1) * u(1) + u(2) * u(2) + u(3) * u(3) - 4.0 * u(0) * u(4);
  if (!(pratt > 0) || !u.allFinite()) return std::nullopt;
  u /= std::sqrt(pratt);
  LocalSurface surface;
  surface.origin_ = moments.origin_;
  surface.scale_ = 1.0 / moments.inv_scale_;
  surface.kind_ = Kind::Sphere;
  surface.u0_ = u(0);
  surface.ul_ = u.segment<3>(1);
  surface.uq_ = std::abs(u(4)) < 1e-9 ? 0.0 : u(4);
  surface.mean_ = surface.origin_ + Vec3(m(0, 1), m(0, 2), m(0, 3)) * surface.scale_;
  return surface;
}

Vec3 LocalSurface::project(const Vec3& x) const {
  const Vec3 q = toLocal(x);
  Vec3 projected;
  if (uq_ == 0) {
    const double d = (u0_ + ul_.dot(q)) / ul_.squaredNorm();
    projected = q - d * ul_;
  } else {
    const Vec3 centre = -ul_ / (2.0 * uq_);
    const double radius_sq = centre.squaredNorm() - u0_ / uq_;
    const Vec3 dir = q - centre;
    const double dn = dir.norm();
    if (!(radius_sq > 0) || !(dn > 0)) {
      // Degenerate (imaginary sphere or x at the centre): fall back to a first-order step.
      const Vec3 g = ul_ + 2.0 * uq_ * q;
      const double value = u0_ + ul_.dot(q) + uq_ * q.squaredNorm();
      projected = q - value / g.squaredNorm() * g;
    } else {
      projected = centre + std::sqrt(radius_sq) / dn * dir;
    }
  }
  return origin_ + projected * scale_;
}

Vec3 LocalSurface::normal(const Vec3& x) const {
  const Vec3 q = toLocal(x);
  Vec3 g = ul_ + 2.0 * uq_ * q;
  const double n = g.norm();
  return n > 0 ? Vec3(g / n) : Vec3::UnitZ();
}

double LocalSurface::signedDistance(const Vec3& x) const {
  const Vec3 q = toLocal(x);
  const double value = u0_ + ul_.dot(q) + uq_ * q.squaredNorm();
  const double g = (ul_ + 2.0 * uq_ * q).norm();
  return g > 0 ? value / g * scale_ : 0.0;
}

double LocalSurface::curvature() const { return 2.0 * uq_ / scale_; }

}  // namespace stampscan::fitting
